"""Sources of the compiled Allan-variance kernels: plain Python that numba compiles twice.

Imported only to compile (it imports numba): :mod:`bayes_imu.allan.kernels` JIT-compiles these
functions on first use (``parallel=True`` where they use ``numba.prange``, cached on disk), and
the package build compiles the same functions ahead of time, one thread each (``prange`` is
``range`` there), into the extension ``bayes_imu._compiled`` (``setup.py``), which loads without
numba. :data:`FASTMATH` names the kernels compiled with reassociation (a vectorised sum of
squares); the running sums never are (their Kahan-Babuska compensation would be optimised away).
"""

import numba
import numpy as np

__all__ = ["pair_sum", "pair_sums", "phase_chunk", "sum3", "chunk_totals", "chunk_bases", "phase_blocks", "sums_all",
           "FASTMATH", "PARALLEL"]

#: LLVM fast-math flags of the sum-of-squares kernels
FASTMATH = {"sum3": {"reassoc", "contract", "nsz", "arcp"}, "sums_all": {"reassoc", "contract", "nsz", "arcp"}}
#: kernels whose ``prange`` loops run on numba's threads when JIT-compiled
PARALLEL = {"pair_sums", "sum3", "chunk_totals", "phase_blocks", "sums_all"}


def pair_sum(table, a, b, n, h, s2, x):
    """``sum_l n(l) c(l)^2`` for one pair of cluster sizes (see :mod:`bayes_imu.noise.avar_covariance`).

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
        amp[g] = s2[g] * phi * (-np.expm1(-a * x[g])) ** 2 * (-np.expm1(-b * x[g])) ** 2 / one_minus_phi**2
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
        t = s + acc
        if abs(s) >= abs(acc):
            c += (s - t) + acc
        else:
            c += (acc - t) + s
        s = t
    state[0] = s
    state[1] = c
    return out


def sum3(a0, a1, a2, block):
    # views sliced per block and indexed from 0: LLVM vectorises this form (indexing the
    # whole arrays from `lo` instead measured 6x slower)
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


def chunk_totals(y, offset, block):
    # the plain sum of (y - offset) over each block, in the order phase_chunk adds it (the
    # threads take 256 blocks at a time)
    n_blocks = (y.size + block - 1) // block
    out = np.empty(n_blocks)
    for g in numba.prange((n_blocks + 255) // 256):
        for b in range(g * 256, min(g * 256 + 256, n_blocks)):
            acc = 0.0
            for i in range(b * block, min(b * block + block, y.size)):
                acc += y[i] - offset
            out[b] = acc
    return out


def chunk_bases(totals):
    # phase_chunk's compensated running total (s + c) before each block, from the block sums
    s = 0.0
    c = 0.0
    out = np.empty(totals.size)
    for b in range(totals.size):
        out[b] = s + c
        acc = totals[b]
        t = s + acc
        if abs(s) >= abs(acc):
            c += (s - t) + acc
        else:
            c += (acc - t) + s
        s = t
    return out


def phase_blocks(y, offset, bases, block, out):
    # out[i] = base of the block + the plain sum within the block after y[i]: phase_chunk's
    # numbers, 256 blocks at a time per thread
    n_blocks = bases.size
    for g in numba.prange((n_blocks + 255) // 256):
        for b in range(g * 256, min(g * 256 + 256, n_blocks)):
            base = bases[b]
            acc = 0.0
            for i in range(b * block, min(b * block + block, y.size)):
                acc += y[i] - offset
                out[i] = base + acc
    return out


def sums_all(x, ms, block):
    # every cluster size in one pass over the record: for each block of start indices the
    # sizes are summed in the order given, so on an octave grid a size's stream at x[i + m] is
    # the block the size before it read at x[i + 2 m'], still in cache, and the small sizes
    # share one block of x. Four sizes m, 2m, 4m, 8m in a row (an octave run) are summed in one
    # loop over the block: six streams x[i], x[i + m], ..., x[i + 16 m] for four sizes instead of
    # twelve (the loop is bound by loads from cache: 1.4-1.5x faster on an octave grid; eight
    # sizes a loop gained nothing more); two sizes m, 2m in one loop where four do not fit. Block sums
    # added in a fixed order (no dependence on the threads); within about 1e-15 of sum3 on the
    # same size (LLVM vectorises the loops differently), not bit for bit.
    k = ms.size
    n_blocks = (x.size - 2 * ms.min() + block - 1) // block
    partial = np.zeros((n_blocks, k))
    for b in numba.prange(n_blocks):
        lo = b * block
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
                if j + 3 < k and ms[j + 2] == 4 * m and ms[j + 3] == 8 * m and lo + block <= x.size - 16 * m:
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
                    partial[b, j + 2] = s4
                    partial[b, j + 3] = s8
                    width = 4
                else:
                    for i in range(block):
                        z = a0[i]
                        d1 = a2[i] - 2.0 * a1[i] + z
                        d2 = a4[i] - 2.0 * a2[i] + z
                        s1 += d1 * d1
                        s2 += d2 * d2
                    width = 2
                partial[b, j] = s1
                partial[b, j + 1] = s2
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
                partial[b, j] = s
            j += 1
    out = np.empty(k)
    for j in range(k):
        total = 0.0
        for b in range((x.size - 2 * ms[j] + block - 1) // block):
            total += partial[b, j]
        out[j] = total
    return out


# a module global, not a closure variable: numba's cache keys a closure's captured dispatcher by
# identity, so a kernel calling one would be recompiled in every process
pair_sum_compiled = numba.njit(cache=True)(pair_sum)
