"""Held-out validation of calibrated-outage drift bands on real IMU logs (issue: honesty on real \
sensors).

For every real channel (six ADIS16405 logs x 6 axes, the Xsens MTi-G gyro) from
``../shared/data_real/smac_imudata`` (read there, never copied; skipped when absent):

1. fit the first half of the log (``bayes_imu.fit_allan``, default options);
2. predict the 1-sigma error of a calibrated outage (bias = mean of the ``--calibration``
   seconds before the outage, paper Euler integral of rate - bias: attitude for a gyro,
   velocity for an accelerometer) at each horizon, model-averaged;
3. measure it on the held-out second half: the RMS error over non-overlapping
   (calibration + outage) windows;
4. call the point consistent when the observed RMS lies inside the 90% predictive interval
   of an RMS over that many windows: posterior draws of sigma times sqrt(chi2_n / n)
   (the RMS's own sampling error; windows taken as independent).

The check assumes the two halves are alike. Each row also prints the ratio of the halves'
Allan deviations at 82 s and 328 s (first / second): values far from 1 mean the sensor
itself changed (warm-up), which no model fitted to one half can predict for the other.

Prints a table and the fraction of consistent (channel, horizon) points; ``--models selected``
repeats it with the selected model alone. Run: ``python scripts/validate_real.py``
(about 10 minutes on 2 cores); ``--quick`` takes two channels.
"""

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
HORIZONS = (0.1, 1.0, 10.0, 100.0)
RATE = 100.0


def channels():
    """(name, kind, values in SI) for every real channel."""
    import pandas as pd

    for i in range(1, 7):
        path = DATA / f"adis_16405_imu{i}.csv.gz"
        frame = pd.read_csv(path)
        for col in frame.columns:
            scale = np.pi / 180.0 if col.startswith("gyro") else 9.80665
            yield (
                f"adis{i}:{col.rsplit('_', 1)[0]}",
                "gyro" if col.startswith("gyro") else "accel",
                frame[col].to_numpy() * scale,
            )
    frame = pd.read_csv(DATA / "cont_imu1.csv.gz")
    yield "mtig:gyro_x", "gyro", frame.iloc[:, 0].to_numpy()


def observed_rms(y, k, n_cal, dt):
    """RMS calibrated-outage error over non-overlapping windows, and the number of windows."""
    span = n_cal + k
    n_win = y.size // span
    w = y[: n_win * span].reshape(n_win, span)
    bias = w[:, :n_cal].mean(axis=1)
    err = dt * (w[:, n_cal:] - bias[:, None]).sum(axis=1)
    return float(np.sqrt(np.mean(err**2))), n_win


