"""Filtered white noise: white noise through a two-tap moving average (sensor decimation filter).

``y_k = sqrt(c) (w_k + w_{k-1})``, ``w`` i.i.d. standard normal, ``c`` = ``filtered_variance``
[u^2]: autocovariance ``2c`` at lag 0, ``c`` at lag 1, zero beyond. Together with the white
term it is any MA(1) process with a positive lag-one correlation up to 1/2, the signature of
the averaging / decimation filters of MEMS IMUs (the ADIS16405 logs show a lag-one
correlation of 0.17-0.31 and none at lag two). At ``tau >> dt`` it is white noise of per-sample
variance ``4c``, which the reported ``noise_density`` includes.

``D(k) = c (4k - 2)`` for ``k >= 1``; AVAR ``c (4m - 3) / m^2`` (exact).
Drift (zero and stationary start are the same: the process has no slow state):
``c dt^2 (4k - 2)`` and ``c dt^4 [(k-1)^2 + (k-1)(2k-1)(2k-3)/3]`` for ``k >= 1``;
calibrated start from the contrast of :mod:`._base`.
"""

from fractions import Fraction

import numpy as np

from ._base import Term, nav_system

__all__ = ["FILTERED_WHITE"]


class _FilteredWhite(Term):
    tail_kind = "none"
    simulated_start = "stationary"

    avar_power = 1

    def avar(self, mf, params, dt):
        return (
            np.asarray(params["filtered_variance"], float)[..., None] * (4.0 * mf - 3.0) / (mf * mf)
        )

    def structure(self, k, params, dt):
        k = np.asarray(k, float)
        return params["filtered_variance"] * np.where(k > 0, 4.0 * k - 2.0, 0.0)

    def simulate(self, params, n, dt, rng):
        w = rng.standard_normal(n + 1)
        return np.sqrt(params["filtered_variance"]) * (w[1:] + w[:-1])

    def bounds(self, scale):
        return [scale.amplitude(0.0, 1.0)]

    def starting_guess(self, tau, avar, m, dt):
        return {"filtered_variance": 0.1 * avar[0] * m[0]}

    def datasheet_rows(self, sensor):
        return {}  # part of the noise density (the white term's row)

    def amplitude2(self, params):
        return np.asarray(params["filtered_variance"], float)

    def white_equivalent(self, params, dt):
        """Per-sample variance of the white noise it amounts to at ``tau >> dt``: ``4 c``."""
        return 4.0 * np.asarray(params["filtered_variance"], float)

    def structure_sums(self, n, dt):
        """``D = 4 n - 2``, ``F = 2 n^2``, ``G = n (n + 1) (2 n + 1) / 3`` (exact, ``n >= 1``)."""
        if n <= 0:
            return Fraction(0), Fraction(0), Fraction(0)
        return Fraction(4 * n - 2), Fraction(2 * n * n), Fraction(n * (n + 1) * (2 * n + 1), 3)

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        if bias_start == "calibrated":
            return super().unit_drift(order, k, dt, bias_start, n_cal)
        if order == 1:
            return dt**2 * np.where(k > 0, 4.0 * k - 2.0, 0.0)
        return dt**4 * np.where(
            k > 0, (k - 1.0) ** 2 + (k - 1.0) * (2.0 * k - 1.0) * (2.0 * k - 3.0) / 3.0, 0.0
        )

    def nav_filter(self, params, dt, *, n_cal=None):
        """State ``w_{i-1}``: ``y_i = sqrt(c) (w_{i-1} + eps_i)``, ``w_i = eps_i``."""
        c = np.sqrt(float(params["filtered_variance"]))
        return nav_system([[0.0]], [[1.0]], [c], [c], [[1.0]])


FILTERED_WHITE = _FilteredWhite(
    "filtered_white",
    ("filtered_variance",),
    {"filtered_variance": "({u})^2"},
    "filtered (moving-average) white noise",
    "short_term",
    selection=("extension",),
    kalibr="noise_density",
    short_label="filtered white noise",
    parameter_labels={"filtered_variance": "filtered white"},
)
