"""Speed of the navigation channel against the fits it reads (docs/navigation.md).

Times, on two fit folders (default: the ADIS16405 gyro y and accelerometer x folders of
``scripts/nav_adis.py``, ``walk_nav/``): ``navigation_bands`` in this process (library, default
grid of 2 h and the ``--times``), and ``bayes-imu nav`` in a fresh process (files and picture
included); ``--refit LOG`` also times the two ``bayes-imu fit --sensor`` runs (fit with drift bands)
that made the folders. Prints a table of medians over ``--runs``. Run from the project root:
``nice python scripts/bench_nav.py --work walk_nav``.
"""

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from bayes_imu.drift.nav_bands import nav_times, navigation_bands
from bayes_imu.inference.archive import load_fit

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, runs):
    out = []
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        out.append(time.perf_counter() - start)
    return float(np.median(out)), out


def cli(args, cwd):
    subprocess.run([sys.executable, "-m", "bayes_imu.cli", *args], cwd=cwd, check=True,
                   capture_output=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path, default=ROOT / "walk_nav")
    parser.add_argument("--gyro", default="gyro_y")
    parser.add_argument("--accel", default="accel_x")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--refit", type=Path, help="the log of both folders (ADIS16405 csv.gz)")
    opts = parser.parse_args(argv)
    rows = []
    if opts.refit is not None:
        for name, column, unit in ((opts.gyro, "gyro_y_dps", "deg/s"), (opts.accel, "accel_x_g", "g")):
            kind = "gyro" if "gyro" in column else "accel"
            args = ["fit", str(opts.refit.resolve()), "--column", column, "--rate", "100", "--units",
                    unit, "--sensor", kind, "--out", f"bench_{name}", "--force", "--quiet"]
            rows.append((f"bayes-imu fit --sensor {kind} ({column})",
                         *timed(lambda a=args: cli(a, opts.work), opts.runs)))
    gyro, accel = load_fit(opts.work / opts.gyro), load_fit(opts.work / opts.accel)
    grid = nav_times(gyro.model.dt, (10, 60, 300))
    rows.append((f"navigation_bands ({grid.size} times to 2 h, 1000 draw pairs)",
                 *timed(lambda: navigation_bands(gyro, accel, grid, rng=0), opts.runs)))
    args = ["nav", "--gyro", opts.gyro, "--accel", opts.accel, "--times", "10,60,300", "--out",
            "bench_nav", "--force", "--quiet"]
    rows.append(("bayes-imu nav (fresh process, files and nav.png)",
                 *timed(lambda: cli(args, opts.work), opts.runs)))
    print("| what | median (s) | runs (s) |")
    print("|---|---|---|")
    for what, median, runs in rows:
        print(f"| {what} | {median:.2f} | {', '.join(f'{r:.2f}' for r in runs)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
