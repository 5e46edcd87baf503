"""``bayes-imu nav``: the navigation error of a gyro + accelerometer pair from their fit folders.

Parsing and printing only; the work is :func:`bayes_imu.report.nav.run_nav`.
"""

import argparse
import math
import re
import sys
from pathlib import Path

__all__ = ["add_nav_parser"]

_EPILOG = """examples:
  bayes-imu nav --gyro fit_gyro_y --accel fit_accel_x --times 10,60,300 --calibration 60 --out nav
  bayes-imu nav --gyro fit_gyro_xyz --accel fit_accel_xyz --speed 15 --out nav_car  (three axes)

nav.csv: t_s,quantity,q05,q50,q95,unit,bound95 -- q05..q95 the 90 % credible band of the
1-sigma error, bound95 the 95 % error bound itself (posterior predictive); rows tilt (rad),
velocity (m/s), position (m)."""


def _times(text):
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated times in seconds, got {text!r}"
        ) from None
    from ..io.limits import RANGES

    low, high, _ = RANGES["time_s"]
    if not values or not all(math.isfinite(v) and low <= v <= high for v in values):
        raise argparse.ArgumentTypeError(f"expected times from {low:g} s to {high:g} s, got "
                                         f"{text[:80]!r}")
    return values


def _in_range(kind):
    """An argparse type: a number in :data:`bayes_imu.io.limits.RANGES` ``[kind]`` (issue 37)."""
    from .main import _ranged

    return _ranged(kind)


def _number_or_text(text):
    try:
        return float(text)
    except ValueError:
        return text


def _seed(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed, got {text!r}") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"expected a seed from 0 to 2**32 - 1, got {text!r}")
    return value


def add_nav_parser(sub):
    """Add the ``nav`` sub-command to ``sub`` (an argparse sub-parsers object)."""
    nav = sub.add_parser(
        "nav",
        help="horizontal navigation error in a GPS outage, from a gyro and an accelerometer fit",
        description="Credible bands of the tilt, velocity and horizontal position error of a "
        "free-inertial "
        "navigator (one horizontal channel, Schuler loop) from bayes-imu fit folders of a gyro "
        "(rad/s) and an accelerometer (m/s^2); three-axis fits give the horizontal radius. Writes "
        "nav.csv, nav.png and summary.json.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    nav.add_argument(
        "--gyro",
        type=Path,
        required=True,
        help="fit folder of the gyro about the perpendicular horizontal axis, fitted with --units "
        "(rad/s after conversion); a three-axis fit for x, y, z",
    )
    nav.add_argument(
        "--accel",
        type=Path,
        required=True,
        help="fit folder of the accelerometer along the channel (m/s^2 after conversion); "
        "three-axis "
        "with a three-axis gyro",
    )
    nav.add_argument(
        "--times",
        type=_times,
        default=(10.0, 60.0, 300.0),
        metavar="T1,T2,...",
        help="outage lengths (s) of the nav.csv rows, default 10,60,300",
    )
    nav.add_argument(
        "--bias-start",
        choices=("calibrated", "zero", "stationary"),
        default="calibrated",
        help="biases at the outage: calibrated (default: the mean of --calibration seconds before "
        "removed from both sensors), zero, or stationary",
    )
    nav.add_argument(
        "--calibration", type=_in_range("calibration_s"), default=60.0,
        help="calibration window (s), default 60"
    )
    nav.add_argument(
        "--no-schuler", action="store_true", help="leave the Schuler loop out (short-term forms)"
    )
    nav.add_argument(
        "--models",
        choices=("averaged", "selected"),
        default="averaged",
        help="average over the candidate models (default) or use the selected one",
    )
    nav.add_argument(
        "--speed",
        type=_in_range("speed"),
        help="vehicle speed (m/s): adds the cross-track error from the "
        "heading (gyro z) error; three-axis fits",
    )
    nav.add_argument(
        "--horizon",
        type=_in_range("time_s"),
        help="longest time of nav.png (s), default 2x the longest --times and at least 1200",
    )
    nav.add_argument(
        "--max-position",
        metavar="AMOUNT",
        help="requirement on the horizontal position error at 95 %% (5, '5 m', '0.5 km'): the "
        "longest outage within it, printed and in summary.json",
    )
    nav.add_argument(
        "--seed", type=_seed, default=0, help="random seed of the draw pairing, default 0"
    )
    nav.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder: new, empty, or a previous bayes_imu result with --force",
    )
    nav.add_argument(
        "--force", action="store_true", help="replace a previous bayes_imu result in --out"
    )
    nav.add_argument("--quiet", action="store_true", help="no printout")
    nav.set_defaults(handler=_cmd_nav)
    return nav


