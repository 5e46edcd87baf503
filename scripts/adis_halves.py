"""Angle random walk of the ADIS16405 gyros, first half against second half (issue 35).

Fits each half of the x and y gyro logs of the six ADIS16405 units (``../shared/data_real``,
read there, never copied; 500 000 samples at 100 Hz per half, in rad/s) with the defaults and
compares the halves' angle random walk (``noise_density``, u/sqrt(Hz)) two ways: the interval of
"this record" alone (``summary.json`` ``parameters_this_record``) and the interval a user copies,
with the repeatability between the record's parts (``parameters``, and the same draws in
``datasheet`` and the Kalibr export; :mod:`bayes_imu.inference.repeatability`); then the IEEE
reading of the Allan deviation at 1 s (``allan_datasheet``), widened likewise. For each pair:
``z = (m1 - m2) / sqrt(s1^2 + s2^2)`` with ``s = (q95 - q05) / 3.29`` (normal 90% width) and
whether the two 90% intervals overlap. Consistent intervals: ``sum z^2`` within its 99%
chi-square quantile (12 degrees of freedom: 26.2; per axis, 6: 16.8) and overlap on at least 9
of 12 pairs.

Run: ``nice -n 10 python scripts/adis_halves.py [--cache DIR]`` (24 fits; ``--cache`` keeps each
half's ``fit.npz`` so that a rerun reads them).
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
RATE = 100.0
PAIRS = [(i, axis) for i in range(1, 7) for axis in ("x", "y")]


def half_fits(cache=None, data=DATA):
    """``{(unit, axis): (first FitResult, second FitResult)}``."""
    import pandas as pd

    from bayes_imu import allan_variance, fit_allan
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.archive import load_fit, save_fit

    out = {}
    for unit in range(1, 7):
        frame = None
        for axis in ("x", "y"):
            fits = []
            for part in (0, 1):
                path = None if cache is None else cache / f"adis{unit}_{axis}_{part}.npz"
                if path is not None and path.exists():
                    fits.append(load_fit(path))
                    continue
                if frame is None:
                    frame = pd.read_csv(data / f"adis_16405_imu{unit}.csv.gz")
                y = frame[f"gyro_{axis}_dps"].to_numpy() * np.pi / 180.0
                half = y.size // 2
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ConvergenceWarning)
                    fit = fit_allan(
                        allan_variance(y[half * part : half * (part + 1)], rate_hz=RATE), rng=0
                    )
                if path is not None:
                    save_fit(fit, path)
                fits.append(fit)
            out[(unit, axis)] = tuple(fits)
    return out


def table(fits, block, name="noise_density"):
    """Rows, ``{axis: sum z^2}`` and overlaps of one summary block (``parameters`` or
    ``parameters_this_record``)."""
    rows, z2, overlaps = [], {"x": 0.0, "y": 0.0}, 0
    for (unit, axis), pair in fits.items():
        p = [f.summary(unit="rad/s")[block][name] for f in pair]
        s = [(e["q95"] - e["q05"]) / 3.29 for e in p]
        z = (p[0]["median"] - p[1]["median"]) / np.hypot(*s)
        over = p[0]["q05"] <= p[1]["q95"] and p[1]["q05"] <= p[0]["q95"]
        z2[axis] += z * z
        overlaps += over
        rows.append(
            f"| adis{unit} gyro {axis} | {p[0]['median']:.4e} [{p[0]['q05']:.4e}, "
            f"{p[0]['q95']:.4e}] | {p[1]['median']:.4e} [{p[1]['q05']:.4e}, {p[1]['q95']:.4e}] | "
            f"{100 * (p[0]['median'] / p[1]['median'] - 1):+.2f}% | {z:+.2f} | "
            f"{'yes' if over else 'no'} |"
        )
    return rows, z2, overlaps


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--data", type=Path, default=DATA, help="the smac_imudata folder")
    args = parser.parse_args(argv)
    if not args.data.exists():
        print(f"skipped: {args.data} not found")
        return 0
    from scipy import stats

    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
    fits = half_fits(args.cache, args.data)
    limit = stats.chi2.ppf(0.99, len(fits))
    for block, name, title in (
            ("parameters_this_record", "noise_density",
             "this record alone (parameters_this_record, rad/s/sqrt(Hz))"),
            ("parameters", "noise_density",
             "with repeatability (parameters, datasheet; rad/s/sqrt(Hz))"),
            ("allan_datasheet", "angle_random_walk",
             "IEEE reading at 1 s, with repeatability (deg/sqrt(h))")):
        rows, per_axis, overlaps = table(fits, block, name)
        z2 = sum(per_axis.values())
        print(f"\n### {name}, 90% intervals: {title}\n")
        print(
            "| channel | first half | second half | difference | z | overlap "
            "|\n|---|---|---|---|---|---|"
        )
        print("\n".join(rows))
        print(
            f"\nsum z^2 = {z2:.1f} on {len(fits)} pairs (99% chi-square quantile {limit:.1f}: "
            f"{'within' if z2 <= limit else 'NOT within'}); intervals overlap on {overlaps} of "
            f"{len(fits)}"
        )
        axis_limit = stats.chi2.ppf(0.99, len(fits) // 2)
        print("per axis: " + "; ".join(f"gyro {a}: {v:.1f}" for a, v in per_axis.items())
              + f" (99% quantile on {len(fits) // 2}: {axis_limit:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
