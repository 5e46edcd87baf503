"""Units people read: drift shown in degrees, requirements written with their unit ("0.5 deg").

Presentation only: every computation stays in SI (rad, m/s, m); these helpers convert at the
edges (drift.csv / drift.png with ``--display-units deg``, the report's ``max_error``).
"""

import math
import re

from ..errors import InputError

__all__ = ["DISPLAY_CHOICES", "QUANTITY_UNITS", "display_unit", "parse_amount"]

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
    """``(shown unit, factor from unit)``: ``rad`` shown as ``deg`` with ``display="deg"``, else unchanged."""
    if display not in DISPLAY_CHOICES:
        raise InputError(f"display units {display!r}: expected one of {', '.join(DISPLAY_CHOICES)}")
    if display == "deg" and unit == "rad":
        return "deg", 180.0 / math.pi
    return unit, 1.0


def parse_amount(value, quantity, where):
    """An amount of ``quantity`` in SI: a number (SI already) or a string with a unit, e.g. ``"0.5 deg"``."""
    units = QUANTITY_UNITS[quantity]
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"{where}: {value!r}: expected a positive number (SI) or a string like '0.5 "
                         f"{list(units)[0]}'")
    if isinstance(value, str):
        match = _AMOUNT.match(value)
        if not match or (match.group(2) or "") not in units:
            raise InputError(f"{where}: {value!r}: expected a number and a unit, one of {', '.join(units)}")
        number, unit = float(match.group(1)), match.group(2)
    else:
        number, unit = float(value), next(iter(units))
    if not (math.isfinite(number) and number > 0):
        raise InputError(f"{where}: {value!r}: expected a positive amount")
    return number * units[unit]
