"""Tests of bayes_imu.allan.estimator against independent computations and published references.

References (provenance in ../shared/data_real/*/SOURCE.md and REFERENCE_VALUES.md):
* NBS14 1000-point set: NIST SP1065 p.108 / Stable32 OADEV at tau = 1, 10, 100 s.
* Stable32 1.53/1.60 result tables from the allantools test suite (PHASE.DAT octave and
  all-tau, pink frequency, Keysight TIC), printed to 5 significant digits.
* SMAC-Group/wv Haar wavelet variance of adis_16405_imu1: OAVAR(2^(j-1)) = 2 WV_j.
"""

import math

import numpy as np
import pytest
from conftest import shared_file
from hypothesis import given, settings
from hypothesis import strategies as st

from bayes_imu import InputError
from bayes_imu.allan.estimator import allan_variance, cluster_sizes, greenhall_edf, identify_noise
from bayes_imu.allan.kernels import phase_from_rate


def direct_oavar(y, m):
    """Independent definition: mean over i of (ybar_{i+m} - ybar_i)**2 / 2, window means by fsum."""
    y = [float(v) for v in y]
    means = [math.fsum(y[i : i + m]) / m for i in range(len(y) - m + 1)]
    diffs = [(means[i + m] - means[i]) ** 2 for i in range(len(means) - m)]
    return math.fsum(diffs) / (2 * len(diffs))


def stable32_table(*parts):
    with open(shared_file(*parts), encoding="utf-8") as handle:
        rows = [line.split() for line in handle if line.strip() and not line.startswith("#")]
    return np.array([[float(v) for v in row] for row in rows])


def printed_units(value, reference):
    """|value - reference| in units of the 5th significant digit of the printed reference."""
    unit = 10.0 ** (np.floor(np.log10(np.abs(reference))) - 4)
    return np.abs(value - reference) / unit


@pytest.mark.parametrize("m", [1, 2, 3, 7, 50, 333])
def test_matches_direct_definition(rng, m):
    y = rng.standard_normal(2000) * 0.3 + np.cumsum(rng.standard_normal(2000)) * 0.01 + 5.0
    result = allan_variance(y, rate_hz=10.0, m=[m], alpha=0)
    assert result.avar[0] == pytest.approx(direct_oavar(y, m), rel=1e-10)
    assert result.tau[0] == m / 10.0
    assert result.n_terms[0] == 2000 + 1 - 2 * m


def test_nbs14_published_values():
    y = np.loadtxt(shared_file("nbs14", "nbs14_1000point_frequency.txt"))
    result = allan_variance(y, rate_hz=1.0, m=[1, 10, 100], alpha=0)
    np.testing.assert_allclose(result.adev, [2.922319e-01, 9.159953e-02, 3.241343e-02], rtol=5e-7)


def test_phase_dat_all_tau_sigmas_to_printed_precision():
    x = np.loadtxt(shared_file("allantools", "phasedat", "PHASE.DAT"))
    table = stable32_table("allantools", "phasedat", "phase_dat_oadev.txt")
    result = allan_variance(np.diff(x), rate_hz=1.0, m=table[:, 0].astype(int), alpha=0)
    np.testing.assert_array_equal(result.n_terms, table[:, 2])
    assert np.all(printed_units(result.adev, table[:, 5]) <= 0.5 + 1e-6)


@pytest.mark.parametrize(
    "parts, phase",
    [
        (
            ("allantools", "phasedat", "phase_dat_oadev_octave.txt"),
            ("allantools", "phasedat", "PHASE.DAT"),
        ),
        (
            ("allantools", "keysight53230A_tic", "tic_oadev.txt"),
            ("allantools", "keysight53230A_tic", "tic_phase.txt"),
        ),
        (("allantools", "pink_frequency", "s32_oadev_octave.txt"), None),
    ],
)
def test_stable32_octave_tables_with_intervals(parts, phase):
    """Sigma to the printed digit. Intervals with ``interval="stable32"``: to the printed
    digit (<= 1 unit of the 5th digit) where Stable32 uses its large-EDF chi-squared
    approximation (EDF > 100), except alpha = 1, whose EDF comes from Greenhall's Tables
    2-3 printed to 3-4 digits (<= 3 units); for EDF <= 100 Stable32's EDF differs from the
    published algorithm by up to 0.3% (solved from both bounds), giving <= 10 units. The
    exact (scipy) interval differs from Stable32's by at most 1e-3 relative.
    """
    table = stable32_table(*parts)
    if phase is None:
        y = np.loadtxt(shared_file("allantools", "pink_frequency", "pink_frequency.txt"))
    else:
        y = np.diff(np.loadtxt(shared_file(*phase)))
    kwargs = dict(rate_hz=1.0, m=table[:, 0].astype(int), alpha=table[:, 3].astype(int))
    s32 = allan_variance(y, interval="stable32", **kwargs)
    exact = allan_variance(y, **kwargs)
    assert np.all(printed_units(s32.adev, table[:, 5]) <= 0.5 + 1e-6)
    large = s32.edf > 100
    flicker_phase = s32.alpha == 1
    for bound, column in ((s32.adev_low, 4), (s32.adev_high, 6)):
        units = printed_units(bound, table[:, column])
        assert np.all(units[large & ~flicker_phase] <= 1.0)
        assert np.all(units[large & flicker_phase] <= 3.0)
        assert np.all(units[~large] <= 10.0)
    np.testing.assert_allclose(exact.adev_low, table[:, 4], rtol=1e-3)
    np.testing.assert_allclose(exact.adev_high, table[:, 6], rtol=1e-3)


