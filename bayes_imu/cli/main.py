"""Command-line interface: a thin layer over the public API.

``bayes-imu allan LOG --column NAME --rate HZ --out DIR``
    Overlapping Allan deviation with confidence intervals (allan.csv, allan.png).
``bayes-imu fit LOG --column NAME[,NAME...] --rate HZ --out DIR [--seed N]``
    Model selection and posterior (summary.json, posterior.nc, allan_fit.png, corner.png,
    drift.csv and drift.png with ``--sensor``); one sub-folder per column when several.
``bayes-imu report SCENE.toml --out DIR``, ``bayes-imu kalibr ...``, ``bayes-imu drift SENSOR.json
--out DIR``

Every output is written to a temporary folder beside ``--out`` and moved into place only
when complete; an existing non-empty ``--out`` is refused unless ``--force``.

Exit status: 0 success, 2 a user error (one line on stderr, no traceback unless
``--debug``), 3 the numbers written but a picture not drawn (one warning line each), 1 an
unexpected internal error (one line; ``--debug`` for the traceback).
"""

import argparse
import contextlib
import dataclasses
import logging
import os
import re
import signal
import sys
import textwrap
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from .._version import __version__
from ..report.output import staged_file, staged_folder, user_os_error
from ..report.runs import fit_job, run_allan, run_fit, run_fit_batch, run_population
from ..report.worker import PICTURE_FAILED_STATUS, background_default
from ..report.text import (interval_numbers, interval_text, number_text, outage_text, p_text,
                           spread_prior_note)
from ..report.writers import FitRequest, write_sigma_csv
from .._progress import progress_bar, show_progress
from ..allan.pipeline import LogSource
from .extra import add_commands, add_fit_options
from ..drift.bands import DEFAULT_CALIBRATION_S, MODEL_CHOICES
from ..drift.display import DISPLAY_CHOICES, display_unit
from .nav import add_nav_parser
from ..drift.closed_forms import DRIFT_BIAS_STARTS, QUANTITY_ORDER, SI_OUTPUT_UNITS
from ..errors import BayesIMUError, InputError
from ..io.readers import INCREMENT_UNITS, UNITS
from ..inference.fit import DISCREPANCY_MODES
from ..inference.likelihood import LIKELIHOODS
from ..noise import BIAS_STARTS, TERMS
from ..io.limits import RANGES
from ..io.timebase import GAP_POLICIES, RATE_RANGE, TIME_UNITS

__all__ = ["main"]

log = logging.getLogger("bayes_imu")


class _UsageError(Exception):
    """An argument error (argparse), reported in one line with exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        command = self.prog.removeprefix("bayes-imu").strip()
        raise _UsageError(f"{command + ': ' if command else ''}{message} (see {self.prog} --help)")


_SCENE_HELP = """scene format (TOML; paths relative to the scene file):

  [scene]
  name = "UAV outage study"
  outages_s = [10, 60, 300]        # GPS outages to bound (s)
  credibility = 0.95               # the bound is this posterior quantile of the 1-sigma drift
  bias_start = "calibrated"        # or "zero" (the paper), "stationary"
  calibration_s = 60               # bias = mean of the last 60 s before the outage
  display_units = "si"             # or "deg": the report also in degrees (--display-units)

  [requirement]                    # optional: longest acceptable outage and ranking
  quantity = "attitude"            # attitude (gyro), velocity or position (accelerometer)
  max_error = "0.5 deg"            # with a unit (deg, rad, mrad, arcmin; m/s, cm/s; m, cm, km, ft)

  [[sensor]]                       # one log of one unit: bounds for that unit
  name = "budget MEMS"
  kind = "gyro"                    # gyro or accel
  log = "budget.csv"
  column = "gyro_x"                # or a list ["gyro_x", "gyro_y", "gyro_z"]: the worst axis counts
  rate_hz = 100                    # or time_column = "t" (and gaps = "longest"); a ROS bag: topic
  units = "deg/s"                  # input = "increments" (rad, deg, m/s); stream = true

  [[sensor]]                       # several units' logs: bounds for a NEW unit (population fit)
  name = "ADIS16405"
  kind = "gyro"
  logs = ["unit1.csv", "unit2.csv", "unit3.csv"]
  column = "gyro_x"
  rate_hz = 100
  units = "deg/s"

  [[sensor]]                       # a bayes-imu fit folder (fitted with --units): no refit
  name = "tactical"
  kind = "gyro"
  fit = "fit_tactical"             # or fits = [...] for several units

  [navigation]                     # optional: rank IMUs by their navigation error (gyro tilt
  quantity = "position"            # included): position (default), velocity or tilt
  max_error = "10 m"               # at credibility (the predictive bound; statistic = "sigma")
  after_s = 30                     # optional: pass or fail at this outage (s)

  [[imu]]                          # a gyro and an accelerometer [[sensor]], by name
  name = "IMU A"
  gyro = "budget MEMS"
  accel = "budget accel"           # a [[sensor]] with kind = "accel" (docs/cli.md)
