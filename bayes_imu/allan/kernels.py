"""Private compiled kernels (numba) for the Allan variance.

Two builds of one source (:mod:`bayes_imu.allan._sources`):

* *precompiled*: the package build compiles the kernels ahead of time into the extension
  ``bayes_imu._compiled`` (``setup.py``, numba's AOT compiler), which imports in under a
  millisecond and without numba. A record shorter than :data:`PRECOMPILED_BELOW` samples (one
  thread's work, :func:`threads_for`) is summed there: a command that fits such a log never imports
  numba nor loads its compiled-code machinery, which would cost it more than the whole Allan
  variance (timings: docs/speed_under_load.md#imports).
* *JIT*: longer records, and the out-of-core pass, use the same kernels compiled by numba on
  first use (``parallel=True``: the record's blocks on several threads), cached on disk next to
  the sources. Where the extension was not built (a numba without its AOT compiler), every
  record takes this path.

The path depends on the record's length alone, never on the machine or the thread count. A record
the precompiled kernels sum gives the same numbers on every x86-64 CPU; the JIT build's sums of
squares are vectorised for the CPU at hand (fast-math reductions), so on another CPU family a long
record's sums may differ in the last bits (about 1e-15, as between the two builds; the running sums
and lag sums are strict IEEE and agree bit for bit).

Why compiled code: the fully overlapping Allan variance sums over the whole phase record for every
cluster size. In numpy each size is three temporaries and a dot product, one pass over the
record each; a fused, multi-threaded loop over blocks of the record sums every
size while the block is in cache (:func:`second_difference_sums`).
"""

import contextlib

import numpy as np

__all__ = [
    "record_mean",
    "phase_from_rate",
    "allan_sums",
    "phase_chunk",
    "second_difference_sum",
    "second_difference_sums",
    "avar_pair_sums",
    "contrast_mean_squares",
    "lag1_deltas",
    "threads_for",
    "threads_for_pass",
    "precompiled",
    "compiled_kernel",
    "SAMPLES_PER_THREAD",
    "PRECOMPILED_BELOW",
]

_BLOCK = 1 << 14
#: start indices per block of the one-pass sums of every cluster size
#: (:func:`second_difference_sums`)
_BLOCK_ALL = 1 << 16
#: samples per plain sum of the compensated running sum
_PHASE_BLOCK = 256
#: 8-sample blocks per thread's share of the position contrasts' block sums and running pairs
#: (``block_sums``, ``pair_prefix``)
_PREFIX_CHUNK = 4096
#: residues per run of the residue sums of the sizes that are whole blocks (:func:`_far_sums`)
_RESIDUES = 256
#: samples per thread of the Allan variance sums (8 MiB of phase: enough work per cluster size to
#: pay for a thread)
SAMPLES_PER_THREAD = 1 << 20
#: records shorter than this are summed by the precompiled kernels, on one thread
#: (:func:`threads_for` gives one thread below it on any machine)
PRECOMPILED_BELOW = 2 * SAMPLES_PER_THREAD
_compiled = {}


def precompiled():
    """The ahead-of-time build of the kernels (module ``bayes_imu._compiled``), or ``None`` where
    the package was built without it."""
    try:
        from .. import _compiled as module
    except ImportError:
        return None
    return module


def _compile():
    """The JIT build of every kernel (imports numba; compiled once, then loaded from numba's
    cache)."""
    if _compiled:
        return _compiled
    import numba

    from . import _sources

    for name in (
        "pair_sums",
        "phase_chunk",
        "sum3",
        "centred_sums",
        "centred_mean",
        "centred_bases",
        "phase_blocks",
        "phase_and_sums",
        "residue_sums",
        "span_sums",
        "sums_all",
        "contrast_sums",
        "block_sums",
        "pair_prefix",
        "lag1_deltas",
    ):
        _compiled[name] = numba.njit(
            parallel=name in _sources.PARALLEL,
            cache=True,
            fastmath=_sources.FASTMATH.get(name, False),
        )(getattr(_sources, name))
    return _compiled


def _precompiled_for(n_samples):
    """The ahead-of-time build where it sums a record of ``n_samples`` (shorter than
    :data:`PRECOMPILED_BELOW` and built), else ``None``: the JIT kernels of :func:`_compile`
    then."""
    return precompiled() if n_samples < PRECOMPILED_BELOW else None


