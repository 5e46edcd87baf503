"""Kalibr values: noise density from the short-term terms, random walk from the slow terms only."""

import numpy as np

from bayes_imu.kalibr import axis_densities


def test_short_term_terms_set_the_density_and_slow_biases_the_random_walk():
    """White q plus filtered white c (autocovariances 2c, c: long-time white level 2c + 2c = 4c)
    plus a fast AR(1) (sum of autocovariances s^2 (1 + phi)/(1 - phi)) give the density
    sqrt(q_eff dt); the random walk is sqrt(2 s^2 / T) of each slow bias and K, never the fast term."""
    dt = 0.01
    draws = {"noise_variance": np.array([2e-5]), "filtered_variance": np.array([6e-6]),
             "correlated_variance": np.array([1e-6]), "correlated_time_constant": np.array([0.03]),
             "bias_variance": np.array([4e-8]), "time_constant": np.array([100.0]),
             "bias_variance_2": np.array([1e-8]), "time_constant_2": np.array([1000.0]),
             "rate_random_walk": np.array([1e-6])}
    summary = {"rate_hz": 100.0, "n_samples": 10**6,
               "model": ["white", "filtered_white", "hf_correlated", "gauss_markov", "gauss_markov_2", "random_walk"]}
    density, walk = axis_densities(summary, draws, 2.0)
    phi = np.exp(-dt / 0.03)
    q_eff = 2e-5 + 4 * 6e-6 + 1e-6 * (1 + phi) / (1 - phi)
    np.testing.assert_allclose(density, 2.0 * np.sqrt(q_eff * dt), rtol=1e-12)
    np.testing.assert_allclose(walk, 2.0 * np.sqrt(2 * 4e-8 / 100 + 2 * 1e-8 / 1000 + 1e-12), rtol=1e-12)