"""

def _input_options(batch=False, optional_log=False):
    """Options shared by the commands that read logs (``batch``: several logs)."""
    common = _Parser(add_help=False)
    if batch:
        common.add_argument(
            "logs", type=Path, nargs="+", help="logs, all with the same columns and options"
        )
    else:
        common.add_argument("log", type=Path, nargs="?" if optional_log else None,
                            help="log: delimited text (.gz accepted), .npy / raw binary, ROS bag"
                                 + (" (or --allan-table)" if optional_log else ""))
    common.add_argument(
        "--column", help="column name or 0-based index (text logs); fit takes a comma list"
    )
    common.add_argument(
        "--topic", help="ROS bag: the sensor_msgs/Imu topic (columns gyro_x ... accel_z)"
    )
    common.add_argument(
        "--stream",
        action="store_true",
        help="read a text log out of core, in chunks (automatic for .npy and raw binary logs)",
    )
    common.add_argument(
        "--rate",
        type=_rate_type,
        help=f"sample rate (Hz, {RATE_RANGE[0]:g} to {RATE_RANGE[1]:g}); optional with "
             "--time-column",
    )
    common.add_argument("--time-column", help="time stamps: the rate is derived from them and "
                                              "checked")
    common.add_argument("--time-unit", choices=tuple(TIME_UNITS),
                        help="unit of the --time-column stamps (default: from the column's name, "
                             "e.g. t_ms, "
                             "time_us, else the one agreeing with --rate, else s)")
    common.add_argument(
        "--gaps",
        choices=GAP_POLICIES,
        default="error",
        help="irregular time steps: error (default) or fit the longest regular segment",
    )
    common.add_argument(
        "--input",
        choices=("rate", "increments"),
        default="rate",
        help="rate samples (default), or delta-angle / delta-velocity increments per sample "
        "(divided by the sample period into rates)",
    )
    common.add_argument(
        "--units",
        "--unit",
        dest="units",
        choices=tuple(UNITS) + tuple(INCREMENT_UNITS),
        help="units of the column(s), converted to SI (rad/s, m/s^2): rates "
        + ", ".join(UNITS)
        + "; increments "
        + ", ".join(INCREMENT_UNITS)
        + "; default: left as they are",
    )
    common.add_argument("--where", metavar="FILTER",
                        help="keep only the rows satisfying FILTER, e.g. 'period == 0' or "
                             "'period == 2 and status != 1' (COLUMN OP NUMBER joined by and; "
                             "OP one of == != < <= > >=; text logs read in memory)")
    common.add_argument("--trust-units", action="store_true",
                        help="skip the check that a static log is plausible in --units (a moving "
                             "log, a test rig)")
    common.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder: new, empty, or a previous bayes_imu result with --force",
    )
    common.add_argument(
        "--force",
        action="store_true",
        help="replace a previous bayes_imu result in --out (never other files)",
    )
    common.add_argument("--quiet", action="store_true", help="no progress bars or messages")
    return common


def _build_parser():
    parser = _Parser(prog="bayes-imu", description="Bayesian characterization of inertial sensors.")
    parser.add_argument("--version", action="version", version=f"bayes-imu {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of errors")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = _input_options()

    allan = sub.add_parser(
        "allan",
        parents=[common],
        help="overlapping Allan deviation of one column of a log",
        description=textwrap.fill(
            "Overlapping Allan deviation with chi-squared confidence intervals (Greenhall EDF). "
            "Writes allan.csv (tau, m, adev, adev_low, adev_high, edf, unit) and allan.png.",
            96,
        ),
        epilog="examples:\n  bayes-imu allan imu.csv --column gyro_x --rate 100 --units deg/s "
        "--out allan_gx\n  bayes-imu allan big.npy --rate 400 --out allan_big   (binary logs are "
        "read out of core)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    allan.add_argument(
        "--grid", default="octave", choices=("octave", "decade", "all"), help="cluster sizes"
    )
    allan.set_defaults(handler=_cmd_allan)

    fit = sub.add_parser(
        "fit",
        parents=[_input_options(optional_log=True)],
        help="Bayesian noise-model fit of columns of a log",
        description=textwrap.fill(
            "Select the noise terms the log needs (Bayesian evidence), sample their posterior "
            "(emcee), check the fit's adequacy. Writes summary.json (posteriors in SI and "
            "datasheet units, adequacy, every candidate's probability), posterior.nc (ArviZ), "
            "fit.npz (for report and kalibr), allan_fit.png and corner.png; with --sensor also "
            "drift.csv and drift.png (the drift credible bands of a GPS outage). Several columns: "
            "one sub-folder each.",
            96,
        ),
        epilog="examples:\n"
        "  bayes-imu fit imu.csv --column gyro_x --rate 100 --units deg/s --sensor gyro --out "
        "fit_gx\n  bayes-imu fit imu.csv --column accel_x,accel_y,accel_z --rate 100 --units g "
        "--sensor accel --out fit_acc\n"
        "  bayes-imu fit --allan-table adev.csv --rate 200 --samples 1440000 --units deg/h --out "
        "fit_table\n  bayes-imu fit dtheta.csv --column dx --rate 400 --input increments --units "
        "rad --out fit_inc\nterms: " + ", ".join(TERMS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _fit_options(fit)
    fit.add_argument(
        "--allan-table",
        type=Path,
        metavar="FILE",
        help="fit a published or external Allan deviation table instead of a log: a header with "
        "tau (s) and adev (or avar), optionally edf; --rate is the rate of the log it came from",
    )
    fit.add_argument(
        "--samples",
        type=_positive_int,
        metavar="N",
        help="with --allan-table: samples in the log it came from (sets the intervals; unknown: "
        "the shortest record the table allows is assumed, the widest intervals)",
    )
    fit.set_defaults(handler=_cmd_fit)
    add_fit_options(fit)  # --datasheet (cli/extra.py, issue 38)

    batch = sub.add_parser("fit-batch", parents=[_input_options(batch=True)],
                           help="fit many logs in parallel (Dask), one output folder per log")
    _fit_options(batch)
    add_fit_options(batch)  # --datasheet, as fit
    batch.add_argument(
        "--scheduler", help="address of a running Dask scheduler (default: a LocalCluster)"
    )
    batch.add_argument(
        "--workers",
        type=_workers_type,
        help="LocalCluster worker processes (default: one per core)",
    )
    batch.add_argument(
        "--serial", action="store_true", help="no Dask: one log after another in this process"
    )
    batch.set_defaults(handler=_cmd_fit_batch)

    population = sub.add_parser(
        "fit-population",
        parents=[_input_options(batch=True)],
        help="joint (hierarchical) fit of several units of one IMU model: what a new unit will do",
        description="Fit the logs of several units of one IMU model (or long sessions of one unit) "
        "jointly: a hierarchical model on the log-parameters gives each unit's posterior, the "
        "population's spread, and the posterior predictive for a NEW unit (parameters, Allan "
        "deviation band, drift bands). Writes summary.json, population.png, and with --sensor (or "
        "gyro / accel --units) drift.csv and drift.png for the new unit.",
        epilog="example: bayes-imu fit-population imu1.csv imu2.csv imu3.csv --column gyro_x "
        "--rate 100 --units deg/s --out pop_gx",
    )
    population.add_argument("--seed", type=_seed_type, default=0,
                            help="random seed, 0 to 2**32 - 1 (recorded in the outputs), default 0")
    population.add_argument(
        "--terms",
        default="auto",
        help="'auto' (the common structure chosen by the units' summed evidence) or a "
        "comma-separated list of terms: " + ", ".join(TERMS),
    )
    population.add_argument(
        "--spread-scale",
        type=_ranged("spread_scale"),
        default=1.0,
        metavar="S",
        help="scale of the half-normal prior on the unit-to-unit spread of each "
        "ln-parameter (default 1: a factor e, weakly informative)",
    )
    _drift_options(population)
    population.set_defaults(handler=_cmd_fit_population, models="selected")

    report = sub.add_parser(
        "report",
        help="conservative drift bounds for several IMUs (scene TOML)",
        description=textwrap.fill(
            "Fit (or read) every sensor of a scene and rank them by their conservative drift "
            "bounds: report.json, report.html (self-contained) and comparison.png.",
            96,
        ),
        epilog=_SCENE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    report.add_argument("scene", type=Path, help="scene TOML file (format below)")
    report.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder: new, empty, or a previous bayes_imu result with --force",
    )
    report.add_argument(
        "--seed", type=_seed_type, default=0, help="random seed (0 to 2**32 - 1), default 0"
    )
    report.add_argument(
        "--force",
        action="store_true",
        help="replace a previous bayes_imu result in --out (never other files)",
    )
    report.add_argument("--quiet", action="store_true", help="no progress messages")
    report.add_argument("--display-units", choices=DISPLAY_CHOICES, default=None,
                        help="units shown in report.html, comparison.png and report.json's "
                             "*_display values: si (default, or the scene's display_units) or deg "
                             "(attitude in degrees, gyro parameters in deg/s); SI values are kept")
    report.add_argument("--allow-outside", action="store_true",
                        help="read logs and fit folders outside the scene's folder (default: "
                             "refused)")
    report.set_defaults(handler=_cmd_report)

    kalibr = sub.add_parser(
        "kalibr",
        help="Kalibr IMU noise YAML from fit folders",
        description="Write a Kalibr / VIO imu.yaml (noise densities and bias random walks, SI) "
        "from bayes-imu fit folders fitted with --units. Either sensor may be given alone; several "
        "axes (folders, or a several-column fit) give the worst axis, each axis's value listed in "
        "comments.",
        epilog="example: bayes-imu kalibr --gyro fit_gyro --accel fit_accel --credibility 0.95 "
        "--topic /imu0 --out imu.yaml",
    )
    kalibr.add_argument("--gyro", type=Path, nargs="+", help="fit folder(s) of gyro axes")
    kalibr.add_argument("--accel", type=Path, nargs="+", help="fit folder(s) of accelerometer axes")
    kalibr.add_argument(
        "--topic", default="/imu0", help="rostopic written into the file, default /imu0"
    )
    kalibr.add_argument("--out", type=file_path, required=True, help="YAML file to write")
    kalibr.add_argument(
        "--credibility",
        type=float,
        default=None,
        help="upper posterior quantile for conservative values (e.g. 0.95); default: medians",
    )
    kalibr.add_argument(
        "--force",
        action="store_true",
        help="replace a file bayes_imu wrote earlier (never other files)",
    )
    kalibr.set_defaults(handler=_cmd_kalibr)
    add_commands(sub)  # export, plan (cli/extra.py, issue 38)

    drift = sub.add_parser("drift", help="drift curves from known noise parameters (JSON)")
    drift.add_argument(
        "sensor",
        type=Path,
        help="JSON file: kind (gyro / accel), rate_hz, noise_density, optional bias_variance, "
        "time_constant, random_walk, and units (of the values: rad/s default, deg/s, deg/h; "
        "m/s^2 default, g, mg)",
    )
    drift.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder: new, empty, or a previous bayes_imu result with --force",
    )
    drift.add_argument("--horizon", type=_ranged("time_s"), default=3600.0,
                       help="longest time (s, 1e-6 to 1e9), default 3600")
    drift.add_argument("--bias-start", choices=DRIFT_BIAS_STARTS, default="zero",
                       help="bias at the start: zero (the paper, default) or stationary")
    drift.add_argument(
        "--display-units",
        choices=DISPLAY_CHOICES,
        default="si",
        help="units of drift.csv and the printout: si (rad, m/s, m; default) or deg (attitude in "
             "degrees)",
    )
    drift.add_argument(
        "--force",
        action="store_true",
        help="replace a previous bayes_imu result in --out (never other files)",
    )
    drift.set_defaults(handler=_cmd_drift)
    add_nav_parser(sub)
    return parser


# ---------------------------------------------------------------------------- reading

def _source(args, **changes):
    """The :class:`LogSource` the parsed arguments ask for (absent options at their defaults)."""
    names = {f.name for f in dataclasses.fields(LogSource)}
    source = LogSource(**{k: v for k, v in vars(args).items() if k in names})
    return dataclasses.replace(source, **changes)


# ---------------------------------------------------------------------------- commands

def _cmd_allan(args):
    run = run_allan(_source(args), args.out, grid=args.grid, force=args.force,
                    progress=args.progress, on_read=lambda read: _say_time_unit(args, read.info))
    result, info = run.read.results[0], run.read.info
    _say(
        args,
        f"{result.tau.size} cluster sizes from {result.n_samples} samples ({info['action']}); "
        f"wrote {args.out / 'allan.csv'} and allan.png",
    )
    return _pictures_status(run.picture_failures)


def _fit_request(args, **source_changes):
    """The :class:`FitRequest` of the parsed arguments (options a command lacks: defaults)."""
    names = {f.name for f in dataclasses.fields(FitRequest)} - {"source", "terms"}
    terms = "auto" if args.terms == "auto" else tuple(t.strip() for t in args.terms.split(","))
    return FitRequest(source=_source(args, **source_changes), terms=terms,
                      **{k: v for k, v in vars(args).items() if k in names})


def _cmd_fit(args):
    if args.allan_table is not None:
        if args.log is not None:
            raise InputError(
                f"fit: give a log or --allan-table, not both (got {args.log} and "
                f"{args.allan_table})"
            )
    elif args.log is None:
        raise InputError("fit: give a log to fit (or --allan-table FILE); see bayes-imu fit --help")
    elif args.samples is not None:
        raise InputError(
            "--samples goes with --allan-table (a log's sample count is read from the log)"
        )
    unused = [f for f, v in (("--horizon", args.horizon != 3600.0),
                             ("--times", args.times is not None),
                             ("--bias-start", args.bias_start != "calibrated")) if v]
    if unused and args.sensor is None:  # issue 37: a drift option was silently ignored
        _warn(f"{', '.join(unused)} without --sensor: no drift is computed (give --sensor gyro "
              "or accel)")
    return _fit(_fit_request(args), args)


def output_process():
    """Whether this command writes its outputs from a second process (``report.worker``): the
    executable's automatic choice; a Python caller of :func:`main` only where
    ``BAYES_IMU_OUTPUT_PROCESS`` asks (a spawned process re-runs the caller's script, which without
    a ``__main__`` guard would run the command again there). ``fit`` and ``nav`` ask it."""
    return background_default(automatic=_EXECUTABLE)


def _fit(request, args, in_batch=False):
    """``request`` fitted into ``args.out`` (``args``: where and how to write and print)."""
    # a batch's fits write in their own process: it has its own parallelism, and its imports are
    # made once
    background = False if in_batch else output_process()
    run = run_fit(request, args.out, force=args.force, background=background,
                  progress=args.progress, on_read=lambda read: _say_time_unit(args, read.info),
                  on_axis=lambda axis: _say_axis(args, axis))
    _say(args, f"wrote {args.out}")
    return _pictures_status(run.picture_failures)


def _pictures_status(failures):
    """0, or :data:`PICTURE_FAILED_STATUS` with one warning line per picture not drawn (the numbers
    were kept)."""
    failures = [f for f in failures if f is not None]
    for failure in failures:
        _warn(str(failure))
    return PICTURE_FAILED_STATUS if failures else 0


def _say_time_unit(args, info):
    if "time_unit" in info:
        source = as_flags(info["time_unit_source"])  # "the unit nearest --rate 200"
        _say(args, f"time stamps in {info['time_unit']} ({source}): {info['rate_hz']:.6g} Hz")


def _say_axis(args, axis):
    """What ``fit`` says of one column's fit (:class:`~bayes_imu.report.runs.AxisRun`)."""
    result, summary, drift, column = axis.result, axis.summary, axis.drift, axis.column
    if axis.folder is not None:
        _say(args, f"[{column}]")
    _say(args, _model_line(summary, result.diagnostics["converged"]))
    # the values below are the selected model's (summary.json "model"), not the average's
    _say(args, f"  parameters of the selected model, {' + '.join(summary['model'])} (90% intervals "
               "include the repeatability between the log's parts; the record alone: "
               "summary.json parameters_this_record)")
    for name, p in (summary.get("parameters_display") or summary["parameters"]).items():
        _say(
            args,
            f"  {name:18s} {interval_text(p['median'], p['q05'], p['q95'])} {p['unit']}",
        )
    _say_datasheet(args, summary["datasheet"], "the selected model")
    _say_readout(args, summary["allan_datasheet"])
    if "datasheet_check" in summary:
        checked = summary["datasheet_check"]
        _say(args, f"  datasheet {Path(checked['file']).name}: {checked['verdict']}")
    _warn_fit(result, column)
    if drift is not None:
        _say_drift(args, drift, column)
    check = axis.check
    if check is not None and not check.adequate:
        _warn(f"{column}: the drift the log itself shows disagrees with the model at t = "
              f"{check.worst_t_s:g} s (p {p_text(check.p_combined)}); the drift bands include the "
              f"log's own interval up to {check.t_s[-1]:g} s and extrapolate the model beyond")
    position = ((summary.get("adequacy") or {}).get("drift") or {}).get("position")
    if position is not None and not position["adequate"]:
        _warn(f"{column}: the position drift the log itself shows disagrees with the model at "
              f"t = {position['worst_t_s']:g} s (p {p_text(position['p_value'])}); the position "
              "bands include the log's own interval where it measures it")


