"""One path from a log to its Allan variances: what ``fit``, ``allan``, batches, fleets and scenes
read.

A :class:`LogSource` is a frozen request: the log (a file, ``-`` for standard input, a named
pipe, a ROS bag, a binary or text log larger than memory), its column(s), the rate or the time
column and the gaps policy, the input kind (rates or increments) and units, or an Allan table
instead of a log. :func:`allan_from_source` turns it into one
:class:`~bayes_imu.allan.estimator.AllanResult` per column (SI when ``units`` is given) and a
JSON-ready description of what was read and done (:class:`SourceAllan`).

Binary logs (``.npy``, raw) and ``stream=True`` are read out of core
(:func:`~bayes_imu.allan.outofcore.allan_variance_file`); everything else in memory with the full
checks of :mod:`bayes_imu.io.readers` and :func:`bayes_imu.io.timebase.check_time`. Standard input
and named pipes are copied as they stream in to a temporary file of the same name and read like
any log (line numbers unchanged); the copy is removed afterwards.
"""

import contextlib
import dataclasses
import os
import shutil
import stat
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.bags import is_bag, read_imu_bag
from ..io.readers import (INCREMENT_UNITS, SI_UNITS, UNITS, check_columns, read_columns,
                          sniff_file)
from ..io.timebase import check_time
from .contrast import DEFAULT_CONTRAST_SPAN_S
from .estimator import allan_variance
from .outofcore import BINARY_SUFFIXES

__all__ = ["LogSource", "SourceAllan", "allan_from_source", "check_source", "MIN_SAMPLES",
           "with_article"]

#: fewest samples per purpose: one Allan variance (``allan``), 4 octave cluster sizes
#: (1, 2, 4, 8 <= N/4) for a fit
MIN_SAMPLES = {"allan": 4, "fit": 32}


@dataclasses.dataclass(frozen=True)
class LogSource:
    """Where the samples come from and how to read them (the input options of ``allan``, ``fit``).

    Attributes
    ----------
    log : Path or None
        The log: delimited text (``.gz`` accepted), ``.npy`` / raw binary, a ROS bag, ``-``
        (standard input) or a named pipe. ``None`` with ``allan_table``.
    column : str or None
        Column name or 0-based index; several separated by commas (a fit of each).
    topic : str or None
        ROS bag: the ``sensor_msgs/Imu`` topic (columns ``gyro_x`` ... ``accel_z``).
    stream : bool
        Read a text log out of core, in chunks (automatic for binary logs).
    rate : float or None
        Sample rate (Hz); optional with ``time_column`` or a bag (their stamps give it).
    time_column : str or None
        Time stamps (s): the rate is derived from them and checked.
    gaps : {"error", "longest"}
        Irregular time steps: an error, or the longest regular segment.
    input : {"rate", "increments"}
        Rate samples, or delta-angle / delta-velocity increments per sample.
    units : str or None
        Units of the column(s), converted to SI (rad/s, m/s^2); ``None``: left as they are.
    sensor : {"gyro", "accel"} or None
        The sensor kind, checked against ``units``.
    allan_table : Path or None
        An Allan deviation table to fit instead of a log (``rate`` is its log's rate).
    samples : int or None
        With ``allan_table``: samples in the log it came from.
    time_unit : {"s", "ms", "us", "ns"} or None
        Unit of the time stamps (``None``: from the column's name, or the unit agreeing with
        ``rate``, else seconds; :func:`~bayes_imu.io.timebase.check_time`).
    trust_units : bool
        Skip the plausibility check of ``units`` against a static log
        (:mod:`bayes_imu.io.plausible`).
    label : str or None
        The name outputs give the log (default: ``log`` as given).
    calibration : float or None
        Calibration window [s] of the calibrated-outage errors the record measures directly
        (:attr:`AllanResult.contrasts`, for the drift-space check); ``None`` skips them.
    where : str or None
        Keep only the rows of a text log satisfying this filter (``"period == 0"``,
        :mod:`bayes_imu.io.rows`), read in memory.
    """

    log: Path = None
    column: str = None
    topic: str = None
    stream: bool = False
    rate: float = None
    time_column: str = None
    time_unit: str = None
    gaps: str = "error"
    input: str = "rate"
    units: str = None
    sensor: str = None
    allan_table: Path = None
    samples: int = None
    label: str = None
    calibration: float = DEFAULT_CONTRAST_SPAN_S
    trust_units: bool = False
    where: str = None

    @property
    def shown(self):
        """The log's name in outputs and messages (its ``label``, or the path as given)."""
        return self.label or str(self.log or self.allan_table)


