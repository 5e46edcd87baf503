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
from .model import REGISTRY
from .quantities import G, SENSORS

__all__ = ["datasheet", "KIND_OF_UNIT", "G", "rows"]

#: kind of sensor of an SI rate unit (:mod:`bayes_imu.noise.quantities` holds the sensor kinds)
KIND_OF_UNIT = {s.si_unit: name for name, s in SENSORS.items()}


def rows(kind):
    """Every term's datasheet rows for a sensor kind (:meth:`bayes_imu.noise.Term.datasheet_rows`),
    in registry order: dict name -> ``(parameter, transform, unit, what)``."""
    out = {}
    for term in REGISTRY.values():
        out.update(term.datasheet_rows(kind))
    return out


def datasheet(posterior, kind):
    """Datasheet values of a posterior: dict name -> ``median``, ``q05``, ``q95``, ``unit``,
    ``what``.

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
    table = rows("gyro" if kind == "gyro" else "accel")
    names = set(posterior.parameter_names) | {"noise_density"}
    out = {}
    for name, (source, convert, unit, what) in table.items():
        if source not in names:
            continue
        d = convert(np.asarray(posterior.draws(source), float))
        out[name] = {"median": float(np.median(d)), "q05": float(np.quantile(d, 0.05)),
                     "q95": float(np.quantile(d, 0.95)), "unit": unit, "what": what}
    return out
