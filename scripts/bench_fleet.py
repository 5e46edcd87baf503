"""Fleet throughput: ``bayes-imu fit-batch`` serial against a Dask LocalCluster.

Writes ``--logs`` simulated gyro logs (white + Gauss-Markov, ``--samples`` each, 100 Hz,
CSV) into a temporary folder, fits them all with model selection, once ``--serial`` (one
process) and once on a LocalCluster with ``--workers`` single-threaded processes, and
prints logs per minute, samples per second and the speed-up; it also checks that every
log's posterior summary is identical between the two runs.

    python scripts/bench_fleet.py [--logs 12] [--samples 100000] [--workers 2]
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--logs", type=int, default=12)
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    from bayes_imu import NoiseModel, simulate_log
    from bayes_imu.cli.main import main as cli

    rng = np.random.default_rng(9)
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        paths = []
        for k in range(args.logs):
            truth = {"noise_variance": 0.25 * 10 ** rng.uniform(-0.3, 0.3), "bias_variance": 1e-3,
                     "time_constant": 30.0}
            path = tmp / f"unit{k:03d}.csv"
            np.savetxt(
                path,
                simulate_log(model, truth, args.samples, rng=rng),
                fmt="%.8g",
                header="gx",
                comments="",
            )
            paths.append(str(path))
        common = ["--column", "gx", "--rate", "100", "--units", "deg/s", "--seed", "1", "--quiet"]
        runs = {}
        for mode, extra in (
            ("serial", ["--serial"]),
            (f"LocalCluster x{args.workers}", ["--workers", str(args.workers)]),
        ):
            out = tmp / mode.split()[0]
            cli(["fit-batch", *paths, *common, *extra, "--out", str(out)])
            runs[mode] = (out, json.loads((out / "batch.json").read_text()))
        print(
            f"{args.logs} logs of {args.samples} samples (white + Gauss-Markov, model selection)\n"
        )
        print(f"{'mode':18s} {'wall_s':>7s} {'logs/min':>9s} {'samples/s':>10s} {'failed':>6s}")
        for mode, (_, batch) in runs.items():
            print(
                f"{mode:18s} {batch['seconds']:7.1f} {batch['logs_per_minute']:9.1f} "
                f"{batch['samples_per_second']:10.3g} {batch['n_failed']:6d}"
            )
        (serial_out, serial), (cluster_out, cluster) = runs.values()
        same = all(
            json.loads((serial_out / r["name"] / "summary.json").read_text())["parameters"]
            == json.loads((cluster_out / r["name"] / "summary.json").read_text())["parameters"]
            for r in serial["logs"]
        )
        print(
            f"\nspeed-up {serial['seconds'] / cluster['seconds']:.2f}x; posterior summaries "
            f"identical: {same}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
