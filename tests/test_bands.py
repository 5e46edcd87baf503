"""Drift bands: per-draw formulas, quantiles, times, and the terms without a paper formula."""

import numpy as np
import pytest

from bayes_imu.drift.bands import default_times, drift_bands, drift_draws, integrated_unit
from bayes_imu.drift.closed_forms import drift_sigma
from bayes_imu.errors import InputError
from bayes_imu.inference.fit import FitResult
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import simulate_log


def fake_fit(terms, samples, dt=0.01):
    """A FitResult holding given posterior draws (bands only read the model and the draws)."""
    model = NoiseModel(terms, dt)
    return FitResult(
        model, np.asarray(samples, float), np.zeros(len(samples)), None, (), 0, {}, "test", None
    )


def test_bands_are_quantiles_of_per_draw_drift(rng):
    """Against an independent loop: one scalar drift_sigma call per draw and time."""
    n = 40
    samples = np.column_stack(
        [rng.uniform(0.5, 2.0, n), rng.uniform(1e-4, 1e-3, n), rng.uniform(10, 100, n)]
    )
    fit = fake_fit(("white", "gauss_markov"), samples)
    t = np.array([0.01, 1.0, 10.0, 300.0])
    for quantity in ("attitude", "position"):
        bands = drift_bands(
            fit, t, quantity=quantity, bias_start="stationary", quantiles=(0.1, 0.5, 0.9)
        )
        loop = np.array(
            [
                [
                    drift_sigma(
                        ti,
                        quantity=quantity,
                        dt=0.01,
                        noise_variance=s[0],
                        bias_variance=s[1],
                        time_constant=s[2],
                        bias_start="stationary",
                    ).total
                    for ti in t
                ]
                for s in samples
            ]
        )
        # atol: position after one sample is exactly 0 here, a 1e-22 rounding residue in the numpy
        # path
        np.testing.assert_allclose(
            bands.total,
            np.quantile(loop, [0.1, 0.5, 0.9], axis=0),
            rtol=1e-12,
            atol=1e-12 * loop.max(),
        )
        assert bands.quantile(0.9).shape == t.shape
    with pytest.raises(InputError, match="quantile"):
        bands.quantile(0.95)


def test_quantization_drift_monte_carlo(rng):
    """Quantization terms: attitude variance 2 Q^2, position Q^2 dt^2 (k-1) k, vs 4000 simulated
    paths (5 sigma)."""
    dt, q, k = 0.1, 0.02, 50
    model = NoiseModel(("quantization",), dt)
    paths = np.array([simulate_log(model, {"quantization": q}, k, rng=rng) for _ in range(4000)])
    attitude = dt * paths.sum(axis=1)
    # p_k = dt sum_{j<k} v_j
    position = dt * np.cumsum(dt * np.cumsum(paths, axis=1), axis=1)[:, -2]
    fit = fake_fit(("quantization",), [[q]], dt)
    d_att = drift_draws(fit, [k * dt], quantity="attitude", bias_start="zero")["total"][0, 0] ** 2
    d_pos = drift_draws(fit, [k * dt], quantity="position", bias_start="zero")["total"][0, 0] ** 2
    for sample, expected in ((attitude, d_att), (position, d_pos)):
        assert abs(sample.var() / expected - 1) < 5 * np.sqrt(2 / 4000)
    np.testing.assert_allclose(d_att, 2 * q * q)


def test_bias_instability_without_calibration_is_sqrt2_plateau():
    """Flicker with no calibration window: the residual rate is the difference of two adjacent
    outage-long means, sqrt(2) ADEV (the Allan variance's definition), so sigma = sqrt(2) ADEV t
    for attitude (a constant residual of that size). Position against a brute-force quadratic
    form is in test_noise_drift."""
    fit = fake_fit(("bias_instability",), [[0.01]])
    t = np.array([1.0, 10.0, 100.0])
    # by the Allan variance's definition, AVAR(m) = E[(mean_2 - mean_1)^2] / 2 over adjacent
    # m-sample means: the attitude error t (mean_2 - mean_1) has variance 2 AVAR(m) t^2 (the model's
    # sampled-data AVAR)
    avar = fit.model.avar(np.round(t / 0.01), {"bias_instability": np.array(0.01)})
    np.testing.assert_allclose(
        drift_draws(fit, t, quantity="attitude", bias_start="zero")["total"][0],
        np.sqrt(2 * avar) * t,
        rtol=1e-9,
    )


def test_default_times_and_units():
    t = default_times(0.01, 3600.0)
    assert t.size >= 50 and t[0] == pytest.approx(0.01) and t[-1] == pytest.approx(3600.0)
    assert np.all(np.diff(np.log(t)) > 0)
    assert (
        integrated_unit("deg/s", "attitude") == "deg"
        and integrated_unit("m/s^2", "position") == "m"
    )
    with pytest.raises(InputError, match="horizon"):
        default_times(0.01, 0.001)


def test_bands_vectorised_speed_shape(rng):
    """1e4 draws x 1e3 times in one call (timed in scripts/bench_drift.py, not here)."""
    samples = np.column_stack(
        [
            rng.uniform(0.5, 2.0, 10_000),
            rng.uniform(1e-4, 1e-3, 10_000),
            rng.uniform(10, 100, 10_000),
        ]
    )
    fit = fake_fit(("white", "gauss_markov"), samples)
    bands = drift_bands(fit, np.geomspace(0.01, 3600, 1000), quantity="velocity", bias_start="zero")
    assert bands.total.shape == (3, 1000) and np.all(np.diff(bands.total[1]) >= 0)


def test_default_bias_start_is_calibrated_60s():
    """Every library entry point defaults to the command line's semantics: calibrated over 60 s
    (issue 35). The white-noise attitude error after k samples with an N-sample calibration mean
    has variance q dt^2 (k + k^2 / N) (a sum of k samples plus k times the mean's error)."""
    import inspect

    from bayes_imu.report.scene import max_outage

    for function in (drift_bands, drift_draws, max_outage):
        parameters = inspect.signature(function).parameters
        assert parameters["bias_start"].default == "calibrated"
        assert parameters["calibration_s"].default == 60.0
    dt, q = 0.01, 0.04
    fit = fake_fit(("white",), [[q]], dt)
    k, n = 1000.0, 6000.0
    got = drift_draws(fit, [k * dt], quantity="attitude")["total"][0, 0]
    np.testing.assert_allclose(got, dt * np.sqrt(q * (k + k * k / n)), rtol=1e-12)
