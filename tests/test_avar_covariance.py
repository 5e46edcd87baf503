"""Covariance of overlapping AVAR estimates: against brute-force Isserlis sums and Greenhall's
EDF."""

import numpy as np
import pytest

from bayes_imu.allan.estimator import greenhall_edf
from bayes_imu.noise.avar_covariance import avar_covariance, equivalent_dof, exact_pair_sums
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import flicker_difference_acov
from test_models import PARAMS

N = 120
DT = 0.5
MS = np.array([1, 2, 3, 5, 8, 16, 29])


def rate_covariance(term, p):
    """Covariance matrix of y_0..y_{N-1} for one term, from its definition (independent of D)."""
    i = np.arange(N)
    if term == "white":
        return p["noise_variance"] * np.eye(N)
    if term == "gauss_markov":
        return p["bias_variance"] * np.exp(
            -np.abs(i[:, None] - i[None, :]) * DT / p["time_constant"]
        )
    if term == "random_walk":
        return p["rate_random_walk"] ** 2 * DT * (np.minimum(i[:, None], i[None, :]) + 1)
    if term == "quantization":
        diff = np.zeros((N, N + 1))
        diff[i, i + 1], diff[i, i] = 1.0, -1.0
        return (p["quantization"] / DT) ** 2 * diff @ diff.T
    z = flicker_difference_acov(N, p["bias_instability"])[np.abs(i[:, None] - i[None, :])]
    lower = np.tril(np.ones((N, N)), -1)  # y_k = sum_{t<k} z_t
    return lower @ z @ lower.T


def brute_force(sigma):
    """Cov(avar_a, avar_b) = 2 tr(A_a S A_b S), A_m the quadratic form of the estimator
    (Isserlis)."""
    forms = []
    for m in MS:
        rows = N - 2 * m + 1
        d = np.zeros((rows, N))
        for r in range(rows):
            d[r, r + m : r + 2 * m] += 1.0
            d[r, r : r + m] -= 1.0
        forms.append(d.T @ d / (2.0 * m * m * rows))
    return np.array([[2.0 * np.trace(a @ sigma @ b @ sigma) for b in forms] for a in forms])


@pytest.mark.parametrize(
    "terms, rtol",
    [
        (("white",), 1e-12),
        (("gauss_markov",), 1e-12),
        (("random_walk",), 1e-12),
        (("quantization",), 1e-12),
        (("white", "quantization", "gauss_markov", "random_walk"), 1e-12),
        # flicker: exact inside the windows, asymptotic tail outside (documented <1%)
        (("bias_instability",), 1e-2),
    ],
)
def test_matches_brute_force_isserlis(terms, rtol):
    params = {k: v for t in terms for k, v in PARAMS[t].items()}
    params["time_constant"] = 3.0
    model = NoiseModel(terms, DT)
    ref = brute_force(sum(rate_covariance(t, params) for t in terms))
    got = avar_covariance(model, params, MS, N)
    assert np.max(np.abs(got - ref)) <= rtol * np.max(np.abs(ref))
    np.testing.assert_allclose(np.diag(got), np.diag(ref), rtol=max(rtol, 1e-10) * 5)


@pytest.mark.parametrize("terms", [("white", "quantization", "gauss_markov", "random_walk"),
                                   ("bias_instability",)])
def test_exact_lag_sums_match_brute_force_isserlis(terms):
    """The path of a ``"generic"`` covariance tail (every lag summed from the table of D) is exact
    for every term, flicker included (the kernel's flicker tail is asymptotic): 1e-9."""
    params = {k: v for t in terms for k, v in PARAMS[t].items()}
    params["time_constant"] = 3.0
    model = NoiseModel(terms, DT)
    ref = brute_force(sum(rate_covariance(t, params) for t in terms))
    table = model.structure_function(np.arange(N + 4 * MS.max() + 1), params)
    mf = MS.astype(float)
    norm = 2.0 * np.outer(mf * mf * (N - 2 * mf + 1), mf * mf * (N - 2 * mf + 1))
    got = exact_pair_sums(np.asarray(table, float), MS, N) / norm
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_gauss_markov_near_random_walk_limit_stays_accurate():
    """T = 1e4 x the record: brute force and lag sums still agree to 1e-9 (no cancellation)."""
    params = {"bias_variance": 1.5, "time_constant": 3e4 * N}
    ref = brute_force(rate_covariance("gauss_markov", params))
    got = avar_covariance(NoiseModel(("gauss_markov",), DT), params, MS, N)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


@pytest.mark.parametrize(
    "term, alpha, rtol",
    [
        ("white", 0, 2e-3),
        ("random_walk", -2, 2e-3),
        ("bias_instability", -1, 5e-3),
        ("quantization", 2, 1e-9),
    ],
)
def test_diagonal_is_greenhall_edf_at_large_m(term, alpha, rtol):
    """Greenhall & Riley's EDF is the large-m limit of the exact diagonal (white phase: exact for
    all m).

    For small m Greenhall's algorithm is an approximation: for white rate noise at m = 1 it
    is 17% above the exact EDF (Monte Carlo confirms the exact value, test below).
    """
    n = 10_000
    m = 2 ** np.arange(6, 12) if alpha != 2 else 2 ** np.arange(12)
    model = NoiseModel((term,), 1.0)
    edf = equivalent_dof(model.avar(m, PARAMS[term]), avar_covariance(model, PARAMS[term], m, n))
    np.testing.assert_allclose(edf, greenhall_edf([alpha] * m.size, m, n + 1), rtol=rtol)


