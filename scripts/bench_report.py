"""Speed and peak memory of ``bayes-imu report`` on real ADIS16405 logs (issue 39).

Each report runs in a fresh process as a user runs it (``python -m bayes_imu.cli report``);
its wall time and peak resident memory (``os.wait4``'s ``ru_maxrss`` of that child) are printed.
Cases (ADIS16405 recordings of ``../shared/data_real/smac_imudata``, 100 Hz):

* ``accel``: the imu1 accelerometer x fit folder (1e6 samples), position requirement 30 m
  (the bisection for the longest acceptable outage searches up to 1e6 s);
* ``gyro``: the imu1 gyro x fit folder, attitude requirement 0.5 deg;
* ``scene4``: four fit folders (imu1 and imu2, gyro x and accelerometer x), position requirement;
* ``refit2``: two accelerometers from 500 000-sample logs (imu1, imu2 accel x, written as CSV),
  fitted by the report; beside it, the two ``bayes-imu fit --sensor accel`` runs on the same logs
  (their sum is the bound: the report should cost at most the fits plus 20%). Both use seed 0,
  and the report fits a log with its seed as the fit command does: the same chains (before the
  twelfth session the report's fits drew from streams spawned per sensor, so the two compared
  chains of different lengths, a 40 000-step chain against one of 6 500 on imu1).

Fit folders and logs are prepared once in ``--work`` (reused on later runs). The bounds of
the issue: fit folders cost their I/O plus the drift bands (seconds); peak memory at most
twice the largest log's samples in float64 plus about 300 MB.

    python scripts/bench_report.py [--cases accel,gyro,scene4,refit2] [--runs 1] [--work DIR]
    python scripts/bench_report.py --pythonpath OTHER_CHECKOUT   # time another tree (before/after)
"""

import argparse
import gzip
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
REPO = Path(__file__).resolve().parents[1]
CASES = ("accel", "gyro", "scene4", "refit2")
REFIT_SAMPLES = 500_000
HEAD = ('[scene]\nname = "{name}"\noutages_s = [10, 60, 300]\n'
        '[requirement]\nquantity = "{q}"\nmax_error = "{e}"\n')
FOLDER = '[[sensor]]\nname = "{name}"\nkind = "{kind}"\nfit = "{path}"\n'
LOG = ('[[sensor]]\nname = "{name}"\nkind = "accel"\nlog = "{path}"\ncolumn = "accel_x_g"\n'
       'rate_hz = 100\nunits = "g"\n')


