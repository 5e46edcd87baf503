"""Sources of the compiled Allan-variance kernels: plain Python that numba compiles twice.

Imported only to compile (it imports numba): :mod:`bayes_imu.allan.kernels` JIT-compiles these
functions on first use (``parallel=True`` where they use ``numba.prange``, cached on disk), and the
package build compiles the same functions ahead of time, one thread each (``prange`` is ``range``
there), into the extension ``bayes_imu._compiled`` (``setup.py``), which loads without numba. The
precompiled build has the kernels of a record shorter than 2**21 samples (``setup.py``'s
``KERNELS``); the kernels of longer records' parallel passes (``centred_sums`` to ``residue_sums``,
``span_sums``, ``contrast_sums``, ``block_sums``, ``pair_prefix`` and ``lag1_deltas``: a shorter
record takes numpy's steps for the contrasts and the noise identification) are JIT-compiled only.
:data:`FASTMATH` names the kernels compiled with reassociation (a vectorised sum of squares); the
running sums never are (their Kahan-Babuska compensation would be optimised away). numba compiles
a callee's signature inside the first caller that needs it, with that caller's fast-math flags,
and reuses that build for every caller (measured: a fixed tree of 8 additions came back
reassociated in a strict caller after a fast-math one had compiled it first; ``fill_blocks``,
called apart, took ``phase_and_sums``' flags into ``phase_blocks`` the same way). A helper that
both a strict and a fast-math kernel call is therefore inlined into each, so that each caller's
flags, not the order of compilation, decide its build: the position contrasts' block sum
``eight_sum`` (strict in ``block_sums``, in any order in the fill) and the running sum's
``fill_blocks`` (strict in ``phase_blocks``; in ``phase_and_sums``' fast-math loop its additions
stay in order all the same, each partial sum being stored: the fused fill is ``phase_blocks``'
bits, tested). Helpers inlined into their callers (``inline="always"``: numba's IR, so they
take the caller's fast-math flags and the precompiled ``sums_all`` compiles to the same code as
before they were split out) are module globals, as a kernel's callees must be for numba's cache.
"""

import numba
import numpy as np

__all__ = [
    "pair_sum",
    "pair_sums",
    "phase_chunk",
    "sum3",
    "centred_sums",
    "compensated_add",
    "centred_mean",
    "centred_bases",
    "fill_blocks",
    "phase_blocks",
    "phase_and_sums",
    "residue_sums",
    "tile_sums",
    "span_sums",
    "gather_points",
    "sums_all",
    "block_totals",
    "contrast_sums",
    "tile_starts",
    "tile_means",
    "eight_sum",
    "block_sums",
    "pair_prefix",
    "head_sum",
    "prefix_at",
    "phase_contrast",
    "lag1_deltas",
    "FASTMATH",
    "PARALLEL",
]

#: LLVM fast-math flags of the sum-of-squares kernels
_SQUARES = {"reassoc", "contract", "nsz", "arcp"}
FASTMATH = {
    "sum3": _SQUARES,
    "sums_all": _SQUARES,
    "phase_and_sums": _SQUARES,
    "residue_sums": _SQUARES,
    "span_sums": _SQUARES,
    "lag1_deltas": _SQUARES,
}
#: kernels whose ``prange`` loops run on numba's threads when JIT-compiled
PARALLEL = {
    "pair_sums",
    "sum3",
    "centred_sums",
    "phase_blocks",
    "phase_and_sums",
    "residue_sums",
    "sums_all",
    "contrast_sums",
    "block_sums",
    "pair_prefix",
    "lag1_deltas",
}