def test_greenhall_edf_matches_edf_implied_by_stable32():
    """EDFs implied by the PHASE.DAT ADEV/OADEV m = 1 row and the octave table (REFERENCE_VALUES.md)
    agree within 0.3% where Stable32 iterates its chi-squared exactly (EDF <= 100)."""
    implied = {16: 86.52, 32: 43.42, 64: 21.24, 128: 9.55}
    edf = greenhall_edf([0] * 4, list(implied), 1001)
    np.testing.assert_allclose(edf, list(implied.values()), rtol=3e-3)


def test_wavelet_variance_reference_adis_imu1():
    """External exact reference: SMAC wv Haar MODWT of adis_16405_imu1, all six channels."""
    import gzip

    import csv

    with open(shared_file("smac_wv", "adis_wv.csv"), encoding="utf-8") as handle:
        records = list(csv.DictReader(line for line in handle if not line.startswith("#")))
    with gzip.open(shared_file("smac_imudata", "adis_16405_imu1.csv.gz"), "rt") as handle:
        data = np.loadtxt(handle, delimiter=",", skiprows=1)
    channels = ["Gyro. X", "Gyro. Y", "Gyro. Z", "Accel. X", "Accel. Y", "Accel. Z"]
    for column, channel in enumerate(channels):
        rows = [r for r in records if r["channel"] == channel]
        ms = np.array([2 ** (int(r["level_j"]) - 1) for r in rows])
        wvar = np.array([float(r["wvar"]) for r in rows])
        result = allan_variance(data[:, column], rate_hz=100.0, m=ms, alpha=0)
        np.testing.assert_allclose(result.avar, 2 * wvar, rtol=1e-8, err_msg=channel)


def test_large_offset_tiny_noise_is_exact(rng):
    """Gravity on an accelerometer axis: offset 9.81 m/s^2, noise ~1e-5, 2e6 samples.

    Data are integers times 2**-24 (exact in float64), so the reference is computed in exact
    integer arithmetic (int64 running sums), then converted once.
    """
    lsb = 2.0**-24
    n = 2_000_000
    counts = np.round(9.81 / lsb) + np.round(
        rng.standard_normal(n) * 170 + np.cumsum(rng.standard_normal(n)) * 0.05
    )
    counts = counts.astype(np.int64)
    y = counts * lsb
    result = allan_variance(y, rate_hz=100.0, m=[1, 16, 1024, 100_000], alpha=0)
    running = np.concatenate([[0], np.cumsum(counts)])
    for m, avar in zip(result.m, result.avar):
        d = running[2 * m :] - 2 * running[m:-m] + running[: -2 * m]  # exact integers
        exact = np.sum(d.astype(np.float64) ** 2) * lsb**2 / (2.0 * d.size * m * m)
        assert avar == pytest.approx(exact, rel=1e-10)


def test_running_sum_is_compensated(rng):
    y = rng.standard_normal(200_000) + 1e6
    x = phase_from_rate(y, np.mean(y))
    exact = math.fsum(y[:150_000] - np.mean(y))
    assert abs(x[150_000] - exact) < 1e-9 * np.sqrt(150_000)


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(1e-6, 1e6), offset=st.floats(-1e4, 1e4), seed=st.integers(0, 2**32 - 1))
def test_scaling_offset_and_sign_properties(scale, offset, seed):
    y = np.random.default_rng(seed).standard_normal(512)
    base = allan_variance(y, rate_hz=1.0, alpha=0)
    moved = allan_variance(scale * y + offset, rate_hz=1.0, alpha=0)
    # the input scale*y + offset is itself rounded to spacing(offset), relative to the noise scale
    input_rounding = np.spacing(abs(offset) + scale * 5) / scale
    np.testing.assert_allclose(moved.avar, scale**2 * base.avar, rtol=1e-11 + 4 * input_rounding)
    assert (
        np.all(base.avar >= 0)
        and np.all(base.avar_low <= base.avar)
        and np.all(base.avar <= base.avar_high)
    )


def test_grids():
    assert list(cluster_sizes("octave", 1000)) == [1, 2, 4, 8, 16, 32, 64, 128]
    assert list(cluster_sizes("decade", 1000)) == [1, 2, 4, 10, 20, 40, 100, 200]
    assert list(cluster_sizes("all", 20)) == [1, 2, 3, 4, 5]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(y=[1.0, np.nan, 2.0, 3.0]), "sample 1"),
        (dict(y=np.ones((3, 3))), "1-D"),
        (dict(y=[1.0, 2.0]), "too few"),
        (dict(y=np.arange(100.0), m="weekly"), "m="),
        (dict(y=np.arange(100.0), m=[1, 70]), "m="),
        (dict(y=np.arange(100.0), alpha=3), "alpha"),
        (dict(y=np.arange(100.0), rate_hz=0), "rate_hz"),
        (dict(y=np.arange(100.0), confidence=1.5), "confidence"),
        (dict(y=np.arange(100.0), interval="bayes"), "interval"),
    ],
)
def test_bad_input(kwargs, match):
    kwargs.setdefault("rate_hz", 1.0)
    with pytest.raises(InputError, match=match):
        allan_variance(kwargs.pop("y"), **kwargs)


