"""Bias instability: flicker rate noise of level ``B`` [u] (IEEE Std 952).

Defined by the generalised covariance of the phase ``D(k) = -(B^2/pi) k^2 ln k``; its AVAR
is exactly flat, ``2 ln2 B^2 / pi`` (the Allan deviation plateau ``B sqrt(2 ln2 / pi)``).
Simulated by circulant embedding of the stationary first differences (Dietrich & Newsam
1997; exact when the embedding is non-negative, which is checked).

Drift: flicker is not stationary, so a bias "at the start of the outage" is undefined; only
an error relative to an estimated bias has a finite variance. ``"calibrated"`` is exact (the
contrast of :mod:`._base`). ``"zero"`` and ``"stationary"`` use the same contrast with a
calibration window as long as the outage: the residual rate is then the difference of two
adjacent means, ``sqrt(2)`` times the Allan deviation, which is the least any window gives
at that horizon (shorter windows add white-like scatter, longer ones stale bias).
"""

import math

import numpy as np

from ..errors import ModelError
from ._base import CovarianceTail, Term
from .quantities import DEG, UG

__all__ = ["BIAS_INSTABILITY", "flicker_difference_acov", "flicker_increment_acov", "power_log_sum"]

FLAT = 2.0 * np.log(2.0) / np.pi


def flicker_difference_acov(n, bias_instability):
    """Autocovariance ``gamma(l)``, ``l = 0..n-1``, of first differences of flicker rate noise."""
    h = bias_instability**2 / np.pi
    k = np.arange(n + 2, dtype=float)
    d = np.zeros_like(k)
    d[1:] = -h * k[1:] ** 2 * np.log(k[1:])
    lag = np.arange(n)
    dm1 = d[np.abs(lag - 1)]
    dm2 = d[np.abs(lag - 2)]
    return -0.5 * (6.0 * d[lag] - 4.0 * d[lag + 1] - 4.0 * dm1 + d[lag + 2] + dm2)


#: below this ``n`` :func:`power_log_sum` adds the terms; above, the first ``_DIRECT`` terms plus
#: the Euler-Maclaurin tail (four Bernoulli corrections: truncation below 1e-22 of the sum)
_DIRECT = 4096
_BERNOULLI = (1.0 / 6.0, -1.0 / 30.0, 1.0 / 42.0, -1.0 / 30.0)  # B_2, B_4, B_6, B_8


def power_log_sum(p, n):
    """``S_p(n) = sum_{l=1}^n l^p ln l`` in extended precision (``numpy.longdouble``), ``n`` an int.

    Direct summation up to :data:`_DIRECT` terms; beyond, ``S_p(n0)`` plus the Euler-Maclaurin
    formula for ``sum_{n0 < l <= n} f(l)``, ``f(x) = x^p ln x``: the integral
    ``[x^(p+1) (ln x / (p + 1) - 1 / (p + 1)^2)]``, the end correction ``(f(n) - f(n0)) / 2`` and
    ``sum_j B_2j / (2j)! [f^(2j-1)]``, with ``f^(m)(x) = x^(p-m) (a_m ln x + b_m)``,
    ``a_(m+1) = (p - m) a_m``, ``b_(m+1) = (p - m) b_m + a_m``. Cost independent of ``n``.
    """
    one = np.longdouble(1.0)
    if n <= _DIRECT:
        ls = np.arange(1, max(n, 0) + 1, dtype=np.longdouble)
        return np.sum(ls**p * np.log(ls)) if n > 0 else 0 * one
    n0 = _DIRECT
    head = power_log_sum(p, n0)

    def primitive(x):
        return x ** (p + 1) * (np.log(x) / (p + 1) - one / (p + 1) ** 2)

    def derivative(m, x):
        a, b = one, 0 * one
        for i in range(m):
            a, b = (p - i) * a, (p - i) * b + a
        return x ** (p - m) * (a * np.log(x) + b)

    hi, lo = np.longdouble(n), np.longdouble(n0)
    tail = primitive(hi) - primitive(lo) + (derivative(0, hi) - derivative(0, lo)) / 2
    factorial = one
    for j, bernoulli in enumerate(_BERNOULLI, start=1):
        factorial *= (2 * j - 1) * (2 * j)
        step = derivative(2 * j - 1, hi) - derivative(2 * j - 1, lo)
        tail += np.longdouble(bernoulli) / factorial * step
    return head + tail


