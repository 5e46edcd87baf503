"""Sampling distribution of the directly measured calibrated-outage error (its EDF under a model).

The direct estimate (:mod:`bayes_imu.allan.contrast`) averages ``e_j^2`` over ``M`` overlapping
starts, ``e_j = sum_p a_p x_{j+p}`` with ``a_{-N} = r``, ``a_0 = -(1 + r)``, ``a_k = 1``
(``r = k / N``). For a Gaussian process with phase structure function ``D`` (Isserlis, as the
Allan variance's covariance, :mod:`bayes_imu.noise.avar_covariance`)::

    C(d) = Cov(e_j, e_{j+d}) = -1/2 sum_l R(l) D(|l + d|),   R(l) = sum_p a_p a_{p+l}
    Var(V_hat) = 2 / M^2 [M C(0)^2 + 2 sum_{u=1}^{M-1} (M - u) C(s u)^2]

over the ``M`` starts averaged, ``s`` apart (:func:`bayes_imu.allan.contrast.contrast_stride`),

with ``R(0) = 1 + (1 + r)^2 + r^2``, ``R(+-N) = -r (1 + r)``, ``R(+-k) = -(1 + r)``,
``R(+-(k + N)) = r``. ``C(d)`` vanishes beyond the span ``L = k + N`` for white noise, random
walks and quantization (``D`` polynomial of degree <= 3, annihilated by the contrast); the
Gauss-Markov and flicker parts decay smoothly there, and between its kinks (``d = k, N, |k - N|,
k + N``) ``C`` is smooth. The sum is exact over ``d <= 256`` and a midpoint rule on a geometric
grid (ratio 1.02, edges at the kinks) beyond (the structure function is evaluated at non-integer
lags there: every term's ``D`` is a smooth closed form in the lag). The equivalent degrees of
freedom ``nu = 2 C(0)^2 / Var(V_hat)`` make ``V_hat ~ E V_hat chi2_nu / nu`` (a gamma approximation
with the exact first two moments; its tails are checked against Monte Carlo in the tests).

Position (order 2, ``order=2``): the contrast ``p_j / dt^2 = sum_p a_p x_{j+p}`` has the weights
``a_{-N} = c``, ``a_0 = -(K + c)``, ``a_i = 1`` for ``1 <= i <= K`` (``K = k - 1``,
``c = k (k - 1) / (2 N)``): two points and a box. ``C(d) = -1/2 sum_pq a_p a_q D(|q - p + d|)``
splits into point-point terms (``D`` itself), point-box terms (sums of ``D`` over ``K``
consecutive lags: differences of ``F^(m)``, ``F^(m) - F^(m - 1) = D(|m|)``) and the box-box term
``sum_{|l|<K} (K - |l|) D(|l + d|) = G^(d + K) - 2 G^(d) + G^(d - K)`` (``G^`` the second sum:
``G^(m) = G(|m| - 1)``), with ``F(n) = sum_{l<=n} D(l)``, ``G(n) = sum_{l<=n} F(l)`` accumulated in
extended precision from one table of ``D`` (:func:`bayes_imu.noise._base.calibrated_contrast`'s
sums; ``C(0)`` is its variance). That is exact at every lag within ``8 (k + N)``. Farther out the
sums' rounding would swamp a small ``C`` (``G`` grows as ``d^2 D(d)``), so there: terms whose
structure function is a polynomial of degree <= 3 (tail kind ``"none"``: white, random walks,
quantization) give exactly 0 (the weights annihilate it); smooth terms (Gauss-Markov, flicker) give
the leading term of the moment expansion, ``C(d) = -A^2 / 8 D^(4)(d)`` with ``A = sum_p a_p p^2``
(the weights' moments 0-3 vanish, ``sum_l R(l) l^4 = 6 A^2``; next term ``O((k + N)^2 / d^2)``,
a few percent at most beyond ``8 (k + N)``), ``D^(4)`` a central fourth difference of step
``d / 16``; other terms (a vibration's sinusoid) the exact sums.
"""

import contextlib

import numpy as np