def pair_sum(table, a, b, n, h, s2, x):
    """``sum_l n(l) c(l)^2`` for one pair of cluster sizes (see
    :mod:`bayes_imu.noise.avar_covariance`).

    ``s2`` and ``x`` are arrays over the model's Gauss-Markov components (variance and dt/T).
    """
    ma = n - 2 * a + 1
    mb = n - 2 * b + 1
    total = 0.0
    # overlap window -2b <= l <= 2a (windows sharing a sample included): exact from the D table
    for l in range(-2 * b, 2 * a + 1):
        cnt = min(ma, mb - l) - max(0, -l)
        if cnt <= 0:
            continue
        c = 0.0
        for p in range(3):
            wa = -2.0 if p == 1 else 1.0
            for q in range(3):
                wb = -2.0 if q == 1 else 1.0
                c += wa * wb * table[abs(p * a - q * b - l)]
        c *= -0.5
        total += cnt * c * c
    n_gm = s2.size
    if n_gm == 0 and h == 0.0:
        return total
    # outside the window: exact geometric Gauss-Markov parts, asymptotic flicker part
    amp = np.empty(n_gm)
    for g in range(n_gm):
        one_minus_phi = -np.expm1(-x[g])
        phi = 1.0 - one_minus_phi
        amp[g] = (
            s2[g]
            * phi
            * (-np.expm1(-a * x[g])) ** 2
            * (-np.expm1(-b * x[g])) ** 2
            / one_minus_phi**2
        )
    for side in range(2):
        start = 2 * a + 1 if side == 0 else 2 * b + 1
        lag = start
        while True:
            # the tail summand is smooth (geometric and ~lc^-4): midpoint rule with steps
            # <= lc/64 and <= 0.1 T/dt for every Gauss-Markov part still above 1e-9 of the
            # summand (relative error ~1e-4)
            lc0 = lag + (b - a if side == 0 else a - b)
            mid0 = lag
            geo0 = 0.0
            for g in range(n_gm):
                geo0 += amp[g] * np.exp(-(mid0 - start + 1.0) * x[g])
            c0 = geo0 + h * (float(a) * a) * (float(b) * b) / (lc0 * lc0)
            limit = lc0 / 64.0
            decay = 0.0
            for g in range(n_gm):
                part = amp[g] * np.exp(-(mid0 - start + 1.0) * x[g])
                if part > 1e-9 * c0:
                    limit = min(limit, 0.1 / x[g])
                    decay = max(decay, 1.0 - np.exp(-2.0 * x[g]))
            step = max(1, int(limit))
            mid = lag + 0.5 * (step - 1)
            l = mid if side == 0 else -mid
            cnt = min(ma, mb - l) - max(0.0, -l)
            if cnt <= 0:
                break
            lc = mid + (b - a if side == 0 else a - b)
            geo = 0.0
            for g in range(n_gm):
                geo += amp[g] * np.exp(-(mid - start + 1.0) * x[g])
            c = -geo - h * (float(a) * a) * (float(b) * b) / (lc * lc)
            term = step * cnt * c * c
            total += term
            # stop when a bound on the remainder is negligible: geometric (GM) or ~ l^-4 (flicker)
            reach = mid + 1.0 / (decay if decay > 0.0 else -np.expm1(-2.0))
            if term / step * min(cnt, reach) <= 1e-12 * total:
                break
            lag += step
    return total


def pair_sums(table, ms, n, h, s2, x):
    k = ms.size
    out = np.zeros((k, k))
    for idx in numba.prange(k * k):
        ia = idx // k
        ib = idx % k
        if ib < ia:
            continue
        out[ia, ib] = pair_sum_compiled(table, ms[ia], ms[ib], n, h, s2, x)
        out[ib, ia] = out[ia, ib]
    return out


def phase_chunk(y, offset, out, block, state):
    # out[i] = running sum of (y - offset) after y[i], continuing state = [s, c]: plain sums
    # inside blocks, block totals added with Kahan-Babuska compensation (strict IEEE: no
    # fastmath, so it is not optimised away). A whole record is one chunk from [0, 0];
    # chunks of a multiple of `block` samples give exactly the same numbers.
    s = state[0]
    c = state[1]
    for lo in range(0, y.size, block):
        hi = min(lo + block, y.size)
        base = s + c
        acc = 0.0
        for i in range(lo, hi):
            acc += y[i] - offset
            out[i] = base + acc
        s, c = compensated_add_compiled(s, c, acc)
    state[0] = s
    state[1] = c
    return out


def sum3(a0, a1, a2, block):
    # views sliced per block and indexed from 0: LLVM vectorises this form (indexing the
    # whole arrays from `lo` instead is not vectorised: several times slower)
    n = a0.size
    n_blocks = (n + block - 1) // block
    partial = np.empty(n_blocks)
    for b in numba.prange(n_blocks):
        lo = b * block
        hi = min(lo + block, n)
        x0 = a0[lo:hi]
        x1 = a1[lo:hi]
        x2 = a2[lo:hi]
        s = 0.0
        for i in range(hi - lo):
            d = x2[i] - 2.0 * x1[i] + x0[i]
            s += d * d
        partial[b] = s
    # the block totals in a fixed order (partial.sum() would be a parallel reduction whose order,
    # hence last bit, depends on the number of threads: results must not depend on the machine)
    total = 0.0
    for b in range(n_blocks):
        total += partial[b]
    return total


