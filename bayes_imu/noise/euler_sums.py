"""Exact, numerically stable sums behind the Euler-integration variances (the noise terms' drift
and :mod:`bayes_imu.drift.closed_forms`).

Each formula is written once, as Python arithmetic that numpy evaluates on arrays and numba
compiles for the scalar loops of :func:`drift_grid` (the closed forms, the series of
``phi_2`` and of ``lambda - a``); the compiled branches are tested equal to the numpy ones.

For the forward-Euler Gauss-Markov recursion ``b_k = A b_{k-1} + dt w_{k-1}`` with
``A = 1 - a`` (``a = dt / tau``) and zero initial state, the state integrated ``r`` times
(r = 0: the bias itself, 1: single integral, 2: double integral) after ``k`` steps is

    x_k = dt**(r+1) * sum_{n=0}^{k-1} c_r(n) w_{k-1-n},
    c_0(n) = A**n,   c_1(n) = sum_{j<n} A**j,   c_2(n) = sum_{j<n} c_1(j),

so its variance is ``dt**(2r+2) * q * V_r(k, a)`` with ``V_r(k, a) = sum_{n<k} c_r(n)**2``.
This module evaluates ``V_r`` to near machine precision for ``0 <= a < 2`` and
``0 <= k <= 2**53`` with two branches (order 0, eq 16, needs only the first):

* the closed forms (derived in ``docs/errata.md``) where their cancellation is bounded,
  i.e. ``a * k >= SWITCH[r]`` or ``a >= 1``, with ``A**k``, ``1 - A**k`` and
  ``1 - A**(2k)`` from ``expm1``/``log1p``;
* otherwise (``a * k`` small, hence ``a < SWITCH[r] / k``) the exact power series in ``a``
  ``V_r = sum_t (-a)**t sum_u W_r[t, u] C(k, u)``, whose integer coefficients follow from
  ``c_r(n) = sum_m (-a)**m C(n, m + r)``, the product rule
  ``C(n,p) C(n,q) = sum_j (p+q-j)! / (j! (p-j)! (q-j)!) C(n, p+q-j)`` and the hockey stick
  ``sum_{n<k} C(n, s) = C(k, s + 1)``. For ``k <= SERIES_TERMS[r] / 2`` the truncated
  series is the whole (finite) polynomial; beyond, ``a < SWITCH[r] / k`` bounds the
  truncation error within the tests' 1e-13 bound.
"""

from functools import lru_cache
from math import factorial

import numpy as np

__all__ = [
    "gm_sum",
    "gm_sum_broadcast",
    "gm_terms_broadcast",
    "gm_coefficient",
    "SWITCH",
    "SERIES_TERMS",
]

#: ``a * k`` at and above which the closed form of order r is used (measured, see tests)
SWITCH = {1: 0.5, 2: 1.0}
#: number of powers of ``a`` kept in the series branch of order r
SERIES_TERMS = {1: 16, 2: 20}


@lru_cache(maxsize=None)
def _series_table(order, n_terms=None):
    """Nonzero terms ``(t, u, (-1)**t W[t][u])`` of ``V_r = sum_t (-a)**t sum_u W[t][u] C(k,
    u)``."""
    n_terms = SERIES_TERMS[order] if n_terms is None else n_terms
    table = {}
    for t in range(n_terms):
        for m in range(t + 1):
            p, q = m + order, t - m + order
            for j in range(min(p, q) + 1):
                w = factorial(p + q - j) // (factorial(j) * factorial(p - j) * factorial(q - j))
                key = (t, p + q - j + 1)
                table[key] = table.get(key, 0) + w
    return tuple((t, u, float((-1) ** t * w)) for (t, u), w in sorted(table.items()))