@pytest.mark.parametrize("alpha", [2, 0, -2])
def test_noise_identification_on_power_law_noise(rng, alpha):
    """Lag-1 ACF identifies simulated white phase (alpha 2), white rate (0), random walk (-2)."""
    w = rng.standard_normal(2**16 + 1)
    y = {2: np.diff(w), 0: w[:-1], -2: np.cumsum(w[:-1])}[alpha]
    ms = np.array([1, 4, 16, 64])
    found = identify_noise(phase_from_rate(y, y.mean()), ms)
    assert np.all(found == alpha)


def test_interval_coverage_white_noise(rng):
    """The 68.3% interval covers the true AVAR of white noise (sigma^2 / m) in about 68% of
    400 simulated records (binomial 4-sigma band 58-78%)."""
    hits = np.zeros(4)
    ms = [1, 8, 64, 256]
    for _ in range(400):
        r = allan_variance(rng.standard_normal(2048), rate_hz=1.0, m=ms, alpha=0)
        truth = 1.0 / np.array(ms)
        hits += (r.avar_low <= truth) & (truth <= r.avar_high)
    assert np.all((hits / 400 > 0.58) & (hits / 400 < 0.78))


def test_thread_count_follows_the_record_and_changes_no_bit(rng, monkeypatch):
    """One thread below SAMPLES_PER_THREAD samples, numba's pool for long records; the sums are per
    fixed block and the blocks are added in a fixed order, so any thread count gives the same bits
    (the same seed gives the same numbers on any machine)."""
    import numba

    from bayes_imu.allan import kernels

    assert (
        kernels.threads_for(1000) == 1 and kernels.threads_for(kernels.SAMPLES_PER_THREAD - 1) == 1
    )
    assert kernels.threads_for(10**12) == numba.config.NUMBA_NUM_THREADS
    # a record the JIT kernels sum (shorter ones go to the precompiled kernels, on one thread)
    x = kernels.phase_from_rate(rng.standard_normal(kernels.PRECOMPILED_BELOW + 1000), 0.0)
    # whole blocks summed by residues
    ms = np.array([1, 4, 16, 1000, 40_000, 65_536, 131_072, 196_608])
    one = kernels.second_difference_sums(x, ms)
    before = numba.get_num_threads()
    for n in range(2, numba.config.NUMBA_NUM_THREADS + 1):
        monkeypatch.setattr(kernels, "threads_for", lambda n_samples, n=n: n)
        np.testing.assert_array_equal(kernels.second_difference_sums(x, ms), one)
        assert numba.get_num_threads() == before  # the caller's setting is restored


def test_one_pass_sums_of_every_size_against_exact_sums(rng):
    """The sums of all cluster sizes in one pass over blocks (sizes smaller and larger than a block,
    octave runs summed four and two sizes a loop, one whose 16 m reach leaves the record in the last
    blocks, and odd sizes, not sorted) equal each size's sum of squared second differences
    added exactly (math.fsum), to 1e-13 relative."""
    import math

    from bayes_imu.allan import kernels

    x = kernels.phase_from_rate(rng.standard_normal(400_000) + 0.3, 0.3)
    ms = np.array(
        [
            1,
            2,
            4,
            8,
            3,
            1000,
            65_535,
            65_536,
            65_537,
            131_072,
            7,
            99_999,
            4096,
            8192,
            16_384,
            32_768,
        ]
    )
    got = kernels.second_difference_sums(x, ms)
    for m, value in zip(ms, got):
        d = x[2 * m:] - 2.0 * x[m:x.size - m] + x[:x.size - 2 * m]
        assert value == pytest.approx(math.fsum(d * d), rel=1e-13)


def test_long_record_running_sum_is_near_exact_on_any_number_of_threads(rng, monkeypatch):
    """The running sum of a record the JIT kernels sum (block sums about each block's first sample,
    their compensated bases, the blocks filled on threads): the same bits on any number of threads,
    allan_sums' own running sum bit for bit, within a few ulp of the exact prefix sums all along the
    record (a large offset; data exact multiples of 2**-20, so the prefix sums are exact integers
    and one rational), and within a few ulp of the sequential pass's (phase_chunk, which rounds the
    block totals differently)."""
    from fractions import Fraction

    import numba

    from bayes_imu.allan import kernels

    n = kernels.PRECOMPILED_BELOW + 12_345  # not a block multiple
    counts = np.round(rng.standard_normal(n) * 2**30).astype(np.int64)
    y = counts * 2.0**-20 + 5e6
    offset = kernels.record_mean(y)
    x = kernels.phase_from_rate(y, offset)
    assert x[0] == 0.0
    for threads in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        monkeypatch.setattr(kernels, "threads_for", lambda n_samples, t=threads: t)
        np.testing.assert_array_equal(kernels.phase_from_rate(y, offset), x)
        np.testing.assert_array_equal(kernels.allan_sums(y, [1, 2, 4])[0], x)
    prefix = np.concatenate([[0], np.cumsum(counts)])
    step = Fraction(5e6) - Fraction(offset)
    for i in list(range(0, n + 1, 9_973)) + [n]:
        exact = Fraction(int(prefix[i]), 2**20) + i * step
        assert (
            abs(Fraction(float(x[i])) - exact)
            <= 4 * abs(exact) * Fraction(2) ** -52 + Fraction(2) ** -40
        ), i
    sequential = kernels.phase_chunk(y, offset, np.zeros(2))
    np.testing.assert_allclose(
        x[1:], sequential, rtol=0, atol=8 * np.finfo(float).eps * np.max(np.abs(x))
    )


