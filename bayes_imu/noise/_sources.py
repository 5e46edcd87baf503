"""Sources of the compiled noise kernels: plain Python that numba compiles twice.

Imported only to compile (it imports numba): :mod:`bayes_imu.noise.gauss_markov` (the Gauss-Markov
AVAR rows), :mod:`bayes_imu.noise.euler_sums` (the drift grid) and :mod:`bayes_imu.drift.navigation`
(the navigation error's state covariance) JIT-compile these functions on first use where the
package was built without its ahead-of-time build, which ``setup.py`` compiles into the extension
``bayes_imu._compiled`` with the Allan-variance kernels. Strict IEEE arithmetic
in both builds: they give the same bits (tested). The formulas the drift grid evaluates
(``_closed_formula``, ``_phi2_series``, ``_lambda_minus_a_series``) are written once, in
:mod:`bayes_imu.noise.euler_sums`, where numpy evaluates them on arrays; here they are compiled for
scalars.
"""

import numba
import numpy as np

from .euler_sums import (
    LAMBDA_SWITCH,
    PHI2_SWITCH,
    _closed_formula,
    _lambda_minus_a_series,
    _phi2_series,
)

__all__ = [
    "avar_rows", "drift_rows", "pair_sum_lags", "second_differences_into", "powers_scalar",
    "coefficient_scalar", "propagate_diagonal", "row_form",
]

# module globals, not closure variables: numba's cache keys a closure's captured dispatcher by
# identity
closed_scalar = numba.njit(cache=True)(_closed_formula)
phi2_series = numba.njit(cache=True)(_phi2_series)
lambda_minus_a_series = numba.njit(cache=True)(_lambda_minus_a_series)


def avar_rows(mf, coeffs, s2, x, fx, e2, fy, switch, out):
    """``out[i, j]`` = AVAR at ``mf[j]`` of row ``i`` (``x = dt/T``, ``fx = 1 - e^-x``, ``e2 = 1 -
    e^-2x``, ``fy = 1 - e^-(m x)``): the exact series below ``m x = switch``, else the closed
    form."""
    n_terms = coeffs.shape[0]
    for i in range(x.size):
        ratio = x[i] / fx[i] if fx[i] > 0 else 1.0
        for j in range(mf.size):
            m = mf[j]
            y = m * x[i]
            if y <= switch:
                ys = -y
                poly = coeffs[n_terms - 1, j] * ys + coeffs[n_terms - 2, j]
                for k in range(n_terms - 3, -1, -1):
                    poly = poly * ys + coeffs[k, j]
                value = x[i] * ratio * ratio * poly / (m * m)
            else:
                value = (m * e2[i] - (1.0 - fx[i]) * fy[i, j] * (2.0 + fy[i, j])) / (
                    m * m * fx[i] * fx[i]
                )
            out[i, j] = s2[i] * value


def second_differences_into(ext, lo, b, out):
    """``out[k] = D(lo + k) - 2 D(lo - b + k) + D(lo - 2b + k)`` from the mirrored table ``ext``
    (:func:`bayes_imu.noise.avar_covariance.exact_pair_sums`), rounded as the numpy form rounds
    it, into a buffer reused for every cluster size."""
    for k in range(out.size):
        out[k] = ext[lo + k] - 2.0 * ext[lo - b + k] + ext[lo - 2 * b + k]