def _log_abs_a(a):
    """``log|1 - a|`` accurate for a near 0 and near 2 (a in [0, 2), a != 1)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a < 1.0, np.log1p(-np.minimum(a, 1.0)), np.log1p(np.maximum(a, 1.0) - 2.0))


def _powers(k, a):
    """Return ``E = A**k``, ``1 - E`` and ``1 - E**2`` computed without cancellation."""
    log_abs = _log_abs_a(a)
    odd = np.mod(k, 2.0) == 1.0
    negative = a > 1.0
    zero_a = a == 1.0
    with np.errstate(invalid="ignore", over="ignore"):
        kl = np.where(zero_a, 0.0, k * log_abs)
        mag = np.exp(kl)
        one_minus_mag = -np.expm1(kl)
        one_minus_e2 = -np.expm1(2.0 * kl)
    flip = negative & odd
    e = np.where(flip, -mag, mag)
    one_minus_e = np.where(flip, 1.0 + mag, one_minus_mag)
    # A = 0 exactly: A**0 = 1 and A**k = 0 for k >= 1
    e = np.where(zero_a, (k == 0).astype(float), e)
    one_minus_e = np.where(zero_a, (k != 0).astype(float), one_minus_e)
    one_minus_e2 = np.where(zero_a, (k != 0).astype(float), one_minus_e2)
    return e, one_minus_e, one_minus_e2


def _closed_formula(order, k, a, e, one_minus_e, one_minus_e2):
    """The closed forms of ``V_r`` given the powers of ``A`` (arithmetic only: the one definition
    that numpy evaluates on arrays and numba compiles for scalars)."""
    geo2 = one_minus_e2 / (a * (2.0 - a))  # sum_{n<k} A**(2n)
    if order == 0:
        return geo2
    if order == 1:
        return (k - 2.0 * one_minus_e / a + geo2) / (a * a)
    sum_n2 = (k - 1.0) * k * (2.0 * k - 1.0) / 6.0
    return (a * a * sum_n2 - a * k * (k - 1.0) + (k - 2.0) - 2.0 * (k - 1.0) * e + geo2) / (
        a * a * a * a
    )


def _closed(order, k, a):
    """Closed forms of ``V_r`` (valid for 0 < a < 2; well conditioned for a*k large)."""
    return _closed_formula(order, k, a, *_powers(k, a))


def _series(order, k, a, n_terms=None):
    """Exact series in ``a`` (for a*k < SWITCH[order]).

    ``a**t C(k, u) = g_u a**(t-u)`` with ``g_u = a**u C(k, u) <= (a k)**u / u!`` from a
    recurrence; ``t - u >= -(2r+1)``, so at most ``a**-(2r+1)`` is ever formed. Where
    ``g_u`` underflows, its term is below ``(a k)**(u - 2r - 1)`` of the result.
    """
    terms = _series_table(order, n_terms)
    u_max = max(u for _, u, _ in terms)
    g = [np.ones_like(a)]
    for u in range(1, u_max + 1):
        g.append(g[-1] * a * (k - (u - 1)) / u)
    powers = {0: np.ones_like(a)}
    with np.errstate(divide="ignore", over="ignore", under="ignore", invalid="ignore"):
        inv = 1.0 / a
        for p in range(1, 2 * order + 2):
            powers[-p] = powers[-p + 1] * inv
        for p in range(1, max(t for t, _, _ in terms) + 1):
            powers[p] = powers[p - 1] * a
        total = np.zeros_like(a)
        for t, u, w in terms:
            total += w * g[u] * powers[t - u]
    return total


def _random_walk(order, k):
    """``V_r(k, 0) = sum_{n<k} C(n, r)**2``, the ``t = 0`` row of the series (exact polynomial)."""
    total = np.zeros_like(k)
    for t, u, w in _series_table(order, 1):
        binom = np.ones_like(k)
        for i in range(u):
            binom = binom * (k - i) / (i + 1)
        total += w * binom
    return total


def gm_sum(order, k, a):
    """Dimensionless ``V_r(k, a) = sum_{n<k} c_r(n)**2`` for arrays ``k`` and ``a``.

    Parameters
    ----------
    order : {0, 1, 2}
    k : ndarray of float
        Whole step counts, ``0 <= k <= 2**53``.
    a : ndarray of float
        ``dt / tau`` in ``[0, 2)``; ``a = 0`` is the random-walk limit.

    Returns
    -------
    ndarray
        ``V_r`` broadcast over ``k`` and ``a``.
    """
    k, a = np.broadcast_arrays(np.asarray(k, dtype=float), np.asarray(a, dtype=float))
    shape = k.shape
    k, a = k.ravel(), a.ravel()
    out = np.empty_like(k)
    if order == 0:  # eq 16 has no cancellation: (1 - A**(2k)) / (1 - A**2)
        positive = a > 0.0
        out[positive] = _closed(0, k[positive], a[positive])
        out[~positive] = k[~positive]
        return out.reshape(shape)
    rw = a * k < 1e-18  # the random walk and its limit, exact to that relative order
    closed = ~rw & ((a * k >= SWITCH[order]) | (a >= 1.0))
    series = ~rw & ~closed
    for mask, kernel in ((closed, _closed), (series, _series)):
        if mask.any():
            out[mask] = kernel(order, k[mask], a[mask])
    if rw.any():
        out[rw] = _random_walk(order, k[rw])
    out[k <= order] = 0.0  # c_r(n) = 0 for n < r: exactly zero, not a rounding residue
    return out.reshape(shape)


def gm_coefficient(order, k, a):
    """Coefficient ``c_r(k)`` multiplying an initial bias ``b_0`` after ``k`` steps.

    ``b_k = A**k b_0``, ``v_k = dt c_1(k) b_0``, ``p_k = dt**2 c_2(k) b_0`` for the
    noise-free recursion; used for the stationary bias start.
    """
    k, a = np.broadcast_arrays(np.asarray(k, dtype=float), np.asarray(a, dtype=float))
    e, one_minus_e, _ = _powers(k, a)
    if order == 0:
        return e
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -_log_abs_a(a)
        c1 = np.where(a == 0.0, k, one_minus_e / np.where(a == 0.0, 1.0, a))
        if order == 1:
            return c1
        # c_2(k) = (k a - (1 - A**k)) / a**2 = (z**2 phi_2(z) - k (lambda - a)) / a**2 for A > 0
        z = k * lam
        stable = (z * z * _phi2(z) - k * _lambda_minus_a(a)) / a**2
        direct = (k * a - one_minus_e) / a**2
        c2 = np.where((a > 0.0) & (a < 1.0), stable, direct)
        return np.where(a == 0.0, k * (k - 1.0) / 2.0, c2)


#: below these arguments the series of phi_2 and of lambda - a are used
PHI2_SWITCH = 0.1
LAMBDA_SWITCH = 0.05


def _phi2_series(z):
    """``(z - 1 + exp(-z)) / z**2`` by its Taylor series, for ``0 <= z < PHI2_SWITCH`` (arithmetic
    only: shared by numpy and the compiled kernel)."""
    return 0.5 + z * (
        -1 / 6 + z * (1 / 24 + z * (-1 / 120 + z * (1 / 720 + z * (-1 / 5040 + z / 40320))))
    )


def _lambda_minus_a_series(s):
    """``-log(1 - s) - s = sum_{n >= 2} s**n / n`` to ``n = 11``, for ``0 <= s < LAMBDA_SWITCH``
    (arithmetic only)."""
    return (
        s
        * s
        * (
            1 / 2
            + s
            * (
                1 / 3
                + s
                * (
                    1 / 4
                    + s
                    * (
                        1 / 5
                        + s
                        * (1 / 6 + s * (1 / 7 + s * (1 / 8 + s * (1 / 9 + s * (1 / 10 + s / 11)))))
                    )
                )
            )
        )
    )


def _phi2(z):
    """``(z - 1 + exp(-z)) / z**2`` for z >= 0, series below ``PHI2_SWITCH``."""
    z = np.asarray(z, dtype=float)
    small = z < PHI2_SWITCH
    series = _phi2_series(np.where(small, z, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        zl = np.where(small, 1.0, z)
        direct = (zl + np.expm1(-zl)) / zl**2
    return np.where(small, series, direct)


def _lambda_minus_a(a):
    """``-log1p(-a) - a`` for 0 <= a < 1, series below ``LAMBDA_SWITCH``."""
    a = np.asarray(a, dtype=float)
    small = a < LAMBDA_SWITCH
    series = _lambda_minus_a_series(np.where(small, a, 0.0))
    direct = -np.log1p(-np.minimum(a, 1.0 - 1e-300)) - a
    return np.where(small, series, direct)


@lru_cache(maxsize=None)
def _horner_rows(order):
    """Series table regrouped by power of ``a``: ``{t: ((u, (-1)**t W[t][u]), ...)}``."""
    rows = {}
    for t, u, w in _series_table(order):
        rows.setdefault(t, []).append((u, w))
    return {t: tuple(v) for t, v in rows.items()}


def series_coefficients(order, k):
    """``Q[t, j] = (-1)**t sum_u W[t][u] C(k_j, u) / k_j**t``: the series is ``sum_t (a k)**t
    Q[t]``.

    All ``W`` are positive, so each ``Q`` is a sum of same-sign terms (no cancellation);
    ``C(k, u) / k**t`` is formed as ``prod (k - i)/((i + 1) k)`` times ``k**(u - t)``
    (``u - t <= 2 order + 1``), so nothing overflows for ``k <= 2**53``.
    """
    k = np.maximum(np.asarray(k, dtype=float), 1.0)
    rows = _horner_rows(order)
    u_max = max(u for row in rows.values() for u, _ in row)
    ratio = [np.ones_like(k)]  # C(k, u) / k**u
    for u in range(1, u_max + 1):
        ratio.append(ratio[-1] * (k - (u - 1)) / (u * k))
    out = np.zeros((SERIES_TERMS[order], k.size))
    for t, row in rows.items():
        for u, w in row:
            out[t] += w * ratio[u] * k ** float(u - t)
    return out


_drift_kernel = None  # set on first use of drift_grid (:func:`_kernel`)


def gm_sum_grid(order, k, a):
    """``gm_sum(order, k[None, :], a[:, None])`` for order 1 or 2, through the compiled kernel
    of :func:`drift_grid` (same branches; tested equal to :func:`gm_sum` to 1e-13)."""
    k = np.ascontiguousarray(k, dtype=float).ravel()
    a = np.ascontiguousarray(a, dtype=float).ravel()
    ones, none_a, none_k = np.ones_like(a), np.zeros((1, a.size)), np.zeros((1, k.size))
    _, root = drift_grid(order, k, a, ones, np.zeros_like(a), none_a, none_k, none_a, none_k)
    return root**2


def drift_grid(
    order, k, a, bias_scale, stationary_scale, white_scales, white_ks, extra_scales, extra_ks
):
    """Fused 1-sigma drift for draws x times: returns ``(total, bias)``, each ``(n_draws,
    n_times)``.

    Per draw ``i`` and time ``j`` (variances add)::

        white = sum_m white_scales[m, i] * white_ks[m, j]
        bias  = bias_scale[i] * V_r(k_j, a_i) + stationary_scale[i] * c_r(k_j, a_i)**2
              + sum_m extra_scales[m, i] * extra_ks[m, j]

    with ``V_r`` and ``c_r`` by the same branches as :func:`gm_sum` and :func:`gm_coefficient`
    (tests: equal to :func:`bayes_imu.drift.closed_forms.drift_sigma`), in the compiled kernel
    :func:`bayes_imu.noise._sources.drift_rows`.
    """
    k = np.ascontiguousarray(k, dtype=float).ravel()
    vec = [np.ascontiguousarray(v, dtype=float).ravel() for v in (a, bias_scale, stationary_scale)]
    mat = [
        np.ascontiguousarray(np.atleast_2d(v), dtype=float)
        for v in (white_scales, white_ks, extra_scales, extra_ks)
    ]
    a = vec[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        log_abs = np.where(
            a < 1.0, np.log1p(-np.minimum(a, 1.0)), np.log1p(np.maximum(a, 1.0) - 2.0)
        )
    total, bias = np.empty((k.size, a.size)), np.empty((k.size, a.size))
    _kernel()(
        int(order),
        k,
        a,
        log_abs,
        np.ascontiguousarray(series_coefficients(order, k), dtype=float),
        np.ascontiguousarray(_random_walk(order, k), dtype=float),
        float(SWITCH[order]),
        vec[1],
        vec[2],
        *mat,
        total,
        bias,
    )
    return total.T, bias.T


def _kernel():
    """The compiled drift grid (:func:`bayes_imu.noise._sources.drift_rows`, through
    :func:`bayes_imu.allan.kernels.compiled_kernel`; its JIT build parallel over times)."""
    global _drift_kernel
    if _drift_kernel is None:
        from ..allan.kernels import compiled_kernel

        _drift_kernel = compiled_kernel("drift_rows", f"{__package__}._sources", parallel=True)
    return _drift_kernel


def gm_sum_broadcast(order, k, a):
    """``gm_sum`` broadcast over ``k`` and ``a``; the (draws, 1) x (times,) layout of posterior
    bands goes to the compiled grid kernel (same branches, tested equal), anything else to numpy."""
    if _grid_layout(order, k, a):
        return gm_sum_grid(order, k, a[:, 0])
    return gm_sum(order, *np.broadcast_arrays(k, a))


def _grid_layout(order, k, a):
    """The (draws, 1) x (times,) layout of posterior bands, large enough for the compiled kernel."""
    return (
        order > 0 and k.ndim == 1 and a.ndim == 2 and a.shape[1] == 1 and a.size * k.size >= 100_000
    )


def gm_terms_broadcast(order, k, a, *, stationary, coefficient=False):
    """``a (2 - a) V_r(k, a) + stationary c_r(k, a)**2`` (and ``c_r(k, a)`` if ``coefficient``),
    broadcast.

    The exact-sampling Gauss-Markov drift in units of ``s^2 dt^(2r)`` (``0 < a < 1``, where
    ``c_r >= 0``); the posterior-band layout goes through the compiled kernel of
    :func:`drift_grid` (same branches, tested equal), anything else through numpy.
    """
    if _grid_layout(order, k, a):
        a1 = a[:, 0]
        none_a, none_k = np.zeros((1, a1.size)), np.zeros((1, k.size))
        _, root = drift_grid(
            order,
            k,
            a1,
            a1 * (2.0 - a1),
            np.full_like(a1, float(stationary)),
            none_a,
            none_k,
            none_a,
            none_k,
        )
        if not coefficient:
            return root**2
        _, c = drift_grid(
            order, k, a1, np.zeros_like(a1), np.ones_like(a1), none_a, none_k, none_a, none_k
        )
        return root**2, c
    kk, aa = np.broadcast_arrays(k, a)
    c = gm_coefficient(order, kk, aa)
    out = aa * (2.0 - aa) * gm_sum(order, kk, aa) + (c * c if stationary else 0.0)
    return (out, c) if coefficient else out
