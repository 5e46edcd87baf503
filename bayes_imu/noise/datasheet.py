"""Posterior noise parameters in the units datasheets print (IEEE Std 952 / 1293 conventions).

Gyro (fit in rad/s): angle random walk in deg/sqrt(h), bias instability in deg/h, rate
random walk in deg/h/sqrt(h), Gauss-Markov and fast correlated biases as a 1-sigma level
in deg/h with their time constants, quantization in arcsec, rate ramp in deg/h^2.
Accelerometer (fit in m/s^2): velocity random walk in m/s/sqrt(h), biases in micro-g
(``ug``, g = 9.80665 m/s^2), acceleration random walk in m/s/h/sqrt(h), quantization in m/s,
ramp in ug/h.

Conversions: ``1/sqrt(s) = 60/sqrt(h)``; ``1/s^1.5 = 3600^1.5 / h^1.5``; the bias
instability is the flicker coefficient ``B`` (the Allan-deviation floor is
``B sqrt(2 ln 2 / pi) = 0.664 B``); the random walks and the angle / velocity random walk
use the white-equivalent short-term ``noise_density`` (what ADEV(1 s) reads).
"""

import numpy as np

from ..errors import InputError
from ..io.readers import SI_UNITS

__all__ = ["datasheet", "KIND_OF_UNIT", "G"]

#: standard gravity (m/s^2)
G = 9.80665
#: kind of sensor of an SI rate unit
KIND_OF_UNIT = {unit: kind for kind, unit in SI_UNITS.items()}
_DEG = 180.0 / np.pi
_UG = 1.0 / (G * 1e-6)

# name -> (parameter the draws come from, transform to the datasheet unit, unit, what it is)
_GYRO = {
    "angle_random_walk": ("noise_density", lambda v: v * _DEG * 60.0, "deg/sqrt(h)", "ARW (white + short-term terms)"),
    "bias_instability": ("bias_instability", lambda v: v * _DEG * 3600.0, "deg/h",
                         "flicker coefficient B (ADEV floor 0.664 B)"),
    "rate_random_walk": ("rate_random_walk", lambda v: v * _DEG * 3600.0**1.5, "deg/h/sqrt(h)", "RRW"),
    "gauss_markov_sigma": ("bias_variance", lambda v: np.sqrt(v) * _DEG * 3600.0, "deg/h",
                           "Gauss-Markov bias, 1-sigma"),
    "gauss_markov_time_constant": ("time_constant", lambda v: v, "s", "Gauss-Markov correlation time"),
    "gauss_markov_2_sigma": ("bias_variance_2", lambda v: np.sqrt(v) * _DEG * 3600.0, "deg/h",
                             "second (slower) Gauss-Markov bias, 1-sigma"),
    "gauss_markov_2_time_constant": ("time_constant_2", lambda v: v, "s", "its correlation time"),
    "fast_correlated_sigma": ("correlated_variance", lambda v: np.sqrt(v) * _DEG * 3600.0, "deg/h",
                              "fast correlated noise (sensor bandwidth), 1-sigma"),
    "fast_correlated_time_constant": ("correlated_time_constant", lambda v: v, "s", "its correlation time"),
    "quantization": ("quantization", lambda v: v * _DEG * 3600.0, "arcsec", "angle quantization"),
    "rate_ramp": ("rate_ramp", lambda v: v * _DEG * 3600.0**2, "deg/h^2", "rate ramp"),
}
_ACCEL = {
    "velocity_random_walk": ("noise_density", lambda v: v * 60.0, "m/s/sqrt(h)", "VRW (white + short-term terms)"),
    "bias_instability": ("bias_instability", lambda v: v * _UG, "ug", "flicker coefficient B (ADEV floor 0.664 B)"),
    "acceleration_random_walk": ("rate_random_walk", lambda v: v * 3600.0**1.5, "m/s/h/sqrt(h)", "AcRW"),
    "gauss_markov_sigma": ("bias_variance", lambda v: np.sqrt(v) * _UG, "ug", "Gauss-Markov bias, 1-sigma"),
    "gauss_markov_time_constant": ("time_constant", lambda v: v, "s", "Gauss-Markov correlation time"),
    "gauss_markov_2_sigma": ("bias_variance_2", lambda v: np.sqrt(v) * _UG, "ug",
                             "second (slower) Gauss-Markov bias, 1-sigma"),
    "gauss_markov_2_time_constant": ("time_constant_2", lambda v: v, "s", "its correlation time"),
    "fast_correlated_sigma": ("correlated_variance", lambda v: np.sqrt(v) * _UG, "ug",
                              "fast correlated noise (sensor bandwidth), 1-sigma"),
    "fast_correlated_time_constant": ("correlated_time_constant", lambda v: v, "s", "its correlation time"),
    "quantization": ("quantization", lambda v: v, "m/s", "velocity quantization"),
    "rate_ramp": ("rate_ramp", lambda v: v * _UG * 3600.0, "ug/h", "acceleration ramp"),
}


def datasheet(posterior, kind):
    """Datasheet values of a posterior: dict name -> ``median``, ``q05``, ``q95``, ``unit``, ``what``.

    Parameters
    ----------
    posterior : FitResult or UnitPosterior
        Fitted in SI (rad/s for a gyro, m/s^2 for an accelerometer).
    kind : {"gyro", "accel"}
        Any other kind (``"magnetometer"``) is an :class:`~bayes_imu.errors.InputError`, never
        another
        sensor's table.
    """
    if kind not in ("gyro", "accel"):
        raise InputError(f"kind={str(kind)[:40]!r}: expected 'gyro' or 'accel' (datasheet units "
                         "exist for those)")
    table = _GYRO if kind == "gyro" else _ACCEL
    names = set(posterior.parameter_names) | {"noise_density"}
    out = {}
    for name, (source, convert, unit, what) in table.items():
        if source not in names:
            continue
        d = convert(np.asarray(posterior.draws(source), float))
        out[name] = {"median": float(np.median(d)), "q05": float(np.quantile(d, 0.05)),
                     "q95": float(np.quantile(d, 0.95)), "unit": unit, "what": what}
    return out