@dataclasses.dataclass(frozen=True)
class SourceAllan:
    """The Allan variances of a :class:`LogSource`.

    Attributes
    ----------
    columns : tuple of str
        The columns read (``("adev",)`` for an Allan table, ``("0",)`` for a binary log).
    results : tuple of AllanResult
        One per column, in ``unit`` squared.
    unit : str
        The unit of the rates: SI (``rad/s``, ``m/s^2``) with ``units``, else ``u`` (``u/s`` for
        increments).
    info : dict
        JSON-ready description of what was read and done (``summary.json``'s ``input``).
    """

    columns: tuple
    results: tuple
    unit: str
    info: dict


def allan_from_source(source, *, purpose="fit", grid="octave", progress=False):
    """The Allan variance of every column of ``source`` (see the module docstring).

    Parameters
    ----------
    source : LogSource
    purpose : {"fit", "allan"}
        What the variances are for: ``allan`` takes one column and 4 samples, ``fit`` several
        columns and 32 samples (:data:`MIN_SAMPLES`).
    grid : {"octave", "decade", "all"}
        Cluster sizes (:func:`~bayes_imu.allan.estimator.allan_variance`'s ``m``).
    progress : bool
        Progress bars on standard error.

    Returns
    -------
    SourceAllan

    Raises
    ------
    InputError
        Anything wrong with the request or the log, in one line that names it.
    """
    if purpose not in MIN_SAMPLES:
        raise InputError(f"purpose={purpose!r}: expected one of {', '.join(MIN_SAMPLES)}")
    paths = {k: Path(v) for k, v in (("log", source.log), ("allan_table", source.allan_table))
             if v is not None and not isinstance(v, Path)}
    source = dataclasses.replace(source, **paths)  # a path given as a string
    increments = source.input == "increments"
    table = UNITS if not increments else INCREMENT_UNITS
    if source.units is not None and source.units not in table:
        what = (
            "an increment unit: add input='increments'"
            if not increments
            else f"a rate unit; increments (input='increments') take {', '.join(INCREMENT_UNITS)}"
        )
        raise InputError(f"units={source.units} is {what}")
    if source.units is not None and source.sensor and source.sensor != table[source.units][0]:
        raise InputError(
            f"units={source.units} is {with_article(table[source.units][0])} unit but sensor is "
            f"{source.sensor}"
        )
    if source.allan_table is not None:
        return _table(source)
    with _spooled(source) as spooled:
        try:
            columns, results, unit, info = _allan(spooled, purpose, grid, progress, increments,
                                                  table)
        except InputError as exc:
            if spooled.log == source.log:
                raise
            # the spooled copy is ours, not the user's: the message names what was given ("-")
            raise InputError(str(exc).replace(str(spooled.log), source.shown)) from None
    info["log"] = source.shown
    return SourceAllan(tuple(columns), tuple(results), unit, info)