def compiled_kernel(name, sources, **jit_options):
    """The compiled kernel ``name`` of another module: the ahead-of-time build's where the package
    has it (no numba import, nothing compiled), else numba's JIT build (``jit_options``, cached on
    disk) of the function ``name`` of the module ``sources``, imported only then (a kernel source
    module imports numba). An extension built before a kernel was added (an in-place build not
    redone) lacks it: that kernel is then JIT-compiled."""
    module = precompiled()
    if module is not None and hasattr(module, name):
        return getattr(module, name)
    import importlib

    import numba

    return numba.njit(cache=True, **jit_options)(getattr(importlib.import_module(sources), name))


def record_mean(y):
    """Mean of a record, the offset removed before its running sum (:func:`phase_from_rate`).

    A record the JIT kernels sum (:func:`_precompiled_for`) is read once on :func:`threads_for`
    threads: the plain sums of its 256-sample blocks about each block's first sample, added with
    their first samples in a compensated (Kahan-Babuska) sum: within 4 ulp of the exact mean in the
    test against rationals, the same bits on any number of threads; that pass also gives the block
    sums of the running sum (:func:`allan_sums` reads the record once for both). A shorter record
    takes ``numpy.mean`` (pairwise sums). Which one depends on the length alone, as the kernels'
    build does.
    """
    y = np.ascontiguousarray(y, dtype=float)
    if y.size == 0 or _precompiled_for(y.size) is not None:
        return float(np.mean(y))
    kernels = _compile()
    with threads_for_pass(y.size):
        return float(
            kernels["centred_mean"](y, kernels["centred_sums"](y, _PHASE_BLOCK), _PHASE_BLOCK)
        )


def phase_from_rate(y, offset):
    """Running sums ``x[i] = sum_{j<i} (y[j] - offset)``, length ``len(y) + 1``, compensated.

    Sums of at most 256 terms are added to a compensated running total, so each ``x[i]``
    is within a few ulp of the exact prefix sum however long the record: the second
    differences of ``x`` keep their precision on long records. A record the precompiled kernels
    sum takes one sequential pass (:func:`phase_chunk`). A longer one is read twice on
    :func:`threads_for` threads: the sums of its 256-sample blocks about each block's first sample
    (as precise as sums about ``offset``, :func:`record_mean`), their compensated total about
    ``offset`` before each block in order, then the blocks filled in parallel: the same bits on any
    number of threads, and :func:`allan_sums`' running sum bit for bit (not the sequential pass's:
    the block totals are rounded differently, within a few ulp of the exact prefix sums either way).
    """
    y = np.ascontiguousarray(y, dtype=float)
    out = np.empty(y.size + 1)
    out[0] = 0.0
    aot = _precompiled_for(y.size)
    if aot is not None:
        aot.phase_chunk(y, float(offset), out[1:], _PHASE_BLOCK, np.zeros(2))
        return out
    kernels = _compile()
    with threads_for_pass(y.size):
        sums = kernels["centred_sums"](y, _PHASE_BLOCK)
        kernels["phase_blocks"](
            y,
            float(offset),
            kernels["centred_bases"](y, sums, float(offset), _PHASE_BLOCK),
            _PHASE_BLOCK,
            out[1:],
        )
    return out


