"""Leave-one-unit-out check of the population fit on the six ADIS16405 logs (component selection).

For each axis of the six ADIS16405 units in ``../shared/data_real/smac_imudata`` (read
there, never copied; skipped when absent) and each held-out unit h:

1. fit the five other units jointly (``bayes_imu.inference.population.fit_population``: common
   structure chosen by their summed evidence, hierarchical posterior, new-unit predictive);
2. predict unit h's calibrated-outage drift (bias = mean of the ``--calibration`` seconds
   before the outage; attitude for a gyro, velocity for an accelerometer) at 0.1-100 s, and
   its Allan deviation at every octave cluster size;
3. check them against unit h's own log: the observed RMS error over non-overlapping
   (calibration + outage) windows must lie in the 90% predictive interval of such an RMS
   (new-unit sigma draws times sqrt(chi2_n / n)); the observed Allan deviation at each tau
   in the 90% new-unit predictive band (model, discrepancy, and the log's own chi-squared
   estimation noise at its EDF).

Contrast: the same drift check with each of the five single-unit fits (model-averaged, as
``bayes-imu fit`` gives) in place of the population: what a bound from one unit on the
bench says about the next unit.

Every fit is cached in ``--cache`` (``bayes_imu.inference.archive`` files), so a second run, here or
on another machine, reuses them; ``--workers`` processes run the fits in parallel. Prints
the table and the fractions of consistent (unit, axis, horizon) points; ``--csv`` writes
the rows, and the population samplers' convergence (R-hat, effective draws) and times (wall and
CPU); the exit status is 1 when any population sampler did not converge. Run:
``python scripts/validate_population.py --workers 2`` (hours on 2 cores without a cache);
``--quick`` takes one axis and 3 units; ``--axes accel_x`` one axis of all six units.
"""

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from functools import lru_cache
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from validate_real import observed_rms, write_rows  # noqa: E402  (one definition of each)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
HORIZONS = (0.1, 1.0, 10.0, 100.0)
RATE = 100.0
AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


@lru_cache(maxsize=None)
def _frame(unit):
    import os

    import pandas as pd

    return pd.read_csv(
        Path(os.environ.get("BAYES_IMU_SMAC", DATA)) / f"adis_16405_imu{unit}.csv.gz"
    )


def values(unit, axis):
    """SI samples (rad/s or m/s^2) of one unit's axis."""
    frame = _frame(unit)
    col = next(c for c in frame.columns if c.startswith(axis))
    scale = np.pi / 180.0 if axis.startswith("gyro") else 9.80665
    return frame[col].to_numpy() * scale


@lru_cache(maxsize=None)
def allan(unit, axis):
    from bayes_imu import allan_variance

    return allan_variance(values(unit, axis), rate_hz=RATE)


def _key(unit, axis, terms):
    return f"imu{unit}_{axis}_{'auto' if terms == 'auto' else '-'.join(terms)}.npz"


def unit_fit(task):
    """The fit of one (unit, axis) with ``terms``, from the cache or computed and cached."""
    from bayes_imu.inference.archive import load_fit, save_fit
    from bayes_imu.inference.fit import fit_allan

    cache, unit, axis, terms = task
    path = Path(cache) / _key(unit, axis, terms)
    if path.exists():
        return load_fit(path)
    seed = 1000 * unit + AXES.index(axis)
    start = time.perf_counter()
    fit = fit_allan(allan(unit, axis), terms=terms, rng=seed)
    save_fit(fit, path.with_suffix(".tmp.npz"))
    path.with_suffix(".tmp.npz").rename(path)
    print(f"  fitted imu{unit} {axis} {terms if terms == 'auto' else '+'.join(terms)} in "
          f"{time.perf_counter() - start:.0f} s", flush=True)
    return fit


def scores(task):
    """Evidences of ``structures`` on one (unit, axis), cached as JSON."""
    from bayes_imu.inference.fit import score_models

    cache, unit, axis, structures = task
    path = Path(cache) / f"imu{unit}_{axis}_scores.json"
    known = json.loads(path.read_text()) if path.exists() else {}
    missing = [s for s in structures if "+".join(s) not in known]
    if missing:
        fit = unit_fit((cache, unit, axis, "auto"))
        for s, c in zip(missing, score_models(allan(unit, axis), missing, widened=fit.widened,
                                              rng=1000 * unit + AXES.index(axis))):
            known["+".join(s)] = [c.log_evidence, c.log_evidence_se]
        path.write_text(json.dumps(known))
    return {s: known["+".join(s)] for s in structures}


def drift_consistent(posterior, y, calibration, rng):
    """Per horizon: (observed RMS, q05, q95, consistent) of the calibrated-outage check."""
    from bayes_imu.drift.bands import drift_draws

    sigma = drift_draws(posterior, np.array(HORIZONS), quantity="attitude", bias_start="calibrated",
                        calibration_s=calibration, max_draws=4000, rng=rng)["total"]
    n_cal, dt = int(round(calibration * RATE)), 1.0 / RATE
    out = []
    for i, h in enumerate(HORIZONS):
        obs, n_win = observed_rms(y, int(round(h * RATE)), n_cal, dt)
        pred = sigma[:, i] * np.sqrt(rng.chisquare(n_win, size=sigma.shape[0]) / n_win)
        lo, hi = np.quantile(pred, [0.05, 0.95])
        out.append((obs, float(lo), float(hi), bool(lo <= obs <= hi)))
    return out


