"""Benchmark: bayes_imu.allan_variance vs allantools.oadev, side by side, and the memory-bandwidth
floor.

Same data (white + random-walk rate noise), octave cluster sizes, same values (maximum relative
difference printed over the sizes both compute). Prints the load average just before, then one table
row per record length: allantools' time (``oadev_s``: ``allantools.oadev(y, rate=100.0,
data_type="freq", taus="octave")``), bayes_imu's times (``allan_sums_s``: the values kernel
``allan_sums`` alone, mean, running sum and sums at allantools' sizes; ``allan_variance_s``: the
public ``bayes_imu.allan_variance(y, rate_hz=100.0)`` exactly as a fit calls it, its defaults:
octave grid, noise identification, EDF, exact intervals, the four parts' Allan variances for the
stationarity check and the phase contrasts for the drift-space check: what users call, and what
claims of speed should quote), the speed-ups (``oadev/allan_sums``, ``oadev/allan_variance``), the
CPU times (``time.process_time``, best of the repeats) of the two public calls and their ratio
(``cpu_oadev/av``: on a busy machine the wall ratio moves with the load, the CPU ratio less), the
threads used, and peak memory of the public call relative to the input array (tracemalloc, numpy
allocations).

The floor: the least memory traffic of this computation in one pass: read the samples once,
write the running sum (a new array, as the Allan variance does) and read it back once, on the
same threads, compiled (``floor_s``); ``sums/floor`` is how far the values kernel (every
cluster size) is from it. ``per_size_s`` is one pass per cluster size instead (the running sum
plus, for every size, the compiled sum of as many terms from one stream): what summing the
sizes one by one would cost at best (``sums/per_size``).

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
    """Best wall time (s) of ``repeat`` calls, and the result of the last."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - start)
    return best, out


def best_times(func, repeat):
    """Best wall and best CPU time (s, ``time.process_time``: every thread of the process) of
    ``repeat`` calls, and the result of the last."""
    wall = cpu = np.inf
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        out = func()
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu, out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", default="1e5,1e6,1e7", help="comma-separated record lengths")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--sensor",
        choices=("none", "gyro", "accel"),
        default="none",
        help="the public call's sensor= (default none: a log of unknown kind, whose contrasts "
        "measure attitude and position drift; gyro: a gyro fit's call (the CLI with --units "
        "deg/s), attitude only)",
    )
    parser.add_argument(
        "--stages", action="store_true", help="also time each stage of the values alone"
    )
    args = parser.parse_args(argv)
    import os

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
    sensor = None if args.sensor == "none" else args.sensor
    allan_variance(rng.standard_normal(1000), rate_hz=100.0)  # compile / load the numba cache
    allan_variance(rng.standard_normal(1 << 21), rate_hz=100.0)  # and the JIT kernels
    print(
        "load average (1, 5, 15 min) before: " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
        + "; allan_variance_s times bayes_imu.allan_variance(y, rate_hz=100.0, "
        + f"sensor={sensor!r}), a fit's call"
    )
    print(
        f"{'samples':>10s} {'threads':>7s} {'oadev_s':>8s} {'allan_sums_s':>12s} "
        f"{'allan_variance_s':>16s} {'oadev/allan_sums':>16s} {'oadev/allan_variance':>20s} "
        f"{'oadev_cpu_s':>11s} {'allan_variance_cpu_s':>20s} {'cpu_oadev/av':>12s} "
        f"{'floor_s':>8s} {'sums/floor':>10s} {'per_size_s':>10s} {'sums/per_size':>13s} "
        f"{'max_rel_diff':>12s} {'peak_mem_x_input':>16s}"
    )
    stages = []
    for n in (int(float(s)) for s in args.sizes.split(",")):
        y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-3
        t_at, c_at, (taus, adev_at, _, _) = best_times(
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
        t_full, c_full, result = best_times(
            lambda: allan_variance(y, rate_hz=100.0, sensor=sensor), args.repeat
        )
        tracemalloc.start()
        allan_variance(y, rate_hz=100.0, sensor=sensor)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        common = np.isin(ms, result.m)
        diff = max(
            np.max(np.abs(np.sqrt(avar) / adev_at - 1)),
            np.max(np.abs(result.adev / adev_at[common] - 1)),
        )
        print(
            f"{n:10d} {threads_for(n):7d} {t_at:8.3f} {t_values:12.3f} {t_full:16.3f} "
            f"{t_at / t_values:16.1f} {t_at / t_full:20.1f} {c_at:11.3f} {c_full:20.3f} "
            f"{c_at / c_full:12.1f} {t_floor:8.3f} {t_values / t_floor:10.2f} "
            f"{t_per_size:10.3f} {t_values / t_per_size:13.2f} {diff:12.1e} "
            f"{peak / y.nbytes:16.2f}"
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
