"""Every single-unit fit of the shared real logs: wall time and whether the sampler converged.

Issue 39 asks every single-unit fit of the shared real logs to converge (R-hat < 1.01, bulk ESS >=
400) in under 15 s on an idle machine. This script fits each column of the six ADIS16405 logs
(three gyro axes in deg/s, three accelerometer axes in g; 1e6 samples at 100 Hz) and the Xsens
MTi-G gyro log (5e5 samples, rad/s), read from ``../shared/data_real/smac_imudata`` in place
(CC BY-NC-SA 4.0: never copied; the script exits cleanly when absent), one after another in
this process, as ``bayes-imu fit`` does (:func:`bayes_imu.allan.pipeline.allan_from_source`, then
:func:`bayes_imu.inference.fit.fit_allan` with model selection and seed 0). It prints one row per
fit (read + Allan variance seconds, fit seconds, sampler steps, autocorrelation time, R-hat and
bulk ESS over walkers, the split R-hat and the ESS of the walkers' mean (``rhat_m``,
``ess_m``), whether the ensemble was tempered, converged, the selected model) and the totals.
Imports and outputs are not timed (a fresh ``bayes-imu fit`` adds about 1 s of each:
``scripts/bench_fit.py``).

    python scripts/bench_real_fits.py [--data DIR] [--units 1,2,...] [--columns gyro_x_dps,...]
        [--seed 0] [--no-xsens]
"""

import argparse
import sys
import time
import warnings
from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
ADIS_COLUMNS = ("gyro_x_dps", "gyro_y_dps", "gyro_z_dps", "accel_x_g", "accel_y_g", "accel_z_g")
GOAL_S = 15.0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=SHARED)
    parser.add_argument("--units", default="1,2,3,4,5,6")
    parser.add_argument("--columns", default=",".join(ADIS_COLUMNS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-xsens", action="store_true")
    args = parser.parse_args(argv)
    logs = [(args.data / f"adis_16405_imu{int(u)}.csv.gz", c)
            for u in args.units.split(",") for c in args.columns.split(",")]
    if not args.no_xsens:
        logs.append((args.data / "cont_imu1.csv.gz", "gyro_x_rad_s"))
    missing = sorted({str(p) for p, _ in logs if not p.exists()})
    if missing:
        print(f"shared real logs not found ({', '.join(missing)}): nothing to do")
        return 0

    from bayes_imu.allan.pipeline import LogSource, allan_from_source
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.fit import fit_allan

    print(f"{'log':>24s} {'column':>13s} {'read_s':>6s} {'fit_s':>6s} {'steps':>6s} {'tau':>6s} "
          f"{'rhat':>6s} {'ess':>6s} {'rhat_m':>6s} {'ess_m':>6s} {'temp':>4s} {'conv':>5s}  model")
    rows = []
    for path, column in logs:
        start = time.perf_counter()
        read = allan_from_source(LogSource(log=path, column=column, rate=100.0))
        read_s = time.perf_counter() - start
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            result = fit_allan(read.results[0], rng=args.seed)
        fit_s = time.perf_counter() - start
        d = result.diagnostics
        rows.append((fit_s, bool(d["converged"]), d["rhat_mean_max"] < 1.01, bool(d["tempered"])))
        print(f"{path.name:>24s} {column:>13s} {read_s:6.2f} {fit_s:6.2f} {d['n_steps']:6d} "
              f"{d['autocorr_time']:6.0f} {d['rhat_max']:6.3f} {d['ess_bulk_min']:6.0f} "
              f"{d['rhat_mean_max']:6.3f} {d['ess_mean_min']:6.0f} "
              f"{'yes' if d['tempered'] else 'no':>4s} {str(d['converged']):>5s}  "
              f"{' + '.join(result.model.terms)}", flush=True)
    times = sorted(r[0] for r in rows)
    met = sum(1 for t, c, _, _ in rows if c and t < GOAL_S)
    print(f"\n{len(rows)} fits: {sum(r[1] for r in rows)} converged, {met} converged in under "
          f"{GOAL_S:g} s (issue 39's goal); fit time median {times[len(times) // 2]:.1f} s, "
          f"longest {times[-1]:.1f} s, total {sum(times):.0f} s; {sum(r[3] for r in rows)} "
          f"tempered; the walkers' mean's split R-hat below 1.01 in {sum(r[2] for r in rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
