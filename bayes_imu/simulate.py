"""Simulated static sensor logs from a :class:`~bayes_imu.models.NoiseModel`, exactly discretised.

Every term is drawn from the discrete process whose Allan variance
:mod:`bayes_imu.models` gives, so the expected AVAR of a simulated log equals the model's
exactly (tests check this by Monte Carlo):

* ``white``: i.i.d. normal, variance ``noise_variance``;
* ``quantization``: first difference of i.i.d. normal angle errors of std ``Q`` divided by ``dt``
  (Gaussian, not uniform: only the second moment enters the AVAR);
* ``bias_instability``: flicker rate noise, whose first differences are stationary with the
  autocovariance implied by ``D(k) = -(B^2/pi) k^2 ln k``, drawn by circulant embedding
  (Dietrich & Newsam 1997; exact when the embedding is non-negative, which is checked);
* ``gauss_markov``: AR(1) ``b_k = phi b_{k-1} + w_k`` with ``phi = exp(-dt/T)``, started from
  its stationary distribution (exact sampling of paper eq 4);
* ``random_walk``: cumulative sum of normal increments of variance ``K^2 dt``, started at 0.
"""

import numpy as np

from .errors import InputError, ModelError
from .models import TERM_PARAMETERS, NoiseModel

__all__ = ["simulate_log"]


def simulate_log(model, params, n_samples, *, rng=None, offset=0.0):
    """Draw one static log of ``n_samples`` rate samples from ``model``.

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        Parameter values by name (see :data:`bayes_imu.models.TERM_PARAMETERS`).
    n_samples : int
    rng : None, int or numpy.random.Generator
    offset : float
        Constant added to every sample (e.g. gravity on an accelerometer axis) [u].

    Returns
    -------
    (n_samples,) float64 ndarray
    """
    if not isinstance(model, NoiseModel):
        raise InputError(f"model: expected a NoiseModel, got {type(model).__name__}")
    n = int(n_samples)
    if n < 2:
        raise InputError(f"n_samples={n_samples!r}: expected at least 2")
    missing = [p for p in model.parameter_names if p not in params]
    if missing:
        raise InputError(f"params: missing {', '.join(missing)} for terms {model.terms}")
    for name in model.parameter_names:
        value = float(params[name])
        if not (np.isfinite(value) and value >= 0):
            raise InputError(f"{name}={params[name]!r}: expected a finite value >= 0")
    rng = np.random.default_rng(rng)
    dt = model.dt
    y = np.full(n, float(offset))
    for term in model.terms:
        p = {k: float(params[k]) for k in TERM_PARAMETERS[term]}
        y += _DRAW[term](p, n, dt, rng)
    return y


def _white(p, n, dt, rng):
    return np.sqrt(p["noise_variance"]) * rng.standard_normal(n)


def _quantization(p, n, dt, rng):
    return np.diff(p["quantization"] * rng.standard_normal(n + 1)) / dt


def _random_walk(p, n, dt, rng):
    return np.cumsum(p["rate_random_walk"] * np.sqrt(dt) * rng.standard_normal(n))


def _gauss_markov(p, n, dt, rng):
    from scipy.signal import lfilter

    phi = np.exp(-dt / p["time_constant"])
    s = np.sqrt(p["bias_variance"])
    w = s * np.sqrt(-np.expm1(-2.0 * dt / p["time_constant"])) * rng.standard_normal(n)
    b0 = s * rng.standard_normal()
    return lfilter([1.0], [1.0, -phi], w, zi=[phi * b0])[0]


def flicker_difference_acov(n, bias_instability):
    """Autocovariance ``gamma(l)``, ``l = 0..n-1``, of first differences of flicker rate noise."""
    h = bias_instability**2 / np.pi
    k = np.arange(n + 2, dtype=float)
    d = np.zeros_like(k)
    d[1:] = -h * k[1:] ** 2 * np.log(k[1:])
    lag = np.arange(n)
    dm1 = d[np.abs(lag - 1)]
    dm2 = d[np.abs(lag - 2)]
    return -0.5 * (6.0 * d[lag] - 4.0 * d[lag + 1] - 4.0 * dm1 + d[lag + 2] + dm2)


def _bias_instability(p, n, dt, rng):
    if p["bias_instability"] == 0:
        return np.zeros(n)
    gamma = flicker_difference_acov(n, p["bias_instability"])
    row = np.concatenate([gamma, gamma[-2:0:-1]])
    lam = np.fft.rfft(row).real
    scale = np.max(np.abs(lam))
    if lam.min() < -1e-9 * scale:
        raise ModelError(f"flicker circulant embedding not non-negative for n={n} (min eigenvalue {lam.min():.3g})")
    lam = np.clip(lam, 0.0, None)
    size = row.size
    # real-valued circulant draw: a real white vector filtered by sqrt of the spectrum
    z = np.fft.irfft(np.sqrt(lam) * np.fft.rfft(rng.standard_normal(size)), n=size)[: n - 1]
    y = np.empty(n)
    y[0] = 0.0
    np.cumsum(z, out=y[1:])
    return y


_DRAW = {
    "white": _white,
    "quantization": _quantization,
    "bias_instability": _bias_instability,
    "gauss_markov": _gauss_markov,
    "random_walk": _random_walk,
}
