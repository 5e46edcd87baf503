"""Benchmark: bayes_imu.allan_variance vs allantools.oadev, side by side, and the memory-bandwidth
floor.

Same data (white + random-walk rate noise), same octave cluster sizes, same values
(maximum relative difference printed). Prints one table row per record length:
allantools time, bayes_imu time (``values_s``: the kernel ``allan_sums`` alone, mean, running
sum and sums; ``full_s``: the public ``bayes_imu.allan_variance(y, rate_hz=..., m=...)`` with the
defaults a fit uses: noise identification, EDF, exact intervals and the four parts' Allan
variances for the stationarity check: what users call, and what claims of speed should quote),
the speed-ups,
the threads used, and peak memory of the bayes_imu call relative to the input array
(tracemalloc, numpy allocations).

The floor: the least memory traffic of this computation in one pass: read the samples once,
write the running sum (a new array, as the Allan variance does) and read it back once, on the
same threads, compiled (``floor_s``); ``values/floor`` is how far the Allan variance (every
cluster size) is from it. ``per_size_s`` is one pass per cluster size instead (the running sum
plus, for every size, the compiled sum of as many terms from one stream): what summing the
sizes one by one would cost at best (``values/per_size``).

``--stages`` adds a second table: where the values' time goes, each stage timed alone (best of
``--repeat``; use 7 or more, a stage takes milliseconds) and as a multiple of the floor: ``mean``
(``record_mean``: one read of the samples); ``running_sum`` (``phase_from_rate`` about that mean:
on a record the JIT kernels sum, at least 2**21 samples, the block sums' read, their bases and the
fill, page zeroing included; a shorter record's is one sequential pass); ``sums_small`` (the cluster
sizes below one block of start indices, 65536, summed in cache from one read of the running sum)
and ``sums_large`` (the sizes from 65536 up: their streams lie beyond the caches; on a long record
summed by residues, one read for all of them). ``added`` is the four stages' sum; the values
(``allan_sums``) cost less than that on a long record, whose single read of the samples gives
both the mean and the block sums, and whose small sizes are summed tile by tile behind the fill
while the running sum is in cache.
"""

import argparse
import time
import tracemalloc

import numpy as np


