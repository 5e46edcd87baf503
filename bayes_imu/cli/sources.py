"""Command-line input to Allan variances: text logs in memory, binary logs out of core, ROS bags.

Helper of :mod:`bayes_imu.cli.main`: resolves ``--column``, ``--rate`` / ``--time-column`` /
``--gaps``, ``--topic``, ``--stream`` and ``--units``, given as a frozen :class:`SourceOptions`
(the command line builds it from its parsed arguments), into one
:class:`~bayes_imu.allan.estimator.AllanResult` per column (SI when ``--units``) and a JSON-ready
description of what was read and done.
"""

import dataclasses
from pathlib import Path

from ..allan.estimator import allan_variance
from ..io.bags import is_bag, read_imu_bag
from ..errors import InputError
from ..io.readers import INCREMENT_UNITS, SI_UNITS, UNITS, read_columns, sniff_file
from ..allan.outofcore import BINARY_SUFFIXES
from ..io.timebase import check_time

__all__ = ["SourceOptions", "allan_results"]


@dataclasses.dataclass(frozen=True)
class SourceOptions:
    """Where the samples come from and how to read them (the input options of ``allan`` and ``fit``)."""

    log: Path
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
    progress: bool = False
    trust_units: bool = False

    @classmethod
    def from_namespace(cls, args):
        """The options an ``argparse`` namespace holds (absent ones at their defaults)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in vars(args).items() if k in names})

#: fewest samples per command: 4 octave cluster sizes (1, 2, 4, 8 <= N/4) for a fit
_MIN_SAMPLES = {"allan": 4, "fit": 32}


def _columns(opts, command):
    if opts.column is None:
        try:
            names = sniff_file(opts.log)["names"]
            shown = "; its columns: " + ", ".join(repr(n) for n in names[:12]) + (", ..." if len(names) > 12 else "")
        except InputError:
            shown = ""
        raise InputError(f"{opts.log}: a text log needs --column (a header name or 0-based index){shown}")
    columns = [c.strip() for c in opts.column.split(",")]
    if any(not c for c in columns):
        raise InputError(f"--column {opts.column!r}: expected column names or indices separated by commas")
    if command == "allan" and len(columns) > 1:
        raise InputError(f"--column {opts.column!r}: allan takes one column (fit takes several)")
    return columns


def allan_results(opts, command, grid="octave"):
    """One AllanResult per column (SI when --units), the unit label and the input description.

    Binary logs (.npy, raw) and ``--stream`` are read out of core (:mod:`bayes_imu.allan.outofcore`),
    everything else in memory with the full checks of :mod:`bayes_imu.io.readers` and the time column.
    """
    increments = opts.input == "increments"
    table = UNITS if not increments else INCREMENT_UNITS
    if opts.units is not None and opts.units not in table:
        what = ("an increment unit: add --input increments" if not increments
                else f"a rate unit; increments (--input increments) take {', '.join(INCREMENT_UNITS)}")
        raise InputError(f"--units {opts.units} is {what}")
    if opts.units is not None and opts.sensor and opts.sensor != table[opts.units][0]:
        raise InputError(f"--units {opts.units} is a {table[opts.units][0]} unit but --sensor is {opts.sensor}")
    if opts.allan_table is not None:
        return _table(opts)
    bag = is_bag(opts.log)
    if opts.rate is None and opts.time_column is None and not bag:
        raise InputError(f"{opts.log}: no sample rate: give --rate HZ or a --time-column")
    factor, unit = (1.0, "u") if opts.units is None else (table[opts.units][1], SI_UNITS[table[opts.units][0]])
    if increments and bag:
        raise InputError(f"{opts.log}: a ROS bag's sensor_msgs/Imu holds rates, not increments; leave out --input")
    if bag and opts.units is None:  # sensor_msgs/Imu is SI by definition
        kinds = {c.strip().split("_")[0] for c in (opts.column or "").split(",")}
        unit = SI_UNITS.get(kinds.pop()) if len(kinds) == 1 else None
        if unit is None:
            raise InputError(f"--column {opts.column!r}: fit gyro and accelerometer fields of a bag separately")
    if not bag and (opts.stream or opts.log.suffix.lower() in BINARY_SUFFIXES):
        columns, results, info = _streamed(opts, command, grid)
    else:
        columns, values, rate, info = _read(opts, command)
        results = [allan_variance(values[:, j], rate_hz=rate, m=grid, progress=opts.progress)
                   for j in range(values.shape[1])]
    if increments:  # increment / dt = mean rate over the sample: every Allan variance times (factor * rate)^2
        factor *= results[0].rate_hz
        unit = unit if opts.units is not None else "u/s"
        info["input"] = "increments (divided by the sample period)"
    info.update(input_units=opts.units or (unit if bag else "unspecified (u)"), unit=unit)
    return columns, [r.scaled(factor) for r in results], unit, info


def _table(opts):
    """An Allan deviation table (``fit --allan-table``) as the one Allan result to fit."""
    from ..allan.table import read_allan_table

    if opts.rate is None:
        raise InputError(f"{opts.allan_table}: --allan-table needs --rate HZ (the rate of the log the table came from)")
    if opts.input == "increments":
        raise InputError("--input increments does not apply to an Allan table (give it in rate units)")
    result, assumption = read_allan_table(opts.allan_table, rate_hz=opts.rate, n_samples=opts.samples)
    factor, unit = (1.0, "u") if opts.units is None else (UNITS[opts.units][1], SI_UNITS[UNITS[opts.units][0]])
    info = {"allan_table": str(opts.allan_table), "rate_hz": result.rate_hz, "rate_source": "--rate",
            "samples_used": result.n_samples, "intervals": assumption, "action": "Allan deviation table fitted",
            "input_units": opts.units or "unspecified (u)", "unit": unit}
    return ["adev"], [result.scaled(factor)], unit, info


def _streamed(opts, command, grid):
    from ..allan.outofcore import allan_variance_file

    if opts.time_column is not None or opts.time_unit is not None:
        raise InputError(f"{opts.log}: --time-column is not available out of core; give --rate HZ")
    binary = opts.log.suffix.lower() in BINARY_SUFFIXES
    if binary and opts.column is not None:
        raise InputError(f"{opts.log}: a binary log has one channel; leave out --column")
    columns = ["0"] if binary else _columns(opts, command)
    results = [allan_variance_file(opts.log, rate_hz=opts.rate, column=None if binary else c, m=grid,
                                   progress=opts.progress) for c in columns]
    _require_samples(opts, results[0].n_samples, command)
    info = {"log": str(opts.log), "columns": columns, "read": "out of core", "rate_hz": results[0].rate_hz,
            "rate_source": "--rate", "samples_used": results[0].n_samples, "action": "all samples used"}
    return columns, results, info


def _read(opts, command):
    """Columns read in memory, cut to the usable time base, and the input description."""
    columns = _columns(opts, command)
    if is_bag(opts.log):
        if opts.topic is None:
            raise InputError(f"{opts.log}: a ROS bag needs --topic (a sensor_msgs/Imu topic)")
        if opts.time_unit is not None:
            raise InputError(f"{opts.log}: a ROS bag's header stamps are seconds and nanoseconds; "
                             "leave out "
                             "--time-unit")
        data = read_imu_bag(opts.log, topic=opts.topic, columns=columns)
        where, what = f"{opts.log}: {opts.topic} header stamps", "message"
    else:
        data = read_columns(opts.log, columns=columns, time_column=opts.time_column, progress=opts.progress)
        where, what = f"{opts.log}: column {opts.time_column!r}", "line"
    if opts.time_unit is not None and data.time_s is None:
        raise InputError(f"{opts.log}: --time-unit {opts.time_unit} goes with --time-column (no "
                         "time column given)")
    timebase = check_time(data.time_s, rate_hz=opts.rate, gaps=opts.gaps, lines=data.lines, where=where,
                          n_samples=data.values.shape[0], what=what,
                          time_unit="s" if is_bag(opts.log) else opts.time_unit,
                          column=getattr(data, "time_name", None))
    values = data.values[timebase.start:timebase.stop]
    _require_samples(opts, values.shape[0], command)
    _plausible(opts, values, timebase.rate_hz, data.columns)
    info = {"log": str(opts.log), "columns": list(data.columns), "delimiter": data.delimiter, "header": data.header,
            "read": "in memory", **timebase.to_json()}
    return data.columns, values, timebase.rate_hz, info


def _plausible(opts, values, rate_hz, columns):
    """Warn of a step in a column, and of declared units a static log contradicts (an error where
    no unit fits,
    unless --trust-units): :mod:`bayes_imu.io.plausible`."""
    import warnings

    from ..io.plausible import PlausibilityWarning, check_units, find_step

    for j, column in enumerate(columns):
        step = find_step(values[:, j])
        if step is not None:
            warnings.warn(f"{opts.log}: column {column!r}: its level steps by {step[1]:.3g} sigma "
                          "of its noise at "
                          f"sample {step[0] + 1}; a step is not noise (the fit treats it as slow "
                          "drift): cut the log "
                          "there, or check the sensor", PlausibilityWarning, stacklevel=2)
    if opts.units is None or opts.units not in UNITS or opts.input != "rate" or opts.trust_units:
        return
    found = check_units(values, opts.units, rate_hz)
    if found is None:
        return
    if found.fatal:
        raise InputError(f"{opts.log}: {found}; give --trust-units if the log is what it should be")
    warnings.warn(f"{opts.log}: {found} (--units {opts.units} as given; --trust-units silences "
                  "this)",
                  PlausibilityWarning, stacklevel=2)


def _require_samples(opts, n, command):
    needed = _MIN_SAMPLES[command]
    if n < needed:
        raise InputError(f"{opts.log}: {n} samples; expected at least {needed} for {command} "
                         f"({'4 octave cluster sizes' if command == 'fit' else 'one Allan variance'})")
