"""Time stamps of a log: the sample rate they give, and what to do about irregular steps.

A step between consecutive time stamps is *regular* when it lies within
``[1 - STEP_TOLERANCE, 1 + STEP_TOLERANCE]`` times the median step (jitter of a logger's
clock is accepted; the Allan variance assumes uniform sampling). Irregular steps:

* ``backwards``: the time decreases;
* ``repeat``: the same time stamp twice;
* ``gap``: a step longer than ``1 + STEP_TOLERANCE`` median steps (lost samples);
* ``short``: a step shorter than ``1 - STEP_TOLERANCE`` median steps (an extra sample).

``gaps="error"`` (default) rejects any irregular step with a one-line error naming its
file line and size; ``gaps="longest"`` keeps the longest run of regular steps and records
what was dropped (:class:`TimeBase`), so the outputs can say what was done. Where most steps
are irregular (a host's bursty stamps) the errors state the mean rate over the whole log and
suggest giving it as the rate instead of the time column.

Units of the stamps (:data:`TIME_UNITS`): given (``time_unit``), else read from the column's
name (``t_ms``, ``time_us``, ``timestamp_ns``, ``time [s]``: :func:`unit_from_name`), else,
when a rate is given too, the one unit whose rate lies within :data:`STEP_TOLERANCE` of it (the
unit nearest it; the two rates must then agree within :data:`RATE_TOLERANCE`), else seconds. Seconds
assumed but not stated are refused where they give a rate outside :data:`TYPICAL_RATE_RANGE`
while another unit gives one inside it (a 100 Hz log stamped in milliseconds reads as
0.1 Hz): the error names every unit's rate and the likely one. The unit used and where it
came from are recorded in :class:`TimeBase`.
"""

import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .readers import positive_number

__all__ = [
    "TimeBase",
    "check_time",
    "check_rate",
    "unit_from_name",
    "GAP_POLICIES",
    "STEP_TOLERANCE",
    "RATE_TOLERANCE",
    "RATE_RANGE",
    "TIME_UNITS",
    "TYPICAL_RATE_RANGE",
]

GAP_POLICIES = ("error", "longest")
#: accepted relative deviation of one step from the median step
STEP_TOLERANCE = 0.5
#: accepted relative difference between the rate of the time column and ``--rate``
RATE_TOLERANCE = 0.01
#: plausible sample rates of an inertial sensor log (Hz)
RATE_RANGE = (0.01, 1e6)
#: the rates of nearly every IMU log (Hz): stamps in an unstated unit giving a rate outside it,
#: where another
#: unit gives one inside it, are refused (:func:`check_time`)
TYPICAL_RATE_RANGE = (1.0, 1e4)
#: units of time stamps and their factor to seconds
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_UNIT_WORDS = {
    "s": ("s", "sec", "secs", "second", "seconds"),
    "ms": ("ms", "msec", "msecs", "millis", "millisecond", "milliseconds"),
    "us": ("us", "\u00b5s", "\u03bcs", "usec", "usecs", "micros", "microsecond", "microseconds"),
    "ns": ("ns", "nsec", "nsecs", "nanos", "nanosecond", "nanoseconds"),
}
_WORD_UNIT = {w: u for u, words in _UNIT_WORDS.items() for w in words}
_NAME_PARTS = re.compile(r"[^0-9a-z\u00b5\u03bc]+")


def unit_from_name(name):
    """The time unit a column's name states (``t_ms`` -> ``"ms"``, ``time [us]`` -> ``"us"``), or
    ``None``.

    The name is split at every character other than a letter or digit; the last part that is a
    unit word (:data:`TIME_UNITS`' keys, ``sec``, ``msec``, ``usec``, ``nsec``, ``micros``,
    ``nanoseconds``, ...) counts. ``time``, ``stamp``, ``t`` state none.
    """
    if name is None:
        return None
    found = [_WORD_UNIT[p] for p in _NAME_PARTS.split(str(name).lower()) if p in _WORD_UNIT]
    return found[-1] if found else None


def check_rate(rate_hz, source="--rate", where=None):
    """``rate_hz`` if it lies in :data:`RATE_RANGE`, else an :class:`InputError` saying why."""
    lo, hi = RATE_RANGE
    if lo <= rate_hz <= hi:
        return rate_hz
    prefix = f"{where}: " if where else ""
    raise InputError(
        f"{prefix}{source} gives a sample rate of {rate_hz:.6g} Hz; expected {lo:g} Hz to {hi:g} Hz"
    )


