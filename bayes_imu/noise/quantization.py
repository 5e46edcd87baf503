"""Quantization noise: white angle (velocity) noise of standard deviation ``Q`` [u s].

``y_k = (e_{k+1} - e_k) / dt`` with ``e`` i.i.d. of variance ``Q^2``. AVAR ``3 Q^2 / tau^2``
(exact: second differences of white angle noise have variance ``6 Q^2``);
``D(k) = 2 (Q/dt)^2`` for ``k > 0``.
Drift: the integrated error is ``e_k - e_0``: ``2 Q^2`` (single integral) and
``Q^2 dt^2 (k - 1) k`` (double integral: ``dt (sum_{j=1}^{k-1} e_j - (k-1) e_0)``),
whatever the start; calibrated start from the contrast of :mod:`._base`.
"""

from fractions import Fraction

import numpy as np

from ._base import Term, nav_system
from .quantities import DEG

__all__ = ["QUANTIZATION"]


class _Quantization(Term):
    tail_kind = "none"
    simulated_start = "stationary"

    avar_power = 2

    def avar(self, mf, params, dt):
        return 3.0 * np.asarray(params["quantization"], float)[..., None] ** 2 / (mf * dt) ** 2

    def structure(self, k, params, dt):
        return 2.0 * (params["quantization"] / dt) ** 2 * (np.asarray(k, float) != 0)

    def simulate(self, params, n, dt, rng):
        return np.diff(params["quantization"] * rng.standard_normal(n + 1)) / dt

    def bounds(self, scale):
        return [scale.amplitude(np.log(scale.tau_min**2 / 3.0), 0.5)]

    def starting_guess(self, tau, avar, m, dt):
        return {"quantization": np.sqrt(0.1 * avar[0] * tau[0] ** 2 / 3.0)}

    def datasheet_rows(self, sensor):
        if sensor == "gyro":
            return {"quantization": ("quantization", lambda v: v * DEG * 3600.0, "arcsec",
                                     "angle quantization")}
        return {"quantization": ("quantization", lambda v: v, "m/s", "velocity quantization")}

    def amplitude2(self, params):
        return np.asarray(params["quantization"], float) ** 2

    def structure_sums(self, n, dt):
        """``D = 2 / dt^2`` (``n >= 1``), ``F = n D``, ``G = n (n + 1) D / 2`` (exact)."""
        level = 2 / Fraction(dt) ** 2 if n > 0 else Fraction(0)
        return level, n * level, Fraction(n * (n + 1), 2) * level

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        if bias_start == "calibrated":
            return super().unit_drift(order, k, dt, bias_start, n_cal)
        return 2.0 * (k > 0) if order == 1 else dt**2 * np.where(k > 0, (k - 1.0) * k, 0.0)

    def nav_filter(self, params, dt, *, n_cal=None):
        """State ``e_i`` (angle noise): ``y_i = (Q eps_i - e_i)/dt``, ``e_{i+1} = Q eps_i``."""
        q = float(params["quantization"])
        return nav_system([[0.0]], [[q]], [-1.0 / dt], [q / dt], [[q * q]])


QUANTIZATION = _Quantization(
    "quantization",
    ("quantization",),
    {"quantization": "{u} s"},
    "quantization noise",
    "short_term",
    selection=("optional",),
    kalibr="none",
    short_label="quantization",
    worst_axis=("quantization",),
    parameter_labels={"quantization": "quantization"},
)
