"""Commands for filter users: ``export`` (noise files for VIO) and ``plan`` (how long to record).

Registered by :func:`add_commands` from :mod:`bayes_imu.cli.main`; the helpers that print and
parse arguments are main's (imported when a command runs: main imports this module).
"""

import argparse
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..report.text import p_text

__all__ = ["add_commands", "add_fit_options"]


def _probability(text):
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.5 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a probability between 0.5 and 1, got {text!r}")
    return value


def _lengths(text):
    try:
        values = [_duration(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    from ..io.limits import RANGES

    low, high, _ = RANGES["time_s"]
    if not values or not all(np.isfinite(v) and low <= v <= high for v in values):
        raise argparse.ArgumentTypeError(
            f"expected comma-separated durations (600, 10min, 4h) from {low:g} s to {high:g} s, "
            f"got {text[:80]!r}"
        )
    return tuple(sorted(set(values)))


def _duration(text):
    text = text.strip()
    for suffix, scale in (("min", 60.0), ("h", 3600.0), ("d", 86400.0), ("s", 1.0)):
        if text.endswith(suffix):
            return float(text[: -len(suffix)]) * scale
    return float(text)


def _datasheet_file(text):
    from ..noise.datasheet_check import read_datasheet_spec

    try:
        kind, spec = read_datasheet_spec(Path(text))
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return Path(text), kind, spec


def add_fit_options(fit):
    """``fit --datasheet FILE``: each datasheet value's probability of being within spec."""
    fit.add_argument(
        "--datasheet",
        type=_datasheet_file,
        metavar="FILE",
        help="vendor datasheet values (JSON or TOML, datasheet units; docs/cli.md): "
        "summary.json gets "
        "each value's posterior probability of being within spec, and a one-line verdict",
    )


def add_commands(sub):
    """Add ``export`` and ``plan`` to the ``bayes-imu`` sub-command parser ``sub``."""
    from ..drift.plan import DEFAULT_LENGTHS_S
    from ..report.exports import FORMATS
    from .main import _ranged, _rate_type, _seed_type, file_path

    export = sub.add_parser(
        "export",
        help="filter noise file (Kalibr, OpenVINS, VINS-Fusion, GTSAM, MATLAB) from fit folders",
        description="Write a filter's noise parameters (white noise density and bias random walk "
        "of each sensor) from bayes-imu fit folders fitted with --units, in the format's own "
        "names, units and time convention (docs/cli.md). With --overbound the values are the "
        "smallest white + random-walk pair whose drift (bias calibrated before the outage) "
        "covers the posterior's upper credible drift at every horizon from --t-min to --t-max; "
        "the point values and the factor are listed beside them. Several axes: the largest, "
        "each axis listed.",
        epilog="example: bayes-imu export --gyro fit_gyro --accel fit_accel --format openvins "
        "--overbound --t-max 60 --out imu_chain.yaml",
    )
    export.add_argument("--gyro", type=Path, nargs="+", help="fit folder(s) of gyro axes")
    export.add_argument("--accel", type=Path, nargs="+", help="fit folder(s) of accelerometer axes")
    export.add_argument("--format", required=True, choices=tuple(FORMATS), help="file format")
    export.add_argument("--out", type=file_path, required=True, help="file to write")
    export.add_argument(
        "--overbound",
        action="store_true",
        help="write overbounding values (default: posterior medians)",
    )
    export.add_argument(
        "--t-min", type=_ranged("time_s"), metavar="S",
        help="shortest horizon (s), default one sample"
    )
    export.add_argument(
        "--t-max",
        type=_ranged("time_s"),
        metavar="S",
        help="longest outage of interest (s), default the record's duration up to 3600",
    )
    export.add_argument(
        "--credibility",
        type=_probability,
        default=0.95,
        help="posterior probability of the bounded drift, default 0.95",
    )
    export.add_argument(
        "--calibration",
        type=_ranged("calibration_s"),
        default=60.0,
        metavar="S",
        help="seconds of bias calibration before an outage, default 60",
    )
    export.add_argument(
        "--topic", default="/imu0", help="rostopic (kalibr, openvins), default /imu0"
    )
    export.add_argument(
        "--seed", type=_seed_type, default=0, help="random seed of the draws subset, default 0"
    )
    export.add_argument(
        "--force",
        action="store_true",
        help="replace a file bayes_imu wrote earlier (never other files)",
    )
    export.add_argument("--quiet", action="store_true", help="no messages")
    export.set_defaults(handler=_cmd_export)

    plan = sub.add_parser(
        "plan",
        help="how long to record: predicted 90%% intervals versus record length",
        description="Predict how the 90% interval of each noise parameter, and of the drift at "
        "--horizons, shrinks with record length, from a pilot fit (a short log fitted by bayes-imu "
        "fit) or from datasheet values, by the Fisher information of the Allan-variance "
        "likelihood the fit uses (validated against simulate-and-fit: docs/validation/plan.md). "
        "Writes plan.csv, plan.json and plan.png.",
        epilog="examples:\n  bayes-imu plan fit_pilot --horizons 10,100 --out plan_gx\n"
        "  bayes-imu plan --datasheet adis.toml --rate 200 --lengths 10min,1h,4h,24h --out plan_ds",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    plan.add_argument(
        "fit", type=Path, nargs="*", help="pilot fit folder (bayes-imu fit, fitted with --units)"
    )
    plan.add_argument(
        "--datasheet",
        type=_datasheet_file,
        metavar="FILE",
        help="plan from datasheet values instead (JSON or TOML, as fit --datasheet); needs --rate",
    )
    plan.add_argument(
        "--rate", type=_rate_type, metavar="HZ", help="with --datasheet: the log's sample rate"
    )
    plan.add_argument(
        "--lengths",
        type=_lengths,
        default=DEFAULT_LENGTHS_S,
        help="record lengths (s, or with min / h / d), default 10min,30min,1h,2h,4h,8h,24h,48h",
    )
    plan.add_argument(
        "--horizons",
        type=_lengths,
        default=(),
        metavar="S,...",
        help="drift horizons (s): the 1-sigma drift's interval too (attitude for a gyro, velocity "
        "for an accelerometer)",
    )
    plan.add_argument(
        "--calibration",
        type=_ranged("calibration_s"),
        default=60.0,
        metavar="S",
        help="seconds of bias calibration before an outage, default 60",
    )
    plan.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder: new, empty, or a previous bayes_imu result with --force",
    )
    plan.add_argument(
        "--force", action="store_true", help="replace a previous bayes_imu result in --out"
    )
    plan.add_argument("--quiet", action="store_true", help="no messages")
    plan.set_defaults(handler=_cmd_plan)


def _cmd_export(args):
    from ..report.exports import export_values_from_folders, write_export
    from ..report.output import staged_file
    from .main import _say, _warn

    if not args.gyro and not args.accel:
        raise InputError("export: give --gyro FIT_FOLDER..., --accel FIT_FOLDER..., or both")
    if not args.overbound and (args.t_min is not None or args.t_max is not None):
        raise InputError("export: --t-min and --t-max go with --overbound")
    values = export_values_from_folders(
        args.gyro or (),
        args.accel or (),
        overbound=args.overbound,
        t_min=args.t_min,
        t_max=args.t_max,
        credibility=args.credibility,
        calibration_s=args.calibration,
        rng=args.seed,
    )
    inputs = [
        p for folder in (args.gyro or []) + (args.accel or []) for p in Path(folder).rglob("*")
    ]
    with staged_file(args.out, force=args.force, inputs=inputs) as tmp:
        write_export(values, tmp, args.format, topic=args.topic)
    if values.inadequate:
        _warn(
            "values from fits that failed the goodness-of-fit check: "
            + ", ".join(values.inadequate)
        )
    factors = values.factors()
    for key, value in values.noise.present().items():
        text = f"  {key:28s} {value:.4g}"
        if values.bound is not None:
            point = values.point.present()[key]
            text += f"  (x{factors[key]:.3g} over the posterior median {point:.4g})"
        _say(args, text)
    for sensor, rows in values.tight.items():
        _say(args, f"  {sensor} bound tight at " + ", ".join(f"{q} {t:.3g} s" for _, q, t in rows))
    _say(args, f"wrote {args.out} ({args.format}, {values.mode})")
    return 0


def _plan_inputs(args):
    """``[(label, model, params, kind, record_s)]`` of the pilot fit's axes, or of the datasheet."""
    from ..inference.archive import fit_axes, load_fit
    from ..noise.datasheet import KIND_OF_UNIT
    from ..noise.datasheet_check import spec_model

    if len(args.fit) > 1:
        raise InputError(
            f"plan: {len(args.fit)} pilot fit folders ({', '.join(map(str, args.fit))}); expected "
            "one (run plan once per folder, or fit the axes together: fit --column gx,gy,gz)"
        )
    args.fit = args.fit[0] if args.fit else None
    if (args.fit is None) == (args.datasheet is None):
        raise InputError("plan: give a pilot fit folder or --datasheet FILE (one of them)")
    if args.datasheet is not None:
        if args.rate is None:
            raise InputError(
                "plan: --datasheet needs --rate HZ (the rate of the log to be recorded)"
            )
        path, kind, spec = args.datasheet
        model, params = spec_model(kind, spec, args.rate)
        return [(path.stem, model, params, kind, None)]
    if args.rate is not None:
        raise InputError("plan: --rate goes with --datasheet (a pilot fit has its own rate)")
    from ..drift.plan import pilot_check

    out = []
    args.pilot_checks = {}
    for axis, place, summary in fit_axes(args.fit):
        fit = load_fit(place)
        params = {p: float(np.median(fit.draws(p))) for p in fit.model.parameter_names}
        out.append((axis, fit.model, params, KIND_OF_UNIT.get(summary.get("unit")), fit.record_s))
        args.plan_warnings.extend(_inadequate_pilot(axis, getattr(fit, "adequacy", None)))
        check = args.pilot_checks[axis] = pilot_check(fit, calibration_s=args.calibration)
        warning = check.warning(axis)
        if warning is not None:
            args.plan_warnings.append(warning)
    return out


def _inadequate_pilot(axis, check):
    """``[warning]`` when the pilot fit failed its goodness-of-fit check (the plan assumes its
    model), else ``[]``."""
    if check is None or check.adequate:
        return []
    return [
        f"[{axis}] the pilot fit failed its goodness-of-fit check (p {p_text(check.p_value)}): "
        "the plan assumes its model, so its widths may be optimistic for this sensor "
        "(record longer, or fit more terms: bayes-imu fit --terms)"
    ]


def _cmd_plan(args):
    import json

    from ..drift.plan import plan_record_length
    from ..report.output import staged_folder
    from ..report.planning import plan_csv, plot_plan
    from ..report.worker import draw_picture
    from .main import _pictures_status, _say, _warn
    from .._version import __version__

    plans, pilot = [], None
    args.plan_warnings, args.pilot_checks = [], {}
    for label, model, params, kind, record_s in _plan_inputs(args):
        if args.horizons and kind is None:
            raise InputError(
                "plan: --horizons needs a gyro or accelerometer fit in SI (bayes-imu fit --units)"
            )
        quantity = {"gyro": "attitude", "accel": "velocity"}.get(kind)
        plans.append(
            (
                label,
                plan_record_length(
                    model,
                    params,
                    lengths_s=args.lengths,
                    horizons_s=args.horizons,
                    quantity=quantity,
                    calibration_s=args.calibration,
                ),
            )
        )
        pilot = record_s
    inputs = [args.fit] if args.fit is not None else [args.datasheet[0]]
    with staged_folder(args.out, force=args.force, inputs=inputs) as tmp:
        (tmp / "plan.csv").write_text(plan_csv(plans), encoding="utf-8")
        doc = {
            "bayes_imu_version": __version__,
            "method": "Fisher information of the correlated Allan-variance likelihood",
            "source": str(inputs[0]),
            "calibration_s": args.calibration,
            "axes": {label: {"rate_hz": p.rate_hz, "rows": p.rows(),
                             **({"pilot": args.pilot_checks[label].to_dict()}
                                if label in args.pilot_checks else {})}
                     for label, p in plans},
            "warnings": args.plan_warnings,
        }
        (tmp / "plan.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        failure = draw_picture(  # a picture that fails costs only the picture (exit 3)
            plot_plan,
            plans,
            tmp / "plan.png",
            pilot_s=pilot,
            title=f"Predicted 90% intervals versus record length: {Path(str(inputs[0])).name}",
        )
    for label, plan in plans:
        _say(args, f"[{label}] 90% interval, upper half-width in % of the value:")
        whats = list(plan.names) + [f"{plan.quantity} drift {t:g} s" for t in plan.horizons_s]
        _say(args, "  " + f"{'length':>8}" + "".join(f"{w[:22]:>24}" for w in whats))
        for i, length in enumerate(plan.lengths_s):
            sds = list(plan.log_sd[i]) + list(plan.drift_log_sd[i])
            _say(
                args,
                "  "
                + f"{_hours(length):>8}"
                + "".join(f"{100 * np.expm1(1.6448536 * s):23.3g}%" for s in sds),
            )
    for text in args.plan_warnings:
        _warn(text)
    _say(args, f"wrote {args.out}/plan.csv, plan.json and plan.png")
    return _pictures_status([failure])


def _hours(seconds):
    return f"{seconds / 3600:g} h" if seconds >= 3600 else f"{seconds / 60:g} min"