def best_time(func, repeat):
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - start)
    return best, out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", default="1e5,1e6,1e7", help="comma-separated record lengths")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--stages", action="store_true", help="also time each stage of the values alone"
    )
    args = parser.parse_args(argv)
    import allantools

    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.allan.kernels import (
        allan_sums,
        phase_from_rate,
        record_mean,
        second_difference_sum,
        threads_for,
    )

    one_pass = _one_pass_kernel()

    rng = np.random.default_rng(1)
    allan_variance(rng.standard_normal(1000), rate_hz=100.0)  # compile / load the numba cache
    print(
        f"{'samples':>10s} {'threads':>7s} {'allantools_s':>12s} {'values_s':>9s} {'full_s':>7s} "
        f"{'speedup_values':>14s} {'speedup_full':>12s} {'floor_s':>8s} {'values/floor':>12s} "
        f"{'per_size_s':>10s} {'values/per_size':>15s} {'max_rel_diff':>12s} "
        f"{'peak_mem_x_input':>16s}"
    )
    stages = []
    for n in (int(float(s)) for s in args.sizes.split(",")):
        y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-3
        t_at, (taus, adev_at, _, _) = best_time(
            lambda: allantools.oadev(y, rate=100.0, data_type="freq", taus="octave"), args.repeat
        )
        ms = np.round(taus * 100).astype(np.int64)

        def values_only():
            x, sums = allan_sums(y, ms)
            return sums / (2.0 * (x.size - 2 * ms) * ms.astype(float) ** 2)

        t_values, avar = best_time(values_only, args.repeat)

        def floor():
            import numba

            numba.set_num_threads(threads_for(y.size))
            try:
                out = np.empty(y.size + 1)
                return one_pass(y, out, 1 << 16)
            finally:
                numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

        def per_size():
            import numba

            x = phase_from_rate(y, record_mean(y))
            numba.set_num_threads(threads_for(x.size))
            try:
                return [
                    second_difference_sum(
                        x[: x.size - 2 * m], x[: x.size - 2 * m], x[: x.size - 2 * m]
                    )
                    for m in ms
                ]
            finally:
                numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

        t_floor, _ = best_time(floor, args.repeat)
        t_per_size, _ = best_time(per_size, args.repeat)
        t_full, result = best_time(lambda: allan_variance(y, rate_hz=100.0, m=ms), args.repeat)
        tracemalloc.start()
        allan_variance(y, rate_hz=100.0, m=ms)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        diff = max(
            np.max(np.abs(np.sqrt(avar) / adev_at - 1)), np.max(np.abs(result.adev / adev_at - 1))
        )
        print(
            f"{n:10d} {threads_for(n):7d} {t_at:12.3f} {t_values:9.3f} {t_full:7.3f} "
            f"{t_at / t_values:14.1f} {t_at / t_full:12.1f} {t_floor:8.3f} "
            f"{t_values / t_floor:12.2f} {t_per_size:10.3f} {t_values / t_per_size:15.2f} "
            f"{diff:12.1e} {peak / y.nbytes:16.2f}"
        )
        if args.stages:
            stages.append((n, _stage_times(y, ms, args.repeat), t_values, t_floor))
    if stages:
        print(
            f"\n{'samples':>10s} {'mean_s':>8s} {'running_sum_s':>13s} {'sums_small_s':>12s} "
            f"{'sums_large_s':>12s} {'added_s':>8s} {'values_s':>9s} {'floor_s':>8s}   per floor: "
            f"{'mean':>5s} {'run':>5s} {'small':>5s} {'large':>5s} {'added':>5s} {'values':>6s}"
        )
        for n, parts, t_values, t_floor in stages:
            mean, running, small, large = parts
            added = float(np.nansum(parts))
            print(
                f"{n:10d} {mean:8.4f} {running:13.4f} {small:12.4f} {_or_dash(large, 12)} "
                f"{added:8.4f} {t_values:9.4f} {t_floor:8.4f}   {'':10s} "
                + " ".join(_or_dash(p / t_floor, 5, 2) for p in parts)
                + f" {added / t_floor:5.2f} {t_values / t_floor:6.2f}"
            )


def _or_dash(value, width, digits=4):
    """``value`` right-aligned in ``width`` characters, or a dash where it is NaN (a stage the
    record does not run)."""
    return f"{'-':>{width}s}" if np.isnan(value) else f"{value:{width}.{digits}f}"


def _stage_times(y, ms, repeat):
    """Best times (s) of the values' stages, each alone: mean, running sum, sums of the sizes below
    a block, and sums of the sizes from a block up (NaN where there are none)."""
    from bayes_imu.allan import kernels

    mean, mu = best_time(lambda: kernels.record_mean(y), repeat)
    running, x = best_time(lambda: kernels.phase_from_rate(y, mu), repeat)
    small = ms < kernels._BLOCK_ALL
    t_small, _ = best_time(lambda: kernels.second_difference_sums(x, ms[small]), repeat)
    t_large = np.nan
    if not small.all():
        t_large, _ = best_time(lambda: kernels.second_difference_sums(x, ms[~small]), repeat)
    return mean, running, t_small, t_large


def _one_pass_kernel():
    """Compiled floor: write ``out[i + 1] = y[i]`` block by block, then sum ``out`` (fixed-order
    totals)."""
    import numba

    @numba.njit(parallel=True)
    def one_pass(y, out, block):
        n_blocks = (y.size + block - 1) // block
        for b in numba.prange(n_blocks):
            for i in range(b * block, min(b * block + block, y.size)):
                out[i + 1] = y[i]
        out[0] = 0.0
        partial = np.empty(n_blocks)
        for b in numba.prange(n_blocks):
            s = 0.0
            for i in range(b * block, min(b * block + block, y.size)):
                s += out[i]
            partial[b] = s
        return partial.sum()

    one_pass(np.ones(10), np.empty(11), 4)
    return one_pass


if __name__ == "__main__":
    main()
