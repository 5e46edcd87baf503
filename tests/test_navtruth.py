"""The independent navigation truth (``scripts/navtruth.py``, issue 36).

References, none from ``bayes_imu``: the augmented-state covariance propagation against the
impulse-response quadratic forms (two exact methods, 1e-9 relative from 0.05 s to 20 min,
and to 6 h under ``-m slow``);
the uncoupled limits against ``scenegen``'s calibrated-outage truths (1e-12); and a Monte Carlo
of the loop integrated by Runge-Kutta from ``scenegen``'s simulated samples (the mean square
within 4.5 standard errors; ~1e-5 chance of a false failure per comparison).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import navtruth as nt  # noqa: E402
import scenegen as sg  # noqa: E402

GYRO = (sg.White(1e-3), sg.GaussMarkov(2e-4, 50.0), sg.RandomWalk(1e-6))
ACCEL = (sg.White(2e-2), sg.GaussMarkov(1e-3, 200.0), sg.RandomWalk(1e-5))


PAIRS = [(GYRO, ACCEL), (GYRO, ()), ((), ACCEL),
         ((sg.Flicker(1e-4, 1.0, 3000.0),), (sg.White(1e-2),))]


def _two_methods(pair, t):
    a = nt.nav_covariance(*pair, t, dt=0.05, calibration_s=30.0)
    b = nt.nav_truth(*pair, t, dt=0.05, calibration_s=30.0)
    for q in nt.QUANTITIES:
        np.testing.assert_allclose(a[q], b[q], rtol=1e-9)


@pytest.mark.parametrize("pair", PAIRS)
def test_covariance_propagation_equals_impulse_response_form(pair):
    _two_methods(pair, [0.05, 0.5, 60.0, 1200.0])


@pytest.mark.slow  # ~10 s: records of 432 000 samples
@pytest.mark.parametrize("pair", PAIRS[::3])
def test_covariance_propagation_equals_impulse_response_form_to_six_hours(pair):
    _two_methods(pair, [0.05, 5063.0, 21600.0])


def test_uncoupled_limits_are_the_calibrated_outage_sums():
    t = [0.02, 1.0, 37.0, 400.0]
    acc = nt.nav_covariance((), ACCEL, t, dt=0.02, calibration_s=20.0, g=0.0, schuler=False)
    scene = sg.Scene("a", 0, 50.0, 10 ** 6, 20.0, ACCEL)
    np.testing.assert_allclose(acc["velocity"], sg.drift_truth(scene, t, 1), rtol=1e-12)
    np.testing.assert_allclose(acc["position"], sg.drift_truth(scene, t, 2, scheme="zoh"),
                               rtol=1e-12)
    gyr = nt.nav_covariance(GYRO, (), t, dt=0.02, calibration_s=20.0, schuler=False)
    scene = sg.Scene("g", 0, 50.0, 10 ** 6, 20.0, GYRO)
    np.testing.assert_allclose(gyr["tilt"], sg.drift_truth(scene, t, 1), rtol=1e-12)
    # the tilt-gravity coupling alone: v = -g * (tilt integral), continuous-time for white
    # gyro noise of density n: Var v = g^2 n^2 t^3 / 3 (ZOH adds O(dt/t))
    white = (sg.White(1e-3),)
    v = nt.nav_covariance(white, (), [400.0], dt=0.02, calibration_s=1e6 * 0.02,
                          schuler=False)["velocity"][0]
    n2, s2, n_cal = 1e-3 ** 2 * 0.02, 1e-3 ** 2, 1e6     # plus the bias estimate's error
    exact = nt.G ** 2 * (n2 * 400.0 ** 3 / 3 + s2 / n_cal * 400.0 ** 4 / 4)
    assert v ** 2 == pytest.approx(exact, rel=1e-3)


def test_monte_carlo_of_the_loop():
    """A short Schuler period (20 s: R = g / (2 pi / 20)^2) so that the loop bends in 30 s."""
    dt, n_cal, ks, reps = 0.05, 100, (1, 40, 200, 600), 3000
    radius = nt.G / (2 * np.pi / 20.0) ** 2
    gyro = (sg.White(2e-3), sg.GaussMarkov(5e-4, 5.0), sg.RandomWalk(2e-4))
    accel = (sg.White(5e-2), sg.GaussMarkov(2e-2, 20.0), sg.RandomWalk(2e-3))
    rng = np.random.default_rng(36)
    n = n_cal + max(ks)
    yg = sum(t.simulate(n, dt, rng, (reps,)) for t in gyro)
    ya = sum(t.simulate(n, dt, rng, (reps,)) for t in accel)
    sim = nt.simulate_loop(yg, ya, n_cal, ks, dt, radius=radius)
    exact = nt.nav_covariance(gyro, accel, np.array(ks) * dt, dt=dt, calibration_s=n_cal * dt,
                              radius=radius)
    for q in nt.QUANTITIES:
        for j in range(len(ks)):
            e2 = sim[q][:, j] ** 2
            se = e2.std(ddof=1) / np.sqrt(reps)
            assert abs(e2.mean() - exact[q][j] ** 2) <= 4.5 * se, (q, ks[j])