@pytest.mark.slow  # a Monte Carlo check of thousands of records: the nightly job
def test_small_m_edf_monte_carlo(rng):
    """White rate noise, N = 4096, m = 1, 2, 4: exact EDF vs 2000 simulated records (5 sigma on
    Var)."""
    from bayes_imu.allan.estimator import allan_variance

    m = np.array([1, 2, 4])
    model = NoiseModel(("white",), 1.0)
    cov = avar_covariance(model, {"noise_variance": 1.0}, m, 4096)
    draws = np.array(
        [allan_variance(rng.standard_normal(4096), rate_hz=1.0, m=m).avar for _ in range(2000)]
    )
    var = draws.var(axis=0, ddof=1)
    assert np.all(np.abs(var / np.diag(cov) - 1) < 5 * np.sqrt(2 / 2000))
    # and Greenhall's approximation is outside that band at m = 1
    assert greenhall_edf([0], [1], 4097)[0] / equivalent_dof(np.array([1.0]), cov[:1, :1])[0] > 1.1


def test_adjacent_octave_correlation():
    """Issue statement: adjacent octaves correlate ~0.5 for white noise, ~0.9 for a random walk."""
    m = 2 ** np.arange(10)
    for term, lo, hi in (("white", 0.4, 0.6), ("random_walk", 0.8, 0.97)):
        cov = avar_covariance(NoiseModel((term,), 1.0), PARAMS[term], m, 100_000)
        sd = np.sqrt(np.diag(cov))
        rho = np.diag(cov, 1) / (sd[:-1] * sd[1:])
        assert np.all((rho[2:] > lo) & (rho[2:] < hi)), rho


def test_vibration_path_keeps_a_random_walk_exact_on_long_records():
    """Regression (a plan predicting wider intervals for longer records): with a vibration line
    every lag is summed from a table of D, and a rate random walk's D(l) ~ l^3 cancelled
    catastrophically in second differences at lags of the record's order (Var of the estimate at
    one sample 470x too large on 8.6e6 samples). Reference: white + random walk at cluster size
    1, d_i = e_{i+1} - e_i + w_i is MA(1) with variance s = 2 sigma^2 + q^2 dt and lag-one
    covariance -sigma^2, so by Isserlis Var(avar_1) = (M s^2 + 2 (M - 1) sigma^4) / (2 M^2),
    exact in rationals; the line's amplitude (1e-12) adds a relative 1e-21."""
    from fractions import Fraction

    n, dt, var, q = 100_000, 0.01, 1e-3, 20.0
    model = NoiseModel(("white", "random_walk", "vibration"), dt=dt)
    p = {"noise_variance": var, "rate_random_walk": q, "vibration_frequency": 0.559,
         "vibration_amplitude": 1e-12}
    got = avar_covariance(model, p, np.array([1, 2]), n)[0, 0]
    big_m, s2, s = n - 1, Fraction(var) ** 2, 2 * Fraction(var) + Fraction(q) ** 2 * Fraction(dt)
    exact = (big_m * s * s + 2 * (big_m - 1) * s2) / (2 * big_m**2)
    assert got == pytest.approx(float(exact), rel=1e-9)


def test_exact_lag_sums_with_window_and_signal_match_the_double_sum():
    """The compiled lag sum (``exact_pair_sums``) against its definition, every pair of second
    differences summed: ``sum_{i,j} C_ij (C_ij + 2 E_ij)``, ``C_ij = -1/2 sum_{p,q} w_p w_q
    D(|p a + i - q b - j|)`` of the noise's table (a Gauss-Markov bias correlated beyond the
    window plus white noise given as the window-only table) and ``E`` of a sinusoid's
    ``D(k) = 2 A^2 (1 - cos(w k))`` (a vibration line's signal). 1e-12 relative."""
    n, ms = 150, np.array([1, 3, 8, 20], dtype=np.int64)
    k = np.arange(n + 4 * ms.max() + 1, dtype=float)
    phi = np.exp(-0.01 / 0.4)
    gm = 0.7 * (k * (1 - phi**2) - 2 * phi * (1 - phi**k)) / (1 - phi) ** 2
    white = 0.3 * k
    signal = 2.0 * 0.5**2 * (1.0 - np.cos(0.9 * k))
    got = exact_pair_sums(gm, ms, n, local=white, deterministic=signal)
    w = (1.0, -2.0, 1.0)

    def cov(table, a, b, i, j):
        return -0.5 * sum(w[p] * w[q] * table[abs(p * a + i - q * b - j)]
                          for p in range(3) for q in range(3))

    ref = np.zeros((ms.size, ms.size))
    for ia, a in enumerate(ms):
        for ib, b in enumerate(ms):
            total = 0.0
            for i in range(n - 2 * a + 1):
                for j in range(n - 2 * b + 1):
                    c = cov(gm + white, a, b, i, j)
                    total += c * (c + 2.0 * cov(signal, a, b, i, j))
            ref[ia, ib] = total
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
