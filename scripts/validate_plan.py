"""Check ``bayes-imu plan`` (Fisher-information prediction) against simulate-and-fit.

A gyro with white noise and a Gauss-Markov bias (10 Hz; N = 1e-3 rad/s/sqrt(Hz), sigma_b =
1e-3 rad/s, T = 60 s, a bias bump clearly above the white floor):

1. a 10-minute pilot log is simulated and fitted (its model's terms fixed), and
   :func:`bayes_imu.drift.plan.plan_from_fit` predicts, at the pilot's posterior medians, the
   90% interval of each parameter and of the calibrated attitude drift at 10 s and 100 s for
   records of 1 h and 4 h (``--lengths``);
2. ``--reps`` logs of each length are simulated from the true parameters and fitted the same
   way; each fit's 90% interval width ``ln(q95 / q05)`` is measured from its posterior draws
   (drift: :func:`bayes_imu.drift.drift_bands` at the same horizons, the model's band: the
   plan predicts the posterior's spread, not the widening of a band to contain the drift the
   record itself measured, ``honest=False``);
3. the table compares the predicted log-width with the replicates' mean (ratio predicted /
   fitted, and the replicates' standard error).

Prints the table; ``--csv`` writes its rows, ``--figure`` the first pilot's plan.png.
``--pilots`` repeats step 1 with other pilot
seeds (the spread of a plan made from different 10-minute pilots: how many of them predict
within 25%). Run (about a minute on 2
cores): ``nice -n 10 python scripts/validate_plan.py --reps 16 --pilots 10
--csv docs/validation/plan.csv
--figure docs/validation/plan.png``;
``--quick``: two replicates of 1 h.
"""

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayes_imu.drift import drift_bands  # noqa: E402
from bayes_imu.drift.plan import Z90, plan_from_fit  # noqa: E402
from bayes_imu.inference.fit import fit  # noqa: E402
from bayes_imu.noise import NoiseModel  # noqa: E402
from bayes_imu.noise.simulate import simulate_log  # noqa: E402

DT = 0.1
TERMS = ("white", "gauss_markov")
TRUTH = {"noise_variance": 1e-6 / DT, "bias_variance": 1e-6, "time_constant": 60.0}
HORIZONS = (10.0, 100.0)
PILOT_S = 600.0


def fitted(length_s, rng):
    model = NoiseModel(TERMS, DT)
    y = simulate_log(model, TRUTH, int(round(length_s / DT)), rng=rng)
    return fit(y, rate_hz=1.0 / DT, terms=TERMS, rng=rng)


def log_widths(result):
    """Measured ln(q95/q05) of each parameter, then of the drift at each horizon."""
    out = [
        float(np.log(np.quantile(result.draws(n), 0.95) / np.quantile(result.draws(n), 0.05)))
        for n in result.model.parameter_names
    ]
    bands = drift_bands(
        result,
        np.array(HORIZONS),
        quantity="attitude",
        bias_start="calibrated",
        quantiles=(0.05, 0.95),
        models="selected",
        honest=False,  # the model's band, what the plan predicts (not widened to the record's own)
    )
    out += [float(v) for v in np.log(bands.total[1] / bands.total[0])]
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=8, help="simulated logs per length (default 8)")
    parser.add_argument(
        "--lengths", default="3600,14400", help="record lengths in s (default 3600,14400)"
    )
    parser.add_argument("--pilots", type=int, default=1, help="pilot seeds (default 1)")
    parser.add_argument("--seed", type=int, default=2026, help="base seed (default 2026)")
    parser.add_argument("--csv", type=Path, help="write the rows here")
    parser.add_argument(
        "--figure", type=Path, help="write the first pilot's plan (10 min to 48 h) as a PNG here"
    )
    parser.add_argument("--quick", action="store_true", help="two replicates of 1 h")
    args = parser.parse_args(argv)
    lengths = [3600.0] if args.quick else [float(v) for v in args.lengths.split(",")]
    reps = 2 if args.quick else args.reps
    start = time.time()
    plans = []
    for p in range(args.pilots):
        pilot = fitted(PILOT_S, np.random.default_rng([args.seed, 0, p]))
        plans.append(
            plan_from_fit(pilot, lengths_s=lengths, horizons_s=HORIZONS, quantity="attitude")
        )
        if p == 0 and args.figure:
            from bayes_imu.report.planning import plot_plan

            plot_plan(
                [("gyro", plan_from_fit(pilot, horizons_s=HORIZONS, quantity="attitude"))],
                args.figure,
                pilot_s=PILOT_S,
                title="Plan from a 10-minute pilot (white + Gauss-Markov, 10 Hz)",
            )
    names = list(plans[0].names) + [f"attitude drift at {t:g} s" for t in HORIZONS]
    rows = []
    for i, length in enumerate(lengths):
        measured = np.array(
            [
                log_widths(fitted(length, np.random.default_rng([args.seed, 1, i, r])))
                for r in range(reps)
            ]
        )
        mean, se = measured.mean(axis=0), measured.std(axis=0, ddof=1) / np.sqrt(reps)
        for j, name in enumerate(names):
            predicted = [
                2
                * Z90
                * (pl.log_sd[i, j] if j < len(pl.names) else pl.drift_log_sd[i, j - len(pl.names)])
                for pl in plans
            ]
            rows.append(
                {
                    "length_s": length,
                    "what": name,
                    "predicted": predicted[0],
                    "predicted_pilots_min": min(predicted),
                    "predicted_pilots_max": max(predicted),
                    "fitted_mean": mean[j],
                    "fitted_se": se[j],
                    "ratio": predicted[0] / mean[j],
                    "reps": reps,
                    "pilots_within_25pct": sum(abs(v / mean[j] - 1) <= 0.25 for v in predicted),
                    "pilots": len(predicted),
                }
            )
    print(
        f"{'length':>7} {'what':30s} {'predicted':>9} {'fitted':>15} {'ratio':>6} "
        f"{'pilots within 25%':>18}"
        "  (ln(q95/q05) of the 90% interval; predicted: the first pilot's)"
    )
    for row in rows:
        print(
            f"{row['length_s'] / 3600:6.2g}h {row['what']:30s} {row['predicted']:9.4f} "
            f"{row['fitted_mean']:8.4f} +-{row['fitted_se']:.4f} {row['ratio']:6.3f} "
            f"{row['pilots_within_25pct']:>11} of {row['pilots']}"
        )
    worst = max(abs(r["ratio"] - 1) for r in rows)
    print(
        f"largest |ratio - 1|: {worst:.3f}; {reps} replicates per length, {args.pilots} pilot(s); "
        f"{time.time() - start:.0f} s (taken under load)"
    )
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(
                {k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()} for r in rows
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
