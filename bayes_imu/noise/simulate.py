"""Simulated static sensor logs from a :class:`~bayes_imu.noise.avar_forms.NoiseModel`, exactly
discretised.

Every term is drawn from the discrete process whose Allan variance
:mod:`bayes_imu.noise.avar_forms` gives, so the expected AVAR of a simulated log equals the model's
exactly (tests check this by Monte Carlo):

* ``white``: i.i.d. normal, variance ``noise_variance``;
* ``quantization``: first difference of i.i.d. normal angle errors of std ``Q`` divided by ``dt``
  (Gaussian, not uniform: only the second moment enters the AVAR);
* ``bias_instability``: flicker rate noise, whose first differences are stationary with the
  autocovariance implied by ``D(k) = -(B^2/pi) k^2 ln k``, drawn by circulant embedding
  (Dietrich & Newsam 1997; exact when the embedding is non-negative, which is checked);
* ``gauss_markov``: AR(1) ``b_k = phi b_{k-1} + w_k`` with ``phi = exp(-dt/T)``, started from
  its stationary distribution (exact sampling of paper eq 4);
* ``random_walk``: cumulative sum of normal increments of variance ``K^2 dt``, started at 0;
* ``hf_correlated``, ``gauss_markov_2``: AR(1) as ``gauss_markov``;
* ``ramp``: the deterministic ``R dt k``.

Each draw is the term's own ``simulate`` (:mod:`bayes_imu.noise`).
"""

import numpy as np

from ..errors import InputError
from ..noise import NoiseModel

__all__ = ["simulate_log"]


def simulate_log(model, params, n_samples, *, rng=None, offset=0.0):
    """Draw one static log of ``n_samples`` rate samples from ``model``.

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        Parameter values by name (see :data:`bayes_imu.noise.avar_forms.TERM_PARAMETERS`).
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
    for term in model.components:
        y += term.simulate({k: float(params[k]) for k in term.parameters}, n, dt, rng)
    return y


def flicker_difference_acov(n, bias_instability):
    """Autocovariance of first differences of flicker rate noise
    (:mod:`bayes_imu.noise.bias_instability`)."""
    from .bias_instability import flicker_difference_acov as acov

    return acov(n, bias_instability)
