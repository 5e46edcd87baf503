"""Private compiled kernels (numba) for the Allan variance.

numba is imported lazily (on first use) so that ``import bayes_imu`` stays fast; the
compiled code is cached on disk next to this module.

Why numba: the fully overlapping Allan variance needs one pass over the whole phase
record per cluster size. In numpy that pass is three temporaries and a dot product
(about 3.5x faster than allantools at best); a fused, multi-threaded loop reads the
record once per cluster size and is memory-bandwidth bound.
"""

import numpy as np

__all__ = ["phase_from_rate", "second_difference_sums"]

_BLOCK = 1 << 14
_compiled = {}


def _compile():
    if _compiled:
        return _compiled
    import numba

    @numba.njit(cache=True)
    def phase(y, offset, out, block):
        # out[i] = sum_{j<i} (y[j] - offset): plain sums inside blocks, block totals added
        # with Kahan-Babuska compensation (strict IEEE: no fastmath, so it is not optimised away)
        s = 0.0
        c = 0.0
        out[0] = 0.0
        for lo in range(0, y.size, block):
            hi = min(lo + block, y.size)
            base = s + c
            acc = 0.0
            for i in range(lo, hi):
                acc += y[i] - offset
                out[i + 1] = base + acc
            t = s + acc
            if abs(s) >= abs(acc):
                c += (s - t) + acc
            else:
                c += (acc - t) + s
            s = t
        return out

    @numba.njit(parallel=True, cache=True, fastmath={"reassoc", "contract", "nsz", "arcp"})
    def sums(x, ms, block):
        out = np.empty(ms.size)
        for j in range(ms.size):
            m = ms[j]
            n = x.size - 2 * m
            n_blocks = (n + block - 1) // block
            partial = np.empty(n_blocks)
            for b in numba.prange(n_blocks):
                lo = b * block
                hi = min(lo + block, n)
                x0 = x[lo:hi]
                x1 = x[lo + m : hi + m]
                x2 = x[lo + 2 * m : hi + 2 * m]
                s = 0.0
                for i in range(hi - lo):
                    d = x2[i] - 2.0 * x1[i] + x0[i]
                    s += d * d
                partial[b] = s
            out[j] = partial.sum()
        return out

    _compiled.update(phase=phase, sums=sums)
    return _compiled


def phase_from_rate(y, offset):
    """Running sums ``x[i] = sum_{j<i} (y[j] - offset)``, length ``len(y) + 1``, compensated.

    Sums of at most 256 terms are added to a compensated running total, so each ``x[i]``
    is within a few ulp of the exact prefix sum however long the record: the second
    differences of ``x`` keep their precision on long records.
    """
    out = np.empty(y.size + 1)
    return _compile()["phase"](y, float(offset), out, 256)


def second_difference_sums(x, ms):
    """``sum_i (x[i+2m] - 2 x[i+m] + x[i])**2`` over ``0 <= i < len(x) - 2m`` for each ``m``."""
    return _compile()["sums"](x, np.ascontiguousarray(ms, dtype=np.int64), _BLOCK)
