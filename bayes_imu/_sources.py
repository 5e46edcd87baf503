"""Command-line input to Allan variances: text logs in memory, binary logs out of core, ROS bags.

Private helper of :mod:`bayes_imu.cli` (it reads the parsed arguments): resolves ``--column``,
``--rate`` / ``--time-column`` / ``--gaps``, ``--topic``, ``--stream`` and ``--units`` into one
:class:`~bayes_imu.allan.AllanResult` per column (SI when ``--units``) and a JSON-ready
description of what was read and done.
"""

import dataclasses

from .allan import allan_variance
from .bags import is_bag, read_imu_bag
from .errors import InputError
from .io import INCREMENT_UNITS, SI_UNITS, UNITS, read_columns, sniff_file
from .outofcore import BINARY_SUFFIXES
from .timebase import check_time

__all__ = ["allan_results"]

#: fewest samples per command: 4 octave cluster sizes (1, 2, 4, 8 <= N/4) for a fit
_MIN_SAMPLES = {"allan": 4, "fit": 32}


def _columns(args, command):
    if args.column is None:
        try:
            names = sniff_file(args.log)["names"]
            shown = "; its columns: " + ", ".join(repr(n) for n in names[:12]) + (", ..." if len(names) > 12 else "")
        except InputError:
            shown = ""
        raise InputError(f"{args.log}: a text log needs --column (a header name or 0-based index){shown}")
    columns = [c.strip() for c in args.column.split(",")]
    if any(not c for c in columns):
        raise InputError(f"--column {args.column!r}: expected column names or indices separated by commas")
    if command == "allan" and len(columns) > 1:
        raise InputError(f"--column {args.column!r}: allan takes one column (fit takes several)")
    return columns


def allan_results(args, command, grid="octave"):
    """One AllanResult per column (SI when --units), the unit label and the input description.

    Binary logs (.npy, raw) and ``--stream`` are read out of core (:mod:`bayes_imu.outofcore`),
    everything else in memory with the full checks of :mod:`bayes_imu.io` and the time column.
    """
    increments = getattr(args, "input", "rate") == "increments"
    table = UNITS if not increments else INCREMENT_UNITS
    if args.units is not None and args.units not in table:
        what = ("an increment unit: add --input increments" if not increments
                else f"a rate unit; increments (--input increments) take {', '.join(INCREMENT_UNITS)}")
        raise InputError(f"--units {args.units} is {what}")
    if args.units is not None and getattr(args, "sensor", None) and args.sensor != table[args.units][0]:
        raise InputError(f"--units {args.units} is a {table[args.units][0]} unit but --sensor is {args.sensor}")
    if getattr(args, "allan_table", None) is not None:
        return _table(args)
    bag = is_bag(args.log)
    if args.rate is None and args.time_column is None and not bag:
        raise InputError(f"{args.log}: no sample rate: give --rate HZ or a --time-column")
    factor, unit = (1.0, "u") if args.units is None else (table[args.units][1], SI_UNITS[table[args.units][0]])
    if increments and bag:
        raise InputError(f"{args.log}: a ROS bag's sensor_msgs/Imu holds rates, not increments; leave out --input")
    if bag and args.units is None:  # sensor_msgs/Imu is SI by definition
        kinds = {c.strip().split("_")[0] for c in (args.column or "").split(",")}
        unit = SI_UNITS.get(kinds.pop()) if len(kinds) == 1 else None
        if unit is None:
            raise InputError(f"--column {args.column!r}: fit gyro and accelerometer fields of a bag separately")
    if not bag and (args.stream or args.log.suffix.lower() in BINARY_SUFFIXES):
        columns, results, info = _streamed(args, command, grid)
    else:
        columns, values, rate, info = _read(args, command)
        results = [allan_variance(values[:, j], rate_hz=rate, m=grid, progress=args.progress)
                   for j in range(values.shape[1])]
    if increments:  # increment / dt = mean rate over the sample: every Allan variance times (factor * rate)^2
        factor *= results[0].rate_hz
        unit = unit if args.units is not None else "u/s"
        info["input"] = "increments (divided by the sample period)"
    info.update(input_units=args.units or (unit if bag else "unspecified (u)"), unit=unit)
    return columns, [_scaled(r, factor) for r in results], unit, info