def _warn_fit(result, column):
    """The warnings of a fit, each starting with ``column``: a model that does not describe the
    log, noise that changes."""
    adequacy = result.adequacy
    if not adequacy.adequate:
        what = [
            f"goodness of fit p {p_text(adequacy.p_value)} (worst at tau = "
            f"{adequacy.worst_tau_s:g} s)"
        ]
        if adequacy.at_prior_bound:
            what.append("at a prior bound: " + ", ".join(adequacy.at_prior_bound))
        widened = ("intervals widened by a fitted model discrepancy" if result.widened
                   else "intervals NOT widened: treat them as too narrow")
        _warn(
            f"{column}: the noise model does not describe this log ({'; '.join(what)}); {widened}"
        )
    steady = result.stationarity
    if steady is not None and not steady.stationary:
        _warn(
            f"{column}: the noise changes during the log: its {steady.n_segments} parts differ by "
            f"{_ratio_text(steady.largest_ratio())} in Allan deviation at tau = "
            f"{steady.worst_tau_s:g} s (p {p_text(steady.p_value)}; warm-up?), with a spread of up "
            f"to x{steady.spread_factor():.2g} (1 sigma) "
            "at longer tau; drift bands include that spread "
            "(parameter intervals: the parts' scatter)"
        )


def _model_line(summary, converged):
    """What the bands use: the model average (its most probable models and each term's probability),
    then the selected model (the simplest within the selection margin) for reference."""
    mixture = sorted(summary["model_averaging"], key=lambda c: -c["probability"])
    shown = ", ".join(f"{' + '.join(c['model'])} {c['probability']:.2f}" for c in mixture[:3])
    more = f", {len(mixture) - 3} more" if len(mixture) > 3 else ""
    terms = ", ".join(f"{t} {p:.2f}" for t, p in summary["term_probability"].items())
    return (f"model average (what the drift bands use): {shown}{more}  (converged: {converged})\n"
            f"  term probabilities: {terms}; simplest model within the evidence margin: "
            f"{' + '.join(summary['model'])}")