class _BiasInstability(Term):
    tail_kind = "flicker"

    avar_power = 2

    def avar(self, mf, params, dt):
        return (
            FLAT * np.asarray(params["bias_instability"], float)[..., None] ** 2 * np.ones_like(mf)
        )

    def structure(self, k, params, dt):
        k = np.asarray(k, dtype=float)
        h = params["bias_instability"] ** 2 / np.pi
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(k > 0, -h * k * k * np.log(np.where(k > 0, k, 1.0)), 0.0)

    def covariance_tail(self, params, dt):
        return CovarianceTail("flicker", flicker=params["bias_instability"] ** 2 / np.pi)

    def starting_guess(self, tau, avar, m, dt):
        return {"bias_instability": np.sqrt(0.5 * avar.min() * np.pi / (2.0 * np.log(2.0)))}

    def datasheet_rows(self, sensor):
        what = "flicker coefficient B (ADEV floor 0.664 B)"
        if sensor == "gyro":
            return {"bias_instability": ("bias_instability", lambda v: v * DEG * 3600.0, "deg/h",
                                         what)}
        return {"bias_instability": ("bias_instability", lambda v: v * UG, "ug", what)}

    def kalibr_random_walk2(self, draws, tau_max):
        # the random walk with the same Allan variance at the longest averaging time of the log
        return draws["bias_instability"] ** 2 * 6.0 * math.log(2.0) / (math.pi * tau_max)

    def simulate(self, params, n, dt, rng):
        if params["bias_instability"] == 0:
            return np.zeros(n)
        gamma = flicker_difference_acov(n, params["bias_instability"])
        row = np.concatenate([gamma, gamma[-2:0:-1]])
        lam = np.fft.rfft(row).real
        if lam.min() < -1e-9 * np.max(np.abs(lam)):
            raise ModelError(
                f"flicker circulant embedding not non-negative for n={n} (min eigenvalue "
                f"{lam.min():.3g})"
            )
        lam = np.clip(lam, 0.0, None)
        z = np.fft.irfft(np.sqrt(lam) * np.fft.rfft(rng.standard_normal(row.size)), n=row.size)[
            : n - 1
        ]
        y = np.empty(n)
        y[0] = 0.0
        np.cumsum(z, out=y[1:])
        return y

    def bounds(self, scale):
        return [scale.amplitude(np.log(1.0 / FLAT), 0.5)]

    def amplitude2(self, params):
        return np.asarray(params["bias_instability"], float) ** 2

    def structure_sums(self, n, dt):
        """``D = -n^2 ln n / pi``, ``F = -S_2(n) / pi``, ``G = -((n + 1) S_2(n) - S_3(n)) / pi``, in
        extended precision, with ``S_p(n) = sum_{l<=n} l^p ln l`` (:func:`power_log_sum`)."""
        pi = np.longdouble(np.pi)  # the table's D uses the double-precision pi too
        s2, s3 = power_log_sum(2, n), power_log_sum(3, n)
        d = -np.longdouble(n) ** 2 * np.log(np.longdouble(max(n, 1))) / pi
        return d, -s2 / pi, -((n + 1) * s2 - s3) / pi

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        return super().unit_drift(
            order, k, dt, "calibrated", n_cal if bias_start == "calibrated" else np.maximum(k, 1.0)
        )

    def nav_variance(self, loop, k, params, dt, *, bias_start="calibrated", n_cal=None):
        """Exact quadratic form over the flicker's stationary rate increments
        (:func:`flicker_increment_acov`); ``"zero"``/``"stationary"`` as :meth:`unit_drift`
        (a calibration window as long as the outage)."""
        k = np.asarray(k, float)
        n = np.broadcast_to(n_cal, k.shape) if bias_start == "calibrated" else np.maximum(k, 1.0)
        unit = loop.unit_variance(self.name, lambda: loop.increment_variance(
            k, dt, n, lambda size: flicker_increment_acov(size, 1.0)), k, dt, bias_start, n)
        return np.asarray(self.amplitude2(params), float)[..., None, None] * unit


BIAS_INSTABILITY = _BiasInstability(
    "bias_instability",
    ("bias_instability",),
    {"bias_instability": "{u}"},
    "bias instability",
    "bias",
    selection=("optional",),
    kalibr="random_walk",
    short_label="bias instability",
    worst_axis=("bias_instability",),
    parameter_labels={"bias_instability": "bias instability"},
)


_ASYMPTOTIC_FROM = 16  # lag from which flicker_increment_acov uses its asymptotic series
_ASYMPTOTIC_TERMS = 14  # terms ~ (2/l)^(2n): (1/8)^26 < 1e-23 at l = 16


def flicker_increment_acov(n, bias_instability):
    """:func:`flicker_difference_acov` without cancellation at large lags.

    ``gamma(l) = (h/2) delta^4 f(l)``, ``f(l) = l^2 ln l``, ``h = B^2/pi``. The fourth central
    difference of ``f`` cancels ``~l^4 ln l`` relative at lag ``l``; from lag 16 it is summed as
    ``delta^4 = (2 sinh(D/2))^4 = sum_{n>=2} 2 (4^n - 4) D^(2n) / (2n)!`` with
    ``f^(2n)(l) = -2 (2n-3)! / l^(2n-2)`` (a series convergent for ``l > 2``), below from the
    definition in extended precision.
    """
    h = bias_instability**2 / np.pi
    from math import factorial

    lag = np.arange(n, dtype=float)
    small = lag < _ASYMPTOTIC_FROM
    k = np.arange(_ASYMPTOTIC_FROM + 3, dtype=np.longdouble)
    f = np.zeros(k.shape, dtype=np.longdouble)
    f[1:] = k[1:] ** 2 * np.log(k[1:])
    ls = np.arange(min(n, _ASYMPTOTIC_FROM))
    delta4 = 6 * f[ls] - 4 * f[ls + 1] - 4 * f[np.abs(ls - 1)] + f[ls + 2] + f[np.abs(ls - 2)]
    out = np.empty(n)
    out[ls] = (0.5 * delta4).astype(float)
    big = lag[~small]
    inv2 = 1.0 / (big * big)
    acc = np.zeros(big.shape)
    for m in range(_ASYMPTOTIC_TERMS + 1, 1, -1):  # Horner in 1/l^2 (m is n of the docstring)
        acc = acc * inv2 + -4.0 * (4.0**m - 4.0) * factorial(2 * m - 3) / factorial(2 * m)
    out[~small] = 0.5 * acc * inv2
    return h * out
