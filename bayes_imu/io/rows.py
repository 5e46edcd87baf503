"""Rows and stamps of a text log beyond plain numbers: ISO 8601 time stamps and a row filter.

ISO 8601 stamps (``2026-11-25T12:00:00.123Z``, ``2026-11-25 12:00:00.5+02:00``, no zone: read
as UTC) in a time column become seconds since the first stamp (:func:`iso_seconds`), computed
in integer nanoseconds, so a log of days keeps nanosecond steps (a float of epoch seconds would
keep only about 0.2 us).

A row filter (``--where 'period == 0'``, a scene's ``where``) keeps the rows whose columns
satisfy every condition of a small grammar, parsed here and never evaluated as code::

    filter     := condition (("and" | "&&" | ",") condition)*
    condition  := column operator number
    column     := a header name or 0-based index (letters, digits, _ . - [ ] /), or quoted
    operator   := == | != | < | <= | > | >=

so a log of several periods, or with a status column, needs no pandas before the fit.
"""

import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .readers import excerpt

__all__ = ["RowFilter", "parse_where", "looks_iso", "iso_seconds"]

_ISO = re.compile(
    r"^(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2}):(\d{2})(?:[.,](\d{1,9}))?"
    r"(Z|[+-]\d{2}(?::?\d{2})?)?$"
)
_OPERATORS = {
    "==": np.equal,
    "!=": np.not_equal,
    "<=": np.less_equal,
    ">=": np.greater_equal,
    "<": np.less,
    ">": np.greater,
}
_CONDITION = re.compile(
    r"""^\s*("[^"]+"|'[^']+'|[A-Za-z0-9_.\-\[\]/]+)\s*(==|!=|<=|>=|<|>)\s*"""
    r"""([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*$"""
)
_JOINERS = re.compile(r"\s+and\s+|&&|,")


def looks_iso(text):
    """Whether one field is an ISO 8601 date and time (:data:`_ISO`)."""
    return _ISO.match(str(text).strip().strip('"').strip("'")) is not None


def _nanoseconds(text, days):
    """Integer nanoseconds since 1970-01-01T00:00Z of one stamp, or ``None`` if it is not one."""
    import datetime

    match = _ISO.match(text.strip().strip('"').strip("'"))
    if match is None:
        return None
    year, month, day, hour, minute, second, fraction, zone = match.groups()
    key = (year, month, day)
    if key not in days:
        try:
            days[key] = datetime.date(int(year), int(month), int(day)).toordinal() - 719163
        except ValueError:
            return None
    if int(hour) > 23 or int(minute) > 59 or int(second) > 60:
        return None
    offset = 0
    if zone and zone != "Z":
        digits = zone[1:].replace(":", "")
        offset = (int(digits[:2]) * 60 + int(digits[2:] or 0)) * (1 if zone[0] == "+" else -1)
    seconds = ((days[key] * 24 + int(hour)) * 60 + int(minute) - offset) * 60 + int(second)
    return seconds * 10**9 + (int(fraction.ljust(9, "0")) if fraction else 0)


def iso_seconds(stamps, lines, where):
    """Seconds since the first stamp of ISO 8601 text stamps ``(n,)`` (``lines``: their 1-based
    file lines, for the error), float64 from integer nanoseconds."""
    days, out = {}, np.empty(len(stamps), dtype=np.int64)
    for i, text in enumerate(stamps):
        value = _nanoseconds(text, days)
        if value is None:
            raise InputError(
                f"{where}: line {lines[i]}: time stamp {excerpt(text, 40)}; expected an "
                "ISO 8601 date and time like 2026-11-25T12:00:00.123Z (as the first "
                "rows)"
            )
        out[i] = value
    return (out - out[0]).astype(np.float64) * 1e-9 if out.size else out.astype(np.float64)


@dataclass(frozen=True)
class RowFilter:
    """Conditions every kept row satisfies.

    Attributes
    ----------
    conditions : tuple of (column, operator, value)
        ``column`` a header name or index (str), ``operator`` one of ``== != < <= > >=``,
        ``value`` a float.
    text : str
        The filter as given (for messages and ``summary.json``).
    """

    conditions: tuple
    text: str

    @property
    def columns(self):
        """The columns the conditions read, in order of first use."""
        return tuple(dict.fromkeys(c for c, _, _ in self.conditions))

    def mask(self, values):
        """``(n,)`` bool: the rows to keep; ``values``: column -> ``(n,)`` float array."""
        keep = None
        for column, op, value in self.conditions:
            hit = _OPERATORS[op](values[column], value)
            keep = hit if keep is None else keep & hit
        return keep


def parse_where(text):
    """A :class:`RowFilter` from its text (module docstring), or a one-line :class:`InputError`."""
    if isinstance(text, RowFilter):
        return text
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"where={excerpt(text)}: expected conditions like 'period == 0'")
    if len(text) > 1000:
        raise InputError(f"where: {len(text)} characters; expected a short filter (at most 1000)")
    conditions = []
    for part in _JOINERS.split(text.strip()):
        match = _CONDITION.match(part)
        if match is None:
            raise InputError(
                f"where={excerpt(text)}: {excerpt(part.strip(), 40)} is not a condition; "
                "expected COLUMN OP NUMBER joined by 'and' (OP one of == != < <= > >=), "
                "e.g. 'period == 0 and status != 1'"
            )
        column, op, number = match.groups()
        value = float(number)
        if not np.isfinite(value):
            raise InputError(f"where={excerpt(text)}: {number!r}: expected a finite number")
        conditions.append((column.strip("\"'"), op, value))
    return RowFilter(tuple(conditions), text.strip())