def _say_readout(args, block):
    if block:
        _say(args, "  Allan deviation readings (IEEE Std 952, model-averaged):")
        for name, p in block.items():
            at = f" at tau = {p['tau_s']:.3g} s" if "tau_s" in p else ""
            _say(
                args,
                f"    {name:30s} {interval_text(p['median'], p['q05'], p['q95'])} "
                f"{p['unit']}{at}{_reading_caveat(p)}",
            )


def _reading_caveat(p):
    """Where an Allan reading is a bound, not a reading (summary.json's ``at_edge``, ``rising``):
    the curve still falls at the longest averaging time, or does not rise there yet."""
    if p.get("at_edge", 0.0) >= 0.5:
        return (f"; the curve still falls at the longest tau in {p['at_edge']:.0%} of draws: an "
                "upper bound, not a reading")
    if "rising" in p and p["rising"] < 0.5:
        return (f"; the curve does not rise at the longest tau in {1.0 - p['rising']:.0%} of "
                "draws: an upper bound, not a reading")
    return ""


def _ratio_text(ratio):
    """``1.3x``; below 1.1x a percentage (``2.4%``): a long log resolves a small change, which "1x"
    would hide."""
    return f"{100.0 * (ratio - 1.0):.2g}%" if ratio < 1.1 else f"{ratio:.2g}x"


def _say_datasheet(args, block, whose=None):
    """The datasheet-unit block of a fit (``whose``: the model its values belong to)."""
    if block:
        _say(args, f"  datasheet units{f' ({whose})' if whose else ''}:")
        for name, p in block.items():
            _say(
                args,
                f"    {name:30s} {interval_text(p['median'], p['q05'], p['q95'])} {p['unit']}",
            )


def _say_small_angle(args, band, unit):
    """Where the median attitude error passes 0.1 rad: the integrated rate error stays exact there,
    but a navigator's linear (small-angle) error model does not (``bayes-imu nav`` hatches it)."""
    from ..report.nav import SMALL_ANGLE_RAD, small_angle_time

    scale = np.pi / 180.0 if unit == "deg" else 1.0
    t = small_angle_time(band.t_s, np.asarray(band.total[1], float) * scale)
    if t is not None:
        limit = SMALL_ANGLE_RAD / scale
        _say(args, f"  (the median passes {limit:.3g} {unit} after {t:.3g} s: the integrated rate "
                   "error is exact beyond, but a navigator's small-angle error model is not; "
                   "bayes-imu nav marks it)")