def centred_sums(y, block):
    # out[b] = the plain sum over block b of (y[i] - y[b * block]), the block's first sample: one
    # read of the record gives its exact mean (centred_mean) and the blocks' sums about any offset
    # (centred_bases) as precisely as summing about that offset would (the terms stay small where
    # the record is locally smooth, whatever its offset); the threads take 256 blocks at a time
    n_blocks = (y.size + block - 1) // block
    out = np.empty(n_blocks)
    for g in numba.prange((n_blocks + 255) // 256):
        for b in range(g * 256, min(g * 256 + 256, n_blocks)):
            lo = b * block
            first = y[lo]
            acc = 0.0
            for i in range(lo, min(lo + block, y.size)):
                acc += y[i] - first
            out[b] = acc
    return out


def compensated_add(s, c, v):
    # Kahan-Babuska (Neumaier) step: s + c + v as a new (s, c)
    t = s + v
    if abs(s) >= abs(v):
        c += (s - t) + v
    else:
        c += (v - t) + s
    return t, c


def centred_mean(y, sums, block):
    # the record's mean from its centred block sums: sum_b sums[b] + L_b y[b * block], compensated
    s = 0.0
    c = 0.0
    for b in range(sums.size):
        lo = b * block
        s, c = compensated_add_compiled(s, c, sums[b])
        s, c = compensated_add_compiled(s, c, (min(lo + block, y.size) - lo) * y[lo])
    return (s + c) / y.size


def centred_bases(y, sums, offset, block):
    # the compensated running total of (y - offset) before each block, from the centred block sums:
    # block b adds sums[b] + L_b (y[b * block] - offset)
    s = 0.0
    c = 0.0
    out = np.empty(sums.size)
    for b in range(sums.size):
        out[b] = s + c
        lo = b * block
        s, c = compensated_add_compiled(
            s, c, sums[b] + (min(lo + block, y.size) - lo) * (y[lo] - offset)
        )
    return out


def fill_blocks(y, offset, bases, block, first, last, out):
    # out[i] = base of the block + the plain sum within the block of (y - offset) up to y[i], for
    # the blocks first <= b < last (inlined: strict IEEE in phase_blocks; in phase_and_sums'
    # fast-math context, where its stored partial sums keep the additions in order: the same bits,
    # tested)
    for b in range(first, last):
        base = bases[b]
        acc = 0.0
        for i in range(b * block, min(b * block + block, y.size)):
            acc += y[i] - offset
            out[i] = base + acc


def phase_blocks(y, offset, bases, block, out):
    # the running sum from the bases of its blocks, 256 blocks at a time per thread
    n_blocks = bases.size
    for g in numba.prange((n_blocks + 255) // 256):
        fill_blocks_compiled(y, offset, bases, block, g * 256, min(g * 256 + 256, n_blocks), out)
    return out


def phase_and_sums(
    y, offset, bases, block, x, ms, tile, lag, n_chunks, partial, starts, steps, counts, offsets,
    points, eights,
):
    # x[0] = 0 and x[1:] = phase_blocks' running sum, filled tile by tile (tile samples, a multiple
    # of block) on n_chunks runs of tiles, one per thread; each run sums the sizes ms over its tiles
    # of start indices (tile_sums) lag tiles behind its fill, while the tiles are in cache (lag
    # tiles cover the reach of the largest size, 2 max(ms)). A run's first tile (it reads the sample
    # the run before writes) and its last lag tiles are summed after every fill. Tile sums added in
    # tile order: the same bits as sums_all(x, ms, tile), on any number of runs. partial: zeros of
    # shape ((len(x) - 2 min(ms) + tile - 1) // tile, len(ms)), left holding each tile's sums (the
    # parts' sums are read off them: span_sums). Each tile just filled also gives gather_points its
    # samples (starts, steps, counts, offsets, points: the noise identification's phase samples,
    # read while the tile is in cache instead of at scattered lines of the record afterwards; x[0]
    # is not gathered) and, where eights is not empty (len(y) // 8: a column of pair_prefix's
    # table), its 8-sample block sums of x[1:] for the position contrasts (eight_sum, inlined,
    # without another read of the record; in this kernel's fast-math context, so the 8 samples may
    # be added in another order than block_sums' tree: a sum of them all the same).
    x[0] = 0.0
    out = x[1:]
    per_tile = tile // block
    n_fill = (y.size + tile - 1) // tile
    n_tiles = partial.shape[0]
    done = np.zeros(n_tiles, dtype=np.bool_)
    run = (n_fill + n_chunks - 1) // n_chunks
    for c in numba.prange(n_chunks):
        first = c * run
        for t in range(first, min(first + run, n_fill)):
            fill_blocks_compiled(
                y, offset, bases, block, t * per_tile, min(t * per_tile + per_tile, bases.size), out
            )
            gather_points_compiled(
                x, t * tile + 1, min(t * tile + tile, y.size) + 1, starts, steps, counts, offsets,
                points,
            )
            for b in range(t * (tile // 8), min(t * (tile // 8) + tile // 8, eights.size)):
                eights[b] = eight_sum_compiled(out, 8 * b)
            s = t - lag
            if first < s < n_tiles:
                tile_sums_compiled(x, ms, s * tile, tile, partial[s])
                done[s] = True
    for s in numba.prange(n_tiles):
        if not done[s]:
            tile_sums_compiled(x, ms, s * tile, tile, partial[s])
    return block_totals_compiled(x, ms, tile, partial)


def residue_sums(x, ms, period, width, n_chunks):
    # the sums of sizes m that are multiples of period (each a whole number of periods, increasing)
    # by residues: for each run of width residues r0 <= r < r0 + width (mod period), the record's
    # samples x[q period + r] are gathered into a buffer of rows q (in cache: len(x) / period rows
    # of width), where a size m is a shift by m / period rows; every size is then summed from the
    # buffer (tile_sums over it in sub-blocks of 16 rows, the rows reading the last, partial row
    # apart). The record is read once for all these sizes instead of once per size (their streams
    # lie further apart than the caches hold). Residue runs split over n_chunks threads; their sums
    # added in residue order, so the bits do not depend on the threads.
    n = x.size
    rows = (n + period - 1) // period
    k = ms.size
    n_runs = period // width
    shifts = ms // period * width
    sub = 16 * width
    partial = np.zeros((n_runs, k))
    per = (n_runs + n_chunks - 1) // n_chunks
    for c in numba.prange(n_chunks):
        buf = np.empty(rows * width)
        row = np.empty(k)
        for rb in range(c * per, min(c * per + per, n_runs)):
            r0 = rb * width
            for q in range(rows):
                lo = q * period + r0
                cnt = min(width, n - lo)
                if cnt > 0:
                    buf[q * width:q * width + cnt] = x[lo:lo + cnt]
            full = buf[:(rows - 1) * width]  # rows 0 .. rows - 2 are complete
            for lo in range(0, full.size, sub):
                row[:] = 0.0
                tile_sums_compiled(full, shifts, lo, min(sub, full.size - lo), row)
                for j in range(k):
                    partial[rb, j] += row[j]
            # the row whose furthest sample lies in the last row: start indices with i + 2 m <
            # len(x)
            last = min(width, n - (rows - 1) * period - r0)
            for j in range(k):
                start = (rows - 1) * width - 2 * shifts[j]
                s = 0.0
                for r in range(max(last, 0)):
                    d = (
                        buf[start + 2 * shifts[j] + r]
                        - 2.0 * buf[start + shifts[j] + r]
                        + buf[start + r]
                    )
                    s += d * d
                partial[rb, j] += s
    out = np.empty(k)
    for j in range(k):
        total = 0.0
        for rb in range(n_runs):
            total += partial[rb, j]
        out[j] = total
    return out


def tile_sums(x, ms, lo, block, row):
    # the sums of every size over the start indices lo <= i < lo + block (and i < len(x) - 2 m),
    # into row[j] (a size with no start index there is left as it is): the sizes in the order given,
    # so on an octave grid a size's stream at x[i + m] is the block the size before it read at
    # x[i + 2 m'], still in cache, and the small sizes share one block of x. Four sizes m, 2m, 4m,
    # 8m in a row (an octave run) are summed in one loop over the block: six streams x[i],
    # x[i + m], ..., x[i + 16 m] for four sizes instead of twelve (the loop is bound by loads from
    # cache: fewer loads, faster on an octave grid; eight sizes a loop gained nothing); two sizes
    # m, 2m in one loop where four do not fit. The furthest sample read is x[lo + block - 1 + 2 M],
    # M the largest size (16 m = 2 x 8m in a run of four). Within about 1e-15 of sum3 on the same
    # size (LLVM vectorises the loops differently), not bit for bit.
    k = ms.size
    j = 0
    while j < k:
        m = ms[j]
        hi = min(lo + block, x.size - 2 * m)
        if j + 1 < k and ms[j + 1] == 2 * m and lo + block <= x.size - 4 * m:
            a0 = x[lo:lo + block]
            a1 = x[lo + m:lo + block + m]
            a2 = x[lo + 2 * m:lo + block + 2 * m]
            a4 = x[lo + 4 * m:lo + block + 4 * m]
            s1 = 0.0
            s2 = 0.0
            if (
                j + 3 < k
                and ms[j + 2] == 4 * m
                and ms[j + 3] == 8 * m
                and lo + block <= x.size - 16 * m
            ):
                a8 = x[lo + 8 * m:lo + block + 8 * m]
                a16 = x[lo + 16 * m:lo + block + 16 * m]
                s4 = 0.0
                s8 = 0.0
                for i in range(block):
                    z = a0[i]
                    d1 = a2[i] - 2.0 * a1[i] + z
                    d2 = a4[i] - 2.0 * a2[i] + z
                    d4 = a8[i] - 2.0 * a4[i] + z
                    d8 = a16[i] - 2.0 * a8[i] + z
                    s1 += d1 * d1
                    s2 += d2 * d2
                    s4 += d4 * d4
                    s8 += d8 * d8
                row[j + 2] = s4
                row[j + 3] = s8
                width = 4
            else:
                for i in range(block):
                    z = a0[i]
                    d1 = a2[i] - 2.0 * a1[i] + z
                    d2 = a4[i] - 2.0 * a2[i] + z
                    s1 += d1 * d1
                    s2 += d2 * d2
                width = 2
            row[j] = s1
            row[j + 1] = s2
            j += width
            continue
        if hi > lo:
            x0 = x[lo:hi]
            x1 = x[lo + m:hi + m]
            x2 = x[lo + 2 * m:hi + 2 * m]
            s = 0.0
            for i in range(hi - lo):
                d = x2[i] - 2.0 * x1[i] + x0[i]
                s += d * d
            row[j] = s
        j += 1


def sums_all(x, ms, block):
    # every cluster size in one pass over the record, block by block of start indices
    # (tile_sums); block sums added in a fixed order (no dependence on the threads)
    k = ms.size
    n_blocks = (x.size - 2 * ms.min() + block - 1) // block
    partial = np.zeros((n_blocks, k))
    for b in numba.prange(n_blocks):
        tile_sums_compiled(x, ms, b * block, block, partial[b])
    return block_totals_compiled(x, ms, block, partial)


def gather_points(x, lo, hi, starts, steps, counts, offsets, points):
    # points[offsets[i] + q] = x[starts[i] + q steps[i]] for 0 <= q <= counts[i] where
    # lo <= starts[i] + q steps[i] < hi: each size's phase samples that lie in x[lo:hi]
    for i in range(starts.size):
        s = starts[i]
        m = steps[i]
        if hi <= s:
            continue
        q0 = 0 if lo <= s else (lo - s + m - 1) // m
        q1 = min(counts[i], (hi - 1 - s) // m)
        for q in range(q0, q1 + 1):
            points[offsets[i] + q] = x[s + q * m]


def span_sums(x, ms, lo, count):
    # the sums of every size over the start indices lo <= i < lo + count (and i < len(x) - 2 m):
    # tile_sums over one span, for the ends of a part of the record that whole tiles do not cover
    row = np.zeros(ms.size)
    tile_sums_compiled(x, ms, lo, count, row)
    return row


def block_totals(x, ms, block, partial):
    # each size's sum of its blocks' sums, in block order
    out = np.empty(ms.size)
    for j in range(ms.size):
        total = 0.0
        for b in range((x.size - 2 * ms[j] + block - 1) // block):
            total += partial[b, j]
        out[j] = total
    return out


def tile_starts(lo, hi, n, n_cal, k, stride):
    # (q0, q1): the starts j = n_cal + q stride (q0 <= q < q1) of outage k in the tile [lo, hi)
    # of a record of n samples, of those j <= n - k
    count = (n - n_cal - k) // stride + 1
    q0 = 0 if lo <= n_cal else (lo - n_cal + stride - 1) // stride
    q1 = min(count, (hi - n_cal + stride - 1) // stride) if hi > n_cal else 0
    return q0, q1


def tile_means(partial, n, n_cal, ks, strides):
    # each outage's tile sums (a column of partial) added in tile order, over its count of starts
    out = np.empty(ks.size)
    for i in range(ks.size):
        total = 0.0
        for t in range(partial.shape[0]):
            total += partial[t, i]
        out[i] = total / ((n - n_cal - ks[i]) // strides[i] + 1)
    return out


def eight_sum(v, lo):
    # v[lo] + ... + v[lo + 7] in a fixed tree (inlined: strict IEEE in block_sums, in any order
    # inside phase_and_sums' fast-math loop)
    return ((v[lo] + v[lo + 1]) + (v[lo + 2] + v[lo + 3])) + (
        (v[lo + 4] + v[lo + 5]) + (v[lo + 6] + v[lo + 7]))


def block_sums(v, chunk, out):
    # out[b] = eight_sum of every whole block of 8 samples of v (len(out) = len(v) // 8; a column
    # of pair_prefix's table), chunk blocks at a time per thread
    nb = out.size
    for h in numba.prange((nb + chunk - 1) // chunk):
        for b in range(h * chunk, min(h * chunk + chunk, nb)):
            out[b] = eight_sum_compiled(v, 8 * b)
    return out


def pair_prefix(pairs, chunk):
    # in place: pairs[b] = (hi, lo) = sum_{q < b} blocks[q] for 0 <= b <= nb, from the block sums
    # blocks[q] = pairs[q + 1, 0] (block_sums or the fill wrote them there: one table,
    # no second array to fault in), as a compensated pair (the value hi + lo, exact to the rounding
    # of the blocks' own sums): each chunk's total on the threads, the chunks' bases added in order
    # with Kahan-Babuska compensation, then each chunk's running pair from its base on the threads
    # (strict IEEE: the compensation is not optimised away). The position contrasts' windows are
    # differences of two such sums (contrast_sums): 16 bytes per 8 samples instead of a running
    # sum of every sample (80 MB at 1e7 samples, written and read)
    nb = pairs.shape[0] - 1
    pairs[0, 0] = 0.0
    pairs[0, 1] = 0.0
    n_chunks = (nb + chunk - 1) // chunk
    totals = np.zeros((n_chunks, 2))
    for h in numba.prange(n_chunks):
        s = 0.0
        c = 0.0
        for b in range(h * chunk, min(h * chunk + chunk, nb)):
            s, c = compensated_add_compiled(s, c, pairs[b + 1, 0])
        totals[h, 0] = s
        totals[h, 1] = c
    bases = np.zeros((n_chunks, 2))
    s = 0.0
    c = 0.0
    for h in range(n_chunks):
        bases[h, 0] = s
        bases[h, 1] = c
        s, c = compensated_add_compiled(s, c, totals[h, 0])
        s, c = compensated_add_compiled(s, c, totals[h, 1])
    for h in numba.prange(n_chunks):
        s = bases[h, 0]
        c = bases[h, 1]
        for b in range(h * chunk, min(h * chunk + chunk, nb)):
            s, c = compensated_add_compiled(s, c, pairs[b + 1, 0])
            pairs[b + 1, 0] = s
            pairs[b + 1, 1] = c
    return pairs


def head_sum(x, lo, r):
    # x[lo] + ... + x[lo + r - 1] for 0 <= r < 8 (lo + 6 < len(x)): the seven samples read and
    # masked, added in a fixed tree, without a branch on r (a loop of r additions in a row was
    # the position contrasts' largest cost)
    v0 = x[lo] if r > 0 else 0.0
    v1 = x[lo + 1] if r > 1 else 0.0
    v2 = x[lo + 2] if r > 2 else 0.0
    v3 = x[lo + 3] if r > 3 else 0.0
    v4 = x[lo + 4] if r > 4 else 0.0
    v5 = x[lo + 5] if r > 5 else 0.0
    v6 = x[lo + 6] if r > 6 else 0.0
    return ((v0 + v1) + (v2 + v3)) + ((v4 + v5) + v6)


def phase_contrast(x, j, k, r, n_cal):
    # x[j + k] - (1 + r) x[j] + r x[j - n_cal] (contrast_sums' phase contrast, in one place for its
    # three loops: the same order of operations, strict IEEE)
    return x[j + k] - (1.0 + r) * x[j] + r * x[j - n_cal]


def prefix_at(v, prefix, p):
    # (b, t): sum v[:p] = prefix[b] + t, b = p // 8, t the samples of block b before p
    b = p >> 3
    if b < prefix.shape[0] - 1:
        return b, head_sum_compiled(v, 8 * b, p - 8 * b)
    t = 0.0  # the record's last, partial block
    for i in range(8 * b, p):
        t += v[i]
    return b, t


def contrast_sums(x, pairs, ks, n_cal, strides, tile, position):
    # (len(ks), 2): the mean squares of the phase contrasts e_j = x[j + k] - (1 + r) x[j] + r x[j -
    # n_cal], r = k / n_cal (column 0; allan/contrast.py's contrast_mean_square, the same e_j:
    # strict IEEE, no contraction into fused multiply-adds) and, with position, of the position
    # contrasts p_j = sum_{j < i < j + k} x[i] - (k - 1 + c) x[j] + c x[j - n_cal], c = k (k - 1) /
    # (2 n_cal) (column 1, else 0; allan/contrast.py's position_mean_square; the constant it
    # annihilates need not be taken out first), over the starts j = n_cal, n_cal + st, ... <=
    # len(x) - 1 - k, for each outage k and its stride st. The starts are taken tile by tile (tile
    # starts, on the threads), every outage in a tile before the next, each tile after one read of
    # the next tile's samples (and of its rows of pairs), a cache line at a time (the hardware
    # prefetcher streams them in): the outages shorter than a tile then read x from cache, not
    # each at scattered lines from memory (a stride of 187 samples is 1.5 kB; scattered, a long
    # record's contrasts took 4x as long). A position window x[j + 1 : j + k] = v[j : j + k - 1] of
    # v = x[1:] longer than 8 samples is the difference of two compensated running pairs of its
    # 8-sample blocks (pairs: pair_prefix; exact differences) and at most seven samples at each
    # end, next to x[j] and x[j + k], which the phase contrast reads anyway; a shorter one is
    # added in order. Tile sums added in tile order.
    n = x.size - 1
    v = x[1:]
    nk = ks.size
    n_tiles = (n + tile) // tile  # starts 0 <= j <= n
    n_pairs = pairs.shape[0]
    partial = np.zeros((n_tiles, 2 * nk + 1))
    for t in numba.prange(n_tiles):
        lo = t * tile
        hi = min(lo + tile, n + 1)
        warm = 0.0
        for p in range(hi, min(hi + tile, n + 1), 8):
            warm += x[p]
        if position:
            for p in range(min(hi >> 3, n_pairs), min((hi + tile) >> 3, n_pairs), 4):
                warm += pairs[p, 0]
        partial[t, 2 * nk] = warm  # kept, so that the reads are not optimised away
        for i in range(nk):
            k = ks[i]
            st = strides[i]
            r = k / n_cal
            c = k * (k - 1) / (2.0 * n_cal)
            a = k - 1 + c
            q0, q1 = tile_starts_compiled(lo, hi, n, n_cal, k, st)
            total = 0.0
            total_2 = 0.0
            if not position:
                for q in range(q0, q1):
                    j = n_cal + q * st
                    e = phase_contrast_compiled(x, j, k, r, n_cal)
                    total += e * e
            elif k <= 9:  # a window of at most 8 samples: added in order (k = 1: empty, p = 0)
                for q in range(q0, q1):
                    j = n_cal + q * st
                    e = phase_contrast_compiled(x, j, k, r, n_cal)
                    total += e * e
                    w = 0.0
                    for m in range(j + 1, j + k):
                        w += x[m]
                    e2 = w - a * x[j] + c * x[j - n_cal]
                    total_2 += e2 * e2
            else:
                for q in range(q0, q1):
                    j = n_cal + q * st
                    e = phase_contrast_compiled(x, j, k, r, n_cal)
                    total += e * e
                    b0, t0 = prefix_at_compiled(v, pairs, j)
                    b1, t1 = prefix_at_compiled(v, pairs, j + k - 1)
                    w = ((pairs[b1, 0] - pairs[b0, 0]) + (pairs[b1, 1] - pairs[b0, 1])) + (
                        t1 - t0)
                    e2 = w - a * x[j] + c * x[j - n_cal]
                    total_2 += e2 * e2
            partial[t, i] = total
            partial[t, nk + i] = total_2
    out = np.empty((nk, 2))
    out[:, 0] = tile_means_compiled(partial[:, :nk], n, n_cal, ks, strides)
    out[:, 1] = tile_means_compiled(partial[:, nk:2 * nk], n, n_cal, ks, strides)
    return out


def lag1_deltas(x, ms, starts, steps, counts, max_differences, n_chunks):
    # the lag-1 noise identification (allan/estimator.py's _lag1_delta, Riley & Greenhall 2004) of
    # each size i: the counts[i] cluster means (x[start + (q + 1) step] - x[start + q step]) / m
    # (step = m on the phase record, 1 on its samples gathered by gather_points), their
    # least-squares line removed, then differenced until delta = r1 / (1 + r1) < 0.25 or
    # max_differences times; out[i] = (delta, d). The same steps as numpy's, the sums vectorised
    # (fast-math: numpy's are pairwise, the deltas agree to about 1e-15). Sizes dealt to
    # n_chunks threads in turn (the small ones, with the most means, on every thread).
    out = np.zeros((ms.size, 2))
    for c in numba.prange(n_chunks):
        for i in range(c, ms.size, n_chunks):
            n = counts[i]
            if n < 2:
                continue
            m = ms[i]
            start = starts[i]
            step = steps[i]
            z = np.empty(n)
            for q in range(n):
                z[q] = (x[start + (q + 1) * step] - x[start + q * step]) / m
            centre = (n - 1) / 2.0
            total = 0.0
            for q in range(n):
                total += z[q]
            mean = total / n
            tz = 0.0
            tt = 0.0
            for q in range(n):
                z[q] -= mean
                t = q - centre
                tz += t * z[q]
                tt += t * t
            slope = tz / tt
            for q in range(n):
                z[q] -= slope * (q - centre)
            d = 0
            size = n
            while True:
                total = 0.0
                for q in range(size):
                    total += z[q]
                mean = total / size
                denom = 0.0
                for q in range(size):
                    z[q] -= mean
                    denom += z[q] * z[q]
                lag = 0.0
                for q in range(size - 1):
                    lag += z[q] * z[q + 1]
                r1 = lag / denom if denom > 0 else 0.0
                delta = r1 / (1.0 + r1)
                if delta < 0.25 or d >= max_differences:
                    out[i, 0] = delta
                    out[i, 1] = d
                    break
                for q in range(size - 1):
                    z[q] = z[q + 1] - z[q]
                size -= 1
                d += 1
    return out


# module globals, not closure variables: numba's cache keys a closure's captured dispatcher by
# identity, so a kernel calling one would be recompiled in every process
pair_sum_compiled = numba.njit(cache=True)(pair_sum)
tile_sums_compiled = numba.njit(inline="always")(tile_sums)
block_totals_compiled = numba.njit(inline="always")(block_totals)
compensated_add_compiled = numba.njit(inline="always")(compensated_add)
fill_blocks_compiled = numba.njit(inline="always")(fill_blocks)
eight_sum_compiled = numba.njit(inline="always")(eight_sum)
gather_points_compiled = numba.njit(inline="always")(gather_points)
tile_starts_compiled = numba.njit(inline="always")(tile_starts)
tile_means_compiled = numba.njit(inline="always")(tile_means)
head_sum_compiled = numba.njit(inline="always")(head_sum)
prefix_at_compiled = numba.njit(inline="always")(prefix_at)
phase_contrast_compiled = numba.njit(inline="always")(phase_contrast)