def check_source(source):
    """Check what ``source`` asks of its log from the log's header alone, before anything is read.

    The columns of a text log (its time column and the columns of its ``where`` filter too) are
    checked against the header (:func:`~bayes_imu.io.readers.check_columns`: the same message,
    with its "did you mean" hint, that :func:`allan_from_source` gives), and a missing log is
    refused, so that a caller about to read several logs (a scene's sensors) finds a wrong name
    before the first fit. Binary logs, ROS bags, standard input and named pipes are left to
    :func:`allan_from_source` (a pipe can be read only once).

    Raises
    ------
    InputError
        The first wrong column or missing log, in one line that names the file.
    """
    if source.allan_table is not None or source.log is None:
        return
    log = Path(source.log)
    if str(log) == "-" or is_bag(log) or log.suffix.lower() in BINARY_SUFFIXES:
        return
    if log.exists() and not log.is_file():  # a named pipe or a device: read as it streams in
        return
    columns = _columns(dataclasses.replace(source, log=log), "fit")
    check_columns(log, columns=columns, time_column=source.time_column, where=source.where)


def with_article(word):
    """``"an accel"``, ``"a gyro"``, ``"an accelerometer"``: ``word`` with its article."""
    return f"an {word}" if word[0] in "aeiou" else f"a {word}"


def _kind(opts, table):
    """The sensor kind of a request (``sensor``, else its units' kind), or ``None``."""
    if opts.sensor:
        return opts.sensor
    return table[opts.units][0] if opts.units in table else None


def _allan(opts, purpose, grid, progress, increments, table):
    bag = is_bag(opts.log)
    if opts.rate is None and opts.time_column is None and not bag:
        raise InputError(f"{opts.log}: no sample rate: give rate_hz or a time column")
    factor, unit = (
        (1.0, "u") if opts.units is None else (table[opts.units][1], SI_UNITS[table[opts.units][0]])
    )
    if increments and bag:
        raise InputError(
            f"{opts.log}: a ROS bag's sensor_msgs/Imu holds rates, not increments; "
            "leave out input='increments'"
        )
    if bag and opts.units is None:  # sensor_msgs/Imu is SI by definition
        kinds = {c.strip().split("_")[0] for c in (opts.column or "").split(",")}
        unit = SI_UNITS.get(kinds.pop()) if len(kinds) == 1 else None
        if unit is None:
            raise InputError(
                f"column={opts.column!r}: fit gyro and accelerometer fields of a bag separately"
            )
    small = None if bag else _small_npy(opts)
    if small is not None:  # held in memory: the record's own drift is measured too
        columns, values, rate, info = _npy_in_memory(opts, small, purpose)
        results = [allan_variance(values[:, 0], rate_hz=rate, m=grid, progress=progress,
                                  contrast_span_s=opts.calibration, sensor=_kind(opts, table))]
    elif not bag and (opts.stream or opts.log.suffix.lower() in BINARY_SUFFIXES):
        columns, results, info = _streamed(opts, purpose, grid, progress)
    else:
        columns, values, rate, info = _read(opts, purpose, progress)
        results = [
            allan_variance(values[:, j], rate_hz=rate, m=grid, progress=progress,
                           contrast_span_s=opts.calibration, sensor=_kind(opts, table))
            for j in range(values.shape[1])
        ]
    if (
        increments
    ):  # increment / dt = mean rate over the sample: every Allan variance times (factor * rate)^2
        factor *= results[0].rate_hz
        unit = unit if opts.units is not None else "u/s"
        info["input"] = "increments (divided by the sample period)"
    info.update(input_units=opts.units or (unit if bag else "unspecified (u)"), unit=unit)
    return columns, [r.scaled(factor) for r in results], unit, info


def _columns(opts, purpose):
    if opts.column is None:
        try:
            names = sniff_file(opts.log)["names"]
            shown = (
                "; its columns: "
                + ", ".join(repr(n) for n in names[:12])
                + (", ..." if len(names) > 12 else "")
            )
        except InputError:
            shown = ""
        raise InputError(
            f"{opts.log}: a text log needs a column (a header name or 0-based index){shown}"
        )
    columns = [c.strip() for c in opts.column.split(",")]
    if any(not c for c in columns):
        raise InputError(
            f"column={opts.column!r}: expected column names or indices separated by commas"
        )
    if purpose == "allan" and len(columns) > 1:
        raise InputError(f"column={opts.column!r}: allan takes one column (fit takes several)")
    return columns