def _warn_inputs(checks):
    """One warning per input fit whose checks failed (a new user's finding: ``nav`` printed bounds
    from an accelerometer fit whose model did not describe its log, without a word)."""
    from ..report.text import p_text

    several = {k: sum(c["sensor"] == k for c in checks) > 1 for k in ("gyro", "accel")}
    for c in checks:
        name = f"--{c['sensor']} fit" + (f" (axis {c['axis'] + 1})" if several[c["sensor"]]
                                         else "")
        if not c["adequate"]:
            print(f"bayes-imu: warning: {name}: the noise model does not describe its log "
                  f"(goodness of fit p {p_text(c['p_value'])}): the "
                  "bounds inherit its bands, too narrow where the model misses", file=sys.stderr)
        if c["stationary"] is False:
            print(f"bayes-imu: warning: {name}: the noise changes during its log (p = "
                  f"{c['stationarity_p']:.2g}): a unit's noise on another day may differ",
                  file=sys.stderr)


def _cmd_nav(args):
    from ..drift.display import parse_amount
    from ..errors import InputError
    from ..report.nav import SMALL_ANGLE_RAD, NavRequest, format_length, run_nav
    from .main import output_process

    limit = (
        None
        if args.max_position is None
        else parse_amount(_number_or_text(args.max_position), "position", "--max-position")
    )

    request = NavRequest(
        args.gyro,
        args.accel,
        args.out,
        args.times,
        args.bias_start,
        args.calibration,
        not args.no_schuler,
        args.models,
        args.speed,
        args.horizon,
        args.seed,
        args.force,
        limit,
    )
    failures = []  # nav.png not drawn: the numbers are kept (exit 3)
    try:
        # nav.png from a second process, as a fit's figures (cli.main.output_process)
        bands, summary = run_nav(request, failures=failures, background=output_process())
    except InputError as exc:  # the library names its parameters; say the flags
        text = re.sub(r"^(gyro|accel)=(\S+):", r"--\1 \2:", str(exc))
        raise InputError(
            text.replace("gyro and accel swapped?", "swap --gyro and --accel?")
        ) from None
    _warn_inputs(summary["inputs"])
    radius = "position_x" in bands.quantities  # three-axis fits: the horizontal radius
    what = ("horizontal position error (radius)" if radius
            else "position error along the accelerometer's axis (one horizontal channel)")
    tilt = bands.quantities["tilt"].sigma[1]
    beyond = [t for t in args.times if tilt[int(abs(bands.t_s - t).argmin())] > SMALL_ANGLE_RAD]
    if beyond:
        print(f"bayes-imu: warning: the median tilt exceeds {SMALL_ANGLE_RAD:g} rad at "
              f"{', '.join(f'{t:g}' for t in beyond)} s: the small-angle error model no longer "
              "holds there (nav.png hatches it); read those rows as orders of magnitude",
              file=sys.stderr)
    if not args.quiet:
        position = bands.quantities["position"]
        for t in args.times:
            i = int(abs(bands.t_s - t).argmin())
            print(
                f"after {bands.t_s[i]:g} s: {what} <= {format_length(position.bound[i])} at 95 % "
                f"(1-sigma {format_length(position.sigma[1][i])}, 90 % band "
                f"{format_length(position.sigma[0][i])} to {format_length(position.sigma[-1][i])})",
                file=sys.stdout,
            )
        if limit is not None:
            print(
                f"{'horizontal position' if radius else 'position in this channel'} within "
                f"{format_length(limit)} at 95 % for "
                f"{summary['requirement']['longest_outage_s']:g} s",
                file=sys.stdout,
            )
        print(f"wrote {args.out}/nav.csv, nav.png, summary.json", file=sys.stdout)
    from ..report.worker import PICTURE_FAILED_STATUS

    for failure in failures:
        print(f"bayes-imu: warning: {failure}", file=sys.stderr)
    return PICTURE_FAILED_STATUS if failures else 0
