"""Drift from known noise parameters: a sensor JSON (a datasheet's values) in, drift curves out.

The ``bayes-imu drift`` command's library: :func:`read_sensor_json` checks the file (kind, rate,
noise density and the optional bias and random-walk values, in the units it names) and
:func:`known_drift` gives :func:`~bayes_imu.drift.closed_forms.drift_sigma` of every quantity of the
sensor on a log grid of times.
"""

import numpy as np

from ..errors import InputError
from ..io.limits import check_range
from ..io.readers import SI_UNITS, UNITS, read_json_object
from ..io.timebase import check_rate
from .bands import SENSOR_QUANTITIES
from .closed_forms import drift_sigma

__all__ = ["SENSOR_JSON_KEYS", "read_sensor_json", "known_drift"]

#: keys of a sensor JSON file
SENSOR_JSON_KEYS = (
    "name",
    "kind",
    "units",
    "rate_hz",
    "noise_density",
    "bias_variance",
    "time_constant",
    "random_walk",
)


def read_sensor_json(path):
    """The checked contents of a sensor JSON file (a dict; values in its ``units``, default SI)."""
    spec = read_json_object(path, "of sensor parameters")
    unknown = sorted(set(spec) - set(SENSOR_JSON_KEYS))
    if unknown:
        raise InputError(
            f"{path}: unknown key {unknown[0]!r}; expected keys: {', '.join(SENSOR_JSON_KEYS)}"
        )
    for key in ("rate_hz", "kind", "noise_density"):
        if key not in spec:
            raise InputError(f"{path}: missing key {key!r}")
    if spec["kind"] not in SENSOR_QUANTITIES:
        raise InputError(f"{path}: kind={spec['kind']!r}: expected 'gyro' or 'accel'")
    units = spec.get("units", SI_UNITS[spec["kind"]])
    if units not in UNITS or UNITS[units][0] != spec["kind"]:
        allowed = [u for u, (k, _) in UNITS.items() if k == spec["kind"]]
        raise InputError(
            f"{path}: units={units!r}: expected one of {', '.join(allowed)} for a {spec['kind']}"
        )
    return spec


def _positive_float(path, spec, key, default=None):
    value = spec.get(key, default)
    if isinstance(value, bool) or (key in spec and not isinstance(value, (int, float))):
        raise InputError(f"{path}: {key}={value!r}: expected a number")
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {key}={value!r}: expected a number") from None
    if not value > 0 and not (value == 0 and default is not None):
        raise InputError(f"{path}: {key}={value!r}: expected a positive number")
    if key == "rate_hz":
        return check_rate(value, source="rate_hz", where=str(path))
    return check_range("time_constant" if key == "time_constant" else "parameter", value,
                       f"{path}: {key}", allow_inf=key == "time_constant")


def known_drift(path, spec, *, horizon_s, bias_start="zero", n_times=200):
    """:class:`~bayes_imu.drift.closed_forms.DriftResult` of each quantity of the sensor ``spec``
    (from :func:`read_sensor_json` of ``path``, named in messages), at ``n_times`` log-spaced whole
    numbers of samples up to ``horizon_s`` (s).

    Raises
    ------
    InputError
        A value that is not a positive number, or ``horizon_s`` not longer than one sample.
    """
    dt = 1.0 / _positive_float(path, spec, "rate_hz")
    if not horizon_s > dt:
        raise InputError(
            f"horizon_s={horizon_s!r}: expected a time (s) longer than one sample ({dt} s)"
        )
    t = np.unique(np.round(np.geomspace(dt, horizon_s, n_times) / dt)) * dt
    k = UNITS[spec.get("units", SI_UNITS[spec["kind"]])][1]  # the values' unit in SI
    return tuple(
        drift_sigma(
            t,
            quantity=quantity,
            dt=dt,
            noise_density=k * _positive_float(path, spec, "noise_density"),
            bias_variance=k * k * _positive_float(path, spec, "bias_variance", 0.0),
            time_constant=_positive_float(path, spec, "time_constant", np.inf),
            random_walk=k * _positive_float(path, spec, "random_walk", 0.0),
            bias_start=bias_start,
        )
        for quantity in SENSOR_QUANTITIES[spec["kind"]]
    )