def _unit_rates(step_raw):
    """``{unit: rate_hz}`` of a median step in raw stamp units, for every unit of
    :data:`TIME_UNITS`."""
    return {unit: 1.0 / (step_raw * factor) for unit, factor in TIME_UNITS.items()}


def _likely_units(step_raw):
    """The units whose rate lies in :data:`TYPICAL_RATE_RANGE` (else in :data:`RATE_RANGE`)."""
    rates = _unit_rates(step_raw)
    for lo, hi in (TYPICAL_RATE_RANGE, RATE_RANGE):
        units = [u for u, r in rates.items() if lo <= r <= hi]
        if units:
            return units
    return []


def _stamp_hint(step_raw, given):
    """Every unit's rate for a median step ``step_raw`` (raw units) and the likely unit, for an
    error message."""
    rates = ", ".join(f"{u}: {r:.4g} Hz" for u, r in _unit_rates(step_raw).items())
    likely = [u for u in _likely_units(step_raw) if u != given]
    if not likely:
        return f" (median step {step_raw:.6g}; as {rates})"
    return (f" (median step {step_raw:.6g}; as {rates}); the likely unit is "
            f"{' or '.join(likely)}: give "
            f"time_unit={likely[0]!r}, or drop the time column and give rate_hz")


def _resolve_unit(time_unit, column, step_raw, rate_hz, where):
    """``(unit, source)``: the unit of the stamps and where it came from (module docstring)."""
    if time_unit is not None:
        if time_unit not in TIME_UNITS:
            raise InputError(f"{where}: time_unit={time_unit!r}: expected one of "
                             f"{', '.join(TIME_UNITS)}")
        return time_unit, "given"
    named = unit_from_name(column)
    if named is not None:
        return named, f"column name {_short(column)}"
    if rate_hz is not None:
        agree = [
            u for u, r in _unit_rates(step_raw).items() if abs(r / rate_hz - 1.0) <= STEP_TOLERANCE
        ]
        if len(agree) == 1:
            # "nearest", not "agrees": within STEP_TOLERANCE picks the unit, and the rate of the
            # stamps must then still agree within RATE_TOLERANCE (check_time says so if not)
            return agree[0], f"the unit nearest rate_hz={rate_hz:g}"
        if not agree and _unlikely(step_raw):
            rates = ", ".join(f"{u}: {r:.4g} Hz" for u, r in _unit_rates(step_raw).items())
            raise InputError(f"{where}: the time column (median step {step_raw:.6g}) gives, as "
                             f"{rates}; none agrees "
                             f"with the rate given ({rate_hz:g} Hz); give time_unit, or only one "
                             "of them")
    return "s", "assumed"


def _short(text, limit=40):
    text = "".join(c if c.isprintable() else "?" for c in str(text))
    return repr(text if len(text) <= limit else text[: limit - 3] + "...")


@dataclass(frozen=True)
class TimeBase:
    """The usable part of a log and its sample rate.

    Attributes
    ----------
    rate_hz : float
        Sample rate (Hz): from the time column, ``(n - 1) / (t_last - t_first)`` over the
        samples used (every stamp counts, so clock jitter averages out), or the given rate.
    rate_source : str
        ``"time column"`` or ``"--rate"``.
    start, stop : int
        The samples used are ``[start, stop)`` (0-based).
    first_line, last_line : int or None
        File lines (or bag messages) of the first and last sample used; ``None`` where the
        reader does not count lines (binary logs).
    irregular : int
        Number of irregular steps found.
    dropped : int
        Samples left out (``gaps="longest"``).
    action : str
        What was done, in words (for the outputs).
    """

    rate_hz: float
    rate_source: str
    start: int
    stop: int
    first_line: int | None = None
    last_line: int | None = None
    irregular: int = 0
    dropped: int = 0
    action: str = "all samples used"
    time_unit: str | None = None
    time_unit_source: str | None = None

    def to_json(self):
        doc = {
            "rate_hz": self.rate_hz,
            "rate_source": self.rate_source,
            "samples_used": self.stop - self.start,
            "first_line": self.first_line,
            "last_line": self.last_line,
            "irregular_steps": self.irregular,
            "dropped_samples": self.dropped,
            "action": self.action,
        }
        if self.time_unit is not None:
            doc.update(time_unit=self.time_unit, time_unit_source=self.time_unit_source)
        return doc

    def describe(self):
        """One line for the command's output: the rate and, from a time column, the stamps' unit."""
        if self.time_unit is None:
            return f"rate {self.rate_hz:.6g} Hz ({self.rate_source})"
        return (f"rate {self.rate_hz:.6g} Hz from the time column, stamps in {self.time_unit} "
                f"({self.time_unit_source})")


