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
what was dropped (:class:`TimeBase`), so the outputs can say what was done.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .readers import positive_number

__all__ = ["TimeBase", "check_time", "check_rate", "GAP_POLICIES", "STEP_TOLERANCE", "RATE_TOLERANCE", "RATE_RANGE"]

GAP_POLICIES = ("error", "longest")
#: accepted relative deviation of one step from the median step
STEP_TOLERANCE = 0.5
#: accepted relative difference between the rate of the time column and ``--rate``
RATE_TOLERANCE = 0.01
#: plausible sample rates of an inertial sensor log (Hz)
RATE_RANGE = (0.01, 1e6)


def check_rate(rate_hz, source="--rate", where=None):
    """``rate_hz`` if it lies in :data:`RATE_RANGE`, else an :class:`InputError` saying why."""
    lo, hi = RATE_RANGE
    if lo <= rate_hz <= hi:
        return rate_hz
    prefix = f"{where}: " if where else ""
    raise InputError(f"{prefix}{source} gives a sample rate of {rate_hz:.6g} Hz; expected {lo:g} Hz to {hi:g} Hz")


def _stamp_hint(step):
    """Why a time column gives an implausible rate: stamps in other units than seconds."""
    for scale, unit in ((1e9, "nanoseconds"), (1e6, "microseconds"), (1e3, "milliseconds")):
        if RATE_RANGE[0] <= scale / step <= RATE_RANGE[1]:
            return (f"; if the stamps are in {unit} (step {step:.6g}) the rate is {scale / step:.6g} Hz: give the "
                    f"time column in seconds (divide by {scale:g}) or drop --time-column and give --rate")
    return ""


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

    def to_json(self):
        return {"rate_hz": self.rate_hz, "rate_source": self.rate_source, "samples_used": self.stop - self.start,
                "first_line": self.first_line, "last_line": self.last_line, "irregular_steps": self.irregular,
                "dropped_samples": self.dropped, "action": self.action}


def check_time(time_s, *, rate_hz=None, gaps="error", lines=None, where="log", n_samples=None, what="line"):
    """Sample rate and usable segment from a time column (or from ``rate_hz`` alone).

    Parameters
    ----------
    time_s : ndarray, shape (n_samples,) or None
        Time stamps (s); ``None`` when the log has no time column.
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

    Returns
    -------
    TimeBase
    """
    if gaps not in GAP_POLICIES:
        raise InputError(f"gaps={gaps!r}: expected one of {', '.join(GAP_POLICIES)}")
    if rate_hz is not None:
        rate_hz = check_rate(positive_number("rate_hz", rate_hz, what="sample rate in Hz"), where=where)
    if time_s is None:
        if rate_hz is None:
            raise InputError(f"{where}: no sample rate: give rate_hz or a time column")
        first, last = (int(lines[0]), int(lines[-1])) if lines is not None and len(lines) else (None, None)
        return TimeBase(rate_hz, "--rate", 0, int(n_samples), first, last)
    t = np.asarray(time_s, dtype=np.float64)
    lines = np.arange(2, t.size + 2) if lines is None else np.asarray(lines)
    if t.size < 3:
        raise InputError(f"{where}: {t.size} time stamps; expected at least 3 to derive a sample rate")
    steps = np.diff(t)
    positive = steps[steps > 0]
    if positive.size == 0:
        raise InputError(f"{where}: time stamps never increase ({what} {lines[0]}: {float(t[0])!r}); expected seconds")
    step = float(np.median(positive))  # classifies the steps; the rate comes from the segment's span
    bad = ~((steps >= (1 - STEP_TOLERANCE) * step) & (steps <= (1 + STEP_TOLERANCE) * step))
    n_bad = int(np.count_nonzero(bad))
    if n_bad and gaps == "error":
        i = int(np.argmax(bad))
        more = f" ({n_bad - 1} more irregular steps after it)" if n_bad > 1 else ""
        raise InputError(f"{where}: {what} {lines[i + 1]}: {_describe(t[i], t[i + 1], step)}{more}; expected steps of "
                         f"{step:.6g} s; use gaps='longest' to fit the longest regular segment")
    # longest run of regular steps: segments are split at every irregular step
    cuts = np.concatenate(([0], np.flatnonzero(bad) + 1, [t.size]))
    k = int(np.argmax(np.diff(cuts)))
    start, stop = int(cuts[k]), int(cuts[k + 1])
    if stop - start < 3:
        raise InputError(f"{where}: no regular segment of at least 3 time stamps; expected steps of {step:.6g} s")
    # least-noise rate: every stamp of the segment counts (clock jitter averages out)
    rate = (stop - start - 1) / float(t[stop - 1] - t[start])
    if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
        raise InputError(f"{where}: the time column gives {rate:.6g} Hz (median step {step:.6g}); expected "
                         f"{RATE_RANGE[0]:g} Hz to {RATE_RANGE[1]:g} Hz with stamps in seconds" + _stamp_hint(step))
    if rate_hz is not None and abs(rate / rate_hz - 1.0) > RATE_TOLERANCE:
        raise InputError(f"{where}: the time column gives {rate:.6g} Hz (step {1 / rate:.6g} s) but rate_hz is "
                         f"{rate_hz:g} Hz; expected them to agree within {RATE_TOLERANCE:.0%} (or give only one)")
    if not n_bad:
        return TimeBase(rate, "time column", 0, t.size, int(lines[0]), int(lines[-1]))
    action = (f"{n_bad} irregular time steps; used the longest regular segment, {what}s {lines[start]}-{lines[stop - 1]} "
              f"({stop - start} of {t.size} samples)")
    return TimeBase(rate, "time column", start, stop, int(lines[start]), int(lines[stop - 1]), n_bad,
                    t.size - (stop - start), action)


def _describe(t0, t1, step):
    t0, t1 = float(t0), float(t1)
    if t1 < t0:
        return f"time goes backwards from {t0!r} s to {t1!r} s"
    if t1 == t0:
        return f"time stamp {t0!r} s repeats"
    if t1 - t0 > step:
        return f"gap from {t0!r} s to {t1!r} s ({t1 - t0:.6g} s, about {round((t1 - t0) / step) - 1} missing samples)"
    return f"short step from {t0!r} s to {t1!r} s ({t1 - t0:.6g} s)"
