"""Speed of the navigation channel against the fits it reads (docs/navigation.md).

Times, on two fit folders (default: the ADIS16405 gyro y and accelerometer x folders of
``scripts/nav_adis.py``, ``walk_nav/``): ``navigation_bands`` in this process (library, default
grid of 2 h and the ``--times``), and ``bayes-imu nav`` in a fresh process (files and picture
included); ``--refit LOG`` also times the two ``bayes-imu fit --sensor`` runs (fit with drift bands)
that made the folders. Prints a table of medians over ``--runs``. Run from the project root:
``nice python scripts/bench_nav.py --work walk_nav``.

``--speed-vs-error``: the navigation bands' own speed against error (docs/navigation.md): for
100, 300 and 1000 draw pairs (``max_draws``) and ``--runs`` random subsets each, the time of
``navigation_bands`` at 10, 60 and 300 s and the relative error of its band (5/50/95 %) and 95 %
bound of position and velocity against a reference from every draw pair (the largest common
posterior, seed 0); also the model's bands alone (``honest=False``, no widening by the record).
Writes ``--csv`` (default ``docs/speed_vs_error/nav_speed_vs_error.csv``).
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


def _values(bands):
    """Band and bound of position and velocity at every time, one flat array."""
    return np.concatenate([np.concatenate([q.sigma.ravel(), q.bound])
                           for name, q in bands.quantities.items()
                           if name in ("position", "velocity")])


def speed_vs_error(gyro, accel, runs, path):
    """The ``--speed-vs-error`` table (module docstring)."""
    import csv

    times = np.array([10.0, 60.0, 300.0])
    from bayes_imu.drift import nav_bands

    nav_bands._FACTORS.clear()  # the first call computes each record's factors (memoised after)
    start = time.perf_counter()
    navigation_bands(gyro, accel, times, rng=0)
    first = time.perf_counter() - start
    full = min(gyro.samples.shape[0], accel.samples.shape[0])
    reference = _values(navigation_bands(gyro, accel, times, max_draws=full, rng=0))
    rows = []
    for honest in (True, False):
        for draws in (100, 300, 1000):
            seconds, errors = [], []
            for seed in range(1, runs + 1):
                start = time.perf_counter()
                bands = navigation_bands(gyro, accel, times, max_draws=draws, rng=seed,
                                         honest=honest)
                seconds.append(time.perf_counter() - start)
                if honest:
                    errors.append(np.abs(_values(bands) / reference - 1.0))
            error = np.concatenate(errors) if errors else np.array([np.nan])
            rows.append({"bands": "honest (default)" if honest else "model alone",
                         "max_draws": draws, "median_seconds": float(np.median(seconds)),
                         "rms_relative_error": float(np.sqrt(np.mean(error**2))),
                         "max_relative_error": float(np.max(error)), "runs": runs,
                         "reference_draws": full})
    print("| bands | draw pairs | median time (s) | rms rel. error | max rel. error |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['bands']} | {r['max_draws']} | {r['median_seconds']:.2f} | "
              f"{r['rms_relative_error']:.3f} | {r['max_relative_error']:.3f} |")
    print(f"(reference: all {full} draw pairs, seed 0; times 10, 60, 300 s; position and "
          "velocity band and 95 % bound; the honest rows reuse the records' factors, which the "
          f"first call of a process computes: {first:.2f} s for 1000 draw pairs)")
    rows.append({"bands": "honest (default), first call", "max_draws": 1000,
                 "median_seconds": first, "rms_relative_error": float("nan"),
                 "max_relative_error": float("nan"), "runs": 1, "reference_draws": full})
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path, default=ROOT / "walk_nav")
    parser.add_argument("--gyro", default="gyro_y")
    parser.add_argument("--accel", default="accel_x")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--refit", type=Path, help="the log of both folders (ADIS16405 csv.gz)")
    parser.add_argument("--speed-vs-error", action="store_true")
    parser.add_argument("--csv", type=Path,
                        default=ROOT / "docs" / "speed_vs_error" / "nav_speed_vs_error.csv")
    opts = parser.parse_args(argv)
    if opts.speed_vs_error:
        return speed_vs_error(load_fit(opts.work / opts.gyro), load_fit(opts.work / opts.accel),
                              opts.runs, opts.csv)
    rows = []
    if opts.refit is not None:
        for name, column, unit in (
            (opts.gyro, "gyro_y_dps", "deg/s"),
            (opts.accel, "accel_x_g", "g"),
        ):
            kind = "gyro" if "gyro" in column else "accel"
            args = [
                "fit",
                str(opts.refit.resolve()),
                "--column",
                column,
                "--rate",
                "100",
                "--units",
                unit,
                "--sensor",
                kind,
                "--out",
                f"bench_{name}",
                "--force",
                "--quiet",
            ]
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
