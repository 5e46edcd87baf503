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


def _alpha_allocating(series, max_differences=2):
    """_lag1_alpha as it was before its buffers (issue 39): a new array at every step."""
    t = np.arange(series.size, dtype=float) - (series.size - 1) / 2.0
    z = series - series.mean()
    z = z - (_dot(t, z) / _dot(t, t)) * t
    d = 0
    while True:
        z = z - z.mean()
        denom = _dot(z, z)
        r1 = _dot(z[:-1], z[1:]) / denom if denom > 0 else 0.0
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= max_differences:
            return delta, d
        z = np.diff(z)
        d += 1


def test_buffered_identification_is_the_allocating_one_bit_for_bit(rng, monkeypatch):
    """noise_from_phase_samples computes every size's series in two reused buffers: the same
    delta, bit for bit, as a new array at every step, on power-law phase records whose sizes take
    30 to 2**12 averages (series of different lengths sharing the buffers, differenced zero to two
    times: white, random-walk, integrated random-walk and blue rates); the series handed to
    _lag1_alpha alone is left as it was."""
    from bayes_imu.allan import estimator

    pairs = []
    original = estimator._lag1_delta

    def recording(series, max_differences, *, work=None):
        reference = _alpha_allocating(series.copy(), max_differences)
        got = original(series, max_differences, work=work)
        pairs.append((reference, got))
        return got

    monkeypatch.setattr(estimator, "_lag1_delta", recording)
    differenced = set()
    for kind in range(4):
        w = rng.standard_normal(2**13)
        y = (w, np.cumsum(w), np.cumsum(np.cumsum(w)), np.diff(w, prepend=0.0))[kind]
        x = np.concatenate(([0.0], np.cumsum(y - y.mean())))
        estimator.identify_noise(x, 2 ** np.arange(9))
    assert len(pairs) == 36
    for reference, got in pairs:
        assert got == reference  # delta and d, bit for bit
        differenced.add(got[1])
    assert differenced == {0, 1, 2}
    monkeypatch.undo()
    series = rng.standard_normal(100)
    kept = series.copy()
    _lag1_alpha(series, 2)
    np.testing.assert_array_equal(series, kept)


def test_a_long_record_s_compiled_identification_equals_numpy_s(rng):
    """On a record the JIT kernels sum, identify_noise takes one compiled call for every size: its
    deltas (and differencing counts) equal numpy's steps on the same cluster means to 1e-12 (1e-9
    on an integrated random walk, whose twice-differenced series cancels: there both are about
    2e-11 from the delta of correctly rounded sums, math.fsum, checked when this was written), and
    the exponents are the same, on white, random-walk, integrated random-walk and blue rates, sizes
    with 2**18 averages (the cap) down to fewer than 30 (the previous size's exponent kept)."""
    from bayes_imu.allan import estimator, kernels

    n = kernels.PRECOMPILED_BELOW + 999
    for kind in range(4):
        w = rng.standard_normal(n)
        y = (w, np.cumsum(w), np.cumsum(np.cumsum(w)) * 1e-3, np.diff(w, prepend=0.0))[kind]
        x = kernels.allan_sums(y, [1])[0]
        ms = 2 ** np.arange(int(np.log2(n // 4)) + 1)
        spans = [estimator.identification_span(int(m), n) for m in ms]
        samples = [x[a:b:int(m)] for m, (a, b) in zip(ms, spans)]
        counts = np.array([s.size - 1 for s in samples])
        compiled = kernels.lag1_deltas(x, ms, [a for a, _ in spans], counts, 2)
        assert counts.max() == 2**18 and counts.min() < 30
        for m, series, (delta, d) in zip(ms, samples, compiled):
            if series.size - 1 >= 30:
                ref_delta, ref_d = estimator._lag1_delta(np.diff(series) / int(m), 2)
                assert d == ref_d
                assert abs(delta - ref_delta) <= (1e-9 if kind == 2 else 1e-12)
        np.testing.assert_array_equal(
            estimator.identify_noise(x, ms), estimator.noise_from_phase_samples(samples, ms)
        )
