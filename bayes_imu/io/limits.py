"""Valid ranges of the numbers a user gives (options, scene and sensor files), checked before any
work.

Each range is closed, in the unit named; a value outside it (or not finite) is refused with a
one-line :class:`~bayes_imu.errors.InputError` naming the range. The bounds are wide enough for
any inertial sensor and narrow enough that nothing computed from them overflows: a drift
horizon of 1e300 s made the drift variance ``inf - inf = NaN`` and crashed after the fit.

============== ============ ============ ===================================================
name           low          high         what
============== ============ ============ ===================================================
time_s         1e-6         1e9          a drift horizon, drift time or GPS outage (s; 32 years)
calibration_s  1e-6         1e9          the bias calibration window (s)
spread_scale   1e-3         1e3          the prior scale of the unit-to-unit spread (ln units)
parameter      0            1e100        a noise parameter of a sensor JSON file (its units)
time_constant  1e-9         1e15         a Gauss-Markov time constant (s); ``inf`` allowed
speed          1e-3         1e4          a vehicle speed (m/s; ``nav --speed``)
============== ============ ============ ===================================================
"""

import math

from ..errors import InputError

__all__ = ["RANGES", "check_range"]

#: name -> (low, high, unit)
RANGES = {
    "time_s": (1e-6, 1e9, "s"),
    "calibration_s": (1e-6, 1e9, "s"),
    "spread_scale": (1e-3, 1e3, ""),
    "parameter": (0.0, 1e100, ""),
    "time_constant": (1e-9, 1e15, "s"),
    "speed": (1e-3, 1e4, "m/s"),
}


def check_range(kind, value, name, *, allow_inf=False):
    """``float(value)`` if it lies in ``RANGES[kind]`` (``inf`` too with ``allow_inf``), else a
    one-line
    :class:`InputError` naming ``name`` (an option or key) and the range."""
    low, high, unit = RANGES[kind]
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not (low <= number <= high or (allow_inf and number == math.inf)):
        shown = repr(value) if not isinstance(value, str) else repr(value[:40])
        raise InputError(
            f"{name}={shown}: expected a number from {low:g} to {high:g}"
            + (f" {unit}" if unit else "")
            + (" (or inf)" if allow_inf else "")
        )
    return number