def _table(args):
    """An Allan deviation table (``fit --allan-table``) as the one Allan result to fit."""
    from .allan_table import read_allan_table

    if args.rate is None:
        raise InputError(f"{args.allan_table}: --allan-table needs --rate HZ (the rate of the log the table came from)")
    if getattr(args, "input", "rate") == "increments":
        raise InputError("--input increments does not apply to an Allan table (give it in rate units)")
    result, assumption = read_allan_table(args.allan_table, rate_hz=args.rate, n_samples=args.samples)
    factor, unit = (1.0, "u") if args.units is None else (UNITS[args.units][1], SI_UNITS[UNITS[args.units][0]])
    info = {"allan_table": str(args.allan_table), "rate_hz": result.rate_hz, "rate_source": "--rate",
            "samples_used": result.n_samples, "intervals": assumption, "action": "Allan deviation table fitted",
            "input_units": args.units or "unspecified (u)", "unit": unit}
    return ["adev"], [_scaled(result, factor)], unit, info


def _scaled(result, factor):
    """The Allan variance of ``factor * y`` (unit conversion): every variance times factor**2."""
    if factor == 1.0:
        return result
    f2 = factor * factor
    return dataclasses.replace(result, avar=result.avar * f2, adev=result.adev * factor,
                               avar_low=result.avar_low * f2, avar_high=result.avar_high * f2)


def _streamed(args, command, grid):
    from .outofcore import allan_variance_file

    if args.time_column is not None:
        raise InputError(f"{args.log}: --time-column is not available out of core; give --rate HZ")
    binary = args.log.suffix.lower() in BINARY_SUFFIXES
    if binary and args.column is not None:
        raise InputError(f"{args.log}: a binary log has one channel; leave out --column")
    columns = ["0"] if binary else _columns(args, command)
    results = [allan_variance_file(args.log, rate_hz=args.rate, column=None if binary else c, m=grid,
                                   progress=args.progress) for c in columns]
    _require_samples(args, results[0].n_samples, command)
    info = {"log": str(args.log), "columns": columns, "read": "out of core", "rate_hz": results[0].rate_hz,
            "rate_source": "--rate", "samples_used": results[0].n_samples, "action": "all samples used"}
    return columns, results, info


def _read(args, command):
    """Columns read in memory, cut to the usable time base, and the input description."""
    columns = _columns(args, command)
    if is_bag(args.log):
        if args.topic is None:
            raise InputError(f"{args.log}: a ROS bag needs --topic (a sensor_msgs/Imu topic)")
        data = read_imu_bag(args.log, topic=args.topic, columns=columns)
        where, what = f"{args.log}: {args.topic} header stamps", "message"
    else:
        data = read_columns(args.log, columns=columns, time_column=args.time_column, progress=args.progress)
        where, what = f"{args.log}: column {args.time_column!r}", "line"
    timebase = check_time(data.time_s, rate_hz=args.rate, gaps=args.gaps, lines=data.lines, where=where,
                          n_samples=data.values.shape[0], what=what)
    values = data.values[timebase.start:timebase.stop]
    _require_samples(args, values.shape[0], command)
    info = {"log": str(args.log), "columns": list(data.columns), "delimiter": data.delimiter, "header": data.header,
            "read": "in memory", **timebase.to_json()}
    return data.columns, values, timebase.rate_hz, info


def _require_samples(args, n, command):
    needed = _MIN_SAMPLES[command]
    if n < needed:
        raise InputError(f"{args.log}: {n} samples; expected at least {needed} for {command} "
                         f"({'4 octave cluster sizes' if command == 'fit' else 'one Allan variance'})")