def write_rows(path, rows):
    """Rows (dicts with the same keys) as a CSV file with a header."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", type=float, default=60.0, help="calibration window (s)")
    parser.add_argument("--models", choices=("averaged", "selected"), default="averaged")
    parser.add_argument("--quick", action="store_true", help="two channels only")
    parser.add_argument("--csv", type=Path, help="also write the rows here")
    args = parser.parse_args(argv)
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    from bayes_imu import allan_variance, fit_allan
    from bayes_imu.drift.bands import drift_draws

    dt = 1.0 / RATE
    n_cal = int(round(args.calibration * RATE))
    rows = []
    print(
        f"{'channel':22s} {'model':44s} {'adequate':>8s} {'stationary':>10s} "
        + " ".join(f"{h:>22g}s" for h in HORIZONS)
        + "  adev 1st/2nd half at 82 s, 328 s"
    )
    for j, (name, kind, y) in enumerate(channels()):
        if args.quick and j >= 2:
            break
        start = time.perf_counter()
        half = y.size // 2
        first, second = (
            allan_variance(y[:half], rate_hz=RATE),
            allan_variance(y[half:], rate_hz=RATE),
        )
        ratio = [
            float(
                first.adev[np.argmin(abs(first.tau - t))]
                / second.adev[np.argmin(abs(second.tau - t))]
            )
            for t in (82.0, 328.0)
        ]
        fit = fit_allan(first, rng=0)
        # each channel's own stream (the part-to-part spread of a flagged log, the predictive
        # chi-squared factors): the same numbers on every run, and a channel's numbers depend on its
        # own fit alone
        rng = np.random.default_rng([20261123, j])
        sigma = drift_draws(fit, np.array(HORIZONS), quantity="attitude", bias_start="calibrated",
                            calibration_s=args.calibration, models=args.models, rng=rng)["total"]
        cells = []
        for i, h in enumerate(HORIZONS):
            k = int(round(h * RATE))
            obs, n_win = observed_rms(y[half:], k, n_cal, dt)
            pred = sigma[:, i] * np.sqrt(rng.chisquare(n_win, size=sigma.shape[0]) / n_win)
            lo, hi = np.quantile(pred, [0.05, 0.95])
            ok = bool(lo <= obs <= hi)
            rows.append(
                {
                    "channel": name,
                    "sensor": kind,
                    "horizon_s": h,
                    "observed_rms": obs,
                    "windows": n_win,
                    "q05": lo,
                    "q95": hi,
                    "consistent": ok,
                    "model": "+".join(fit.model.terms),
                    "adequate": fit.adequacy.adequate,
                    "p_value": fit.adequacy.p_value,
                    "widened": fit.widened,
                    "stationary": fit.stationarity.stationary,
                    "stationarity_p": fit.stationarity.p_value,
                    "adev_ratio_82s": ratio[0],
                    "adev_ratio_328s": ratio[1],
                }
            )
            cells.append(f"{obs:9.3g} [{lo:8.3g},{hi:8.3g}]{'' if ok else '*'}")
        print(
            f"{name:22s} {'+'.join(fit.model.terms):44s} {str(fit.adequacy.adequate):>8s} "
            f"{str(fit.stationarity.stationary):>10s} "
            + " ".join(cells)
            + f"  {ratio[0]:.2f} {ratio[1]:.2f} ({time.perf_counter() - start:.0f} s)",
            flush=True,
        )
    ok = np.array([r["consistent"] for r in rows])
    print(
        f"\nconsistent with the 90% band: {ok.sum()} of {ok.size} (channel, horizon) points = "
        f"{ok.mean():.1%}"
    )
    for h in HORIZONS:
        sel = np.array([r["horizon_s"] == h for r in rows])
        print(f"  horizon {h:g} s: {ok[sel].mean():.1%}")
    for kind in ("gyro", "accel"):
        sel = np.array([r["sensor"] == kind for r in rows])
        if sel.any():
            print(f"  {kind}: {ok[sel].mean():.1%}")
    steady = np.array([max(r["adev_ratio_82s"], 1 / r["adev_ratio_82s"]) < 1.25 for r in rows])
    print(
        f"  channels whose halves agree within 25% at 82 s: {ok[steady].mean():.1%} of "
        f"{steady.sum()} points; the others: {ok[~steady].mean():.1%} of {(~steady).sum()}"
    )
    adequate = np.array([r["adequate"] for r in rows[:: len(HORIZONS)]])
    print(
        f"adequate fits (first halves): {adequate.sum()} of {adequate.size}; the others widened "
        "and flagged"
    )
    stationary = np.array([r["stationary"] for r in rows[:: len(HORIZONS)]])
    print(f"first halves flagged non-stationary (their bands include the spread between parts): "
          f"{(~stationary).sum()} of {stationary.size}")
    flagged = np.repeat(~stationary, len(HORIZONS))
    if flagged.any() and (~flagged).any():
        print(
            f"  consistent: {ok[flagged].mean():.1%} of {flagged.sum()} points of flagged "
            f"channels, {ok[~flagged].mean():.1%} of {(~flagged).sum()} of the others"
        )
    if args.csv:
        write_rows(args.csv, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