def _say_drift(args, drift, column=None):
    """The drift at the horizon, and a warning where the horizon lies beyond what the record
    measures (starting with ``column``'s name, as every warning of one column of a fit does)."""
    for b, u in zip(drift.bands, drift.units):
        _say(
            args,
            f"{b.quantity}: 1-sigma drift after {b.t_s[-1]:g} s: "
            f"{interval_text(b.total[1][-1], b.total[0][-1], b.total[2][-1])} {u}",
        )
        if b.quantity == "attitude" and u in ("rad", "deg"):
            _say_small_angle(args, b, u)
    first = drift.bands[0]
    if first.extrapolated[-1]:
        measured = first.measured_s
        if np.isfinite(measured) and measured > 0:  # the record's own drift reaches half the log
            where = (f"than the outages the record measures ({measured:.4g} s: outage plus "
                     f"calibration within half the {first.record_s:.4g} s log)")
        else:
            where = f"than the log ({first.record_s:g} s)"
        _warn(f"{column + ': ' if column is not None else ''}the drift horizon "
              f"({first.t_s[-1]:g} s) is longer {where}: beyond it the bands extrapolate the "
              "fitted model (drift.csv column 'extrapolated')")


def _cmd_report(args):
    from ..report.scene import build_report, read_scene
    from ..report.html import write_report

    scene = read_scene(args.scene, allow_outside=args.allow_outside)
    if args.display_units is not None:  # the command's choice over the scene's display_units
        scene = dataclasses.replace(scene, display_units=args.display_units)
    inputs = [args.scene] + [p for s in scene.sensors for p in s.paths]
    staged = staged_folder(args.out, force=args.force, inputs=inputs)
    with staged as tmp, _sensor_progress(args, scene) as progress:
        report = build_report(scene, rng=args.seed, progress=progress)
        failures = write_report(report, tmp)
    for s in report.sensors:  # a population whose spread between units is mostly its prior's
        pop = s.axes[s.worst].population
        note = None if pop is None else spread_prior_note(pop)
        if note:
            _warn(f"{s.spec.name}: {note}")
    for s in report.sensors:  # what each fit alone would have warned of
        for ax in s.axes:
            for label, fit in ax.unit_fits:
                _warn_fit(fit, " ".join(p for p in (s.spec.name, label, ax.axis) if p))
    outage = {s.spec.name: s.max_outage_s for s in report.sensors}
    _say(args, "ranking: " + ", ".join(_with_outage(n, outage.get(n)) for n in report.ranking)
         + f" ({report.reason})")
    if report.imus:  # a [navigation] requirement: the IMUs' ranking
        outage = {r.name: r.longest_outage_s for r in report.imus}
        _say(args, "IMU ranking: " + ", ".join(_with_outage(n, outage.get(n))
                                               for n in report.imu_ranking)
             + f" ({report.imu_reason})")
    written = [n for n in ("report.json", "report.html", "comparison.png")
               if (Path(args.out) / n).exists()]
    _say(args, f"wrote {args.out}/{', '.join(written)}")
    return _pictures_status(failures)


def _with_outage(name, outage_s):
    """``"name (longest outage 416 s)"`` on the report's console line, or the name alone where the
    sensor has no longest outage (no requirement, or it cannot give the required quantity)."""
    return name if outage_s is None else f"{name} (longest outage {outage_text(outage_s)})"


@contextlib.contextmanager
def _sensor_progress(args, scene):
    """Progress of a report on standard error: a bar on a terminal, else one line per sensor."""
    if getattr(args, "quiet", False):
        yield None
        return
    start = time.perf_counter()
    n = len(scene.sensors)
    with progress_bar(total=n, desc="sensors", unit="sensor", enabled=args.progress) as bar:
        def progress(done, total, name):
            if args.progress:
                bar.update(1)
                bar.set_postfix_str(name)
            else:
                seconds = time.perf_counter() - start
                print(f"sensor {done}/{total} done: {name} ({seconds:.1f} s)", file=sys.stderr,
                      flush=True)

        yield progress


def _cmd_kalibr(args):
    from ..report.kalibr import kalibr_values_from_folders, write_kalibr_yaml

    if not args.gyro and not args.accel:
        raise InputError("kalibr: give --gyro FIT_FOLDER..., --accel FIT_FOLDER..., or both")
    result = kalibr_values_from_folders(
        args.gyro or (), args.accel or (), credibility=args.credibility
    )
    inputs = [
        p for folder in (args.gyro or []) + (args.accel or []) for p in Path(folder).rglob("*")
    ]
    with staged_file(args.out, force=args.force, inputs=inputs) as tmp:
        write_kalibr_yaml(result, tmp, topic=args.topic)
    if not result.adequate:
        _warn(
            "Kalibr values from fits that failed the goodness-of-fit check: "
            + ", ".join(result.inadequate)
        )
    several = any(len(rows) > 1 for rows in result.per_axis.values())
    _say(args, f"wrote {args.out} ({result.mode}{', worst axis' if several else ''})")
    return 0


def _fit_options(parser):
    parser.add_argument("--seed", type=_seed_type, default=0,
                        help="random seed, 0 to 2**32 - 1 (recorded in the outputs), default 0")
    parser.add_argument(
        "--terms",
        default="auto",
        help="'auto' (model selection, default) or a comma-separated list of terms: "
        + ", ".join(TERMS),
    )
    parser.add_argument(
        "--likelihood",
        choices=LIKELIHOODS,
        default=LIKELIHOODS[0],
        help="Allan-variance likelihood: correlated (default: multivariate normal on log AVAR with "
        "the exact covariance of the estimates), copula (gamma margins, same correlation), "
        "independent (gamma per cluster size, ignores correlation: faster, overconfident)",
    )
    _drift_options(parser)
    parser.add_argument(
        "--models",
        choices=MODEL_CHOICES,
        default="averaged",
        help="drift from every candidate model weighted by its posterior probability (averaged, "
        "default) or from the selected model alone (selected)",
    )
    parser.add_argument(
        "--discrepancy",
        choices=DISCREPANCY_MODES,
        default="auto",
        help="model-discrepancy term that widens the intervals of an inadequate fit: auto (added "
        "when the best model fails the goodness-of-fit check), never, always",
    )


def _drift_options(parser):
    parser.add_argument(
        "--sensor",
        choices=("gyro", "accel"),
        help="also write drift.csv / drift.png: attitude (gyro) or velocity and position (accel)",
    )
    parser.add_argument("--horizon", type=_ranged("time_s"), default=3600.0,
                        help="longest drift time (s, 1e-6 to 1e9), default 3600")
    parser.add_argument(
        "--bias-start",
        choices=BIAS_STARTS,
        default="calibrated",
        help="bias at the start of the outage: calibrated (default: the mean of the --calibration "
        "seconds before it is removed), zero (the paper) or stationary (never estimated)",
    )
    parser.add_argument(
        "--calibration",
        type=_ranged("calibration_s"),
        default=DEFAULT_CALIBRATION_S,
        metavar="S",
        help="calibration window of --bias-start calibrated (s), default "
             f"{DEFAULT_CALIBRATION_S:g}",
    )
    parser.add_argument(
        "--times",
        type=_times,
        metavar="T1,T2,...",
        help="write drift.csv rows at exactly these times (s) instead of a log grid up to "
             "--horizon",
    )
    parser.add_argument(
        "--display-units",
        choices=DISPLAY_CHOICES,
        default="si",
        help="units shown: si (rad, m/s, m; default) or deg: drift.csv / drift.png's attitude in "
             "degrees, and a gyro's figures, printout and summary.json's *_display values in deg/s "
             "(beside the SI values, which are kept)",
    )


