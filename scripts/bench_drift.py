"""Benchmark: time to evaluate 1e6 (parameter draw x time) drift points.

Prints a table: quantity, regime, seconds per 1e6 points (best of 5).
Regimes: "mixed" (tau log-uniform 1..1e4 s, t log-spaced 0.01..3600 s at 100 Hz),
"series" (tau 1e6..1e8 s, so dt/tau * k is small: every point in the series branch),
"closed" (tau 0.1..1 s: every point in the closed-form branch).
"""

import argparse
import time

import numpy as np

from bayes_imu import drift_sigma


def bench(quantity, taus, t, repeat=5):
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        drift_sigma(
            t, quantity=quantity, dt=0.01, noise_variance=1e-6,
            bias_variance=1e-8, time_constant=taus[:, None], bias_start="stationary",
        )
        best = min(best, time.perf_counter() - start)
    return best


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--points", type=float, default=1e6)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    n_t = 1000
    n_draws = int(args.points) // n_t
    t = np.geomspace(0.01, 3600, n_t)
    regimes = {
        "mixed": 10 ** rng.uniform(0, 4, n_draws),
        "series": 10 ** rng.uniform(6, 8, n_draws),
        "closed": 10 ** rng.uniform(-1, 0, n_draws),
    }
    print(f"{'quantity':10s} {'regime':8s} {'points':>9s} {'seconds':>8s}")
    for quantity in ("attitude", "velocity", "position"):
        for name, taus in regimes.items():
            seconds = bench(quantity, taus, t)
            print(f"{quantity:10s} {name:8s} {n_draws * n_t:9d} {seconds:8.3f}")


if __name__ == "__main__":
    main()
