"""Benchmark: time to evaluate 1e6 (parameter draw x time) drift points.

Prints a table: quantity, regime, seconds per 1e6 points (best of 5).
Regimes: "mixed" (tau log-uniform 1..1e4 s, t log-spaced 0.01..3600 s at 100 Hz),
"series" (tau 1e6..1e8 s, so dt/tau * k is small: every point in the series branch),
"closed" (tau 0.1..1 s: every point in the closed-form branch).
A last table times ``bayes_imu.drift.bands.drift_bands`` (1e4 posterior draws x 1e3 times,
white + Gauss-Markov + random walk, quantiles included).
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
    bench_bands(rng, t)


def bench_bands(rng, t, n_draws=10_000):
    from bayes_imu.drift.bands import drift_bands
    from bayes_imu.inference.fit import FitResult
    from bayes_imu.noise.avar_forms import NoiseModel

    model = NoiseModel(("white", "gauss_markov", "random_walk"), 0.01)
    samples = np.column_stack([rng.uniform(0.5, 2, n_draws), rng.uniform(1e-4, 1e-3, n_draws),
                               10 ** rng.uniform(0, 4, n_draws), rng.uniform(1e-5, 1e-4, n_draws)])
    fit = FitResult(model, samples, np.zeros(n_draws), None, (), 0, {}, "bench", None)
    print(f"\n{'drift_bands':10s} {'draws':>6s} {'times':>6s} {'seconds':>8s}")
    # warm-up: loads the compiled kernel
    drift_bands(fit, t, quantity="attitude", bias_start="stationary")
    for quantity in ("attitude", "position"):
        start = time.perf_counter()
        drift_bands(fit, t, quantity=quantity, bias_start="stationary")
        print(f"{quantity:10s} {n_draws:6d} {t.size:6d} {time.perf_counter() - start:8.3f}")


if __name__ == "__main__":
    main()