def fold(task):
    """Population of the other units -> held-out unit h: drift and ADEV checks, and the single-unit
    contrast."""
    from bayes_imu.inference.population import fit_population

    cache, units, axis, held, structure, calibration = task
    others = [u for u in units if u != held]
    fits = [unit_fit((cache, u, axis, "auto")) for u in others]
    fits = [
        f if f.model.terms == structure else unit_fit((cache, u, axis, structure))
        for u, f in zip(others, fits)
    ]
    rng = np.random.default_rng(7919 * held + AXES.index(axis))
    wall, cpu = time.perf_counter(), time.process_time()
    pop = fit_population(
        [allan(u, axis) for u in others],
        labels=[f"imu{u}" for u in others],
        terms=structure,
        unit_fits=fits,
        rng=rng,
    )
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    y = values(held, axis)
    target = allan(held, axis)
    avar = pop.new_unit.predictive_avar(target.m, edf=target.edf, n_draws=4000, rng=rng)
    lo, hi = np.quantile(np.sqrt(avar), [0.05, 0.95], axis=0)
    adev_ok = (target.adev >= lo) & (target.adev <= hi)
    drift = drift_consistent(pop.new_unit, y, calibration, rng)
    single = [
        drift_consistent(unit_fit((cache, u, axis, "auto")), y, calibration, rng) for u in others
    ]
    spread = {n: float(np.median(pop.spread[:, i])) for i, n in enumerate(pop.parameter_names)}
    return {
        "axis": axis,
        "held_out": held,
        "structure": "+".join(structure),
        "drift": drift,
        "single_consistent": [
            float(np.mean([s[i][3] for s in single])) for i in range(len(HORIZONS))
        ],
        "adev_consistent": float(adev_ok.mean()),
        "adev_points": int(adev_ok.size),
        "spread": spread,
        "converged": bool(pop.diagnostics["converged"]),
        "rhat_max": pop.diagnostics["rhat_max"],
        "ess_min": pop.diagnostics["ess_hyper_min"],
        "n_par": len(pop.parameter_names),
        "population_s": wall,
        "population_cpu_s": cpu,
    }


