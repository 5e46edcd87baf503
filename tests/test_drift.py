"""Tests of bayes_imu.drift.closed_forms against exact references.

References: ``tests/exact.py`` (exact rational covariance propagation, and 400-bit mpmath
binary-splitting propagation), neither of which uses the package's closed forms; the
continuous-time variances are integrated numerically with mpmath.quad.
"""

import mpmath as mp
import numpy as np
import pytest
from exact import fraction_variance, mpmath_variance

from bayes_imu import (
    InputError,
    ModelError,
    drift_sigma,
    euler_variance,
    gauss_markov_driving_variance,
)
from bayes_imu import noise_density_to_variance, noise_variance_to_density
from bayes_imu.noise.euler_sums import SERIES_TERMS, SWITCH, gm_coefficient, gm_sum

REL = 1e-13  # the issue asks for 1e-12; the kernel reaches a few 1e-15

A_VALUES = [1e-13, 1e-9, 3e-7, 1e-4, 1e-2, 0.3, 0.999, 1.0, 1.5, 1.99, 2 - 1e-9]


def _rel(value, reference):
    reference = float(reference)
    return abs(value - reference) / abs(reference) if reference else abs(value)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_white_matches_exact_propagation(order):
    ks = np.arange(0, 41)
    got = euler_variance("white", order, ks, dt=1.0, noise_variance=1.0)
    for k, value in zip(ks, got):
        assert value == fraction_variance("white", order, int(k))


