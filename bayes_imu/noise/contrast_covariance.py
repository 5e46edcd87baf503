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
"""

import numpy as np

__all__ = ["contrast_edf"]

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


def contrast_edf(model, params, k, n_cal, n_samples, stride=1):
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

    Returns
    -------
    (n_k,) ndarray
        ``nu = 2 (E V_hat)^2 / Var(V_hat)`` (module docstring).
    """
    out = []
    ks = np.atleast_1d(np.asarray(k, dtype=float))
    for kk, step in zip(ks, np.broadcast_to(np.asarray(stride, dtype=np.int64), ks.shape)):
        r = kk / n_cal
        lags = np.array([0.0, n_cal, -n_cal, kk, -kk, kk + n_cal, -(kk + n_cal)])
        weights = np.array(
            [1 + (1 + r) ** 2 + r * r, -r * (1 + r), -r * (1 + r), -(1 + r), -(1 + r), r, r]
        )
        m = int((n_samples - n_cal - kk) // step + 1)  # starts averaged, ``step`` apart
        u, w = _lags(m, kk / step, n_cal / step)
        d = step * np.concatenate(([0.0], u))
        table = model.structure_function(np.abs(d[:, None] + lags[None, :]).ravel(), params)
        c = -0.5 * np.asarray(table, dtype=float).reshape(d.size, lags.size) @ weights
        var = 2.0 / m**2 * (m * c[0] ** 2 + 2.0 * np.dot(w, c[1:] ** 2))
        out.append(2.0 * c[0] ** 2 / var)
    return np.array(out)
