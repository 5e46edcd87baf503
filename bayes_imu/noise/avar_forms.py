"""Sensor noise models (compatibility layer over :mod:`bayes_imu.noise`).

The terms live in :mod:`bayes_imu.noise`, one module each; this module keeps the
per-term Allan-variance functions under their historical names. All functions broadcast:
parameters of shape ``(...)`` with ``m`` of shape ``(n_tau,)`` give ``(..., n_tau)``.
"""

import numpy as np

from ..noise import PARAMETER_UNITS, REGISTRY, TERM_PARAMETERS, TERMS, NoiseModel
from .model import m_array

__all__ = [
    "TERMS",
    "BASE_TERMS",
    "TERM_PARAMETERS",
    "PARAMETER_UNITS",
    "NoiseModel",
    "white_avar",
    "quantization_avar",
    "bias_instability_avar",
    "gauss_markov_avar",
    "random_walk_avar",
    "ramp_avar",
    "structure_function",
]

#: the five terms of IEEE Std 952 / the paper, the pilot model of a fit
BASE_TERMS = tuple(name for name, t in REGISTRY.items() if {"base", "optional"} & set(t.selection))


def white_avar(m, noise_variance):
    """Allan variance of white rate noise, ``q / m`` (SP1065 Table 3; ARW N^2 / tau)."""
    return REGISTRY["white"].avar(m_array(m), {"noise_variance": noise_variance}, 1.0)


def quantization_avar(m, quantization, *, dt):
    """Allan variance of quantization noise, ``3 Q^2 / tau^2`` (exact for sampled data)."""
    return REGISTRY["quantization"].avar(m_array(m), {"quantization": quantization}, dt)


def bias_instability_avar(m, bias_instability):
    """Allan variance of flicker rate noise, ``2 ln2 B^2 / pi`` (flat)."""
    return REGISTRY["bias_instability"].avar(
        m_array(m), {"bias_instability": bias_instability}, 1.0
    )


def random_walk_avar(m, rate_random_walk, *, dt):
    """Allan variance of a discrete rate random walk, ``K^2 dt (2 m^2 + 1) / (6 m)``."""
    return REGISTRY["random_walk"].avar(m_array(m), {"rate_random_walk": rate_random_walk}, dt)


def ramp_avar(m, rate_ramp, *, dt):
    """Allan variance of a rate ramp, ``R^2 tau^2 / 2`` (exact for sampled data)."""
    return REGISTRY["ramp"].avar(m_array(m), {"rate_ramp": rate_ramp}, dt)


def gauss_markov_avar(m, bias_variance, time_constant, *, dt):
    """Exact Allan variance of a sampled first-order Gauss-Markov process
    (:mod:`bayes_imu.noise.gauss_markov`)."""
    return REGISTRY["gauss_markov"].avar(
        m_array(m), {"bias_variance": bias_variance, "time_constant": time_constant}, dt
    )


def structure_function(k, term, params, *, dt):
    """Phase structure function ``D(k)`` of one term, in sample units (``x = sum y``) [u^2].

    A generalised covariance: for any contrasts ``a``, ``b`` annihilating constants and
    linear trends, ``Cov(sum a_p x_p, sum b_q x_q) = -1/2 sum a_p b_q D(p - q)``.
    """
    if term not in REGISTRY:
        from ..errors import InputError

        raise InputError(f"term {term!r}: expected one of {', '.join(TERMS)}")
    return REGISTRY[term].structure(np.asarray(k, dtype=float), params, dt)