def pair_sum_lags(g, h, half, w_lo, a, ma, mb, reach, use_g, use_h):
    """``sum_l n(l) c(l) (c(l) + 2 e(l))`` over the lags ``l = -(M_a - 1) .. M_b - 1`` of one pair
    of cluster sizes (:func:`bayes_imu.noise.avar_covariance.exact_pair_sums`): ``n(l)`` the index
    pairs the two estimates share at lag ``l``, ``c(l) = -1/2 sum_p w_p g(p a - l)`` (``use_g``;
    else 0) less ``half`` on the lags from offset ``w_lo``, ``e`` the same of ``h`` (``use_h``; else
    the sum of ``n(l) c(l)^2``); ``g``, ``h`` second differences of step ``b``
    (:func:`second_differences_into`). Each ``c`` and product is rounded as the whole-array numpy
    form rounds it; the sum runs in blocks of 1024 lags, each block's total added to the whole."""
    size = ma + mb - 1
    f0 = reach - (mb - 1) + size - 1  # c's term p at lag offset j reads g at f0 + p a - j
    w_hi = w_lo + half.size
    total = 0.0
    for start in range(0, size, 1024):
        block = 0.0
        for j in range(start, min(size, start + 1024)):
            lag = j - (ma - 1)
            count = float(min(ma, mb - lag) - max(0, -lag))
            c = 0.0
            if use_g:
                c = c + 1.0 * g[f0 - j]
                c = c + -2.0 * g[f0 + a - j]
                c = c + 1.0 * g[f0 + 2 * a - j]
                c = -0.5 * c
            if w_lo <= j < w_hi:
                c = c - half[j - w_lo]
            if use_h:
                e = 0.0
                e = e + 1.0 * h[f0 - j]
                e = e + -2.0 * h[f0 + a - j]
                e = e + 1.0 * h[f0 + 2 * a - j]
                e = -0.5 * e
                block += count * (c * (c + 2.0 * e))
            else:
                block += count * (c * c)
        total += block
    return total


@numba.njit(cache=True)
def powers_scalar(k, a, log_abs):
    """Scalar ``(E, 1 - E, 1 - E**2)`` of :func:`bayes_imu.noise.euler_sums._powers`, given
    ``log|1 - a|`` (a != 1)."""
    if a == 1.0:
        return (1.0, 0.0, 0.0) if k == 0 else (0.0, 1.0, 1.0)
    kl = k * log_abs
    mag = np.exp(kl)
    if a > 1.0 and k % 2.0 == 1.0:
        e, one_minus_e = -mag, 1.0 + mag
    else:
        e, one_minus_e = mag, -np.expm1(kl)
    return e, one_minus_e, one_minus_e * (1.0 + e)


@numba.njit(cache=True)
def coefficient_scalar(order, k, a, one_minus_e, lam):
    """Scalar :func:`bayes_imu.noise.euler_sums.gm_coefficient` for order 1 or 2 (same branches);
    ``lam = -log1p(-a)``."""
    if k < order:  # c_r(k) = 0 exactly for k < r
        return 0.0
    if a == 0.0:
        return k if order == 1 else k * (k - 1.0) / 2.0
    if order == 1:
        return one_minus_e / a
    if a < 1.0:
        z = k * lam
        phi2 = phi2_series(z) if z < PHI2_SWITCH else (z + np.expm1(-z)) / (z * z)
        lma = lambda_minus_a_series(a) if a < LAMBDA_SWITCH else lam - a
        return (z * z * phi2 - k * lma) / (a * a)
    return (k * a - one_minus_e) / (a * a)


def drift_rows(
    order,
    k,
    a,
    log_abs,
    q,
    rw,
    switch,
    bias_scale,
    stationary_scale,
    white_scales,
    white_ks,
    extra_scales,
    extra_ks,
    total,
    bias,
):
    """``total[j, i]``, ``bias[j, i]``: the fused 1-sigma drift of draw ``i`` at time ``k[j]``
    (:func:`bayes_imu.noise.euler_sums.drift_grid`), laid out (times, draws) so that quantiles over
    draws read contiguous memory; ``numba.prange`` over times (one thread in the ahead-of-time
    build)."""
    n_terms = q.shape[0]
    for j in numba.prange(k.size):
        kj = k[j]
        for i in range(a.size):
            ai = a[i]
            y = ai * kj
            closed = y >= switch or ai >= 1.0
            need_powers = (bias_scale[i] != 0.0 and closed) or (
                stationary_scale[i] != 0.0 and ai > 0.0
            )
            e, one_minus_e, one_minus_e2 = (
                powers_scalar(kj, ai, log_abs[i]) if need_powers else (1.0, 0.0, 0.0)
            )
            if bias_scale[i] == 0.0 or kj <= order:
                v = 0.0
            elif y < 1e-18:
                v = rw[j]
            elif closed:
                v = closed_scalar(order, kj, ai, e, one_minus_e, one_minus_e2)
            else:
                v = q[n_terms - 1, j]
                for t in range(n_terms - 2, -1, -1):
                    v = v * y + q[t, j]
            b = bias_scale[i] * v
            if stationary_scale[i] != 0.0:
                c = coefficient_scalar(order, kj, ai, one_minus_e, -log_abs[i])
                b += stationary_scale[i] * c * c
            for m in range(extra_scales.shape[0]):
                b += extra_scales[m, i] * extra_ks[m, j]
            w = 0.0
            for m in range(white_scales.shape[0]):
                w += white_scales[m, i] * white_ks[m, j]
            bias[j, i] = np.sqrt(b)
            total[j, i] = np.sqrt(b + w)