def _cmd_fit_population(args):
    """Several logs (units) of one column: the hierarchical fit and the new-unit predictive."""
    if args.units is not None and args.sensor is None:
        args.sensor = UNITS[args.units][0]
    request = _fit_request(args, log=args.logs[0])
    run = run_population(request, args.logs, args.out, spread_scale=args.spread_scale,
                         force=args.force, progress=args.progress,
                         on_fit=lambda run: _say_population(args, run))
    _say(args, f"wrote {args.out}")
    args.picture_failures.extend(run.picture_failures)
    status = _pictures_status(args.picture_failures)
    d = run.population.diagnostics
    if not d["converged"]:
        _warn(
            f"the population sampler did not converge (R-hat {d['rhat_max']:.3f}, effective draws "
            f"{d['ess_hyper_min']:.0f}; needed < 1.01 and > 400): the numbers in {args.out} are "
            f"not reliable (exit status {NOT_CONVERGED_STATUS})"
        )
        return NOT_CONVERGED_STATUS
    return status


#: exit status of ``fit-population`` when its numbers were written but the population sampler did
#: not converge
NOT_CONVERGED_STATUS = 4


def _say_population(args, run):
    """What ``fit-population`` says of its fit (:class:`~bayes_imu.report.runs.PopulationRun`)."""
    pop, summary = run.population, run.summary
    _say(args, f"common model: {' + '.join(pop.model.terms)} ({len(pop.labels)} units; "
               f"population sampler converged: {pop.diagnostics['converged']})")
    _say(args, "a new unit of this model (unit-to-unit spread included):")
    for name, p in (summary.get("new_unit_display") or summary["new_unit"]).items():
        _say(args, f"  {name:18s} {interval_text(p['median'], p['q05'], p['q95'])} {p['unit']}")
    _say_datasheet(args, summary["new_unit_datasheet"])
    for name, p in summary["population"].items():
        median, low, high = interval_numbers(*(p["spread_ln"][k] for k in ("median", "q05", "q95")))
        _say(args, f"  unit-to-unit spread of {name}: {median} (90% [{low}, {high}]) in ln units "
                   "(0.1 = 10%)")
    if run.drift is not None:
        _say_drift(args, run.drift)
    weak = spread_prior_note(pop)
    if weak:
        _warn(weak)


def _cmd_fit_batch(args):
    """Every log's own fit into a staged copy of --out (claimed, moved in whole: the rules of any
    output)."""
    scheduler = "serial" if args.serial else args.scheduler
    run = run_fit_batch(_fit_request(args, log=None), args.logs, args.out, task=_fleet_fit,
                        scheduler=scheduler, n_workers=args.workers, force=args.force,
                        progress=args.progress)
    results, doc = run.results, run.summary
    failed = [r for r in results if not r.fitted]
    for r in failed:
        print(
            f"bayes-imu: error: {r.name}: {r.error.removeprefix('bayes-imu: error: ')}",
            file=sys.stderr,
        )
    _say(args, f"{len(results) - len(failed)} of {len(results)} logs fitted in {run.seconds:.1f} s "
               f"({doc['logs_per_minute']:.1f} logs/min); wrote {args.out / 'batch.json'}")
    for entry in doc["logs"]:  # what the fit alone would have warned of, one line a log
        flagged = {column: _check_flags(c) for column, c in entry.get("checks", {}).items()}
        bad = [f"{column}: {', '.join(flags)}" for column, flags in flagged.items() if flags]
        if bad:
            _warn(f"{entry['name']}: " + "; ".join(bad) + " (its summary.json says more)")
    unpictured = [r for r in results if r.status == PICTURE_FAILED_STATUS]
    for r in unpictured:
        _warn(f"{r.name}: a picture was not drawn; the numbers were written")
    return 2 if failed else PICTURE_FAILED_STATUS if unpictured else 0


def _check_flags(checks):
    """What one column's ``batch.json`` checks flag (:func:`bayes_imu.report.writers.fit_checks`;
    ``None``: not checked, no flag)."""
    return [what for what, flagged in (
        ("sampler not converged", not checks["converged"]),
        ("the noise model does not describe the log", checks["adequate"] is False),
        ("the noise changes during the log", checks["stationary"] is False)) if flagged]


def _fleet_fit(job):
    """One log of ``fit-batch`` (the fleet's task): exactly ``bayes-imu fit`` of the job's request
    (:func:`~bayes_imu.report.runs.fit_job`), its errors in this command's terms."""
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = _one_line_warning
        try:
            return fit_job(job)
        except BayesIMUError as exc:  # in this command's terms, as the fit alone would say it
            raise type(exc)(as_flags(str(exc))) from None


def _cmd_drift(args):
    from ..drift.known import known_drift, read_sensor_json

    spec = read_sensor_json(args.sensor)
    results = known_drift(args.sensor, spec, horizon_s=args.horizon, bias_start=args.bias_start)
    shown = [display_unit(SI_OUTPUT_UNITS[r.quantity], args.display_units) for r in results]
    units, factors = zip(*shown)
    with staged_folder(args.out, force=args.force, inputs=[args.sensor]) as tmp:
        write_sigma_csv(results, units, factors, tmp / "drift.csv")
    for result, unit, f in zip(results, units, factors):
        last = number_text(result.total[-1] * f, 4)
        _say(args, f"{result.quantity}: 1-sigma drift after {result.t_s[-1]:g} s = {last} "
                   f"{unit} (order {QUANTITY_ORDER[result.quantity]})")
    _say(args, f"wrote {args.out / 'drift.csv'}")
    return 0


# ---------------------------------------------------------------------------- entry point

def _checked(convert, ok, expected, *, not_number=None):
    """An argparse type: ``convert(text)``, refused unless ``ok(value)``, with ``expected`` in the
    message; text that ``convert`` cannot read (``100Hz``) is refused with ``not_number`` where
    given (what form the value takes), as it is not out of range but not a number."""
    def check(text):
        try:
            value = convert(text)
        except ValueError:
            if not_number is not None:
                raise argparse.ArgumentTypeError(f"expected {not_number}, got {text!r}") from None
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value

    return check


