"""Command-line interface: a thin layer over the public API.

``bayes-imu allan LOG.csv --column NAME --rate HZ --out DIR``
    Overlapping Allan deviation with confidence intervals (allan.csv, allan.png).
``bayes-imu fit LOG.csv --column NAME --rate HZ --out DIR [--seed N]``
    Model selection and posterior (summary.json, posterior.nc, allan_fit.png, corner.png).
``bayes-imu drift SENSOR.json --out DIR``
    1-sigma drift curves from known (datasheet) noise parameters.

Exit status: 0 success, 2 a user error (one line on stderr, no traceback unless
``--debug``), 1 an unexpected internal error.
"""

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np

from . import __version__
from .allan import allan_variance
from .drift import QUANTITY_ORDER, drift_sigma
from .errors import BayesIMUError, InputError
from .io import read_log, read_text

__all__ = ["main"]

log = logging.getLogger("bayes_imu")
_SENSOR_QUANTITIES = {"gyro": ("attitude",), "accel": ("velocity", "position")}


def _build_parser():
    parser = argparse.ArgumentParser(prog="bayes-imu", description="Bayesian characterization of inertial sensors.")
    parser.add_argument("--version", action="version", version=f"bayes-imu {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of user errors")
    sub = parser.add_subparsers(dest="command", required=True)

    allan = sub.add_parser("allan", help="overlapping Allan deviation of one column of a CSV log")
    allan.add_argument("log", type=Path, help="CSV log with a header row (.gz accepted)")
    allan.add_argument("--column", required=True, help="name of the rate column")
    allan.add_argument("--rate", type=float, required=True, help="sample rate (Hz)")
    allan.add_argument("--out", type=Path, required=True, help="output folder")
    allan.add_argument("--grid", default="octave", choices=("octave", "decade", "all"), help="cluster sizes")
    allan.set_defaults(handler=_cmd_allan)

    fit = sub.add_parser("fit", help="Bayesian noise-model fit of one column of a CSV log")
    fit.add_argument("log", type=Path, help="CSV log with a header row (.gz accepted)")
    fit.add_argument("--column", required=True, help="name of the rate column")
    fit.add_argument("--rate", type=float, required=True, help="sample rate (Hz)")
    fit.add_argument("--out", type=Path, required=True, help="output folder")
    fit.add_argument("--seed", type=int, default=0, help="random seed (recorded in the outputs), default 0")
    fit.add_argument("--unit", default="u", help="unit of the column, used in summary.json (e.g. deg/s)")
    fit.add_argument("--terms", default="auto",
                     help="'auto' (model selection) or a comma-separated list of terms, e.g. white,gauss_markov")
    fit.add_argument("--likelihood", choices=("correlated", "independent"), default="correlated")
    fit.add_argument("--sensor", choices=("gyro", "accel"),
                     help="also write drift.csv / drift.png: attitude (gyro) or velocity and position (accel)")
    fit.add_argument("--horizon", type=float, default=3600.0, help="longest drift time (s), default 3600")
    fit.add_argument("--bias-start", choices=("zero", "stationary"), default="zero",
                     help="bias at the start of the outage: zero (paper) or stationary (conservative)")
    fit.set_defaults(handler=_cmd_fit)

    report = sub.add_parser("report", help="conservative drift bounds for several IMUs (scene TOML)")
    report.add_argument("scene", type=Path, help="scene TOML file (see README)")
    report.add_argument("--out", type=Path, required=True, help="output folder")
    report.add_argument("--seed", type=int, default=0, help="random seed, default 0")
    report.set_defaults(handler=_cmd_report)

    kalibr = sub.add_parser("kalibr", help="Kalibr IMU noise YAML from fit folders")
    kalibr.add_argument("--gyro", type=Path, nargs="+", required=True, help="fit folder(s) of gyro axes (rad/s or deg/s)")
    kalibr.add_argument("--accel", type=Path, nargs="+", required=True, help="fit folder(s) of accelerometer axes")
    kalibr.add_argument("--out", type=Path, required=True, help="YAML file to write")
    kalibr.add_argument("--credibility", type=float, default=None,
                        help="upper posterior quantile for conservative values (e.g. 0.95); default: medians")
    kalibr.set_defaults(handler=_cmd_kalibr)

    drift = sub.add_parser("drift", help="drift curves from known noise parameters (JSON)")
    drift.add_argument("sensor", type=Path, help="JSON file: rate_hz, kind, noise_density, bias_variance, time_constant")
    drift.add_argument("--out", type=Path, required=True, help="output folder")
    drift.add_argument("--horizon", type=float, default=3600.0, help="longest time (s), default 3600")
    drift.add_argument("--bias-start", choices=("zero", "stationary"), default="zero")
    drift.set_defaults(handler=_cmd_drift)
    return parser


