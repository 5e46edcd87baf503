"""Autocorrelation identification (paper eq 4, Fig 1): simulated Markov data sigma^2 = 4, tau = 300
s."""

import numpy as np
import pytest

from bayes_imu import InputError
from bayes_imu.allan.autocorr import autocorrelation_fit


def gauss_markov(n, dt, variance, tau, rng):
    phi = np.exp(-dt / tau)
    e = rng.standard_normal(n) * np.sqrt(variance * (1 - phi**2))
    b = np.empty(n)
    b[0] = rng.standard_normal() * np.sqrt(variance)
    for i in range(1, n):
        b[i] = phi * b[i - 1] + e[i]
    return b


def test_recovers_fig1_parameters(rng):
    """Record of 400 tau at 1 Hz plus unit white noise: the relative standard error of sigma^2 is
    about sqrt(2 tau / T) = 7%; assert within 30% (about 4 standard errors) for both."""
    n = 120_000
    y = gauss_markov(n, 1.0, 4.0, 300.0, rng) + rng.standard_normal(n)
    fit = autocorrelation_fit(y, rate_hz=1.0, cutoff_hz=0.05)
    assert fit.bias_variance == pytest.approx(4.0, rel=0.3)
    assert fit.time_constant == pytest.approx(300.0, rel=0.3)
    assert fit.record_over_tau > 100


def test_short_record_warns(rng):
    y = gauss_markov(3000, 1.0, 4.0, 300.0, rng)
    with pytest.warns(UserWarning, match="time constants long"):
        autocorrelation_fit(y, rate_hz=1.0, cutoff_hz=0.05)


def test_bad_input():
    with pytest.raises(InputError, match="cutoff_hz"):
        autocorrelation_fit(np.zeros(1000) + np.arange(1000.0), rate_hz=1.0, cutoff_hz=0.6)
    with pytest.raises(InputError, match="at least 64"):
        autocorrelation_fit([1.0, 2.0], rate_hz=1.0)