_positive_int = _checked(int, lambda v: v > 0, "a positive whole number")
_seed_type = _checked(int, lambda v: 0 <= v < 2**32, "a whole number from 0 to 2**32 - 1")
_workers_type = _checked(int, lambda v: v >= 1, "at least 1 worker process")
_rate_type = _checked(float, lambda v: np.isfinite(v) and RATE_RANGE[0] <= v <= RATE_RANGE[1],
                      f"a sample rate from {RATE_RANGE[0]:g} Hz to {RATE_RANGE[1]:g} Hz",
                      not_number="a plain number in Hz (no unit written: --rate 100)")
_positive_number = _checked(float, lambda v: np.isfinite(v) and v > 0, "a positive number")


def file_path(text):
    """An argparse type: the path of a file to write (``out/``, a folder, is refused: issue 37)."""
    if text.endswith(("/", os.sep)) or Path(text).name in ("", ".", ".."):
        raise argparse.ArgumentTypeError(f"expected a file name, got {text[:80]!r} (a folder)")
    return Path(text)


def _ranged(kind):
    """An argparse type: a number in :data:`bayes_imu.io.limits.RANGES` ``[kind]``."""
    low, high, unit = RANGES[kind]
    return _checked(float, lambda v: np.isfinite(v) and low <= v <= high and v > 0,
                    f"a number from {low:g} to {high:g}{' ' + unit if unit else ''}",
                    not_number=f"a plain number in {unit} (no unit written)" if unit else None)


def _times(text):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated times in seconds, got {text!r}"
        ) from None
    low, high, _ = RANGES["time_s"]
    if not values or not all(np.isfinite(v) and low <= v <= high for v in values):
        raise argparse.ArgumentTypeError(f"expected times from {low:g} s to {high:g} s, got "
                                         f"{text[:80]!r}")
    return tuple(sorted(set(values)))


def _say(args, text):
    if getattr(args, "quiet", False):
        return
    try:
        print(text)
    # the reader left early (| head): the run goes on and writes its outputs, quietly
    except BrokenPipeError:
        _stdout_to_devnull()