def _table(opts):
    """An Allan deviation table (``fit --allan-table``) as the one Allan result to fit."""
    from .table import read_allan_table

    if opts.rate is None:
        raise InputError(
            f"{opts.allan_table}: an Allan table needs rate_hz (the rate of the log the "
            "table came from)"
        )
    if opts.input == "increments":
        raise InputError(
            "input='increments' does not apply to an Allan table (give it in rate units)"
        )
    result, assumption = read_allan_table(
        opts.allan_table, rate_hz=opts.rate, n_samples=opts.samples
    )
    factor, unit = (
        (1.0, "u") if opts.units is None else (UNITS[opts.units][1], SI_UNITS[UNITS[opts.units][0]])
    )
    info = {
        "allan_table": str(opts.allan_table),
        "rate_hz": result.rate_hz,
        "rate_source": "--rate",
        "samples_used": result.n_samples,
        "intervals": assumption,
        "action": "Allan deviation table fitted",
        "input_units": opts.units or "unspecified (u)",
        "unit": unit,
        "log": opts.shown,
    }
    return SourceAllan(("adev",), (result.scaled(factor),), unit, info)


#: a .npy log of at most this many samples is read into memory (unless ``stream``): 512 MB of
#: float64
IN_MEMORY_NPY = 2**26


def _small_npy(opts):
    """The samples of a ``.npy`` log small enough to hold in memory, ``None`` otherwise
    (streamed)."""
    if opts.stream or opts.log.suffix.lower() != ".npy" or opts.column not in (None, "0"):
        return None
    from .outofcore import _npy_layout

    dtype, offset, count = _npy_layout(opts.log)
    if count > IN_MEMORY_NPY or offset + count * dtype.itemsize > opts.log.stat().st_size:
        return None  # the streaming reader says what is wrong with a truncated file
    return np.fromfile(opts.log, dtype=dtype, count=count, offset=offset).astype(np.float64)


def _npy_in_memory(opts, values, purpose):
    """``_read``'s outputs for a ``.npy`` log held in memory (one channel, ``rate`` given)."""
    if opts.time_column is not None or opts.time_unit is not None:
        raise InputError(f"{opts.log}: a binary log has no time column; give rate_hz")
    if opts.where is not None:
        raise InputError(f"{opts.log}: where={opts.where!r} filters the rows of a text log; a "
                         "binary log has no columns to filter by")
    if opts.rate is None:
        raise InputError(f"{opts.log}: no sample rate: give rate_hz")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError(
            f"{opts.log}: sample {bad[0]} is {values[bad[0]]!r}; expected finite numbers"
        )
    _require_samples(opts, values.size, purpose)
    steps = _plausible(opts, values[:, None], opts.rate, ["0"])
    info = {"log": str(opts.log), "columns": ["0"], "read": "in memory", "rate_hz": opts.rate,
            "rate_source": "--rate", "samples_used": int(values.size), "action": "all samples used",
            **({"steps": steps} if steps else {})}
    return ["0"], values[:, None], opts.rate, info


#: samples at the start of a log read out of core that the plausibility checks look at
STREAMED_CHECK = 1 << 16


