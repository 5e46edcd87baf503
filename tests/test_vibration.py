"""The vibration line: exact sampled-data AVAR and drift against mpmath sums over the samples.

References: a random-phase sinusoid's functional ``sum_t w_t y_t`` has variance
``(A^2/2) |sum_t w_t e^{i omega t}|^2``; that sum is evaluated here term by term in mpmath
(60 digits), and the average over phase of the squared second difference is taken exactly over
seven equally spaced phases (the square of a sinusoid is a trigonometric polynomial of degree
2, which seven equally spaced points average exactly). Nothing here uses the module's Dirichlet
kernels or its series.
"""

import mpmath as mp
import numpy as np
import pytest

from bayes_imu.noise import REGISTRY
from bayes_imu.noise.vibration import sinc_complement

TERM = REGISTRY["vibration"]
DT = 0.01
#: half phase steps x = pi f dt: 1e-7 (a line of ~3e-6 Hz at 100 Hz: small f t), both sides
#: of the series switch, and up to the Nyquist frequency
XS = (1e-7, 1e-4, 0.01, 0.3, 1.0, 1.5, np.pi / 2)


def _params(x, amplitude=0.7):
    return {
        "vibration_frequency": np.array(x / (np.pi * DT)),
        "vibration_amplitude": np.array(amplitude),
    }


def _mp_variance(weights, x, amplitude, start=0):
    """(A^2/2) |sum_t w_t e^{2 i x t}|^2 in mpmath, t from ``start``."""
    with mp.workdps(60):
        omega = 2 * mp.mpf(x)
        s = mp.mpc(0)
        for i, w in enumerate(weights):
            s += mp.mpf(w) * mp.expj(omega * (start + i))
        return float(mp.mpf(amplitude) ** 2 / 2 * abs(s) ** 2)


@pytest.mark.parametrize("u", [0.0, 1e-9, 1e-3, 0.2, 0.4999, 0.5, 0.5001, 1.0, 30.0, -0.3])
def test_sinc_complement_matches_mpmath_across_switch(u):
    with mp.workdps(50):
        ref = float(1 - mp.sin(mp.mpf(u)) / mp.mpf(u)) if u != 0 else 0.0
    got = float(sinc_complement(np.array(u)))
    assert got == pytest.approx(ref, rel=3e-15, abs=1e-300)


@pytest.mark.parametrize("x", XS)
def test_avar_equals_the_phase_average_of_second_differences(x):
    """AVAR(m) = E_phi[d^2] / (2 m^2), E_phi exact over 7 phases, each sample in mpmath: 1e-12."""
    m = np.array([1, 2, 3, 7, 64, 1000])
    got = TERM.avar(m.astype(float), _params(x), DT)
    with mp.workdps(60):
        for mi, g in zip(m, got):
            total = mp.mpf(0)
            for j in range(7):
                phi = 2 * mp.pi * j / 7
                y = [mp.mpf("0.7") * mp.sin(2 * mp.mpf(x) * t + phi) for t in range(2 * mi)]
                d = sum(y[mi:]) - sum(y[:mi])
                total += d * d / 7
            ref = float(total / (2 * mi * mi))
            assert g == pytest.approx(ref, rel=1e-12, abs=1e-13 * 0.49), (x, mi)


def _weights(order, k, n_cal):
    outage = np.ones(k) if order == 1 else (k - 1 - np.arange(k, dtype=float))
    cal = -outage.sum() / n_cal * np.ones(n_cal) if n_cal else np.zeros(0)
    return np.concatenate([cal, outage])


@pytest.mark.parametrize("x", XS)
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("start", ["zero", "stationary", "calibrated"])
def test_drift_matches_mpmath_sums(x, order, start):
    """Every start, orders 1 and 2, from f t ~ 1e-7 (the calibrated forms cancel there) to
    Nyquist: relative error <= 1e-9 (1e-7 where the calibrated value is below 1e-12 of the
    uncalibrated one, i.e. nearly all cancelled)."""
    for k, n_cal in ((1, 1), (2, 3), (5, 40), (37, 11), (200, 200)):
        calibrated = start == "calibrated"
        w = _weights(order, k, n_cal if calibrated else 0)
        ref = _mp_variance(w, x, 0.7, start=-n_cal if calibrated else 0) * DT ** (2 * order)
        got = TERM.drift_variance(order, np.array([float(k)]), _params(x), DT, bias_start=start,
                                  n_cal=float(n_cal))[0]
        # the size of the cancelled terms
        scale = _mp_variance(np.abs(w), 0.0, 0.7) * DT ** (2 * order)
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-15 * scale), (k, n_cal)


