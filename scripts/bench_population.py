"""Simulation study of the population fit: coverage of the unit-to-unit spread and of a new unit's \
drift.

Scenes: a population of units of one sensor model, white noise + Gauss-Markov bias at
100 Hz (medians: white 1e-5 (rad/s)^2 per sample, bias variance 4e-9 (rad/s)^2, time
constant 30 s), each unit's ln parameters drawn with a true spread ``s`` (0.1 = 10%, 0.3 =
30% between units) for 3, 5 and 8 units. For each replicate:

1. draw the units and simulate a ``--samples`` log of each; fit each alone
   (``terms`` fixed to white + gauss_markov, to keep the study's cost down; structure
   selection is tested separately) and jointly (``fit_population``);
2. *spread*: is the true ``s`` of each parameter inside the 90% interval of its posterior?
3. *new unit*: draw a fresh unit from the true population; is its exact 1-sigma
   calibrated-outage attitude drift (60 s calibration) at 1, 10, 100 and 1000 s inside
   the new-unit 90% band? The same question for the single-unit band of unit 1 (contrast);
4. *overshrinkage*: the median posterior spread over the true one (well below 1 would
   mean the pooled bands are too narrow).

Prints one row per (spread, units) cell: coverage of the spread (all parameters) and of the
new unit's drift (all horizons) with its binomial standard error, the single-unit band's
coverage, and the median posterior/true spread ratio. Run:
``python scripts/bench_population.py --reps 40 --workers 16`` (about 10 minutes on 16
cores; hours on 2); ``--quick`` runs one replicate of two cells.
"""

import argparse
from pathlib import Path
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from validate_real import write_rows  # noqa: E402

TERMS = ("white", "gauss_markov")
MEDIANS = {"noise_variance": 1e-5, "bias_variance": 4e-9, "time_constant": 30.0}
HORIZONS = (1.0, 10.0, 100.0, 1000.0)
RATE = 100.0


def replicate(task):
    from bayes_imu import NoiseModel, allan_variance, fit_allan, simulate_log
    from bayes_imu.drift.bands import drift_draws
    from bayes_imu.inference.population import UnitPosterior, fit_population

    spread, n_units, rep, n_samples = task
    rng = np.random.default_rng([int(spread * 1000), n_units, rep])
    model = NoiseModel(TERMS, 1.0 / RATE)
    names = model.parameter_names
    mu = np.log([MEDIANS[n] for n in names])
    allans, fits = [], []
    for _ in range(n_units):
        theta = np.exp(mu + spread * rng.standard_normal(mu.size))
        y = simulate_log(model, dict(zip(names, theta)), n_samples, rng=rng)
        allans.append(allan_variance(y, rate_hz=RATE))
        fits.append(fit_allan(allans[-1], terms=TERMS, rng=rng))
    pop = fit_population(allans, terms=TERMS, unit_fits=fits, rng=rng)
    lo, hi = np.quantile(pop.spread, [0.05, 0.95], axis=0)
    spread_in = (lo <= spread) & (spread <= hi)
    ratio = np.median(pop.spread, axis=0) / spread
    new = np.exp(mu + spread * rng.standard_normal(mu.size))
    truth = drift_draws(
        UnitPosterior(model, new[None, :], np.inf),
        np.array(HORIZONS),
        quantity="attitude",
        bias_start="calibrated",
        calibration_s=60.0,
    )["total"][0]

    def covered(posterior):
        d = drift_draws(posterior, np.array(HORIZONS), quantity="attitude", bias_start="calibrated",
                        calibration_s=60.0, max_draws=4000, rng=rng)["total"]
        q05, q95 = np.quantile(d, [0.05, 0.95], axis=0)
        return (q05 <= truth) & (truth <= q95)

    return {
        "spread": spread,
        "units": n_units,
        "rep": rep,
        "spread_in": spread_in.tolist(),
        "ratio": ratio.tolist(),
        "new_in": covered(pop.new_unit).tolist(),
        "single_in": covered(fits[0]).tolist(),
        "converged": bool(pop.diagnostics["converged"]),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=40, help="replicates per cell")
    parser.add_argument(
        "--samples", type=int, default=200_000, help="samples per unit log (100 Hz)"
    )
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--quick", action="store_true", help="one replicate of two cells, short logs"
    )
    parser.add_argument("--csv", help="also write one row per replicate here")
    args = parser.parse_args(argv)
    cells = [(0.1, 3), (0.3, 3)] if args.quick else [(s, u) for s in (0.1, 0.3) for u in (3, 5, 8)]
    reps = 1 if args.quick else args.reps
    samples = 50_000 if args.quick else args.samples
    tasks = [(s, u, r, samples) for s, u in cells for r in range(reps)]
    start = time.perf_counter()
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            results = list(pool.map(replicate, tasks))
    else:
        results = [replicate(t) for t in tasks]
    print(
        f"{'spread':>6s} {'units':>5s} {'reps':>4s} {'spread cov.':>14s} "
        f"{'new-unit drift cov.':>20s} {'single-unit cov.':>17s} {'post/true spread':>16s}"
    )
    rows = []
    for s, u in cells:
        rs = [r for r in results if r["spread"] == s and r["units"] == u]
        sp = np.array([r["spread_in"] for r in rs], float)
        nu = np.array([r["new_in"] for r in rs], float)
        si = np.array([r["single_in"] for r in rs], float)
        ratio = np.median([r["ratio"] for r in rs])
        se = np.sqrt(0.9 * 0.1 / len(rs))  # per-horizon binomial SE at 90%, replicates independent
        print(f"{s:6.1f} {u:5d} {len(rs):4d} {sp.mean():8.2f} +-{np.sqrt(0.09 / sp.size):.2f} "
              f"{nu.mean():13.2f} +-{se:.2f} {si.mean():17.2f} {ratio:16.2f}")
        rows.append(
            {
                "spread": s,
                "units": u,
                "reps": len(rs),
                "spread_coverage": sp.mean(),
                "new_unit_coverage": nu.mean(),
                "new_unit_by_horizon": nu.mean(axis=0).round(3).tolist(),
                "single_unit_coverage": si.mean(),
                "median_spread_ratio": ratio,
                "converged": sum(r["converged"] for r in rs),
            }
        )
    print(f"new-unit coverage by horizon {list(HORIZONS)} s: " + "; ".join(
        f"s={r['spread']:g} U={r['units']}: {r['new_unit_by_horizon']}" for r in rows))
    print(f"{len(tasks)} replicates in {time.perf_counter() - start:.0f} s")
    if args.csv:
        write_rows(args.csv, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
