"""The independent scene generator and its exact truths (``scripts/scenegen.py``, issue 35).

References, none from ``bayes_imu``:

* the O(n) evaluators of ``E[(w.y)^2]`` against brute-force n x n quadratic forms built from
  each term's autocovariance (or the random walk's ``min(i, j)`` covariance), 1e-10 relative;
* textbook Allan variances in exact rational arithmetic (white ``sigma^2 / m``, quantization
  ``3 q^2 / tau^2``, discrete random walk ``q (2 m^2 + 1) / (6 m)``) and the flicker floor
  ``sqrt(2 ln 2 h_-1)`` of the log-spaced ladder (within its ripple, 10%);
* Monte Carlo of the simulators: the calibrated-outage errors computed by their definition
  (mean of the calibration samples subtracted, Euler sums) and the overlapping Allan
  variance by its own estimator; the mean square must agree with the exact value within
  4.5 standard errors (the standard error from the sample's own spread), the chance of a
  false failure ~1e-5 per comparison.
"""

import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import scenegen as sg  # noqa: E402

DT = 0.01
N_SIGMA = 4.5

TERMS = {
    "white": sg.White(0.3),
    "quantization": sg.Quantization(0.002),
    "filtered": sg.FilteredWhite(0.5, 7),
    "gm_fast": sg.GaussMarkov(0.2, 0.03),
    "gm_slow": sg.GaussMarkov(0.1, 50.0),
    "flicker": sg.Flicker(0.05, 0.05, 20.0, 2.0),
    "random_walk": sg.RandomWalk(0.4),
    "ramp": sg.Ramp(-0.7),
}


def _contrast(rng, n):
    w = rng.standard_normal(n)
    return w - w.mean()


@pytest.mark.parametrize("name", sorted(TERMS))
def test_quad_equals_brute_force(name, rng):
    term = TERMS[name]
    ws = [_contrast(rng, 257), sg.drift_weights(40, 60, DT, 1), sg.drift_weights(97, 33, DT, 2),
          sg.drift_weights(50, 20, DT, 2, scheme="zoh"), sg.avar_weights(31)]
    for w in ws:
        fast = sg.quad([term], w, DT)
        slow = sg.brute_force_quad([term], w, DT)
        assert fast == pytest.approx(slow, rel=1e-10)


def test_weights_are_the_calibrated_outage_definition():
    """Each sample's weight = the errors of a record that is one at that sample, zero elsewhere."""
    n_cal, k = 13, 9
    eye = np.eye(n_cal + k)
    e1, e2 = sg.calibrated_errors(eye, n_cal, k, DT)
    np.testing.assert_allclose(e1, sg.drift_weights(k, n_cal, DT, 1), rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(e2, sg.drift_weights(k, n_cal, DT, 2), rtol=1e-13, atol=1e-18)
    # hand-written: k = 3, e2 = dt^2 (2 y0 + y1) minus 3 dt^2 b
    e1, e2 = sg.calibrated_errors(np.array([1.0, 3.0, 5.0, 7.0, 11.0]), 2, 3, 0.5)
    b = 2.0
    assert e1 == 0.5 * (5 + 7 + 11 - 3 * b)
    assert e2 == 0.25 * (2 * 5 + 7 - 3 * b)


def test_avar_textbook_values_exact():
    m_values = (1, 2, 5, 16)
    w, q, rw = sg.White(0.3), sg.Quantization(0.002), sg.RandomWalk(0.4)
    for m in m_values:
        tau = Fraction(m) * Fraction(DT)
        assert sg.quad([w], sg.avar_weights(m), DT) / 2 == pytest.approx(0.09 / m, rel=1e-13)
        q_exact = 3 * Fraction(0.002) ** 2 / tau ** 2
        assert sg.quad([q], sg.avar_weights(m), DT) / 2 == pytest.approx(float(q_exact), rel=1e-12)
        inc = Fraction(0.4) ** 2 * Fraction(DT)
        rw_exact = inc * (2 * m * m + 1) / (6 * m)
        assert sg.quad([rw], sg.avar_weights(m), DT) / 2 == pytest.approx(float(rw_exact),
                                                                          rel=1e-12)


def test_flicker_ladder_has_a_flat_allan_floor():
    fl = sg.Flicker(0.05, 0.01, 1000.0, 2.0)
    floor = np.sqrt(2 * np.log(2) * fl.h_minus1)
    m = np.array([100, 400, 1600, 6400])            # tau 1-64 s, well inside 0.01-1000 s
    adev = np.sqrt([sg.quad([fl], sg.avar_weights(int(k)), DT) / 2 for k in m])
    np.testing.assert_allclose(adev, floor, rtol=0.10)


def _mc_check(samples, exact):
    mean = samples.mean()
    se = samples.std(ddof=1) / np.sqrt(samples.size)
    assert abs(mean - exact) <= N_SIGMA * se + 1e-12 * exact, (mean, exact, se)


@pytest.mark.parametrize("name", sorted(TERMS))
def test_monte_carlo_calibrated_outage(name):
    rng = np.random.default_rng(sg.scene_seed("random_mix", 100 + sorted(TERMS).index(name)))
    term = TERMS[name]
    n_cal, ks, reps = 150, (1, 37, 400), 4000
    y = term.simulate(n_cal + max(ks), DT, rng, (reps,))
    for k in ks:
        e1, e2 = sg.calibrated_errors(y, n_cal, k, DT)
        for order, e in ((1, e1), (2, e2)):
            exact = sg.quad([term], sg.drift_weights(k, n_cal, DT, order), DT)
            if name == "ramp":
                assert np.mean(e * e) == pytest.approx(exact, rel=1e-9)
            else:
                _mc_check(e * e, exact)


def test_monte_carlo_allan_variance_of_a_scene():
    scene = sg.Scene("test", 0, 100.0, 2048, 1.0, (TERMS["white"], TERMS["quantization"],
                                                   TERMS["gm_slow"], TERMS["random_walk"],
                                                   TERMS["flicker"]))
    rng = np.random.default_rng(7)
    m = np.array([1, 4, 32, 256])
    est = sg.overlapping_avar(scene.simulate(rng, (1000,)), m, scene.dt)
    exact = sg.avar_truth(scene, m)
    for j in range(len(m)):
        _mc_check(est[:, j], exact[j])


def test_generator_is_deterministic_and_within_ranges():
    for family in sg.FAMILIES:
        for seed in range(5):
            a, b = sg.make_scene(family, seed), sg.make_scene(family, seed)
            assert a == b
            assert 2 ** 16 - 1 <= a.n <= 2 ** 20 + 1
            assert a.rate_hz in sg.RATES and a.calibration_s in sg.CALIBRATIONS
            h = sg.horizons(a)
            assert h[0] == pytest.approx(1.0) and h[-1] <= a.record_s / 4 + a.dt
    assert sg.make_scene("two_gm", 0) != sg.make_scene("two_gm", 1)