def _streamed(opts, purpose, grid, progress):
    from .outofcore import allan_variance_file, head_samples

    if opts.time_column is not None or opts.time_unit is not None:
        raise InputError(f"{opts.log}: a time column is not available out of core; give rate_hz")
    if opts.where is not None:
        raise InputError(f"{opts.log}: where={opts.where!r} is not available out of core (stream, "
                         "a binary log); read the text log in memory")
    binary = opts.log.suffix.lower() in BINARY_SUFFIXES
    # its one channel is column "0" (a scene names it)
    if binary and opts.column not in (None, "0"):
        raise InputError(
            f"{opts.log}: a binary log has one channel; leave out column (or give '0')"
        )
    columns = ["0"] if binary else _columns(opts, purpose)
    results = [
        allan_variance_file(
            opts.log, rate_hz=opts.rate, column=None if binary else c, m=grid, progress=progress
        )
        for c in columns
    ]
    _require_samples(opts, results[0].n_samples, purpose)
    heads = [head_samples(opts.log, column=None if binary else c, n=STREAMED_CHECK)
             for c in columns]
    size = min(h.size for h in heads)
    steps = _plausible(opts, np.column_stack([h[:size] for h in heads]), opts.rate, columns)
    info = {
        "log": str(opts.log),
        "columns": columns,
        "read": "out of core",
        "rate_hz": results[0].rate_hz,
        "rate_source": "--rate",
        "samples_used": results[0].n_samples,
        "action": "all samples used",
        **({"steps": steps} if steps else {}),
    }
    return columns, results, info


def _read(opts, purpose, progress):
    """Columns read in memory, cut to the usable time base, and the input description."""
    columns = _columns(opts, purpose)
    if is_bag(opts.log):
        if opts.where is not None:
            raise InputError(f"{opts.log}: where={opts.where!r} filters the rows of a text log; "
                             "a ROS bag has none")
        if opts.topic is None:
            raise InputError(f"{opts.log}: a ROS bag needs a topic (a sensor_msgs/Imu topic)")
        if opts.time_unit is not None:
            raise InputError(f"{opts.log}: a ROS bag's header stamps are seconds and nanoseconds; "
                             "leave out time_unit")
        data = read_imu_bag(opts.log, topic=opts.topic, columns=columns)
        where, what = f"{opts.log}: {opts.topic} header stamps", "message"
    else:
        data = read_columns(
            opts.log, columns=columns, time_column=opts.time_column, progress=progress,
            where=opts.where,
        )
        where, what = f"{opts.log}: column {opts.time_column!r}", "line"
    if opts.time_unit is not None and data.time_s is None:
        raise InputError(f"{opts.log}: time_unit={opts.time_unit!r} goes with a time column (no "
                         "time column given)")
    timebase = check_time(
        data.time_s,
        rate_hz=opts.rate,
        gaps=opts.gaps,
        lines=data.lines,
        where=where,
        n_samples=data.values.shape[0],
        what=what,
        time_unit="s" if is_bag(opts.log) or data.time_iso else opts.time_unit,
        column=getattr(data, "time_name", None),
    )
    values = data.values[timebase.start : timebase.stop]
    _require_samples(opts, values.shape[0], purpose)
    steps = _plausible(opts, values, timebase.rate_hz, data.columns)
    info = {
        "log": str(opts.log),
        "columns": list(data.columns),
        "delimiter": data.delimiter,
        "header": data.header,
        "read": "in memory",
        **timebase.to_json(),
        **({"steps": steps} if steps else {}),
    }
    if opts.where is not None:
        info["where"] = opts.where
    if data.time_iso:
        info.update(time_stamps="ISO 8601", time_unit_source="ISO 8601 stamps")
    return data.columns, values, timebase.rate_hz, info


def _plausible(opts, values, rate_hz, columns):
    """Warn of a step in a column, and of declared units a static log contradicts (an error where
    no unit fits, unless ``trust_units``): :mod:`bayes_imu.io.plausible`. The warnings name the log
    as the user gave it (``opts.shown``: ``-`` for standard input, not the spooled copy). Returns
    the steps found, ``{column: {"sample": first sample after it (1-based), "sigmas": its
    size}}``, for the outputs' record of what was read."""
    import warnings

    from ..io.plausible import PlausibilityWarning, check_units, find_step

    steps = {}
    for j, column in enumerate(columns):
        step = find_step(values[:, j])
        if step is not None:
            steps[str(column)] = {"sample": step[0] + 1, "sigmas": round(step[1], 3)}
            warnings.warn(f"{opts.shown}: column {column!r}: its level steps by {step[1]:.3g} "
                          f"sigma of its noise at sample {step[0] + 1}; a step is not noise (the "
                          "fit treats it as slow drift): cut the log there, or check the sensor",
                          PlausibilityWarning, stacklevel=2)
    if opts.units is None or opts.units not in UNITS or opts.input != "rate" or opts.trust_units:
        return steps
    found = check_units(values, opts.units, rate_hz)
    if found is None:
        return steps
    if found.fatal:
        raise InputError(f"{opts.log}: {found}; give trust_units if the log is what it should be")
    warnings.warn(f"{opts.shown}: {found} (units={opts.units} as given; trust_units silences "
                  "this)", PlausibilityWarning, stacklevel=2)
    return steps