from ._base import TABLE_MAX, _blocked_sums

__all__ = ["contrast_edf", "position_covariance", "reused_sums"]

#: lags summed one by one before the covariance sum switches to the geometric midpoint rule
_EXACT_LAGS = 256
_RATIO = 1.02


def _lags(m, k, n_cal):
    """Lags ``d >= 1`` and weights ``(M - d)`` x step: every lag up to :data:`_EXACT_LAGS`, then a
    midpoint rule on a geometric grid (ratio :data:`_RATIO`) whose edges include the lags where
    ``C(d)`` has a kink (``k``, ``N``, ``|k - N|``, ``k + N``)."""
    exact = np.arange(1, min(m, _EXACT_LAGS + 1), dtype=float)
    w = m - exact
    if exact.size == 0 or exact[-1] >= m - 1:
        return exact, w
    lo, hi = exact[-1] + 0.5, m - 0.5
    edges = np.geomspace(lo, hi, max(2, int(np.log(hi / lo) / np.log(_RATIO)) + 2))
    kinks = np.array([k, n_cal, abs(k - n_cal), k + n_cal], dtype=float) + 0.5
    edges = np.unique(np.concatenate((edges, kinks[(kinks > lo) & (kinks < hi)])))
    mid = 0.5 * (edges[1:] + edges[:-1])
    return np.concatenate((exact, mid)), np.concatenate((w, (m - mid) * np.diff(edges)))


def contrast_edf(model, params, k, n_cal, n_samples, stride=1, *, order=1):
    """EDF of the direct calibrated-outage estimate at outages ``k`` under ``model`` at ``params``.

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        One parameter point (scalars).
    k : (n_k,) array_like of int
        Outage lengths [samples].
    n_cal : int
        Calibration window [samples].
    n_samples : int
        Record length (rate samples).
    stride : int or (n_k,) array_like of int
        Step between the starts averaged (:func:`bayes_imu.allan.contrast.contrast_stride`).
    order : {1, 2}
        Integration order: 1 the attitude / velocity contrast, 2 the position contrast
        (:func:`position_covariance`).

    Returns
    -------
    (n_k,) ndarray
        ``nu = 2 (E V_hat)^2 / Var(V_hat)`` (module docstring).
    """
    ks = np.atleast_1d(np.asarray(k, dtype=float))
    nodes = [_start_nodes(kk, step, n_cal, n_samples)
             for kk, step in zip(ks, np.broadcast_to(np.asarray(stride, dtype=np.int64), ks.shape))]
    if order == 2:
        cov = position_covariance(model, params, ks, n_cal, [d for _, _, d in nodes])
        return np.array([_edf(c, m, w) for (m, w, _), c in zip(nodes, cov)])
    out = []
    for kk, (m, w, d) in zip(ks, nodes):
        r = kk / n_cal
        lags = np.array([0.0, n_cal, -n_cal, kk, -kk, kk + n_cal, -(kk + n_cal)])
        weights = np.array(
            [1 + (1 + r) ** 2 + r * r, -r * (1 + r), -r * (1 + r), -(1 + r), -(1 + r), r, r]
        )
        table = model.structure_function(np.abs(d[:, None] + lags[None, :]).ravel(), params)
        out.append(_edf(-0.5 * np.asarray(table, dtype=float).reshape(d.size, lags.size) @ weights,
                        m, w))
    return np.array(out)