_COMPILE_ORDER_PROBE = """
import re, sys
import numpy as np
from bayes_imu.allan import kernels
jit = kernels._compile()
block, tile = kernels._PHASE_BLOCK, kernels._BLOCK_ALL
y = np.random.default_rng(0).standard_normal(3 * tile + 5) + 0.25
sums = jit["centred_sums"](y, block)
mean = jit["centred_mean"](y, sums, block)
bases = jit["centred_bases"](y, sums, mean, block)
ms = np.array([1, 2, 4])
x = np.empty(y.size + 1)
partial = np.zeros(((y.size - 1 + tile - 1) // tile, ms.size))
eights = np.empty(y.size // 8)
# the fast-math kernel first: the order in which a shared callee took its caller's flags
plan = kernels._gather_plan(None)
jit["phase_and_sums"](y, mean, bases, block, x, ms, tile, 1, 2, partial, *plan, eights)
jit["phase_blocks"](y, mean, bases, block, np.empty(y.size))
ir = "".join(jit["phase_blocks"].inspect_llvm(s) for s in jit["phase_blocks"].signatures)
flagged = re.findall(r"= fadd (?:reassoc|fast|nnan|ninf|nsz|arcp|contract|afn)", ir)
print(len(flagged), len(re.findall(r"= fadd double", ir)))
"""