def _require_samples(opts, n, purpose):
    needed = MIN_SAMPLES[purpose]
    if n < needed:
        raise InputError(
            f"{opts.log}: {n} sample{'' if n == 1 else 's'}; expected at least {needed} for "
            f"{purpose} "
            f"({'4 octave cluster sizes' if purpose == 'fit' else 'one Allan variance'})"
        )


# ------------------------------------------------------------------ pipes and standard input


@contextlib.contextmanager
def _spooled(source):
    """``source`` itself, or, for ``-`` (standard input) or a named pipe, ``source`` with ``log`` a
    temporary copy of the same name, made as the data streams in and removed afterwards. A pipe
    with no writer is an error at once, not a wait."""
    path = source.log
    fifo = str(path) != "-" and path.exists() and stat.S_ISFIFO(path.stat().st_mode)
    if str(path) != "-" and not fifo:
        yield source
        return
    folder = Path(tempfile.mkdtemp(prefix="bayes-imu-input-"))
    spooled = folder / ("stdin.csv" if str(path) == "-" else path.name)
    try:
        with open(spooled, "wb") as target:
            if fifo:
                _copy_pipe(path, target)
            else:
                _copy_bounded(sys.stdin.buffer.read, target, path)
        if spooled.stat().st_size == 0:
            raise InputError(
                f"{path}: nothing was read from "
                f"{'standard input' if not fifo else 'the pipe'}; expected a log"
            )
        yield dataclasses.replace(source, log=spooled, label=source.shown)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _copy_pipe(path, target):
    fd = os.open(
        path, os.O_RDONLY | os.O_NONBLOCK
    )  # never blocks; a first read tells if a writer exists
    try:
        for _ in range(WRITER_WAIT_STEPS):  # a writer blocked in open() is woken by ours: a moment
            try:
                first = os.read(fd, 1 << 16)
            except BlockingIOError:  # a writer, nothing written yet: wait for it
                first = None
            if first != b"":
                break
            time.sleep(0.02)
        if first == b"":
            raise InputError(
                f"{path}: a named pipe with no writer; start the program that writes the log first"
            )
        os.set_blocking(fd, True)
        if first:
            target.write(first)
        _copy_bounded(lambda size: os.read(fd, size), target, path, done=len(first or b""))
    finally:
        os.close(fd)


#: 20 ms polls for a named pipe's writer to appear (0.5 s) before "no writer" is said
WRITER_WAIT_STEPS = 25

#: most bytes spooled from standard input or a named pipe (a never-ending pipe ends here)
MAX_SPOOL_BYTES = 2**30


def _copy_bounded(read, target, path, done=0):
    """``read(size)`` into ``target`` until it returns nothing, refused beyond
    :data:`MAX_SPOOL_BYTES` (a pipe that never ends, ``yes | bayes-imu fit -``, would otherwise
    fill the temporary folder for as long as it runs)."""
    while chunk := read(1 << 20):
        done += len(chunk)
        if done > MAX_SPOOL_BYTES:
            shown = "standard input" if str(path) == "-" else "the pipe"
            raise InputError(f"{path}: more than {MAX_SPOOL_BYTES / 2**30:g} GiB came from {shown} "
                             "without an end; save a log that large to a file and give its path")
        target.write(chunk)
