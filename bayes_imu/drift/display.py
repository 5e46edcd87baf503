"""Units people read: drift shown in degrees, requirements written with their unit ("0.5 deg").

Presentation only: every computation stays in SI (rad, m/s, m); these helpers convert at the
edges (drift.csv / drift.png with ``--display-units deg``, the report's ``max_error``).
"""

import math
import re

from ..errors import InputError

__all__ = ["DISPLAY_CHOICES", "QUANTITY_UNITS", "display_unit", "amount_parts", "parse_amount",
           "rate_display",
           "unit_power", "display_parameters"]

DISPLAY_CHOICES = ("si", "deg")
#: accepted units of a requirement on each integrated quantity: factor to SI
QUANTITY_UNITS = {
    "attitude": {"rad": 1.0, "mrad": 1e-3, "deg": math.pi / 180.0, "arcmin": math.pi / 180.0 / 60.0,
                 "arcsec": math.pi / 180.0 / 3600.0},
    "velocity": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "km/h": 1.0 / 3.6, "ft/s": 0.3048},
    "position": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3, "ft": 0.3048, "nmi": 1852.0},
}
_AMOUNT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)?\s*$")


def display_unit(unit, display):
    """``(shown unit, factor from unit)``: ``rad`` shown as ``deg`` with ``display="deg"``, else
    unchanged."""
    if display not in DISPLAY_CHOICES:
        raise InputError(f"display units {display!r}: expected one of {', '.join(DISPLAY_CHOICES)}")
    if display == "deg" and unit == "rad":
        return "deg", 180.0 / math.pi
    return unit, 1.0


def amount_parts(text):
    """``(number, unit)`` of an amount written as text (``"0.5 deg"``, ``"10m"``, ``"1e1 m"``; the
    unit ``""`` where none is written), or ``None`` where ``text`` is not a number and a unit."""
    match = _AMOUNT.match(str(text))
    return None if match is None else (float(match.group(1)), match.group(2) or "")


def parse_amount(value, quantity, where):
    """An amount of ``quantity`` in SI: a number (SI already) or a string with a unit, e.g. ``"0.5
    deg"``."""
    units = QUANTITY_UNITS[quantity]
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(
            f"{where}: {value!r}: expected a positive number (SI) or a string like '0.5 "
            f"{list(units)[0]}'"
        )
    if isinstance(value, str):
        parts = amount_parts(value)
        if parts is None or parts[1] not in units:
            raise InputError(
                f"{where}: {value!r}: expected a number and a unit, one of {', '.join(units)}"
            )
        number, unit = parts
    else:
        number, unit = float(value), next(iter(units))
    if not (math.isfinite(number) and number > 0):
        raise InputError(f"{where}: {value!r}: expected a positive amount")
    return number * units[unit]


def rate_display(unit, display):
    """``(shown unit, factor from unit)`` of rate samples: ``rad/s`` shown as ``deg/s`` with
    ``display="deg"`` (Allan deviations, noise parameters), any other unit unchanged."""
    shown, factor = display_unit("rad" if unit == "rad/s" else unit, display)
    return (f"{shown}/s", factor) if unit == "rad/s" else (unit, 1.0)


def unit_power(template):
    """Power of the rate unit ``{u}`` in a parameter's unit template (``"({u})^2"``: 2, ``"s"``:
    0), :data:`bayes_imu.noise.avar_forms.PARAMETER_UNITS`."""
    if "{u}" not in template:
        return 0
    match = re.search(r"\(\{u\}\)\^(\d+)", template)
    return int(match.group(1)) if match else 1


def display_parameters(parameters, unit, display):
    """``summary.json``'s ``parameters`` block (name -> median, mean, q05, q95, unit) in display
    units: ``None`` where they are the same as given (SI, or a log not in rad/s)."""
    from ..noise.avar_forms import PARAMETER_UNITS

    shown, factor = rate_display(unit, display)
    if factor == 1.0:
        return None
    out = {}
    for name, block in parameters.items():
        template = PARAMETER_UNITS.get(name, "1")
        scale = factor ** unit_power(template)
        out[name] = {k: (v * scale if k != "unit" else template.format(u=shown))
                     for k, v in block.items()}
    return out