def phase_chunk(y, offset, state):
    """Running sums of one chunk of a record, continuing ``state = [s, c]`` (updated in place).

    Returns ``x`` after each sample of the chunk; with chunks of a multiple of 256 samples
    the concatenation is the sequential pass over the whole record: :func:`phase_from_rate` (without
    its leading 0) bit for bit for a record shorter than :data:`PRECOMPILED_BELOW`, within a few ulp
    of it for a longer one (whose block totals are rounded differently).
    """
    out = np.empty(y.size)
    return _compile()["phase_chunk"](
        np.ascontiguousarray(y, dtype=float), float(offset), out, _PHASE_BLOCK, state
    )


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
    """Run numba's parallel loops on :func:`threads_for` ``(n_samples)`` threads inside the block,
    restoring the caller's setting after it."""
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
    per size. On a record the JIT kernels sum, the sizes that are whole multiples of a block
    (an octave grid's from 65536 up) are summed by residues instead (:func:`_far_sums`): one
    read of the record for all of them. Block sums are added in a fixed order, so the result
    does not depend on the number of threads (:func:`threads_for`).
    """
    ms = np.ascontiguousarray(ms, dtype=np.int64)
    if ms.size == 0:
        return np.empty(0)
    x = np.ascontiguousarray(x, dtype=float)
    aot = _precompiled_for(x.size)
    if aot is not None:
        return aot.sums_all(x, ms, _BLOCK_ALL)
    with threads_for_pass(x.size):
        return _far_sums(x, ms)


def _far_sums(x, ms):
    """JIT sums of the sizes ``ms`` (at least one) of a long record, inside
    :func:`threads_for_pass`: the whole multiples of :data:`_BLOCK_ALL` by residue runs of
    :data:`_RESIDUES` (``residue_sums``: the record gathered once, a run at a time, into a buffer of
    ``len(x) / 32`` bytes a thread), the others block by block (``sums_all``)."""
    kernels = _compile()
    by_residue = ms % _BLOCK_ALL == 0
    sums = np.empty(ms.size)
    if by_residue.any():
        sums[by_residue] = kernels["residue_sums"](
            x, ms[by_residue], _BLOCK_ALL, _RESIDUES, threads_for(x.size)
        )
    if not by_residue.all():
        sums[~by_residue] = kernels["sums_all"](x, ms[~by_residue], _BLOCK_ALL)
    return sums


def allan_sums(y, ms, progress=None, *, parts=None, gather=None, blocks=False):
    """The running sum ``x = phase_from_rate(y, record_mean(y))`` and its
    ``second_difference_sums(x, ms)`` (and, with ``parts``, those of consecutive parts of ``x``).

    A record the precompiled kernels sum takes exactly those three calls. A longer one is read
    twice instead of four times: once on :func:`threads_for` threads for the block sums that give
    both the mean and the running sum's block bases (:func:`record_mean`); then each thread fills a
    run of tiles of :data:`_BLOCK_ALL` samples and sums the sizes below a block over each tile of
    start indices one or two tiles behind its fill, while the running sum is still in cache
    (``phase_and_sums``); the sizes from a block up follow (:func:`_far_sums`). The same ``x`` as
    :func:`phase_from_rate` (bit for bit), the same sums as :func:`second_difference_sums` (bit for
    bit where no octave run of sizes straddles 65536), the same bits on any number of threads.

    Parameters
    ----------
    y : array_like, shape (n_samples,)
        Rate samples.
    ms : array_like of int
        Cluster sizes, ``2 m <= n_samples``, increasing (octave runs are detected in this order).
    progress : callable or None
        Called with the number of sizes just summed (a progress bar's ``update``).
    parts : (int, array_like of int) or None
        ``(n_parts, part_ms)``: also the sums of each of ``n_parts`` consecutive parts of
        ``length = n_samples // n_parts`` samples, ``second_difference_sums(x[k length:(k + 1)
        length + 1], part_ms)`` (sizes of ``ms``, ``4 m <= length``). A record the precompiled
        kernels sum takes those calls; a longer one reads the sizes below a block off the tiles
        the whole record's sums were added from (:func:`_part_sums`): no further pass over the
        record for them, the same values to about 1e-15 (the tiles are added in another order).
    gather : (array_like of int, array_like of int, array_like of int) or None
        ``(starts, steps, counts)``: also the phase samples ``x[starts[i] + q steps[i]]``, ``0 <= q
        <= counts[i]`` (the noise identification's, :func:`lag1_deltas`), gathered on a record the
        JIT kernels sum from each tile of ``x`` as it is filled (in cache).
    blocks : bool
        Also the sums of ``x[1:]`` in blocks of 8 samples that the position contrasts read
        (:func:`position_mean_squares`' ``pairs``), summed on a record the JIT kernels sum from
        each tile of ``x`` as it is filled; the result then always has five items.

    Returns
    -------
    x : ndarray, shape (n_samples + 1,)
    sums : ndarray, shape (len(ms),)
    part_sums : ndarray, shape (n_parts, len(part_ms)), or None
        With ``parts`` or ``gather`` (``None`` without ``parts``).
    points : (ndarray, ndarray of int) or None
        With ``parts`` or ``gather``: the gathered samples, all sizes' in one array, and where each
        size's begin; ``None`` without ``gather`` or where they were not gathered (a record the
        precompiled kernels sum, or no size below a block: :func:`lag1_deltas` reads ``x`` then).
    pairs : ndarray, shape (n_samples // 8 + 1, 2), or None
        With ``blocks``: the block sums in ``pairs[1:, 0]`` (:func:`position_mean_squares`'
        table), or ``None`` where they were not summed in the fill (a record the precompiled
        kernels sum, or no size below a block).
    """
    y = np.ascontiguousarray(y, dtype=float)
    ms = np.ascontiguousarray(ms, dtype=np.int64)
    report = progress if progress is not None else (lambda done: None)
    near = ms < _BLOCK_ALL
    partial = points = pairs = None
    if _precompiled_for(y.size) is not None or ms.size == 0:
        x = phase_from_rate(y, record_mean(y))
        sums = second_difference_sums(x, ms)
        report(ms.size)
    else:
        x, sums, partial, points, pairs = _fused_sums(y, ms, near, report, gather, blocks)
    if parts is None and gather is None and not blocks:
        return x, sums
    part_sums = None
    if parts is not None:
        n_parts, part_ms = parts
        part_ms = np.ascontiguousarray(part_ms, dtype=np.int64)
        if partial is None:
            every = np.ones(part_ms.size, dtype=bool)
            part_sums = _each_part(x, part_ms, int(n_parts), every)
        else:
            part_sums = _part_sums(x, ms[near], partial, part_ms, int(n_parts))
    return (x, sums, part_sums, points) + ((pairs,) if blocks else ())


def _gather_plan(gather):
    """``(starts, steps, counts, offsets, points)`` for ``phase_and_sums``' gathering of
    :func:`allan_sums`' ``gather`` (empty arrays without it); ``x[0]``, which it does not gather, is
    0 where a size starts there."""
    starts, steps, counts = (
        np.ascontiguousarray(a, dtype=np.int64)
        for a in (gather if gather is not None else ([], [], []))
    )
    offsets = np.concatenate(([0], np.cumsum(counts + 1)[:-1])).astype(np.int64)
    points = np.empty(int(np.sum(counts + 1)))
    points[offsets[starts == 0]] = 0.0
    return starts, steps, counts, offsets, points


def _fused_sums(y, ms, near, report, gather=None, blocks=False):
    """:func:`allan_sums` of a record the JIT kernels sum: ``x``, the sums, the tile sums of the
    sizes below a block (``(n_tiles, near.sum())``, ``None`` where there are none), the gathered
    ``(points, offsets)`` (``None`` without ``gather`` or sizes below a block) and the table of
    :func:`position_mean_squares` with the 8-sample block sums of ``x[1:]`` (``None`` without
    ``blocks`` or sizes below a block)."""
    kernels = _compile()
    sums = np.empty(ms.size)
    partial = points = pairs = None
    with threads_for_pass(y.size):
        centred = kernels["centred_sums"](y, _PHASE_BLOCK)
        mean = kernels["centred_mean"](y, centred, _PHASE_BLOCK)
        bases = kernels["centred_bases"](y, centred, mean, _PHASE_BLOCK)
        x = np.empty(y.size + 1)
        if near.any():
            # tiles the largest size reaches ahead
            lag = (2 * int(ms[near].max()) + _BLOCK_ALL - 2) // _BLOCK_ALL
            n_tiles = (x.size - 2 * int(ms[near].min()) + _BLOCK_ALL - 1) // _BLOCK_ALL
            partial = np.zeros((n_tiles, int(near.sum())))
            plan = _gather_plan(gather)
            pairs = np.empty((y.size // 8 + 1 if blocks else 1, 2))
            sums[near] = kernels["phase_and_sums"](
                y, mean, bases, _PHASE_BLOCK, x, ms[near], _BLOCK_ALL, lag, threads_for(y.size),
                partial, *plan, pairs[1:, 0],
            )
            pairs = pairs if blocks else None
            if gather is not None:
                points = plan[4], plan[3]
        else:
            x[0] = 0.0
            kernels["phase_blocks"](y, mean, bases, _PHASE_BLOCK, x[1:])
        report(int(near.sum()))
        if not near.all():
            sums[~near] = _far_sums(x, ms[~near])
            report(int((~near).sum()))
    return x, sums, partial, points, pairs


def _each_part(x, ms, n_parts, which):
    """``(n_parts, which.sum())`` sums of the sizes ``ms[which]`` of each part of ``x``, summed
    part by part (:func:`second_difference_sums`)."""
    length = (x.size - 1) // n_parts
    return np.array(
        [
            second_difference_sums(x[k * length:(k + 1) * length + 1], ms[which])
            for k in range(n_parts)
        ]
    ).reshape(n_parts, int(which.sum()))


def _part_sums(x, near_ms, partial, part_ms, n_parts):
    """The parts' sums (:func:`allan_sums`' ``parts``) of a record the JIT kernels sum, from the
    tile sums ``partial`` of the whole record's sizes ``near_ms``: a part's starts
    ``k L <= i <= (k + 1) L - 2 m`` are the whole tiles between its ends (their sums added, no
    pass over the record), and two spans at its ends (``span_sums``: at most a tile at the start,
    at most a tile plus the largest size's reach at the end, each size's last start cut by
    reading a view of ``x`` that ends with the part). Sizes of the parts from a block up, and
    parts too short for a whole tile between their spans, are summed part by part."""
    length = (x.size - 1) // n_parts
    column = np.searchsorted(near_ms, part_ms)
    tiled = (column < near_ms.size) & (part_ms < _BLOCK_ALL)
    tiled[tiled] = near_ms[column[tiled]] == part_ms[tiled]
    out = np.empty((n_parts, part_ms.size))
    if not tiled.all():
        out[:, ~tiled] = _each_part(x, part_ms, n_parts, ~tiled)
    if not tiled.any():
        return out
    ms = part_ms[tiled]
    kernels = _compile()
    reach = 2 * int(ms.max())
    for k in range(n_parts):
        start, stop = k * length, (k + 1) * length + 1  # the part's phase points x[start:stop]
        first = -(-start // _BLOCK_ALL)  # its first whole tile
        last = (stop - reach) // _BLOCK_ALL  # the tile where the end span begins
        view = x[:stop]
        if last <= first:
            out[k, tiled] = second_difference_sums(x[start:stop], ms)
            continue
        head = kernels["span_sums"](view, ms, start, first * _BLOCK_ALL - start)
        middle = partial[first:last, column[tiled]].sum(axis=0)
        tail = kernels["span_sums"](view, ms, last * _BLOCK_ALL, stop - last * _BLOCK_ALL)
        out[k, tiled] = head + middle + tail
    return out


def avar_pair_sums(table, ms, n, h, s2, x):
    """Lag sums ``sum_l n(l) c(l)^2`` for every pair of cluster sizes (symmetric matrix).

    ``table[k] = D(k)`` is the model's phase structure function for ``0 <= k <= 4 max(ms)``;
    ``h`` the flicker level ``B^2/pi``; ``s2`` and ``x = dt/T`` arrays over the Gauss-Markov
    components (empty when there are none); ``n`` the record's length, which chooses the build as
    for the record's own sums.
    """
    aot = _precompiled_for(int(n))
    pair_sums = _compile()["pair_sums"] if aot is None else aot.pair_sums
    return pair_sums(
        np.ascontiguousarray(table, dtype=float),
        np.ascontiguousarray(ms, dtype=np.int64),
        int(n),
        float(h),
        np.ascontiguousarray(s2, dtype=float),
        np.ascontiguousarray(x, dtype=float),
    )


def contrast_mean_squares(x, ks, n_cal, strides):
    """Mean squares of the phase contrasts of :func:`bayes_imu.allan.contrast.contrast_mean_square`
    (outages ``ks``, window ``n_cal``, strides ``strides``; all valid) of a phase record ``x`` that
    the JIT kernels sum, in one compiled call on :func:`threads_for` threads, tile by tile of
    starts (each tile's window of ``x`` read once for every outage shorter than a tile; no
    temporaries, no BLAS threads); ``None`` for a record the precompiled kernels sum (``len(x) -
    1`` below :data:`PRECOMPILED_BELOW`: numpy's products there, without importing numba). The same
    contrasts as numpy's, their squares added in another order (about 1e-15 relative)."""
    if _precompiled_for(x.size - 1) is not None:
        return None
    return _contrast_pass(x, np.zeros((1, 2)), ks, n_cal, strides, False)[:, 0]


def _contrast_pass(x, pairs, ks, n_cal, strides, position):
    """``contrast_sums``' tile pass on :func:`threads_for` threads: the phase contrasts' mean
    squares and, with ``position``, the position contrasts' from ``pairs`` (``pair_prefix``'s)."""
    kernels = _compile()
    with threads_for_pass(x.size):
        return kernels["contrast_sums"](
            np.ascontiguousarray(x, dtype=float),
            pairs,
            np.ascontiguousarray(ks, dtype=np.int64),
            int(n_cal),
            np.ascontiguousarray(strides, dtype=np.int64),
            _BLOCK_ALL,
            position,
        )


def position_mean_squares(x, ks, n_cal, strides, pairs=None):
    """``(len(ks), 2)``: the mean squares of the phase contrasts of
    :func:`contrast_mean_squares` (column 0, the same bits) and of the position contrasts of
    :func:`bayes_imu.allan.contrast.position_mean_square` (column 1), outages ``ks``, window
    ``n_cal``, strides ``strides`` (all valid), of a phase record ``x`` that the JIT kernels sum,
    in compiled passes on :func:`threads_for` threads; ``None`` for a record the precompiled
    kernels sum (numpy's steps there, without importing numba).

    A position contrast reads a window of ``x``: the sums of ``x[1:]`` in blocks of 8 samples (in
    ``pairs[1:, 0]``, ``pairs`` of shape ``((len(x) - 1) // 8 + 1, 2)``, where :func:`allan_sums`
    already summed them as it filled ``x``: ``blocks=True``; else one pass, ``block_sums``) are
    added in place into a compensated running pair per block (``pair_prefix``: 16 bytes per 8
    samples, 20 MB at 1e7 samples, instead of numpy's running sum of every sample, 80 MB written and
    read), and the last pass, tile by tile of starts as :func:`contrast_mean_squares`, takes each
    window as the difference of two such pairs and at most seven samples at each end (the same
    ``contrast_sums`` pass). The windows are exact to the rounding of their own samples' sums, not
    of the running sum's magnitude: nearer an extended-precision reference than numpy's ``cumsum``
    steps (tests). The fill adds each block's 8 samples in any order (its fast-math loop), the pass
    of its own in a fixed tree: the same sums to rounding."""
    if _precompiled_for(x.size - 1) is not None:
        return None
    kernels = _compile()
    x = np.ascontiguousarray(x, dtype=float)
    with threads_for_pass(x.size):
        if pairs is None:
            pairs = np.empty(((x.size - 1) // 8 + 1, 2))
            kernels["block_sums"](x[1:], _PREFIX_CHUNK, pairs[1:, 0])
        kernels["pair_prefix"](pairs, _PREFIX_CHUNK)
    return _contrast_pass(x, pairs, ks, n_cal, strides, True)


def lag1_deltas(x, ms, starts, counts, max_differences, *, steps=None, n_samples=None):
    """``(n_sizes, 2)``: ``(delta, d)`` of the lag-1 noise identification of each size of a phase
    record ``x`` that the JIT kernels sum (:func:`bayes_imu.allan.estimator.identify_noise`'s, from
    the ``counts[i]`` cluster means from ``x[starts[i]]`` on, ``steps[i]`` apart: ``ms`` by default,
    or 1 in the samples :func:`allan_sums` gathered, given as ``x`` with the record's
    ``n_samples``), in one compiled call on :func:`threads_for` threads, the cluster means read as
    they are used (no strided copies, no temporaries); ``None`` for a record the precompiled kernels
    sum (numpy's steps there, without importing numba). The deltas agree with numpy's to about
    1e-15 (sums added in another order), and are the same bits from the record or its gathered
    samples."""
    n_samples = x.size - 1 if n_samples is None else int(n_samples)
    if _precompiled_for(n_samples) is not None:
        return None
    kernels = _compile()
    with threads_for_pass(n_samples):
        return kernels["lag1_deltas"](
            np.ascontiguousarray(x, dtype=float),
            np.ascontiguousarray(ms, dtype=np.int64),
            np.ascontiguousarray(starts, dtype=np.int64),
            np.ascontiguousarray(ms if steps is None else steps, dtype=np.int64),
            np.ascontiguousarray(counts, dtype=np.int64),
            int(max_differences),
            threads_for(n_samples),
        )