def test_white_scales_with_dt_and_variance():
    got = euler_variance("white", 2, 7, dt=0.01, noise_variance=3.0)
    assert _rel(got, 3.0 * 0.01**4 * 6 * 7 * 13 / 6) < 1e-15


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("a", A_VALUES)
def test_gauss_markov_small_k_matches_fractions(order, a):
    ks = [0, 1, 2, 3, 10, 11, 12, 40, 100]
    got = euler_variance(
        "gauss_markov", order, ks, dt=1.0, noise_variance=1.0, time_constant=1.0 / a
    )
    for k, value in zip(ks, got):
        assert _rel(value, fraction_variance("gauss_markov", order, k, a)) < REL, (k, a)


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("a", A_VALUES)
def test_gauss_markov_large_k_matches_mpmath(order, a):
    ks = [1000, 12345, 10**6, 10**8, 3 * 10**9]
    got = gm_sum(order, np.array(ks, dtype=float), np.full(len(ks), a))
    for k, value in zip(ks, got):
        assert _rel(value, mpmath_variance(order, k, a)) < REL, (k, a)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("k", [3, SERIES_TERMS[2] // 2, SERIES_TERMS[2] // 2 + 1, 65, 10**4, 10**9])
@pytest.mark.parametrize("side", [1 - 1e-9, 1.0, 1 + 1e-9])
def test_switch_over_between_series_and_closed_form(order, k, side):
    a = SWITCH[order] * side / k
    got = gm_sum(order, np.array([float(k)]), np.array([a]))[0]
    assert _rel(got, mpmath_variance(order, k, a)) < REL


@pytest.mark.parametrize("order", [0, 1, 2])
def test_random_walk_limit_tau_infinite(order):
    ks = [0, 1, 5, 64, 65, 1000, 10**7]
    got = euler_variance(
        "gauss_markov", order, ks, dt=1.0, noise_variance=1.0, time_constant=np.inf
    )
    for k, value in zip(ks, got):
        ref = (
            fraction_variance("gauss_markov", order, k, 0)
            if k <= 1000
            else mpmath_variance(order, k, 0)
        )
        assert _rel(value, ref) < REL


def test_dt_scaling_of_gauss_markov():
    """Against the recursion with dt written out (exact fractions; no dt**6 scaling assumed)."""
    from exact import fraction_variance_dt

    dt, tau, q = 0.01, 3.0, 2.5
    got = euler_variance("gauss_markov", 2, 300, dt=dt, noise_variance=q, time_constant=tau)
    assert _rel(got, float(fraction_variance_dt(2, 300, dt=dt, tau=tau, q=q))) < REL


@pytest.mark.parametrize("ratio", [2.0, 2.5, 10.0])
def test_unstable_euler_recursion_is_refused(ratio):
    with pytest.raises(ModelError, match="unstable"):
        euler_variance("gauss_markov", 1, 10, dt=ratio, noise_variance=1.0, time_constant=1.0)


def test_batch_equals_loop(rng):
    ks = rng.integers(0, 10**7, size=50)
    taus = rng.uniform(0.01, 1e5, size=(30, 1))
    dt = 0.01
    batch = euler_variance("gauss_markov", 2, ks, dt=dt, noise_variance=1.0, time_constant=taus)
    assert batch.shape == (30, 50)
    for i in range(30):
        for j in range(0, 50, 7):
            single = euler_variance(
                "gauss_markov", 2, ks[j], dt=dt, noise_variance=1.0, time_constant=taus[i, 0]
            )
            assert single == batch[i, j]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(source="pink", order=1, k=3), "source"),
        (dict(source="white", order=3, k=3), "order"),
        (dict(source="white", order=1, k=-1), "k="),
        (dict(source="white", order=1, k=2.5), "k="),
        (dict(source="gauss_markov", order=1, k=2), "time_constant"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises((InputError, ModelError), match=match):
        euler_variance(
            kwargs.pop("source"), kwargs.pop("order"), kwargs.pop("k"), dt=1.0, noise_variance=1.0
        )


def test_negative_time_constant_is_refused():
    with pytest.raises(ModelError, match="time_constant"):
        euler_variance("gauss_markov", 1, 3, dt=1.0, noise_variance=1.0, time_constant=-1.0)


# --- Monte Carlo in the spirit of the paper's Figs 4-11 -------------------------------

def _simulate(a, ks, n_paths, rng, source):
    """Simulate the paper's recursion literally; return (b, v, p) at each k in ks."""
    b = np.zeros(n_paths)
    v = np.zeros(n_paths)
    p = np.zeros(n_paths)
    out = {}
    for step in range(max(ks) + 1):
        if step in ks:
            out[step] = (b.copy(), v.copy(), p.copy())
        w = rng.standard_normal(n_paths)
        x = w if source == "white" else b
        b, v, p = (1 - a) * b + w, v + x, p + v
    return out


@pytest.mark.parametrize(
    "source, a", [("white", None), ("gauss_markov", 0.05), ("gauss_markov", 1.6)]
)
def test_monte_carlo_confirms_variances_and_index_convention(source, a, rng):
    """4000 simulated paths; each sample variance within 5 standard errors of the formula.

    The mean of squares of n zero-mean Gaussians has standard error ``V sqrt(2/n)``.
    The printed eq 11 (``k(k+1)(2k+1)/6``) at k = 3 is 14 instead of 5 and is rejected.
    """
    ks = [1, 2, 3, 10, 40, 120]
    n = 4000
    sims = _simulate(a or 0.0, ks, n, rng, source)
    tau = None if a is None else 1.0 / a
    for order in (1, 2):
        formula = euler_variance(source, order, ks, dt=1.0, noise_variance=1.0, time_constant=tau)
        for k, expected in zip(ks, formula):
            sample = np.mean(sims[k][order] ** 2)
            if expected == 0:
                assert sample == 0
                continue
            z = (sample - expected) / (expected * np.sqrt(2.0 / n))
            assert abs(z) < 5, (order, k, sample, expected)
    if source == "white":
        printed_eq11 = 3 * 4 * 7 / 6
        sample = np.mean(sims[3][2] ** 2)
        assert abs(sample - printed_eq11) / (printed_eq11 * np.sqrt(2.0 / n)) > 20


# --- physical layer -------------------------------------------------------------------

@pytest.mark.parametrize("discretization", ["exact", "euler"])
def test_driving_variance_gives_stationary_bias_variance(discretization):
    dt, tau, sigma_b2 = 0.01, 0.7, 4.0
    q = gauss_markov_driving_variance(sigma_b2, tau, dt, discretization=discretization)
    stationary = euler_variance(
        "gauss_markov",
        0,
        10**7,
        dt=dt,
        noise_variance=q,
        time_constant=_tau_eff(dt, tau, discretization),
    )
    assert _rel(stationary, sigma_b2) < 1e-13


def _tau_eff(dt, tau, discretization):
    """time constant of the paper's Euler form with the same A as the chosen discretization."""
    return dt / -np.expm1(-dt / tau) if discretization == "exact" else tau


def test_noise_density_round_trip():
    dt = 0.005
    q = noise_density_to_variance(2e-3, dt)
    assert _rel(q, 2e-3**2 / dt) < 1e-15
    assert _rel(noise_variance_to_density(q, dt), 2e-3) < 1e-15
    r1 = drift_sigma([0.0, 1.0, 60.0], quantity="attitude", dt=dt, noise_density=2e-3)
    np.testing.assert_allclose(r1.white, 2e-3 * np.sqrt([0.0, 1.0, 60.0]), rtol=1e-13)
    r2 = drift_sigma([0.0, 1.0, 60.0], quantity="attitude", dt=dt, noise_variance=q)
    np.testing.assert_allclose(r2.total, r1.total, rtol=1e-15)


def _continuous_bias_variance(order, t, sigma_b2, tau, stationary):
    """Variance of the once / twice integrated continuous Gauss-Markov bias (mpmath.quad).

    Cov(b(s), b(u)) = sigma_b**2 (exp(-|s-u|/tau) - [zero start] exp(-(s+u)/tau)); the
    integral has weight 1 (attitude / velocity) or (t-s)(t-u) (position).
    """
    with mp.workdps(30):  # local precision: a global mp.dps would leak into other test modules
        t, tau = mp.mpf(t), mp.mpf(tau)

        def cov(s, u):
            c = mp.exp(-abs(s - u) / tau)
            return c if stationary else c - mp.exp(-(s + u) / tau)

        weight = (lambda s, u: 1) if order == 1 else (lambda s, u: (t - s) * (t - u))
        inner = lambda s: mp.quad(lambda u: weight(s, u) * cov(s, u), [0, s, t])  # noqa: E731
        return float(sigma_b2 * mp.quad(inner, [0, t]))


@pytest.mark.parametrize("quantity", ["velocity", "position"])
@pytest.mark.parametrize("bias_start", ["zero", "stationary"])
@pytest.mark.parametrize("t_over_tau", [0.05, 1.0, 20.0])
def test_continuous_time_limit(quantity, bias_start, t_over_tau):
    """dt -> 0 at fixed t: the discrete variance converges to the continuous one, O(dt)."""
    tau, sigma_b2 = 50.0, 0.3
    t = t_over_tau * tau
    order = 2 if quantity == "position" else 1
    reference = _continuous_bias_variance(order, t, sigma_b2, tau, bias_start == "stationary")
    errors = []
    for dt in (t / 1e3, t / 1e5):
        r = drift_sigma(
            t,
            quantity=quantity,
            dt=dt,
            bias_variance=sigma_b2,
            time_constant=tau,
            bias_start=bias_start,
        )
        errors.append(abs(float(r.bias) ** 2 / reference - 1))
    assert errors[1] < 5e-5  # O(dt / min(t, tau)) with dt = t / 1e5
    assert errors[1] < errors[0] / 50  # first-order convergence (factor 100 in dt)


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("a", [1e-6, 0.05, 0.9, 1.0, 1.5])
def test_initial_bias_coefficient_matches_fractions(order, a):
    ks = [0, 1, 2, 7, 64, 65, 90]
    got = gm_coefficient(order, np.array(ks, dtype=float), np.full(len(ks), a))
    for k, value in zip(ks, got):
        # variance propagated from b_0 ~ N(0, 1) with no driving noise = c_r(k)**2
        exact = _propagate_initial(order, k, a)
        assert _rel(value**2, exact) < 1e-13 or (exact == 0 and abs(value) < 1e-15)


def _propagate_initial(order, k, a):
    from fractions import Fraction

    a = Fraction(a)
    b, v, p = Fraction(1), Fraction(0), Fraction(0)
    for _ in range(k):
        b, v, p = (1 - a) * b, v + b, p + v
    return (b, v, p)[order] ** 2


def test_stationary_start_adds_initial_bias_term():
    dt, tau, sigma_b2 = 0.1, 5.0, 2.0
    t = np.array([0.0, 0.1, 1.0, 30.0, 400.0])
    zero = drift_sigma(t, quantity="position", dt=dt, bias_variance=sigma_b2, time_constant=tau)
    stat = drift_sigma(
        t,
        quantity="position",
        dt=dt,
        bias_variance=sigma_b2,
        time_constant=tau,
        bias_start="stationary",
    )
    assert np.all(stat.bias >= zero.bias)
    # the initial bias b_0 ~ N(0, sigma_b^2) carried by the exact AR(1) recursion with dt written
    # out: p_k = p_{k-1} + dt v_{k-1}, v_k = v_{k-1} + dt b_{k-1}, b_k = A b_{k-1}
    A = np.exp(-dt / tau)
    extra = []
    for k in np.round(t / dt).astype(int):
        b, v, p = 1.0, 0.0, 0.0
        for _ in range(k):
            b, v, p = A * b, v + dt * b, p + dt * v
        extra.append(sigma_b2 * p * p)
    np.testing.assert_allclose(stat.bias**2 - zero.bias**2, extra, rtol=1e-12, atol=1e-30)


def test_random_walk_drift():
    dt, K = 0.01, 1e-4
    r = drift_sigma([100.0], quantity="attitude", dt=dt, random_walk=K)
    # b_k = b_{k-1} + N(0, K^2 dt): attitude variance K^2 dt^3 sum_{n<k} n^2 -> K^2 t^3 / 3
    k = 10000
    assert _rel(float(r.random_walk[0]) ** 2, K**2 * dt**3 * (k - 1) * k * (2 * k - 1) / 6) < 1e-13


def test_drift_broadcasts_over_draws_and_times(rng):
    draws = rng.uniform(0.5, 2.0, size=(40, 1))
    t = np.geomspace(0.01, 3600, 25)
    r = drift_sigma(
        t,
        quantity="position",
        dt=0.01,
        noise_variance=draws * 1e-4,
        bias_variance=draws * 1e-6,
        time_constant=draws * 100,
    )
    assert r.total.shape == (40, 25)
    one = drift_sigma(
        t,
        quantity="position",
        dt=0.01,
        noise_variance=draws[3, 0] * 1e-4,
        bias_variance=draws[3, 0] * 1e-6,
        time_constant=draws[3, 0] * 100,
    )
    np.testing.assert_array_equal(one.total, r.total[3])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(quantity="heading"), "quantity"),
        (dict(quantity="position", bias_start="warm"), "bias_start"),
        (dict(quantity="position", noise_variance=1.0, noise_density=1.0), "at most one"),
        (dict(quantity="position", bias_variance=-1.0), "bias_variance"),
        (dict(quantity="position", discretization="rk4"), "discretization"),
    ],
)
def test_drift_sigma_bad_arguments(kwargs, match):
    with pytest.raises((InputError, ModelError), match=match):
        drift_sigma([1.0], dt=0.01, **kwargs)