def check_time(
    time_s,
    *,
    rate_hz=None,
    gaps="error",
    lines=None,
    where="log",
    n_samples=None,
    what="line",
    time_unit=None,
    column=None,
):
    """Sample rate and usable segment from a time column (or from ``rate_hz`` alone).

    Parameters
    ----------
    time_s : ndarray, shape (n_samples,) or None
        Time stamps, in ``time_unit`` (or the unit the module docstring infers); ``None`` when
        the log has no time column.
    rate_hz : float or None
        The rate the user gave (Hz); cross-checked against the time column (within
        :data:`RATE_TOLERANCE`).
    gaps : {"error", "longest"}
    lines : ndarray of int, optional
        File line of every sample, for the messages.
    where : str
        File (and column) named in the messages.
    n_samples : int
        Number of samples when ``time_s`` is None.
    what : str
        What ``lines`` count, in the messages (``"line"`` of a file, ``"message"`` of a bag).
    time_unit : {"s", "ms", "us", "ns"} or None
        Unit of the stamps; ``None``: from ``column``'s name, else from ``rate_hz``, else seconds.
    column : str or None
        Name of the time column (its unit may be in it: :func:`unit_from_name`).

    Returns
    -------
    TimeBase
    """
    if gaps not in GAP_POLICIES:
        raise InputError(f"gaps={gaps!r}: expected one of {', '.join(GAP_POLICIES)}")
    if rate_hz is not None:
        rate_hz = check_rate(
            positive_number("rate_hz", rate_hz, what="sample rate in Hz"), where=where
        )
    if time_s is None:
        if rate_hz is None:
            raise InputError(f"{where}: no sample rate: give rate_hz or a time column")
        first, last = (
            (int(lines[0]), int(lines[-1])) if lines is not None and len(lines) else (None, None)
        )
        return TimeBase(rate_hz, "--rate", 0, int(n_samples), first, last)
    raw = np.asarray(time_s, dtype=np.float64)
    lines = np.arange(2, raw.size + 2) if lines is None else np.asarray(lines)
    if raw.size < 3:
        raise InputError(f"{where}: {raw.size} time stamps; expected at least 3 to derive a "
                         "sample rate")
    steps = np.diff(raw)
    positive = steps[steps > 0]
    if positive.size == 0:
        raise InputError(f"{where}: time stamps never increase ({what} {lines[0]}: "
                         f"{float(raw[0])!r}); "
                         "expected increasing stamps")
    step_raw = float(np.median(positive))
    unit, source = _resolve_unit(time_unit, column, step_raw, rate_hz, where)
    t = raw * TIME_UNITS[unit] if unit != "s" else raw
    steps = np.diff(t)
    # classifies the steps; the rate comes from the segment's span
    step = step_raw * TIME_UNITS[unit]
    mean_rate = (t.size - 1) / float(t[-1] - t[0]) if t[-1] > t[0] else None
    stated = f"stamps in {unit}" + ("" if source == "given" else f" ({source})")
    if not RATE_RANGE[0] <= 1.0 / step <= RATE_RANGE[1]:
        raise InputError(
            f"{where}: the time column gives {1.0 / step:.6g} Hz with {stated}; "
            "expected "
            f"{RATE_RANGE[0]:g} Hz to {RATE_RANGE[1]:g} Hz" + _stamp_hint(step_raw, unit)
        )
    if source == "assumed" and _unlikely(step_raw):
        raise InputError(f"{where}: the time column gives {1.0 / step:.6g} Hz if its stamps are "
                         "seconds (no unit "
                         "given or in its name), unusual for an IMU (most log at "
                         f"{TYPICAL_RATE_RANGE[0]:g} Hz to "
                         f"{TYPICAL_RATE_RANGE[1]:g} Hz)" + _stamp_hint(step_raw, None)
                         + "; time_unit='s' keeps seconds")
    bad = ~((steps >= (1 - STEP_TOLERANCE) * step) & (steps <= (1 + STEP_TOLERANCE) * step))
    n_bad = int(np.count_nonzero(bad))
    if n_bad and gaps == "error":
        i = int(np.argmax(bad))
        more = f" ({n_bad - 1} more irregular steps after it)" if n_bad > 1 else ""
        raise InputError(
            f"{where}: {what} {lines[i + 1]}: {_describe(t[i], t[i + 1], step)}{more}; expected "
            f"steps of {step:.6g} s" + _bursty_hint(n_bad, steps.size, mean_rate, gaps_ok=True)
        )
    # longest run of regular steps: segments are split at every irregular step
    cuts = np.concatenate(([0], np.flatnonzero(bad) + 1, [t.size]))
    k = int(np.argmax(np.diff(cuts)))
    start, stop = int(cuts[k]), int(cuts[k + 1])
    if stop - start < 3:
        raise InputError(f"{where}: no regular segment of at least 3 time stamps; expected steps "
                         f"of {step:.6g} s"
                         + _bursty_hint(n_bad, steps.size, mean_rate, gaps_ok=False))
    # least-noise rate: every stamp of the segment counts (clock jitter averages out)
    rate = (stop - start - 1) / float(t[stop - 1] - t[start])
    if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
        raise InputError(
            f"{where}: the time column gives {rate:.6g} Hz with {stated}; expected "
            f"{RATE_RANGE[0]:g} Hz to {RATE_RANGE[1]:g} Hz" + _stamp_hint(step_raw, unit)
        )
    if rate_hz is not None and abs(rate / rate_hz - 1.0) > RATE_TOLERANCE:
        raise InputError(f"{where}: the time column gives {rate:.6g} Hz, a step of "
                         f"{1 / rate:.6g} s with {stated}, but rate_hz is {rate_hz:g} Hz; "
                         f"expected them to agree within {RATE_TOLERANCE:.0%} (or give only one)")
    if not n_bad:
        return TimeBase(
            rate,
            "time column",
            0,
            t.size,
            int(lines[0]),
            int(lines[-1]),
            time_unit=unit,
            time_unit_source=source,
        )
    if stop - start < 0.5 * t.size and n_bad > 0.01 * steps.size and mean_rate is not None:
        raise InputError(f"{where}: the longest regular segment holds only {stop - start} of "
                         f"{t.size} samples"
                         + _bursty_hint(n_bad, steps.size, mean_rate, gaps_ok=False))
    action = (
        f"{n_bad} irregular time steps; used the longest regular segment, {what}s "
        f"{lines[start]}-{lines[stop - 1]} ({stop - start} of {t.size} samples)"
    )
    return TimeBase(
        rate,
        "time column",
        start,
        stop,
        int(lines[start]),
        int(lines[stop - 1]),
        n_bad,
        t.size - (stop - start),
        action,
        unit,
        source,
    )