@numba.njit(cache=True, inline="always")
def row_form(x, m):
    """``x' M x`` of a row ``x`` and a square matrix ``M``, summed in index order."""
    d = x.size
    v = 0.0
    for c in range(d):
        w = 0.0
        for r in range(d):
            w += x[r] * m[r, c]
        v += w * x[c]
    return v


def propagate_diagonal(a, q, p0, kint, out):
    """``out[b, t, r]``: the diagonal entry ``r < out.shape[2]`` of ``A^k P0 A^k' + sum_{m<k} A^m Q
    A^m'`` with ``A = a[b]``, ``Q = q[b]``, ``P0 = p0[b]`` and ``k = kint[t]``, by binary powering.

    The ladder ``A^(2^j)``, ``S_(2^j) = sum_{m<2^j} A^m Q A^m'`` (``S_2n = S_n + A^n S_n A^n'``) is
    built once per batch row; each length then multiplies the rungs of the bits it has into
    ``R = A^(its lower bits)``, adding ``R S R'``. Row ``r`` of ``R @ A^n`` needs only row ``r`` of
    ``R``, so only the first ``out.shape[2]`` rows of ``R`` are carried, and of each ``R S R'`` only
    its diagonal: for the navigation error's three rows of five or six states, each length's part
    takes about a third of the full matrices' products (the ladder, once per batch row, is the
    same). ``a``, ``q``, ``p0``: ``(batch, d, d)``; ``kint`` ``(n_t,)`` non-negative;
    ``out.shape[2] <= d``."""
    nb, d = a.shape[0], a.shape[1]
    nt, nr = kint.size, out.shape[2]
    top = 0
    for t in range(nt):
        kk, bits = kint[t], 0
        while kk > 0:
            bits += 1
            kk >>= 1
        top = max(top, bits)
    power = np.empty((max(top, 1), d, d))
    acc = np.empty((max(top, 1), d, d))
    rows = np.empty((nr, d))
    tmp = np.empty((nr, d))
    left = np.empty((d, d))
    for b in range(nb):
        if top:
            power[0] = a[b]
            acc[0] = q[b]
        for j in range(1, top):
            # S_2n = S_n + A^n S_n A^n', A^2n = A^n A^n (A^n S_n once per rung)
            for r in range(d):
                for m in range(d):
                    w = 0.0
                    for l in range(d):
                        w += power[j - 1, r, l] * acc[j - 1, l, m]
                    left[r, m] = w
            for r in range(d):
                for c in range(d):
                    v = 0.0
                    for m in range(d):
                        v += left[r, m] * power[j - 1, c, m]
                    acc[j, r, c] = acc[j - 1, r, c] + v
                    u = 0.0
                    for m in range(d):
                        u += power[j - 1, r, m] * power[j - 1, m, c]
                    power[j, r, c] = u
        for t in range(nt):
            for r in range(nr):
                out[b, t, r] = 0.0
                for c in range(d):
                    rows[r, c] = 1.0 if r == c else 0.0
            for j in range(top):
                if not (kint[t] >> j) & 1:
                    continue
                for r in range(nr):
                    # out += (R S_j R')_rr, then R <- R A^(2^j)
                    out[b, t, r] += row_form(rows[r], acc[j])
                    for c in range(d):
                        u = 0.0
                        for m in range(d):
                            u += rows[r, m] * power[j, m, c]
                        tmp[r, c] = u
                rows[:, :] = tmp
            for r in range(nr):
                out[b, t, r] += row_form(rows[r], p0[b])
