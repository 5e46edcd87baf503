"""Noise identification without BLAS products (issue 39: on a busy machine OpenBLAS's threads
made each 2**18-term product of the lag-1 method far slower, most of
allan_variance's time: docs/speed_under_load.md#threads-on-a-busy-machine).

Reference: the lag-1 autocorrelation method (Riley & Greenhall 2004, eqs 2-4) written here with
``math.fsum`` (correctly rounded sums), independent of the package's products.
"""

import math

import numpy as np

from bayes_imu.allan.estimator import _dot, _lag1_alpha


def _alpha_fsum(series, max_differences=2):
    n = len(series)
    t = [i - (n - 1) / 2.0 for i in range(n)]
    mean = math.fsum(series) / n
    z = [v - mean for v in series]
    slope = math.fsum(a * b for a, b in zip(t, z)) / math.fsum(a * a for a in t)
    z = [v - slope * a for v, a in zip(z, t)]
    d = 0
    while True:
        mean = math.fsum(z) / len(z)
        z = [v - mean for v in z]
        denom = math.fsum(v * v for v in z)
        r1 = math.fsum(a * b for a, b in zip(z[:-1], z[1:])) / denom if denom > 0 else 0.0
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= max_differences:
            return int(np.clip(-np.round(2.0 * delta) - 2 * d, -2, 2))
        z = [b - a for a, b in zip(z[:-1], z[1:])]
        d += 1


def test_dot_is_the_correctly_rounded_sum_to_1e_12(rng):
    for size in (1, 7, 1000, 2**18):
        a, b = rng.standard_normal(size), rng.standard_normal(size)
        ref = math.fsum(a * b)
        assert abs(_dot(a, b) - ref) <= 1e-12 * math.fsum(np.abs(a * b))


def test_lag1_alpha_matches_an_fsum_reference_on_power_law_series(rng):
    """White, random-walk and differenced (blue) series of 30-1500 points: the same exponent."""
    for _ in range(60):
        w = rng.standard_normal(int(rng.integers(30, 1500)))
        kind = rng.integers(3)
        series = w if kind == 0 else np.cumsum(w) if kind == 1 else np.diff(w, prepend=0.0)
        assert _lag1_alpha(series, 2) == _alpha_fsum(series.tolist())