def test_calibrated_drift_is_never_negative_where_both_windows_hold_whole_periods():
    """A 0.5 Hz line at 100 Hz (a drawn frequency 4e-9 off it), a 1000-sample outage after a
    6000-sample window: both hold whole periods and the error nearly cancels. The variance is not
    negative (the expanded form gave -1e-18, so a drift band's term curve took the square root of a
    negative number) and it matches the mpmath sum to 1e-15 of the cancelled terms' size; so do
    frequencies around it on a fine grid."""
    for f in (0.49999999583868976, 0.5, 0.5 + 1e-9, 1.0, 2.5):
        x = np.pi * f * DT
        k, n_cal = 1000, 6000
        got = TERM.drift_variance(1, np.array([float(k)]), _params(x), DT,
                                  bias_start="calibrated", n_cal=float(n_cal))[0]
        w = _weights(1, k, n_cal)
        ref = _mp_variance(w, x, 0.7, start=-n_cal) * DT**2
        scale = _mp_variance(np.abs(w), 0.0, 0.7) * DT**2
        assert got >= 0.0 and got == pytest.approx(ref, rel=1e-9, abs=1e-15 * scale), f
    grid = {"vibration_frequency": np.linspace(0.49, 0.51, 20001)[:, None],
            "vibration_amplitude": np.ones((20001, 1))}
    k = np.array([10.0, 100.0, 1000.0, 6000.0, 12000.0])
    assert np.all(TERM.drift_variance(1, k, grid, DT, bias_start="calibrated", n_cal=6000.0) >= 0)


def test_drift_broadcasts_over_draws():
    p = {
        "vibration_frequency": np.array([[0.5, 3.0, 20.0]]),
        "vibration_amplitude": np.array([[1.0, 0.2, 0.05]]),
    }
    k = np.array([0.0, 1.0, 10.0, 1e4])
    for order in (1, 2):
        batch = TERM.drift_variance(order, k, p, DT, bias_start="calibrated", n_cal=100.0)
        assert batch.shape == (1, 3, 4)
        for j in range(3):
            one = {n: v[0, j] for n, v in p.items()}
            assert np.array_equal(
                batch[0, j],
                TERM.drift_variance(order, k, one, DT, bias_start="calibrated", n_cal=100.0),
            )


def test_prior_box_spans_one_cycle_per_record_to_nyquist():
    from bayes_imu.noise import PriorScale

    scale = PriorScale(np.log(1e-4), np.log(1e-1), DT, DT, 100.0, 1.0, 1000.0)
    (f_lo, f_hi), (a_lo, a_hi) = TERM.bounds(scale)
    assert np.exp(f_lo) == pytest.approx(1e-3) and np.exp(f_hi) == pytest.approx(50.0)
    # the amplitude whose AVAR peak (0.5251 A^2, max of sin^4 u / u^2) spans the AVAR range
    assert 0.5251 * np.exp(2 * a_lo) == pytest.approx(1e-4, rel=1e-3)
    u = np.linspace(0.5, 2.0, 200001)
    assert np.max(np.sin(u) ** 4 / u**2) == pytest.approx(0.5251, abs=1e-4)


@pytest.mark.slow  # a Monte Carlo check of thousands of records: the nightly job
def test_avar_covariance_of_a_line_matches_monte_carlo(rng):
    """White noise plus a fixed-amplitude line (random phase), 1024 samples, 3000 records: the
    variance of each AVAR estimate is within 5 standard errors (sqrt(2/R) of a variance, doubled
    for the non-Gaussian line) of the covariance code's (its ``"deterministic"`` tail), while the
    Gaussian treatment of the line (its structure function in the table) is far above where the
    line dominates."""
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.noise import NoiseModel
    from bayes_imu.noise.avar_covariance import avar_covariance, exact_pair_sums

    n, reps = 1024, 3000
    model = NoiseModel(("white", "vibration"), DT)
    p = {"noise_variance": 1.0, "vibration_frequency": 7.0, "vibration_amplitude": 2.0}
    m = np.array([1, 2, 4, 8, 16])
    draws = np.array(
        [
            allan_variance(
                model.components[0].simulate(p, n, DT, rng) + TERM.simulate(p, n, DT, rng),
                rate_hz=1 / DT,
                m=m,
                segments=0,
            ).avar
            for _ in range(reps)
        ]
    )
    cov = avar_covariance(model, p, m, n)
    var = draws.var(axis=0, ddof=1)
    assert np.all(np.abs(var / np.diag(cov) - 1) < 5 * 2 * np.sqrt(2 / reps)), var / np.diag(cov)
    table = model.structure_function(np.arange(n + 4 * m.max() + 1), p)
    mf = m.astype(float)
    norm = 2.0 * np.outer(mf * mf * (n - 2 * mf + 1), mf * mf * (n - 2 * mf + 1))
    gaussian = exact_pair_sums(np.asarray(table, float), m, n) / norm
    line = np.argmax(TERM.avar(mf, p, DT))
    assert np.diag(gaussian)[line] > 10 * var[line]
