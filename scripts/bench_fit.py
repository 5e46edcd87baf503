"""End-to-end speed of ``bayes-imu fit`` on a 1e6-sample single-column CSV.

Writes a white + Gauss-Markov log (100 Hz, 1e6 samples, ``bayes_imu.noise.simulate``) to a
temporary folder and times the command as a user runs it (a fresh process: imports,
reading the CSV, Allan variance, model selection over 16 candidates, sampling, writing
summary.json, posterior.nc and both figures). Prints one row per run and the stages of
the last run (from the Python API, same process).

    python scripts/bench_fit.py [--runs 3] [--samples 1000000]
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--samples", type=int, default=1_000_000)
    args = parser.parse_args(argv)
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    truth = {"noise_variance": 0.25, "bias_variance": 1e-4, "time_constant": 100.0}
    y = simulate_log(NoiseModel(("white", "gauss_markov"), 0.01), truth, args.samples, rng=1)
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "gyro.csv"
        np.savetxt(log, y, fmt="%.9g", header="gyro_x_dps", comments="")
        print(f"{'run':>3s} {'samples':>9s} {'wall_s':>7s}  model")
        for run in range(args.runs):
            out = Path(tmp) / f"out{run}"
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "bayes_imu.cli.main", "fit", str(log), "--column", "gyro_x_dps",
                                   "--rate", "100", "--out", str(out), "--seed", str(run)],
                                  capture_output=True, text=True, check=True)
            wall = time.perf_counter() - start
            print(f"{run:3d} {args.samples:9d} {wall:7.2f}  {proc.stdout.splitlines()[0]}")
        stages(log)


def stages(log):
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.io.readers import read_log

    t0 = time.perf_counter()
    values = read_log(log, column="gyro_x_dps").values
    t1 = time.perf_counter()
    allan = allan_variance(values, rate_hz=100.0)
    t2 = time.perf_counter()
    result = fit_allan(allan, rng=0)
    t3 = time.perf_counter()
    print(f"\nstages (in-process, warm): read {t1 - t0:.2f} s, Allan variance {t2 - t1:.2f} s, "
          f"selection + sampling {t3 - t2:.2f} s ({result.diagnostics['n_steps']} steps x {result.diagnostics['n_walkers']} walkers)")


if __name__ == "__main__":
    main()