def _stdout_to_devnull():
    """Standard output to the null device, for the rest of the run (what is still buffered is
    dropped there)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    finally:
        os.close(devnull)


def _warn(text):
    print(f"bayes-imu: warning: {text}", file=sys.stderr)


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    _warn(as_flags(str(message)))  # the library's parameter names as this command's flags


def _warning_line(flags):
    """A ``warnings.showwarning`` that writes one line, the library's names put in the command's
    terms by ``flags``."""
    if flags is as_flags:
        return _one_line_warning

    def show(message, category, filename, lineno, file=None, line=None):
        _warn(flags(str(message)))

    return show


def _flags(args):
    """How a library message is put in the command's terms: :func:`as_flags`, or for ``report``
    (whose sensors' options are scene keys) :func:`_report_flags`."""
    return _report_flags if getattr(args, "handler", None) is _cmd_report else as_flags


def main(argv=None):
    """Run the ``bayes-imu`` command; return the exit status."""
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        print(f"bayes-imu: error: {exc}", file=sys.stderr)
        return 2
    args.progress = show_progress(getattr(args, "quiet", False))
    args.picture_failures = []
    # third-party loggers stay quiet
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    log.setLevel(logging.INFO)
    with warnings.catch_warnings(), _sigterm_as_interrupt():  # warnings shown the command's way
        warnings.simplefilter("default")
        warnings.showwarning = _warning_line(_flags(args))
        return _run(args)


#: set by :func:`command`: the executable's fits write their outputs from a second process
#: (report.worker)
_EXECUTABLE = False


#: glibc's malloc for the executable: blocks below this size [bytes] come from the heap, and a free
#: returns memory to the system only past twice it (:func:`_steady_allocator`)
MALLOC_MMAP_BYTES = 32 * 2**20


def _steady_allocator():
    """Fix glibc's ``malloc`` thresholds for this process and the processes it starts.

    By default glibc maps every block above a threshold (128 KiB at start) afresh and unmaps it
    when freed, raising the threshold to the size of the largest mapped block freed so far. A
    fit's arrays of a few megabytes (importance draws, the walkers' Allan variances) were then
    mapped anew at each call, or not, depending on which blocks the process had happened to free
    before: the same fit took 110 000 or 230 000 page faults (0.2-0.3 s of system time) from one
    version of the code to the next, the arithmetic unchanged (docs/speed_under_load.md,
    "Eleventh session"). Fixed thresholds (``mallopt``: mapped from :data:`MALLOC_MMAP_BYTES`,
    trimmed past twice it) make that deterministic: blocks below 32 MiB are reused from the heap,
    and at most 64 MiB of freed memory is kept. The processes it starts (the output process)
    get the same through glibc's environment variables. Left alone where the user set either
    variable, and off glibc (``mallopt`` missing). Returns whether it was set.
    """
    names = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")
    if not sys.platform.startswith("linux") or any(n in os.environ for n in names):
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt  # this process's C library
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    m_trim_threshold, m_mmap_threshold = -1, -3  # <malloc.h>
    if not (mallopt(m_mmap_threshold, MALLOC_MMAP_BYTES) == 1
            and mallopt(m_trim_threshold, 2 * MALLOC_MMAP_BYTES) == 1):
        return False
    os.environ.update(zip(names, (str(MALLOC_MMAP_BYTES), str(2 * MALLOC_MMAP_BYTES))))
    return True


#: environment variables that set how many threads a BLAS library starts as it loads (OpenBLAS, as
#: numpy's and scipy's wheels bundle it; MKL, as conda's numpy may use)
BLAS_THREADS_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _one_blas_thread():
    """BLAS on one thread in every BLAS library loaded from now on: scipy's (loaded by a fit's first
    ``scipy.linalg`` import) and all of those of the processes the command starts (the output
    process, a batch's workers), through :data:`BLAS_THREADS_VARIABLES`. numpy's, loaded with the
    package, keeps its threads; the fits limit it to one (``threadpoolctl``, as they do every BLAS
    library loaded by then).

    The command's work multiplies small matrices (a fit's walkers or importance draws by an
    ``n_tau x n_tau`` factor), which a second BLAS thread does not speed up; and each OpenBLAS
    starts a thread per further core that busy-waits for work for about 0.1 s after it starts and
    after each use, on the core the other process needs. In a ``bayes-imu fit`` of an ADIS16405
    gyro log those threads used 0.10 and 0.05 s of CPU in the command's process (numpy's and
    scipy's; ad hoc, per-thread CPU from ``/proc``), and the output process loads both libraries
    too. With the variables set, nine fits (imu1, imu3, imu6 gyro x, seeds 0-2) took 15.1 s
    against 16.2 s, each beside the same fit without them (``scripts/bench_fit_ab.py``). Left
    alone where the user set either variable. Returns the variables set."""
    if any(name in os.environ for name in BLAS_THREADS_VARIABLES):
        return ()
    os.environ.update(dict.fromkeys(BLAS_THREADS_VARIABLES, "1"))
    return BLAS_THREADS_VARIABLES


def command(argv=None):
    """The ``bayes-imu`` executable: :func:`main`, then leave at once with its status.

    Every file of the run is written and closed, and the worker process stopped, before
    :func:`main` returns; standard output and error are flushed here. Leaving without the
    interpreter's teardown (freeing numba's compiled code and the imported libraries) saves a
    noticeable part of a short run (docs/speed_under_load.md#kernels). The executable also fixes
    glibc's allocator thresholds (:func:`_steady_allocator`) and runs BLAS on one thread
    (:func:`_one_blas_thread`), for itself and the processes it starts. Python callers use
    :func:`main`, which returns;
    there ``fit`` writes its outputs in the calling process unless ``BAYES_IMU_OUTPUT_PROCESS``
    is set (:mod:`bayes_imu.report.worker`).
    """
    global _EXECUTABLE
    _EXECUTABLE = True
    _steady_allocator()
    _one_blas_thread()
    status = main(argv)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        # a reader that left early (| head), or a closed stream
        except (BrokenPipeError, ValueError):
            pass
    logging.shutdown()
    os._exit(status)


class _Terminated(BaseException):
    """SIGTERM, raised in the main thread so that staged outputs are cleaned up as on Ctrl-C."""


@contextlib.contextmanager
def _sigterm_as_interrupt():
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise _Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


#: the library's parameter names in its messages -> this command's flags (the library never names a
#: flag)
_FLAGS = (
    (re.compile(r"\bforce=True\b"), "--force"),
    (re.compile(r"\bscheduler='serial'"), "--serial"),
    (re.compile(r"\bgaps='longest'"), "--gaps longest"),
    (re.compile(r"\bgive rate_hz or a time column\b"), "give --rate HZ or a --time-column"),
    (re.compile(r"^(out|scheduler)="), r"--\1 "),
    (re.compile(r"^columns="), "--column "),
    (re.compile(r"\bbut rate_hz is\b"), "but --rate is"),
    (re.compile(r"\bthe unit nearest rate_hz="), "the unit nearest --rate "),
    (re.compile(r"\(or allow_outside=True\)"), "(or --allow-outside)"),
    (re.compile(r"\(is rate_hz right\?\)"), "(is --rate right?)"),
    (re.compile(r"\bgive a column\b"), "give --column"),
    (re.compile(r"\btime_unit='(\w+)'"), r"--time-unit \1"),
    (re.compile(r"\b(give|leave out) time_unit\b"), r"\1 --time-unit"),
    (re.compile(r"\btrust_units\b"), "--trust-units"),
    (re.compile(r"\bunits=(\S+) as given"), r"--units \1 as given"),
    (re.compile(r"\bgive rate_hz="), "give --rate "),
    (re.compile(r"\bgive rate_hz\b"), "give --rate HZ"),
    (re.compile(r"\bthe time column and give\b"), "--time-column and give"),
    (re.compile(r"\bgoes with a time column\b"), "goes with --time-column"),
    (re.compile(r"^horizon_s="), "--horizon="),
    # allan.pipeline's LogSource fields
    (re.compile(r"^(column|units|datasheet)="), r"--\1 "),
    (re.compile(r"\bbut sensor is\b"), "but --sensor is"),
    (re.compile(r"\bleave out input='increments'"), "leave out --input"),
    (re.compile(r"\binput='increments'"), "--input increments"),
    (re.compile(r"\bneeds a (column|topic) \("), r"needs --\1 ("),
    (re.compile(r"\bleave out column\b"), "leave out --column"),
    (re.compile(r"^display_units='deg'"), "--display-units deg"),
    (re.compile(r"^horizon=(\S+) and times: give one \(times:"),
     r"--horizon \1 and --times: give one (--times:"),
    (re.compile(r"; horizon: a log grid up to it\)"), "; --horizon: a log grid up to it)"),
    (re.compile(r"\(sensor='accel'\) has none: use 'si'"),
     "(--sensor accel) has none: use --display-units si"),
    (re.compile(r"\(give units\)"), "(give --units)"),
    (re.compile(r"\ban Allan table needs rate_hz\b"), "--allan-table needs --rate HZ"),
    (
        re.compile(r"\ba time column is not available out of core; give rate_hz\b"),
        "--time-column is not available out of core; give --rate HZ",
    ),
)


def as_flags(message):
    """A library error message in this command's terms: ``out=X`` -> ``--out X``, ``force=True`` ->
    ``--force`` (parameters are named at the start of a message, so a path that contains ``out=`` is
    left alone)."""
    for pattern, flag in _FLAGS:
        message = pattern.sub(flag, message)
    return message


#: a report's messages: only the command's own options become flags; what a sensor's reading says
#: of ``rate_hz``, ``time_unit``, ``column`` ... names the scene's keys, spelled as in the scene
_REPORT_FLAGS = (
    (re.compile(r"\bforce=True\b"), "--force"),
    (re.compile(r"^out="), "--out "),
    (re.compile(r"\(or allow_outside=True\)"), "(or --allow-outside)"),
)


def _report_flags(message):
    """A library message in ``report``'s terms (:data:`_REPORT_FLAGS`)."""
    for pattern, flag in _REPORT_FLAGS:
        message = pattern.sub(flag, message)
    return message


def _run(args):
    try:
        return args.handler(args)
    except KeyboardInterrupt:
        print(
            "bayes-imu: interrupted (Ctrl-C): nothing was kept from this run; earlier results are "
            "unchanged",
            file=sys.stderr,
        )
        return 130
    except _Terminated:
        print(
            "bayes-imu: terminated (SIGTERM): nothing was kept from this run; earlier results are "
            "unchanged",
            file=sys.stderr,
        )
        return 143
    except BayesIMUError as exc:
        if args.debug or os.environ.get("BAYES_IMU_DEBUG") == "1":
            raise
        print(f"bayes-imu: error: {_flags(args)(str(exc))}", file=sys.stderr)
        return 2
    except Exception as exc:  # an internal error: one line, the traceback with --debug
        if args.debug or os.environ.get("BAYES_IMU_DEBUG") == "1":
            raise
        # a path, permission or full disk: the user's to fix (exit 2), not a bug
        reason = user_os_error(exc)
        if reason is not None:
            print(f"bayes-imu: error: {reason}", file=sys.stderr)
            return 2
        text = str(exc).strip().splitlines()
        print(f"bayes-imu: internal error: {type(exc).__name__}: {text[0] if text else ''} "
              "(rerun with --debug for the traceback, and please report it)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    command()
