"""Private compiled kernels (numba) for the Allan variance.

numba is imported lazily (on first use) so that ``import bayes_imu`` stays fast; the
compiled code is cached on disk next to this module.

Why numba: the fully overlapping Allan variance sums over the whole phase record for every
cluster size. In numpy each size is three temporaries and a dot product (about 3.5x faster
than allantools at best); a fused, multi-threaded loop over blocks of the record sums every
size while the block is in cache (:func:`second_difference_sums`).
"""

import contextlib

import numpy as np

__all__ = ["phase_from_rate", "phase_chunk", "second_difference_sum", "second_difference_sums", "avar_pair_sums",
           "threads_for", "threads_for_pass", "SAMPLES_PER_THREAD"]

_BLOCK = 1 << 14
#: start indices per block of the one-pass sums of every cluster size (:func:`second_difference_sums`)
_BLOCK_ALL = 1 << 16
#: samples per plain sum of the compensated running sum
_PHASE_BLOCK = 256
#: samples per thread of the Allan variance sums (8 MiB of phase: ~1 ms of work per cluster size)
SAMPLES_PER_THREAD = 1 << 20
_compiled = {}
_pair_sum = None  # the compiled pair sum, set by _compile


def _compile():
    if _compiled:
        return _compiled
    import numba

    # a module global, not a closure variable: numba's cache keys a closure's captured
    # dispatcher by identity, so a kernel calling one recompiled in every process
    global _pair_sum
    _pair_sum = numba.njit(cache=True)(_pair_sum_py)

    @numba.njit(parallel=True, cache=True)
    def pair_sums(table, ms, n, h, s2, x):
        k = ms.size
        out = np.zeros((k, k))
        for idx in numba.prange(k * k):
            ia = idx // k
            ib = idx % k
            if ib < ia:
                continue
            out[ia, ib] = _pair_sum(table, ms[ia], ms[ib], n, h, s2, x)
            out[ib, ia] = out[ia, ib]
        return out

    @numba.njit(cache=True)
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

    @numba.njit(parallel=True, cache=True, fastmath={"reassoc", "contract", "nsz", "arcp"})
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

    @numba.njit(parallel=True, cache=True)
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

    @numba.njit(cache=True)
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

    @numba.njit(parallel=True, cache=True)
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

    @numba.njit(parallel=True, cache=True, fastmath={"reassoc", "contract", "nsz", "arcp"})
    def sums_all(x, ms, block):
        # every cluster size in one pass over the record: for each block of start indices the
        # sizes are summed in increasing order, so a size's stream at x[i + m] is the block the
        # size before it read at x[i + 2 m'] (an octave grid), still in cache, and the small
        # sizes share one block of x. Block sums added in a fixed order (no dependence on the
        # threads); within about 1e-15 of sum3 on the same size (LLVM vectorises the two loops
        # differently), not bit for bit.
        k = ms.size
        n_blocks = (x.size - 2 * ms.min() + block - 1) // block
        partial = np.zeros((n_blocks, k))
        for b in numba.prange(n_blocks):
            lo = b * block
            for j in range(k):
                m = ms[j]
                hi = min(lo + block, x.size - 2 * m)
                if hi <= lo:
                    continue
                x0 = x[lo:hi]
                x1 = x[lo + m:hi + m]
                x2 = x[lo + 2 * m:hi + 2 * m]
                s = 0.0
                for i in range(hi - lo):
                    d = x2[i] - 2.0 * x1[i] + x0[i]
                    s += d * d
                partial[b, j] = s
        out = np.empty(k)
        for j in range(k):
            total = 0.0
            for b in range((x.size - 2 * ms[j] + block - 1) // block):
                total += partial[b, j]
            out[j] = total
        return out

    _compiled.update(pair_sums=pair_sums, phase_chunk=phase_chunk, sum3=sum3, sums_all=sums_all,
                     chunk_totals=chunk_totals, chunk_bases=chunk_bases, phase_blocks=phase_blocks)
    return _compiled


def _pair_sum_py(table, a, b, n, h, s2, x):
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


def phase_from_rate(y, offset):
    """Running sums ``x[i] = sum_{j<i} (y[j] - offset)``, length ``len(y) + 1``, compensated.

    Sums of at most 256 terms are added to a compensated running total, so each ``x[i]``
    is within a few ulp of the exact prefix sum however long the record: the second
    differences of ``x`` keep their precision on long records. The 256-sample sums are
    formed on :func:`threads_for` threads, the compensated total of them in order, then the
    blocks filled in parallel: the numbers of one sequential pass (:func:`phase_chunk`), bit
    for bit, on any number of threads.
    """
    kernels = _compile()
    y = np.ascontiguousarray(y, dtype=float)
    out = np.empty(y.size + 1)
    out[0] = 0.0
    if threads_for(y.size) == 1:  # one thread: the sequential pass itself, reading the record once instead of twice
        kernels["phase_chunk"](y, float(offset), out[1:], _PHASE_BLOCK, np.zeros(2))
        return out
    with threads_for_pass(y.size):
        bases = kernels["chunk_bases"](kernels["chunk_totals"](y, float(offset), _PHASE_BLOCK))
        kernels["phase_blocks"](y, float(offset), bases, _PHASE_BLOCK, out[1:])
    return out


def phase_chunk(y, offset, state):
    """Running sums of one chunk of a record, continuing ``state = [s, c]`` (updated in place).

    Returns ``x`` after each sample of the chunk; with chunks of a multiple of 256 samples
    the concatenation equals :func:`phase_from_rate` (without its leading 0) bit for bit.
    """
    out = np.empty(y.size)
    return _compile()["phase_chunk"](np.ascontiguousarray(y, dtype=float), float(offset), out, _PHASE_BLOCK, state)


def second_difference_sum(x0, x1, x2):
    """``sum_i (x2[i] - 2 x1[i] + x0[i])**2`` over three equal-length slices of a phase record."""
    return float(_compile()["sum3"](x0, x1, x2, _BLOCK))


def threads_for(n_samples):
    """Threads for a pass over ``n_samples``: one per :data:`SAMPLES_PER_THREAD` (at least one, at
    most numba's pool). A short record is summed on one thread: starting the others costs more than
    they save, and on a busy machine they would wait for cores (oversubscription)."""
    import numba

    return int(max(1, min(numba.config.NUMBA_NUM_THREADS, n_samples // SAMPLES_PER_THREAD)))


@contextlib.contextmanager
def threads_for_pass(n_samples):
    """Run numba's parallel loops on :func:`threads_for` ``(n_samples)`` threads inside the block, restoring
    the caller's setting after it."""
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(threads_for(n_samples))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def second_difference_sums(x, ms):
    """``sum_i (x[i+2m] - 2 x[i+m] + x[i])**2`` over ``0 <= i < len(x) - 2m`` for each ``m``.

    One pass over the record for every cluster size at once: for each block of
    :data:`_BLOCK_ALL` start indices the sizes are summed in increasing order, so that the
    small sizes share one block of ``x`` in cache and, on an octave grid, a size's middle
    stream ``x[i + m]`` is the block the size before it has just read as ``x[i + 2m']``; the
    record is read about once plus once per size larger than a block, instead of three times
    per size. Block sums are added in a fixed order, so the result does not depend on the
    number of threads (:func:`threads_for`).
    """
    ms = np.ascontiguousarray(ms, dtype=np.int64)
    if ms.size == 0:
        return np.empty(0)
    with threads_for_pass(x.size):
        return _compile()["sums_all"](np.ascontiguousarray(x, dtype=float), ms, _BLOCK_ALL)


def avar_pair_sums(table, ms, n, h, s2, x):
    """Lag sums ``sum_l n(l) c(l)^2`` for every pair of cluster sizes (symmetric matrix).

    ``table[k] = D(k)`` is the model's phase structure function for ``0 <= k <= 4 max(ms)``;
    ``h`` the flicker level ``B^2/pi``; ``s2`` and ``x = dt/T`` arrays over the Gauss-Markov
    components (empty when there are none).
    """
    return _compile()["pair_sums"](np.ascontiguousarray(table, dtype=float),
                                    np.ascontiguousarray(ms, dtype=np.int64), int(n), float(h),
                                    np.ascontiguousarray(s2, dtype=float), np.ascontiguousarray(x, dtype=float))