def _read_sensor_json(path):
    try:
        spec = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg})") from None
    if not isinstance(spec, dict):
        raise InputError(f"{path}: expected a JSON object of sensor parameters")
    for key in ("rate_hz", "kind", "noise_density"):
        if key not in spec:
            raise InputError(f"{path}: missing key {key!r}")
    if spec["kind"] not in _SENSOR_QUANTITIES:
        raise InputError(f"{path}: kind={spec['kind']!r}: expected 'gyro' or 'accel'")
    return spec


def _positive_float(path, spec, key, default=None):
    value = spec.get(key, default)
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {key}={value!r}: expected a number") from None
    if not value > 0 and not (value == 0 and default is not None):
        raise InputError(f"{path}: {key}={value!r}: expected a positive number")
    return value


def _cmd_drift(args):
    spec = _read_sensor_json(args.sensor)
    dt = 1.0 / _positive_float(args.sensor, spec, "rate_hz")
    if not args.horizon > dt:
        raise InputError(f"--horizon={args.horizon!r}: expected a time (s) longer than one sample ({dt} s)")
    t = np.unique(np.round(np.geomspace(dt, args.horizon, 200) / dt)) * dt
    rows = []
    for quantity in _SENSOR_QUANTITIES[spec["kind"]]:
        result = drift_sigma(
            t,
            quantity=quantity,
            dt=dt,
            noise_density=_positive_float(args.sensor, spec, "noise_density"),
            bias_variance=_positive_float(args.sensor, spec, "bias_variance", 0.0),
            time_constant=_positive_float(args.sensor, spec, "time_constant", np.inf),
            random_walk=_positive_float(args.sensor, spec, "random_walk", 0.0),
            bias_start=args.bias_start,
        )
        rows += [(ti, quantity, w, b, r, tot) for ti, w, b, r, tot in zip(result.t_s, result.white, result.bias, result.random_walk, result.total)]
    args.out.mkdir(parents=True, exist_ok=True)
    lines = ["t_s,quantity,white,bias,random_walk,total"]
    lines += [f"{ti:.6g},{q},{w:.9g},{b:.9g},{r:.9g},{tot:.9g}" for ti, q, w, b, r, tot in rows]
    (args.out / "drift.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    for quantity in _SENSOR_QUANTITIES[spec["kind"]]:
        last = [row for row in rows if row[1] == quantity][-1]
        unit = {"attitude": "rad", "velocity": "m/s", "position": "m"}[quantity]
        print(f"{quantity}: 1-sigma drift after {last[0]:g} s = {last[5]:.4g} {unit} (order {QUANTITY_ORDER[quantity]})")
    print(f"wrote {args.out / 'drift.csv'}")
    return 0


def _cmd_allan(args):
    log_data = read_log(args.log, column=args.column)
    result = allan_variance(log_data.values, rate_hz=args.rate, m=args.grid)
    args.out.mkdir(parents=True, exist_ok=True)
    lines = ["tau,m,adev,adev_low,adev_high,edf"]
    lines += [
        f"{t:.9g},{m},{a:.9g},{lo:.9g},{hi:.9g},{e:.6g}"
        for t, m, a, lo, hi, e in zip(result.tau, result.m, result.adev, result.adev_low, result.adev_high, result.edf)
    ]
    (args.out / "allan.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    from .plots import plot_allan

    plot_allan(result, args.out / "allan.png", label=f"{Path(log_data.path).name}: {args.column}")
    print(f"{result.tau.size} cluster sizes from {result.n_samples} samples; wrote {args.out / 'allan.csv'} and allan.png")
    return 0


def _cmd_fit(args):
    from .fit import fit_allan
    from .plots import plot_allan_fit, plot_corner

    log_data = read_log(args.log, column=args.column)
    allan = allan_variance(log_data.values, rate_hz=args.rate, m="octave")
    terms = "auto" if args.terms == "auto" else tuple(t.strip() for t in args.terms.split(","))
    result = fit_allan(allan, terms=terms, likelihood=args.likelihood, rng=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    summary = result.summary(unit=args.unit)
    summary.update(log=str(log_data.path), column=args.column, unit=args.unit)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    result.inference_data.to_netcdf(str(args.out / "posterior.nc"))
    plot_allan_fit(result, args.out / "allan_fit.png", label=f"{Path(log_data.path).name}: {args.column}", rng=args.seed)
    plot_corner(result, args.out / "corner.png")
    if args.sensor:
        _write_drift(result, args, args.out)
    print(f"model: {' + '.join(result.model.terms)}  (converged: {result.diagnostics['converged']})")
    for name, p in summary["parameters"].items():
        print(f"  {name:18s} median {p['median']:.5g}  90% [{p['q05']:.5g}, {p['q95']:.5g}] {p['unit']}")
    print(f"wrote {args.out}/summary.json, posterior.nc, allan_fit.png, corner.png")
    return 0


def _write_drift(result, args, out):
    from .bands import SENSOR_QUANTITIES, default_times, drift_bands, integrated_unit
    from .plots import plot_drift

    t = default_times(result.model.dt, args.horizon)
    bands = [drift_bands(result, t, quantity=q, bias_start=args.bias_start) for q in SENSOR_QUANTITIES[args.sensor]]
    lines = ["t_s,quantity,q05,q50,q95,unit"]
    for b in bands:
        unit = integrated_unit(args.unit, b.quantity)
        lines += [f"{ti:.6g},{b.quantity},{lo:.9g},{med:.9g},{hi:.9g},{unit}" for ti, lo, med, hi in zip(b.t_s, *b.total)]
    (out / "drift.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    plot_drift(bands, out / "drift.png", units=[integrated_unit(args.unit, b.quantity) for b in bands])
    for b in bands:
        print(f"{b.quantity}: 1-sigma drift after {b.t_s[-1]:g} s: median {b.total[1][-1]:.4g}, "
              f"90% [{b.total[0][-1]:.4g}, {b.total[2][-1]:.4g}] {integrated_unit(args.unit, b.quantity)}")


def _cmd_report(args):
    from .report import build_report, read_scene
    from .report_html import write_report

    scene = read_scene(args.scene)
    report = build_report(scene, rng=args.seed)
    write_report(report, args.out)
    print(f"ranking: {', '.join(report.ranking)} ({report.reason})")
    print(f"wrote {args.out}/report.json and report.html")
    return 0


def _cmd_kalibr(args):
    from .kalibr import kalibr_values, write_kalibr_yaml

    values = kalibr_values(args.gyro, args.accel, credibility=args.credibility)
    write_kalibr_yaml(values, args.out)
    print(f"wrote {args.out} ({values['_mode']})")
    return 0


def main(argv=None):
    """Run the ``bayes-imu`` command; return the exit status."""
    parser = _build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")  # third-party loggers stay quiet
    log.setLevel(logging.INFO)
    try:
        return args.handler(args)
    except BayesIMUError as exc:
        if args.debug:
            raise
        print(f"bayes-imu: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
