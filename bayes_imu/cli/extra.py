"""Commands for filter users: ``export`` (noise files for VIO / filters) and ``plan`` (how long to record).

Registered by :func:`add_commands` from :mod:`bayes_imu.cli.main`; the helpers that print and
parse arguments are main's (imported when a command runs: main imports this module).
"""

import argparse
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["add_commands"]


def _positive(text):
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _probability(text):
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.5 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a probability between 0.5 and 1, got {text!r}")
    return value


def add_commands(sub):
    """Add ``export`` and ``plan`` to the ``bayes-imu`` sub-command parser ``sub``."""
    from ..report.exports import FORMATS

    export = sub.add_parser(
        "export", help="filter noise file (Kalibr, OpenVINS, VINS-Fusion, GTSAM, MATLAB) from fit folders",
        description="Write a filter's noise parameters (white noise density and bias random walk of each sensor) "
                    "from bayes-imu fit folders fitted with --units, in the format's own names, units and time "
                    "convention (docs/cli.md). With --overbound the values are the smallest white + random-walk "
                    "pair whose drift (bias calibrated before the outage) covers the posterior's upper credible "
                    "drift at every horizon from --t-min to --t-max; the point values and the factor are listed "
                    "beside them. Several axes: the largest, each axis listed.",
        epilog="example: bayes-imu export --gyro fit_gyro --accel fit_accel --format openvins --overbound "
               "--t-max 60 --out imu_chain.yaml")
    export.add_argument("--gyro", type=Path, nargs="+", help="fit folder(s) of gyro axes")
    export.add_argument("--accel", type=Path, nargs="+", help="fit folder(s) of accelerometer axes")
    export.add_argument("--format", required=True, choices=tuple(FORMATS), help="file format")
    export.add_argument("--out", type=Path, required=True, help="file to write")
    export.add_argument("--overbound", action="store_true",
                        help="write overbounding values (default: posterior medians)")
    export.add_argument("--t-min", type=_positive, metavar="S", help="shortest horizon (s), default one sample")
    export.add_argument("--t-max", type=_positive, metavar="S",
                        help="longest outage of interest (s), default the record's duration up to 3600")
    export.add_argument("--credibility", type=_probability, default=0.95,
                        help="posterior probability of the bounded drift, default 0.95")
    export.add_argument("--calibration", type=_positive, default=60.0, metavar="S",
                        help="seconds of bias calibration before an outage, default 60")
    export.add_argument("--topic", default="/imu0", help="rostopic (kalibr, openvins), default /imu0")
    export.add_argument("--seed", type=int, default=0, help="random seed of the draws subset, default 0")
    export.add_argument("--force", action="store_true", help="replace a file bayes_imu wrote earlier (never other files)")
    export.add_argument("--quiet", action="store_true", help="no messages")
    export.set_defaults(handler=_cmd_export)


def _cmd_export(args):
    from ..report.exports import export_values_from_folders, write_export
    from ..report.output import staged_file
    from .main import _say, _warn

    if not args.gyro and not args.accel:
        raise InputError("export: give --gyro FIT_FOLDER..., --accel FIT_FOLDER..., or both")
    if not args.overbound and (args.t_min is not None or args.t_max is not None):
        raise InputError("export: --t-min and --t-max go with --overbound")
    values = export_values_from_folders(args.gyro or (), args.accel or (), overbound=args.overbound,
                                        t_min=args.t_min, t_max=args.t_max, credibility=args.credibility,
                                        calibration_s=args.calibration, rng=args.seed)
    inputs = [p for folder in (args.gyro or []) + (args.accel or []) for p in Path(folder).rglob("*")]
    with staged_file(args.out, force=args.force, inputs=inputs) as tmp:
        write_export(values, tmp, args.format, topic=args.topic)
    if values.inadequate:
        _warn("values from fits that failed the goodness-of-fit check: " + ", ".join(values.inadequate))
    factors = values.factors()
    for key, value in values.noise.present().items():
        text = f"  {key:28s} {value:.4g}"
        if values.bound is not None:
            text += f"  (x{factors[key]:.2g} over the posterior median {values.point.present()[key]:.4g})"
        _say(args, text)
    for sensor, rows in values.tight.items():
        _say(args, f"  {sensor} bound tight at " + ", ".join(f"{q} {t:.3g} s" for _, q, t in rows))
    _say(args, f"wrote {args.out} ({args.format}, {values.mode})")
    return 0