def test_negative_time_is_refused():
    with pytest.raises(InputError, match="t="):
        drift_sigma([-1.0], quantity="attitude", dt=0.01, noise_variance=1.0)


def test_compiled_grid_kernels_equal_numpy_reference():
    """gm_sum_grid / drift_grid (compiled, used for posterior bands) equal gm_sum / gm_coefficient
    to 1e-13, over both branches, the switch-overs, A = 0 (a = 1), A < 0 (a > 1) and k from 0 to
    2**53."""
    from bayes_imu.noise.euler_sums import drift_grid, gm_coefficient, gm_sum, gm_sum_grid

    rng = np.random.default_rng(5)
    k = np.concatenate(
        [[0, 1, 2, 3], np.unique(np.round(np.geomspace(1, 3.6e5, 300))), [2.0**40, 2.0**53]]
    )
    a = np.concatenate([10 ** rng.uniform(-16, 0.3, 300), [0.0, 1e-20, 0.5 / 7, 1.0, 1.5, 1.999]])
    for order in (1, 2):
        ref = gm_sum(order, k[None, :], a[:, None])
        np.testing.assert_allclose(gm_sum_grid(order, k, a), ref, rtol=1e-13, atol=0)
        coef = gm_coefficient(order, k[None, :], a[:, None])
        ones = np.ones_like(a)
        total, bias = drift_grid(
            order,
            k,
            a,
            ones,
            ones,
            [np.zeros_like(a)],
            [np.zeros_like(k)],
            [np.zeros_like(a)],
            [np.zeros_like(k)],
        )
        # c_2(1) = 0: exact here, 1e-33 in numpy
        np.testing.assert_allclose(bias**2, ref + coef**2, rtol=1e-12, atol=1e-20)
        if order == 2:  # c_2(k) = 0 exactly for k < 2
            assert np.all(bias[:, k < 2] == 0.0)
        np.testing.assert_array_equal(total, bias)
