"""Simulation: the mean Allan variance of simulated logs equals the model's (Monte Carlo, 5
sigma)."""

import numpy as np
import pytest

from bayes_imu.allan.estimator import allan_variance
from bayes_imu.errors import InputError
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import simulate_log
from test_models import PARAMS


@pytest.mark.parametrize("term", list(PARAMS))
def test_mean_avar_matches_model(term, rng):
    """300 logs of 4096 samples; the mean AVAR at each m is within 5 standard errors of the
    model."""
    model = NoiseModel((term,), 0.5)
    m = np.array([1, 2, 4, 16, 64])
    draws = np.array(
        [
            allan_variance(simulate_log(model, PARAMS[term], 4096, rng=rng), rate_hz=2.0, m=m).avar
            for _ in range(300)
        ]
    )
    expected = model.avar(m, PARAMS[term])
    se = draws.std(axis=0, ddof=1) / np.sqrt(draws.shape[0])
    assert np.all(np.abs(draws.mean(axis=0) - expected) < 5 * se)


def test_gauss_markov_stationary_variance(rng):
    """The AR(1) bias starts stationary: sample variance over many short logs equals sigma_b^2 (5
    sigma)."""
    model = NoiseModel(("gauss_markov",), 1.0)
    first = np.array(
        [
            simulate_log(model, {"bias_variance": 4.0, "time_constant": 50.0}, 2, rng=rng)[0]
            for _ in range(4000)
        ]
    )
    assert abs(first.var() - 4.0) < 5 * 4.0 * np.sqrt(2 / 4000)


def test_reproducible_and_offset(rng):
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    p = {"noise_variance": 1.0, "bias_variance": 0.1, "time_constant": 5.0}
    a = simulate_log(model, p, 1000, rng=7, offset=9.80665)
    b = simulate_log(model, p, 1000, rng=7)
    np.testing.assert_allclose(a - 9.80665, b, atol=1e-12)
    with pytest.raises(InputError, match="missing"):
        simulate_log(model, {"noise_variance": 1.0}, 100)