@pytest.mark.slow  # ~10 s: the parallel kernels compiled afresh in another process
def test_the_running_sum_is_strict_whichever_kernel_compiles_first(tmp_path):
    """phase_blocks (strict IEEE) fills the running sum through fill_blocks, which the fast-math
    phase_and_sums calls too. numba compiles a callee's signature inside the first caller that needs
    it, with that caller's fast-math flags, and reuses it: with fill_blocks called apart,
    phase_and_sums compiled first gave phase_blocks 18 fast-math additions and no strict one. In a
    fresh process and an empty numba cache, phase_and_sums compiled first, phase_blocks' build has
    strict additions and no addition with a fast-math flag."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", _COMPILE_ORDER_PROBE], env=env,
                          capture_output=True, text=True, check=True)
    flagged, strict = map(int, done.stdout.split())
    assert flagged == 0 and strict > 0


def test_fused_fill_and_sums_on_any_number_of_runs(rng):
    """phase_and_sums (each thread fills a run of tiles and sums the sizes below a tile behind its
    fill) gives phase_blocks' running sum and sums_all's sums of the same sizes bit for bit, on 1 to
    7 runs, whichever tiles are summed behind the fill and which after it (a run's first and last
    tiles), on a record that is not a whole number of tiles; one to two tiles of lag (the largest
    size's reach). The position contrasts' 8-sample block sums it adds as it fills (in its fast-math
    loop: any order of the 8) are the same bits on any number of runs, within the rounding bound of
    8 additions of block_sums' strict ones."""
    from bayes_imu.allan import kernels

    jit = kernels._compile()
    y = rng.standard_normal(23 * kernels._BLOCK_ALL + 4_321) + 0.25
    block, tile = kernels._PHASE_BLOCK, kernels._BLOCK_ALL
    sums = jit["centred_sums"](y, block)
    mean = jit["centred_mean"](y, sums, block)
    bases = jit["centred_bases"](y, sums, mean, block)
    reference = np.empty(y.size + 1)
    reference[0] = 0.0
    jit["phase_blocks"](y, mean, bases, block, reference[1:])
    eights = np.empty(y.size // 8)
    jit["block_sums"](reference[1:], 4096, eights)
    blocks = np.abs(reference[1:8 * eights.size + 1]).reshape(-1, 8)
    bound = 14 * np.finfo(float).eps * blocks.sum(axis=1)
    first_fill = None
    for ms in (np.array([1, 2, 4, 8, 16, 3, 1000, 32_768]), np.array([5, 10, 20, 40_000])):
        expected = jit["sums_all"](reference, ms, tile)
        lag = (2 * int(ms.max()) + tile - 2) // tile
        assert lag == (1 if ms.max() <= tile // 2 else 2)
        n_tiles = (y.size + 1 - 2 * int(ms.min()) + tile - 1) // tile
        for runs in (1, 2, 3, 7):
            x = np.full(y.size + 1, np.nan)
            partial = np.zeros((n_tiles, ms.size))
            # a column of position_mean_squares' table, as allan_sums passes it
            filled = np.full((y.size // 8 + 1, 2), np.nan)[1:, 0]
            got = jit["phase_and_sums"](
                y, mean, bases, block, x, ms, tile, lag, runs, partial, *kernels._gather_plan(None),
                filled,
            )
            np.testing.assert_array_equal(x, reference)
            assert np.all(np.abs(filled - eights) <= bound)
            if first_fill is None:
                first_fill = filled.copy()
            np.testing.assert_array_equal(filled, first_fill)
            np.testing.assert_array_equal(got, expected)
            # the tile sums it leaves are each tile's: their running total is the sums
            np.testing.assert_array_equal(np.cumsum(partial, axis=0)[-1], expected)


@pytest.mark.parametrize("extra", [0, 1, 200, 65_535])
def test_residue_sums_of_whole_block_sizes_are_exact_on_any_number_of_threads(rng, extra):
    """residue_sums (the sizes that are whole blocks, from a buffer of residue rows) equal each
    size's sum of squared second differences added exactly (math.fsum) to 1e-13, the largest size
    reaching the record's last sample, records ending anywhere in a row (the last, partial row),
    octave runs and odd multiples; the same bits on 1, 2 and 5 threads."""
    import math

    from bayes_imu.allan import kernels

    period = kernels._BLOCK_ALL
    x = np.cumsum(rng.standard_normal(12 * period + extra))
    ms = np.array([1, 2, 3, 4, 5], dtype=np.int64) * period
    ms = ms[2 * ms <= x.size - 1]
    got = kernels._compile()["residue_sums"](x, ms, period, kernels._RESIDUES, 2)
    for m, value in zip(ms, got):
        d = x[2 * m:] - 2.0 * x[m:x.size - m] + x[:x.size - 2 * m]
        assert value == pytest.approx(math.fsum(d * d), rel=1e-13)
    for threads in (1, 5):
        np.testing.assert_array_equal(
            kernels._compile()["residue_sums"](x, ms, period, kernels._RESIDUES, threads), got
        )


def test_allan_sums_is_the_running_sum_and_its_sums(rng):
    """allan_sums is phase_from_rate(y, record_mean(y)) and second_difference_sums of it: bit for
    bit on a record the precompiled kernels sum (the same three calls) and on a long one (one read
    for the mean and the block sums, the small sizes fused with the fill, the whole-block sizes by
    residues), on an octave grid with sizes on both sides of a block, and with progress reported for
    every size."""
    from bayes_imu.allan import kernels

    for n in (300_000, kernels.PRECOMPILED_BELOW + 777):
        y = rng.standard_normal(n) * 0.01 + 9.81 + np.cumsum(rng.standard_normal(n)) * 1e-5
        ms = 2 ** np.arange(int(np.log2(n // 2)) + 1)
        done = []
        x, sums = kernels.allan_sums(y, ms, progress=done.append)
        np.testing.assert_array_equal(x, kernels.phase_from_rate(y, kernels.record_mean(y)))
        np.testing.assert_array_equal(sums, kernels.second_difference_sums(x, ms))
        assert sum(done) == ms.size
        x, sums = kernels.allan_sums(y, [70_001])  # no size below a block, none a whole block
        np.testing.assert_array_equal(sums, kernels.second_difference_sums(x, [70_001]))


def test_parts_sums_read_off_the_tiles_equal_each_part_s_own_sums(rng):
    """allan_sums' parts (the stationarity check's segments) equal second_difference_sums of each
    part's slice of the running sum: bit for bit on a record the precompiled kernels sum (the same
    calls), to 1e-13 on a long one, whose sizes below a block are read off the whole record's tile
    sums plus two spans at each part's ends (parts not aligned to tiles, an octave grid with sizes
    from a block up summed part by part, sizes of the parts missing from the whole record's grid,
    and parts too short for a whole tile between their spans)."""
    from bayes_imu.allan import kernels

    for n, n_parts in ((300_000, 4), (kernels.PRECOMPILED_BELOW + 12_345, 4),
                       (kernels.PRECOMPILED_BELOW + 777, 3), (kernels.PRECOMPILED_BELOW + 5, 16)):
        y = rng.standard_normal(n) * 0.01 + 9.81 + np.cumsum(rng.standard_normal(n)) * 1e-5
        ms = 2 ** np.arange(int(np.log2(n // 4)) + 1)
        length = n // n_parts
        part_ms = np.concatenate([ms[ms <= length // 4], [3]]) if n_parts == 3 else ms[
            ms <= length // 4]
        part_ms = np.sort(part_ms)
        x, sums, parts, points = kernels.allan_sums(y, ms, parts=(n_parts, part_ms))
        assert points is None
        np.testing.assert_array_equal(sums, kernels.allan_sums(y, ms)[1])
        expected = np.array([
            kernels.second_difference_sums(x[k * length:(k + 1) * length + 1], part_ms)
            for k in range(n_parts)
        ])
        if n < kernels.PRECOMPILED_BELOW:
            np.testing.assert_array_equal(parts, expected)
        else:
            np.testing.assert_allclose(parts, expected, rtol=1e-13, atol=0)


def test_allan_variance_s_segments_are_segment_allan_s(rng):
    """The segments allan_variance computes in its pass over the record equal segment_allan's from
    the same running sum (the parts summed one by one, as allan_variance did before issue 39's
    shared pass): bit for bit on a short record, to 1e-13 on a long one; and segment_allan's from
    the samples (each part's own mean and running sum) to 1e-12."""
    from bayes_imu.allan import kernels
    from bayes_imu.allan.estimator import segment_allan

    for n in (100_000, kernels.PRECOMPILED_BELOW + 54_321):
        y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-3
        got = allan_variance(y, rate_hz=100.0, contrast_span_s=None).segments
        ms = cluster_sizes("octave", n)
        expected = segment_allan(y, ms, 4, x=kernels.allan_sums(y, ms)[0])
        np.testing.assert_array_equal(got.m, expected.m)
        assert got.n_samples == expected.n_samples
        if n < kernels.PRECOMPILED_BELOW:
            np.testing.assert_array_equal(got.avar, expected.avar)
        else:
            np.testing.assert_allclose(got.avar, expected.avar, rtol=1e-13, atol=0)
        np.testing.assert_allclose(got.avar, segment_allan(y, ms, 4).avar, rtol=1e-12, atol=0)


def test_identification_samples_gathered_in_the_fill_are_the_record_s(rng):
    """allan_sums' gather (the noise identification's phase samples, copied from each tile as it is
    filled) gives x at every requested index on a record the JIT kernels sum (sizes starting at 0,
    whose x[0] the fill does not write, sizes of the 2**18 cap, the last sample of the record), so
    that allan_variance's exponents are identify_noise's of the record, bit for bit (the same
    deltas); nothing is gathered on a record the precompiled kernels sum."""
    from bayes_imu.allan import estimator, kernels

    n = kernels.PRECOMPILED_BELOW + 3_333
    y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-2
    ms = cluster_sizes("octave", n)
    starts, steps, counts = estimator._starts_steps(ms, n)
    assert starts.min() == 0 and counts.max() == 2**18
    x, sums, parts, (values, offsets) = kernels.allan_sums(y, ms, gather=(starts, steps, counts))
    assert parts is None
    for m, a, c, o in zip(ms, starts, counts, offsets):
        np.testing.assert_array_equal(values[o:o + c + 1], x[a:a + c * m + 1:m])
    assert values.size == int(np.sum(counts + 1))
    deltas = kernels.lag1_deltas(x, ms, starts, counts, 2)
    gathered = kernels.lag1_deltas(
        values, ms, offsets, counts, 2, steps=np.ones_like(counts), n_samples=n
    )
    np.testing.assert_array_equal(gathered, deltas)
    np.testing.assert_array_equal(
        allan_variance(y, rate_hz=100.0).alpha, estimator.identify_noise(x, ms)
    )
    short = rng.standard_normal(10_000)
    assert kernels.allan_sums(short, [1, 2], gather=([0, 0], [1, 2], [10, 5]))[3] is None


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("n", [1_000, 2**21 + 3])
def test_a_non_finite_sample_is_named_after_the_pass(bad, n):
    """The samples are checked for non-finite values only where the running sum is not finite (a
    non-finite sample makes the mean, hence all of it, non-finite): still named, on either build."""
    y = np.ones(n)
    y[n // 3] = bad
    with pytest.raises(InputError, match=f"sample {n // 3} is"):
        allan_variance(y, rate_hz=100.0)


def _exact_sum(y):
    """The exact rational sum of float64 ``y``: each sample is ``q 2^(e-53)`` with an integer ``q``
    of at most 53 bits (``frexp``), split into 26-bit halves whose sums fit int64; summed per
    exponent and added as fractions (Python's sum of ``Fraction`` takes ~5 s on 2e6 samples)."""
    from fractions import Fraction

    mantissa, exponent = np.frexp(y)
    q = np.ldexp(mantissa, 53).astype(np.int64)
    high, low = q >> 26, q & ((1 << 26) - 1)
    total = Fraction(0)
    for e in np.unique(exponent):
        at = exponent == e
        total += Fraction((int(high[at].sum()) << 26) + int(low[at].sum())) * Fraction(2) ** int(
            e - 53
        )
    return total


def test_exact_sum_is_the_sum_of_fractions(rng):
    """The test's exact sum against Python's sum of Fractions, on signs, zeros, tiny and huge
    values."""
    from fractions import Fraction

    y = np.concatenate(
        [rng.standard_normal(3000) * 10.0 ** rng.integers(-300, 300, 3000), [0.0, -0.0, 5e-324]]
    )
    assert _exact_sum(y) == sum(map(Fraction, y.tolist()), Fraction(0))


@pytest.mark.parametrize("extra", [0, 12_345])
def test_record_mean_is_the_exact_mean_on_any_number_of_threads(rng, monkeypatch, extra):
    """record_mean of a record the JIT kernels sum (block sums about each block's first sample on
    threads, added with those samples in a compensated sum) is within 4 ulp of the exact rational
    mean, on a large offset with noise, the same bits on 1 or more threads; a short record's mean is
    numpy's."""
    from fractions import Fraction

    import numba

    from bayes_imu.allan import kernels

    y = rng.standard_normal(kernels.PRECOMPILED_BELOW + extra) * 3.0 + 9.81
    exact = _exact_sum(y) / y.size
    got = kernels.record_mean(y)
    assert abs(Fraction(got) - exact) <= 4 * abs(exact) * Fraction(2) ** -52
    for n in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        monkeypatch.setattr(kernels, "threads_for", lambda n_samples, n=n: n)
        assert kernels.record_mean(y) == got
    short = y[:1000]
    assert kernels.record_mean(short) == float(np.mean(short))


def test_scaled_is_the_allan_variance_of_the_scaled_log(rng):
    """A unit conversion scales every variance by factor**2, the segment Allan variances included
    (checked against computing everything again from the scaled samples)."""
    y = rng.standard_normal(40_000) + 1e-3 * rng.standard_normal(40_000).cumsum()
    factor = 9.80665
    direct = allan_variance(factor * y, rate_hz=100.0)
    scaled = allan_variance(y, rate_hz=100.0).scaled(factor)
    for name in ("avar", "adev", "avar_low", "avar_high"):
        np.testing.assert_allclose(getattr(scaled, name), getattr(direct, name), rtol=1e-12)
    np.testing.assert_allclose(scaled.segments.avar, direct.segments.avar, rtol=1e-12)
    assert allan_variance(y, rate_hz=100.0).scaled(1.0).segments is not None


def test_chi2_interval_is_scipy_stats_chi2():
    """The interval's chi-squared quantiles (taken from scipy.special, so that the Allan variance
    does not import scipy.stats) are scipy.stats.chi2's, from 0.5 to 1e7 degrees of freedom."""
    from scipy import stats

    from bayes_imu.allan.estimator import chi2_interval

    edf = np.geomspace(0.5, 1e7, 301)
    avar = np.linspace(1.0, 2.0, edf.size)
    for confidence in (0.683, 0.9, 0.999):
        tail = (1.0 - confidence) / 2.0
        low, high = chi2_interval(avar, edf, confidence)
        np.testing.assert_allclose(low, edf * avar / stats.chi2.isf(tail, edf), rtol=1e-14)
        np.testing.assert_allclose(high, edf * avar / stats.chi2.ppf(tail, edf), rtol=1e-14)


def test_precompiled_kernels_agree_with_the_jit_build(rng):
    """The ahead-of-time build (``bayes_imu._compiled``, setup.py) of the same sources as numba's
    JIT build: built wherever numba has its AOT compiler; the running sums, lag sums, Gauss-Markov
    AVAR rows and the drift grid (both orders, bias and stationary parts) bit for bit (strict IEEE
    arithmetic in both), the fast-math sums of squares to 1e-14 relative (the two builds vectorise
    them for different CPUs)."""
    import importlib.util

    from bayes_imu.allan import _sources, kernels
    from bayes_imu.noise._sources import avar_rows

    if importlib.util.find_spec("numba.pycc") is not None:
        assert kernels.precompiled() is not None, (
            "numba has its AOT compiler but bayes_imu._compiled was not built"
        )
    aot = kernels.precompiled()
    if aot is None:
        pytest.skip("this numba has no AOT compiler: every kernel is JIT-compiled")
    import numba

    jit = kernels._compile()
    y = rng.standard_normal(300_001) * 2.0 + 7.0
    a, b = np.empty(y.size), np.empty(y.size)
    aot.phase_chunk(y, 7.0, a, 256, np.zeros(2))
    jit["phase_chunk"](y, 7.0, b, 256, np.zeros(2))
    np.testing.assert_array_equal(a, b)
    ms = np.array([1, 2, 4, 8, 16, 1024, 65_536, 70_001], dtype=np.int64)
    np.testing.assert_allclose(
        aot.sums_all(a, ms, 1 << 16), jit["sums_all"](a, ms, 1 << 16), rtol=1e-14
    )
    assert aot.sum3(a[:-20], a[10:-10], a[20:], 1 << 14) == pytest.approx(
        jit["sum3"](a[:-20], a[10:-10], a[20:], 1 << 14), rel=1e-14)
    table = np.cumsum(rng.random(4 * 64 + 1))
    args = (
        table,
        np.array([1, 4, 16, 64], dtype=np.int64),
        5000,
        0.3,
        np.array([0.5, 2.0]),
        np.array([1e-3, 0.2]),
    )
    np.testing.assert_array_equal(aot.pair_sums(*args), jit["pair_sums"](*args))
    mf = np.array([1.0, 2.0, 4.0, 64.0, 4096.0])
    x = np.array([1e-9, 1e-4, 0.3, 5.0])
    coeffs = rng.random((12, mf.size))
    fy = -np.expm1(-np.outer(x, mf))
    rows = (mf, coeffs, np.ones(4), x, -np.expm1(-x), -np.expm1(-2 * x), fy, 0.5)
    out_aot, out_jit = np.empty((4, mf.size)), np.empty((4, mf.size))
    aot.avar_rows(*rows, out_aot)
    numba.njit(avar_rows)(*rows, out_jit)
    np.testing.assert_array_equal(out_aot, out_jit)
    from bayes_imu.noise._sources import pair_sum_lags, second_differences_into

    table = np.cumsum(rng.random(700 + 4 * 8 + 1))  # D(0 .. n + 4 max(m)), n = 700
    ext = np.concatenate([table[:0:-1], table])
    reach = 700 + 2 * 8
    lo, size = table.size - 1 - reach, 2 * reach + 1
    g_aot, g_jit = np.empty(size), np.empty(size)
    aot.second_differences_into(ext, lo, 8, g_aot)
    numba.njit(second_differences_into)(ext, lo, 8, g_jit)
    np.testing.assert_array_equal(g_aot, g_jit)
    h, half = np.cos(np.arange(size)), rng.random(9)
    for flags in ((1, 1), (1, 0), (0, 0)):  # a = 3, b = 8: M_a = 695, M_b = 685
        lag_sum = (g_aot, h, half, 40, 3, 695, 685, reach, *flags)
        assert aot.pair_sum_lags(*lag_sum) == numba.njit(pair_sum_lags)(*lag_sum)
    # the running sums are strict IEEE (fast-math would optimise their compensation away; their
    # builds: test_the_running_sum_is_strict_whichever_kernel_compiles_first)
    running = {
        "phase_chunk",
        "centred_sums",
        "centred_mean",
        "centred_bases",
        "fill_blocks",
        "phase_blocks",
    }
    assert not running & set(_sources.FASTMATH)
    from bayes_imu.noise import _sources as noise_sources
    from bayes_imu.noise.euler_sums import SWITCH, _random_walk, series_coefficients

    jit_drift = numba.njit(parallel=True)(noise_sources.drift_rows)
    k = np.unique(np.round(np.geomspace(1.0, 1e6, 200)))
    a = np.concatenate([10 ** rng.uniform(-12, -1e-3, 300), [0.5, 0.999999]])
    log_abs = np.log1p(-a)
    scales = [rng.random(a.size), rng.random(a.size) * (rng.random(a.size) < 0.5)]
    extra = [
        rng.random((2, a.size)),
        rng.random((2, k.size)),
        rng.random((1, a.size)),
        rng.random((1, k.size)),
    ]
    for order in (1, 2):
        outputs = []
        for kernel in (aot.drift_rows, jit_drift):
            total, bias = np.empty((k.size, a.size)), np.empty((k.size, a.size))
            kernel(
                order,
                k,
                a,
                log_abs,
                series_coefficients(order, k),
                _random_walk(order, k),
                float(SWITCH[order]),
                *scales,
                *extra,
                total,
                bias,
            )
            outputs.append((total, bias))
        np.testing.assert_array_equal(outputs[0][0], outputs[1][0])
        np.testing.assert_array_equal(outputs[0][1], outputs[1][1])
    # the navigation error's propagated diagonal (drift.navigation._propagate_diagonal)
    n_b, d = 7, 6
    a = rng.standard_normal((n_b, d, d))
    a /= 1.001 * np.abs(np.linalg.eigvals(a)).max(axis=-1)[:, None, None]  # stable: no overflow
    q = rng.standard_normal((n_b, d, d))
    q = q @ np.swapaxes(q, -1, -2)
    p0 = q[::-1].copy()
    k = np.array([0, 1, 5, 64, 1000, 33333], dtype=np.int64)
    out_aot, out_jit = np.empty((n_b, k.size, 3)), np.empty((n_b, k.size, 3))
    aot.propagate_diagonal(a, q, p0, k, out_aot)
    numba.njit(noise_sources.propagate_diagonal)(a, q, p0, k, out_jit)
    assert np.all(np.isfinite(out_aot))
    np.testing.assert_array_equal(out_aot, out_jit)


def test_compiled_kernel_takes_the_precompiled_build_or_compiles_what_it_lacks(monkeypatch):
    """compiled_kernel: the extension's kernel where it has it; a kernel an older in-place build
    lacks is JIT-compiled from its source module instead (the same values)."""
    import types

    import numba

    from bayes_imu.allan import kernels

    aot = kernels.precompiled()
    if aot is not None:
        assert kernels.compiled_kernel("avar_rows", "bayes_imu.noise._sources") is aot.avar_rows
    # built before drift_rows existed
    monkeypatch.setattr(kernels, "precompiled", lambda: types.SimpleNamespace())
    jit = kernels.compiled_kernel("drift_rows", "bayes_imu.noise._sources", parallel=True)
    assert isinstance(jit, numba.core.registry.CPUDispatcher)


def test_edf_where_few_averages_identify_the_noise_is_the_neighbours_smallest(rng):
    """Where fewer than 100 cluster averages identify the noise type, one step off changes the
    EDF several times over (the Xsens MTi-G log's white-rate tail read as flicker phase: intervals
    ~5x too narrow at 164-655 s). There the EDF is the smallest Greenhall EDF of alpha - 1 ..
    alpha + 1; with enough averages it is alpha's own. Greenhall's algorithm itself is checked
    against Stable32 above."""
    from bayes_imu.allan.estimator import carried_edf, greenhall_edf, identification_plan

    n = 500_000
    ms = np.array([1, 64, 4096, 16384, 32768, 65536], dtype=np.int64)
    _, counts = identification_plan(ms, n)
    assert list(counts >= 100) == [True, True, True, False, False, False]
    alpha = np.array([0, 0, 0, 1, 1, 1])
    own = greenhall_edf(alpha, ms, n + 1)
    got = carried_edf(own, alpha, ms, n)
    np.testing.assert_array_equal(got[:3], own[:3])
    for i in range(3, 6):
        near = [greenhall_edf([a], ms[i:i + 1], n + 1)[0] for a in (0, 1, 2)]
        assert got[i] == min(near) < own[i] / 5  # flicker phase's EDF is far larger
    # a white-rate record: its longest sizes never get more EDF than white rate's
    y = rng.standard_normal(n)
    result = allan_variance(y, rate_hz=100.0)
    few = identification_plan(result.m, n)[1] < 100
    white = greenhall_edf(np.zeros(result.m.size, dtype=int), result.m, n + 1)
    assert few.any() and np.all(result.edf[few] <= white[few] * (1 + 1e-12))