def _unlikely(step_raw):
    """Seconds (assumed) give a rate outside :data:`TYPICAL_RATE_RANGE` while another unit gives
    one inside."""
    lo, hi = TYPICAL_RATE_RANGE
    rates = _unit_rates(step_raw)
    return not lo <= rates["s"] <= hi and any(lo <= r <= hi for r in rates.values())


def _bursty_hint(n_bad, n_steps, mean_rate, *, gaps_ok):
    """The way out of irregular stamps: the longest segment where they are few, the mean rate where
    they are many
    (a host's bursty stamps: no long regular segment exists)."""
    if (
        mean_rate is not None
        and n_bad > 0.01 * n_steps
        and RATE_RANGE[0] <= mean_rate <= RATE_RANGE[1]
    ):
        return (f"; {n_bad} of {n_steps} steps are irregular (bursty stamps?): the mean rate over "
                "the log is "
                f"{mean_rate:.6g} Hz; if the sensor samples on its own clock, drop the time "
                "column and give "
                f"rate_hz={mean_rate:.6g}")
    return "; use gaps='longest' to fit the longest regular segment" if gaps_ok else ""


def _describe(t0, t1, step):
    t0, t1 = float(t0), float(t1)
    if t1 < t0:
        return f"time goes backwards from {t0!r} s to {t1!r} s"
    if t1 == t0:
        return f"time stamp {t0!r} s repeats"
    if t1 - t0 > step:
        return (
            f"gap from {t0!r} s to {t1!r} s ({t1 - t0:.6g} s, about {round((t1 - t0) / step) - 1} "
            "missing samples)"
        )
    return f"short step from {t0!r} s to {t1!r} s ({t1 - t0:.6g} s)"