def _child(cmd, env):
    """Run ``cmd``; return (wall s, peak RSS MB, return code)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if proc.returncode != 0:
        command = " ".join(map(str, cmd))
        print(f"  failed ({proc.returncode}): {command}\n{err[-2000:]}", file=sys.stderr)
    return wall, usage.ru_maxrss / 1024.0, proc.returncode


def _cli(*args):
    return [sys.executable, "-m", "bayes_imu.cli", *map(str, args)]


def _fit(log, column, unit, kind, out, env, n=None):
    if (out / "summary.json").exists():
        return None
    return _child(_cli("fit", log, "--column", column, "--units", unit, "--rate", 100,
                       "--sensor", kind, "--out", out, "--quiet", "--seed", 0), env)


def _short_log(imu, work):
    path = work / f"adis_imu{imu}_{REFIT_SAMPLES}.csv"
    if not path.exists():
        with gzip.open(DATA / f"adis_16405_imu{imu}.csv.gz", "rt") as src, open(path, "w") as dst:
            for i, line in enumerate(src):
                if i > REFIT_SAMPLES:
                    break
                dst.write(line)
    return path


def _prepare(work, env):
    folders = {}
    for imu in (1, 2):
        for kind, column, unit in (("gyro", "gyro_x_dps", "deg/s"), ("accel", "accel_x_g", "g")):
            out = work / f"fit_imu{imu}_{kind}"
            print(f"preparing {out.name} ...", file=sys.stderr, flush=True)
            _fit(DATA / f"adis_16405_imu{imu}.csv.gz", column, unit, kind, out, env)
            folders[(imu, kind)] = out
    return folders


def _scene(work, name, text):
    path = work / f"scene_{name}.toml"
    path.write_text(text)
    return path


def _report(scene, env):
    with tempfile.TemporaryDirectory() as tmp:
        return _child(_cli("report", scene, "--out", Path(tmp) / "out", "--quiet"), env)


def main(argv=None):
    global DATA
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", default=",".join(CASES),
                        help="comma-separated subset of " + ", ".join(CASES))
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--work", type=Path,
                        default=Path(tempfile.gettempdir()) / "bayes_imu_bench_report")
    parser.add_argument("--data", type=Path, default=DATA,
                        help="the smac_imudata folder (default ../shared/...)")
    parser.add_argument("--pythonpath", type=Path, default=REPO,
                        help="checkout to time (default this one)")
    args = parser.parse_args(argv)
    if not args.data.exists():
        print(f"skipped: {args.data} not found")
        return
    DATA = args.data
    cases = [c for c in args.cases.split(",") if c]
    unknown = set(cases) - set(CASES)
    if unknown:
        parser.error(f"unknown cases {sorted(unknown)}: expected some of {', '.join(CASES)}")
    env = dict(os.environ, PYTHONPATH=str(args.pythonpath.resolve()))
    args.work.mkdir(parents=True, exist_ok=True)
    folders = _prepare(args.work, env) if set(cases) & {"accel", "gyro", "scene4"} else {}
    load = os.getloadavg()[0]
    print(f"tree {args.pythonpath.resolve()}; load average at start {load:.1f} "
          f"({os.cpu_count()} cores)")
    print(f"{'case':8s} {'run':>3s} {'wall s':>8s} {'peak MB':>8s}  bound")
    for case in cases:
        for run in range(1, args.runs + 1):
            bound = "fit folders: I/O + drift bands (seconds); memory <= ~300 MB"
            if case == "accel":
                scene = HEAD.format(name="accel", q="position", e="30 m") + FOLDER.format(
                    name="imu1 accel", kind="accel", path=folders[(1, "accel")])
            elif case == "gyro":
                scene = HEAD.format(name="gyro", q="attitude", e="0.5 deg") + FOLDER.format(
                    name="imu1 gyro", kind="gyro", path=folders[(1, "gyro")])
            elif case == "scene4":
                scene = HEAD.format(name="four", q="position", e="30 m") + "".join(
                    FOLDER.format(name=f"imu{i} {k}", kind=k, path=folders[(i, k)])
                    for i in (1, 2) for k in ("gyro", "accel"))
            else:
                logs = [_short_log(i, args.work) for i in (1, 2)]
                scene = HEAD.format(name="refit", q="position", e="30 m") + "".join(
                    LOG.format(name=f"imu{i} accel", path=p) for i, p in zip((1, 2), logs))
                fits = []
                with tempfile.TemporaryDirectory() as tmp:
                    for i, p in zip((1, 2), logs):
                        fits.append(_fit(p, "accel_x_g", "g", "accel", Path(tmp) / f"f{i}", env))
                total = sum(f[0] for f in fits)
                bound = (f"fits alone {fits[0][0]:.1f} + {fits[1][0]:.1f} = {total:.1f} s "
                         f"(x1.2: {1.2 * total:.1f} s), peak {max(f[1] for f in fits):.0f} MB; "
                         f"memory <= {2 * REFIT_SAMPLES * 8 / 2**20 + 300:.0f} MB")
            wall, peak, rc = _report(_scene(args.work, case, scene), env)
            status = "" if rc == 0 else f"  FAILED ({rc})"
            print(f"{case:8s} {run:3d} {wall:8.1f} {peak:8.0f}  {bound}{status}", flush=True)
    print(f"load average at end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
