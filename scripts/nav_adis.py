"""The README's navigation step on a real IMU: ADIS16405 unit 1, gyro y + accelerometer x.

Fits the two columns of ``../shared/data_real/smac_imudata/adis_16405_imu1.csv.gz`` (read there,
never copied; the script stops when it is absent) with ``bayes-imu fit`` (deg/s and g converted
to SI), runs ``bayes-imu nav`` on the two fit folders, copies ``nav.png`` to
``docs/navigation/adis16405_nav.png`` and prints the numbers docs/navigation.md and the README
quote. Folders go to ``--work`` (default ``walk_nav/``); existing fit folders are reused.
Run from the project root: ``nice python scripts/nav_adis.py``.
"""

import argparse
import csv
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
LOG_PATH = ("data_real", "smac_imudata", "adis_16405_imu1.csv.gz")
FITS = {"gyro_y": ("gyro_y_dps", "deg/s"), "accel_x": ("accel_x_g", "g")}
TIMES = (10, 30, 60, 120, 300)


def run(args, cwd):
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "bayes_imu.cli", *args], cwd=cwd, check=True)
    return time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path, default=ROOT / "walk_nav")
    parser.add_argument(
        "--shared", type=Path, default=SHARED, help="the shared data folder, default ../shared"
    )
    opts = parser.parse_args(argv)
    log = opts.shared.joinpath(*LOG_PATH).resolve()
    if not log.exists():
        print(f"{log} not found: the shared ADIS16405 logs are needed", file=sys.stderr)
        return 1
    opts.work.mkdir(parents=True, exist_ok=True)
    for name, (column, unit) in FITS.items():
        if not (opts.work / name / "fit.npz").exists():
            took = run(
                [
                    "fit",
                    str(log),
                    "--column",
                    column,
                    "--rate",
                    "100",
                    "--units",
                    unit,
                    "--out",
                    name,
                    "--quiet",
                    "--force",
                ],
                opts.work,
            )
            print(f"fit {name}: {took:.1f} s")
    took = run(
        [
            "nav",
            "--gyro",
            "gyro_y",
            "--accel",
            "accel_x",
            "--times",
            ",".join(map(str, TIMES)),
            "--calibration",
            "60",
            "--max-position",
            "5",
            "--out",
            "nav",
            "--force",
            "--quiet",
        ],
        opts.work,
    )
    print(f"nav: {took:.1f} s")
    with open(opts.work / "nav" / "nav.csv") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        print(
            f"  {float(r['t_s']):6g} s  {r['quantity']:8s} 1-sigma {float(r['q50']):.3g} "
            f"[{float(r['q05']):.3g}, {float(r['q95']):.3g}] {r['unit']:4s} "
            f"95% bound {float(r['bound95']):.3g}"
        )
    summary = json.loads((opts.work / "nav" / "summary.json").read_text())
    req = summary["requirement"]
    print(f"  bayes-imu nav --max-position 5: within {req['max_error_m']:g} m for "
          f"{req['longest_outage_s']:g} s")
    for r in summary["rows"]:
        if r["quantity"] == "position":
            top = sorted(r["terms"].items(), key=lambda kv: -kv[1])[:3]
            print(
                f"  position at {r['t_s']:g} s: dominant {r['dominant_sensor']}; largest terms "
                + ", ".join(f"{k} {v:.3g} m" for k, v in top)
            )
    from bayes_imu.drift.nav_bands import navigation_bands
    from bayes_imu.inference.archive import load_fit

    fine = navigation_bands(
        load_fit(opts.work / "gyro_y"),
        load_fit(opts.work / "accel_x"),
        [t / 4 for t in range(4, 1201)],
        calibration_s=60.0,
        rng=0,
    )
    for limit in (1.0, 5.0, 10.0, 100.0):
        print(
            f"  horizontal position within {limit:g} m at 95 % for "
            f"{fine.within('position', limit):g} s "
            "(0.25 s grid)"
        )
    out = ROOT / "docs" / "navigation"
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(opts.work / "nav" / "nav.png", out / "adis16405_nav.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