def all_units(cache, units, axis, structure):
    """The population of every unit (no held-out one): its time (wall and CPU), R-hat and ESS."""
    from bayes_imu.inference.population import fit_population

    fits = [unit_fit((cache, u, axis, "auto")) for u in units]
    fits = [f if f.model.terms == structure else unit_fit((cache, u, axis, structure))
            for u, f in zip(units, fits)]
    wall, cpu = time.perf_counter(), time.process_time()
    pop = fit_population([allan(u, axis) for u in units], labels=[f"imu{u}" for u in units],
                         terms=structure, unit_fits=fits, rng=AXES.index(axis))
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    d = pop.diagnostics
    print(f"{axis}: population of all {len(units)} units, {len(pop.parameter_names)} parameters "
          f"each: {wall:.1f} s (CPU {cpu:.1f} s), R-hat {d['rhat_max']:.4f}, ESS "
          f"{d['ess_hyper_min']:.0f}, {d['n_steps']} iterations x {d['n_walkers']} chains"
          + ("" if d["converged"] else " NOT CONVERGED"), flush=True)
    return {"axis": axis, "converged": bool(d["converged"]), "population_s": wall,
            "population_cpu_s": cpu}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", type=float, default=60.0, help="calibration window (s)")
    parser.add_argument(
        "--cache", type=Path, default=Path("validate_population_cache"), help="fit cache folder"
    )
    parser.add_argument("--workers", type=int, default=1, help="processes for the fits")
    parser.add_argument("--quick", action="store_true", help="gyro_x of units 1-3 only")
    parser.add_argument(
        "--axes", default=",".join(AXES), help="comma-separated axes, default all six"
    )
    parser.add_argument("--csv", type=Path, help="also write the rows here")
    parser.add_argument(
        "--data", type=Path, default=DATA, help=f"folder of the ADIS16405 logs (default {DATA})"
    )
    args = parser.parse_args(argv)
    if not args.data.exists():
        print(f"skipped: {args.data} not found")
        return 0
    import os

    os.environ["BAYES_IMU_SMAC"] = str(args.data)  # the worker processes read it
    from bayes_imu.inference.selection import CandidateScore, select

    args.cache.mkdir(parents=True, exist_ok=True)
    units = (1, 2, 3) if args.quick else (1, 2, 3, 4, 5, 6)
    axes = ("gyro_x",) if args.quick else tuple(args.axes.split(","))
    cache = str(args.cache)
    pool = ProcessPoolExecutor(args.workers) if args.workers > 1 else None
    run = pool.map if pool else map
    start = time.perf_counter()
    results, rows, whole_units = [], [], []
    for a in axes:  # one axis at a time: a partial run gives whole axes
        print(
            f"[{a}] single-unit fits, evidences, common structures, {len(units)} folds", flush=True
        )
        autos = dict(zip(units, run(unit_fit, [(cache, u, a, "auto") for u in units])))
        structures = []
        for u in units:
            for t in [autos[u].model.terms] + [c.terms for c in autos[u].mixture]:
                if tuple(t) not in structures:
                    structures.append(tuple(t))
        evid = dict(zip(units, run(scores, [(cache, u, a, structures) for u in units])))
        folds = []
        for h in units:
            others = [u for u in units if u != h]
            summed = [
                CandidateScore(
                    s,
                    sum(evid[u][s][0] for u in others),
                    float(np.sqrt(sum(evid[u][s][1] ** 2 for u in others))),
                    np.nan,
                    np.empty(0),
                )
                for s in structures
            ]
            folds.append((cache, units, a, h, structures[select(summed)], args.calibration))
        every = [CandidateScore(s, sum(evid[u][s][0] for u in units),
                                float(np.sqrt(sum(evid[u][s][1] ** 2 for u in units))), np.nan,
                                np.empty(0)) for s in structures]
        whole = structures[select(every)]  # the population of every unit: the speed goal's case
        needed = sorted({(cache, u, a, f[4]) for f in folds for u in units
                         if u != f[3] and autos[u].model.terms != f[4]}
                        | {(cache, u, a, whole) for u in units if autos[u].model.terms != whole})
        list(run(unit_fit, needed))
        whole_units.append(all_units(cache, units, a, whole))
        for r in run(fold, folds):
            results.append(r)
            cells = [
                f"{o:9.3g} [{lo:8.3g},{hi:8.3g}]{'' if ok else '*'}" for o, lo, hi, ok in r["drift"]
            ]
            print(
                f"{r['axis']:8s} {r['held_out']:4d} {r['structure']:40s} "
                + " ".join(cells)
                + f"  adev {r['adev_consistent']:4.0%} of {r['adev_points']}  single-unit "
                + " ".join(f"{v:.0%}" for v in r["single_consistent"])
                + f"  population: {r['n_par']} parameters, {r['population_s']:.1f} s "
                f"(CPU {r['population_cpu_s']:.1f} s), R-hat {r['rhat_max']:.3f}, ESS "
                f"{r['ess_min']:.0f}"
                + ("" if r["converged"] else " NOT CONVERGED"),
                flush=True,
            )
            for (o, lo, hi, ok), h, single in zip(r["drift"], HORIZONS, r["single_consistent"]):
                rows.append(
                    {
                        "axis": r["axis"],
                        "held_out": r["held_out"],
                        "horizon_s": h,
                        "observed_rms": o,
                        "q05": lo,
                        "q95": hi,
                        "consistent": ok,
                        "single_unit_consistent": single,
                        "adev_consistent": r["adev_consistent"],
                        "structure": r["structure"],
                        "spread": json.dumps(r["spread"]),
                        "converged": r["converged"],
                    }
                )
    if pool:
        pool.shutdown()
    ok = np.array([r["consistent"] for r in rows])
    single = np.array([r["single_unit_consistent"] for r in rows])
    adev = np.array([r["adev_consistent"] for r in results])
    print(f"\nnew-unit 90% band consistent with the held-out unit's drift: {ok.sum()} of {ok.size} "
          f"(unit, axis, horizon) points = {ok.mean():.1%}")
    for h in HORIZONS:
        sel = np.array([r["horizon_s"] == h for r in rows])
        print(
            f"  horizon {h:g} s: {ok[sel].mean():.1%} (single-unit bands: {single[sel].mean():.1%})"
        )
    for kind in ("gyro", "accel"):
        sel = np.array([r["axis"].startswith(kind) for r in rows])
        if sel.any():
            print(f"  {kind}: {ok[sel].mean():.1%} (single-unit bands: {single[sel].mean():.1%})")
    print(f"single-unit bands (each of the other units alone) consistent: {single.mean():.1%}")
    print(
        f"held-out Allan deviation inside the new-unit 90% band: {adev.mean():.1%} of cluster sizes"
    )
    for w in whole_units:
        print(f"population of every unit, {w['axis']}: {w['population_s']:.1f} s "
              f"(CPU {w['population_cpu_s']:.1f} s), "
              f"converged: {w['converged']}")
    results = results + whole_units  # every population sampler counts
    converged = sum(r["converged"] for r in results)
    times = np.array([r["population_s"] for r in results])
    cpu = np.array([r["population_cpu_s"] for r in results])
    print(
        f"population samplers converged (R-hat < 1.01, ESS > 400 per hyper-parameter): {converged} "
        f"of {len(results)}; population fits {np.median(times):.1f} s median, {times.max():.1f} s "
        f"at most (CPU {np.median(cpu):.1f} s median, {cpu.max():.1f} s at most)"
    )
    print(f"wall time of this run: {time.perf_counter() - start:.0f} s")
    if args.csv:
        write_rows(args.csv, rows)
    if converged < len(results):
        print(
            f"error: {len(results) - converged} population fit(s) did not converge", file=sys.stderr
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