def _start_nodes(k, step, n_cal, n_samples):
    """``(m, w, d)`` of one outage ``k``: the ``m`` starts averaged, ``step`` apart, and the lags
    ``d`` between two of them [samples] (``d[0] = 0``) with the weights ``w`` of ``d[1:]``
    (:func:`_lags`)."""
    m = int((n_samples - n_cal - k) // step + 1)
    u, w = _lags(m, k / step, n_cal / step)
    return m, w, step * np.concatenate(([0.0], u))


def _edf(c, m, w):
    """``2 (E V_hat)^2 / Var(V_hat)`` from the contrast's covariance ``c`` at the lags of
    :func:`_start_nodes` (``c[0]`` its variance)."""
    var = 2.0 / m**2 * (m * c[0] ** 2 + 2.0 * np.dot(w, c[1:] ** 2))
    return 2.0 * c[0] ** 2 / var


#: lags within this many spans ``k + N`` of the position contrast are summed exactly
_NEAR_SPANS = 8
#: step of the far region's fourth difference, as a fraction of the lag
_FAR_STEP = 1.0 / 16.0


def position_covariance(model, params, k, n_cal, lags):
    """``C(d) = Cov(p_j, p_{j+d}) / dt^4`` of the position contrast (module docstring).

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        One parameter point (scalars).
    k : (n_k,) array_like of int
        Outage lengths [samples].
    n_cal : int
        Calibration window [samples].
    lags : sequence of (n_d,) array_like
        For each outage, the lags ``d >= 0`` [samples] (rounded to whole samples within
        ``8 (k + N)``; farther lags may be fractional).

    Returns
    -------
    list of (n_d,) ndarray
        [u^2] (phase units: times ``dt^4`` for [u^2 s^4]).
    """
    ks = np.atleast_1d(np.asarray(k, dtype=float))
    n_cal = float(n_cal)
    lags = [np.asarray(d, dtype=float) for d in lags]
    near = [d <= _NEAR_SPANS * (kk + n_cal) for kk, d in zip(ks, lags)]
    kinds = ("none", "gauss_markov", "flicker")
    exact_far = [t for t in model.components if t.tail_kind not in kinds]
    smooth_far = [t for t in model.components if t.tail_kind in kinds[1:]]
    dt = model.dt

    def structure(terms):
        return lambda lag: sum(t.structure(lag, params, dt) for t in terms)

    exact = [np.where(nr, np.round(d), 0.0) for nr, d in zip(near, lags)]
    point = (model.terms, float(dt), tuple(float(params[p]) for p in model.parameter_names))
    out = _exact_covariance(structure(model.components), ks, n_cal, exact, key=point)
    out = [np.where(nr, c, 0.0) for nr, c in zip(near, out)]
    if exact_far and any((~nr).any() for nr in near):
        far = [np.where(nr, 0.0, np.round(d)) for nr, d in zip(near, lags)]
        extra = _exact_covariance(structure(exact_far), ks, n_cal, far, key=("far",) + point)
        out = [np.where(nr, c, e) for nr, c, e in zip(near, out, extra)]
    for i, (kk, d, nr) in enumerate(zip(ks, lags, near)):
        if smooth_far and not nr.all():
            out[i][~nr] += _far_moment_term(structure(smooth_far), kk, n_cal, d[~nr])
    return out


def _far_moment_term(structure, k, n_cal, d):
    """``-A^2 / 8 D^(4)(d)`` (module docstring) at lags ``d`` far beyond the span ``k + N``."""
    big_k = k - 1.0
    c = k * (k - 1.0) / (2.0 * n_cal)
    a2 = big_k * (big_k + 1.0) * (2.0 * big_k + 1.0) / 6.0 + c * n_cal**2
    h = _FAR_STEP * d
    fourth = (
        structure(d - 2 * h) - 4 * structure(d - h) + 6 * structure(d)
        - 4 * structure(d + h) + structure(d + 2 * h)
    ) / h**4
    return -a2 * a2 / 8.0 * fourth


def _exact_covariance(structure, ks, n_cal, lags, key=None):
    """Exact ``C(d)`` at whole-sample lags from the sums ``F``, ``G`` of one table of ``D``:
    ``F^(m) = F(m)`` (``m >= 0``), ``-F(-m - 1)`` (``m < 0``); ``G^(m) = G(max(|m| - 1, 0))``.
    ``key``: what ``structure`` is (:func:`_sums`' reuse), or ``None``."""
    parts = []
    for kk, d in zip(ks, lags):
        big_k = kk - 1.0
        c = kk * (kk - 1.0) / (2.0 * n_cal)
        points = ((-n_cal, c), (0.0, -(big_k + c)))
        f_args = [a for p, _ in points
                  for a in (d - p + big_k, d - p, d + p - 1.0, d + p - big_k - 1.0)]
        parts.append((kk, d, big_k, points, f_args, [d + big_k, d, d - big_k]))
    f_idx = [np.where(a >= 0, a, -a - 1.0) for p in parts for a in p[4]]
    g_idx = [np.maximum(np.abs(a) - 1.0, 0.0) for p in parts for a in p[5]]
    f_tab, g_tab = _sums(structure, np.concatenate(f_idx + g_idx).astype(np.int64), key)

    def f_hat(m):
        i = np.where(m >= 0, m, -m - 1.0).astype(np.int64)
        return np.where(m >= 0, 1.0, -1.0) * f_tab(i)

    def g_hat(m):
        return g_tab(np.maximum(np.abs(m) - 1.0, 0.0).astype(np.int64))

    out = []
    for kk, d, big_k, points, _, _ in parts:
        if kk < 2:
            out.append(np.zeros(d.shape))
            continue
        total = g_hat(d + big_k) - 2.0 * g_hat(d) + g_hat(d - big_k)  # box-box
        for p, alpha in points:  # point-box, both orders
            total = total + alpha * (
                f_hat(d - p + big_k) - f_hat(d - p) + f_hat(d + p - 1.0)
                - f_hat(d + p - big_k - 1.0)
            )
            for q, beta in points:  # point-point
                total = total + alpha * beta * np.asarray(
                    structure(np.abs(q - p + d)), dtype=np.longdouble)
        out.append(np.asarray(-0.5 * total, dtype=float))
    return out


#: the last sums :func:`_sums` made with a key, ``(key, top, F, G)``, for the two keys last used,
#: kept within :func:`reused_sums` only. A report's bound search asks for one parameter point's
#: position contrast at every outage it tries: two tables each time (every term, and the far-lag
#: terms alone), up to about the record's length (1e6 samples: 26 ms a table, 46 tables for one
#: accelerometer); 32 MB a table at 1e6 samples
_LAST_SUMS = []
_KEPT_SUMS = 2
_REUSING = [0]


@contextlib.contextmanager
def reused_sums():
    """Within it, :func:`position_covariance` reuses the structure-function sums it made for a
    parameter point (the same numbers, bit for bit: :func:`_sums`); on leaving the outermost one,
    they are dropped. A report's bound search for one sensor runs in one (it cost an
    accelerometer's report 0.7 s of 2.9 s: docs/speed_under_load.md, "Twelfth session")."""
    _REUSING[0] += 1
    try:
        yield
    finally:
        _REUSING[0] -= 1
        if not _REUSING[0]:
            _LAST_SUMS.clear()


def _sums(structure, wanted, key=None):
    """Lookups ``F(i)``, ``G(i)`` (extended precision) at the whole-sample indices ``wanted``.

    With ``key`` (what ``structure`` is: terms, ``dt`` and parameter point), within
    :func:`reused_sums`, the last table made for that key is reused where it reaches ``wanted``:
    its first entries are the same numbers a shorter table would hold (``D`` element by element,
    running sums in order; tested)."""
    top = int(wanted.max()) if wanted.size else 0
    if top <= TABLE_MAX:
        keep = key is not None and _REUSING[0] > 0
        last = next((e for e in _LAST_SUMS if keep and e[0] == key and e[1] >= top), None)
        if last is not None:
            return (lambda i: last[2][i]), (lambda i: last[3][i])
        if keep:  # a shorter table of this key: dropped before the new one is made
            _LAST_SUMS[:] = [e for e in _LAST_SUMS if e[0] != key][-(_KEPT_SUMS - 1):]
        table = np.asarray(structure(np.arange(top + 1, dtype=float)), dtype=np.longdouble)
        f = np.cumsum(table)
        del table
        g = np.cumsum(f)
        if keep:
            _LAST_SUMS.append((key, top, f, g))
        return (lambda i: f[i]), (lambda i: g[i])
    _, f, g = _blocked_sums(structure, top, wanted)
    return (lambda i: f[i]), (lambda i: g[i])
