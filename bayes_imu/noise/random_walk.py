"""Rate random walk: ``y_k`` increments by ``N(0, K^2 dt)`` each sample (IEEE Std 952 ``K``).

AVAR ``K^2 dt (2 m^2 + 1) / (6 m)`` (exact; ``K^2 tau / 3`` for large ``m``);
``D(k) = K^2 dt (k - k^3) / 6`` (a generalised covariance of order 2).
Drift: from a zero start (the walk is at 0 when the outage starts; ``"stationary"`` is the
same, a walk has no stationary state) ``K^2 dt^(2r+1) V_r(k, 0)``
(:mod:`bayes_imu.noise.euler_sums`); calibrated start from the contrast of :mod:`._base`.
"""

from fractions import Fraction

import numpy as np

from .euler_sums import gm_sum
from ._base import Term, nav_system
from .quantities import DEG

__all__ = ["RANDOM_WALK"]


class _RandomWalk(Term):
    tail_kind = "none"
    # a simulated walk holds one increment at its first sample, a walk from a zero start none
    simulated_start = None

    avar_power = 2

    def avar(self, mf, params, dt):
        q = np.asarray(params["rate_random_walk"], float)[..., None] ** 2 * dt
        return q * (2.0 * mf * mf + 1.0) / (6.0 * mf)

    def structure(self, k, params, dt):
        k = np.asarray(k, float)
        return params["rate_random_walk"] ** 2 * dt * (k - k**3) / 6.0

    def simulate(self, params, n, dt, rng):
        return np.cumsum(params["rate_random_walk"] * np.sqrt(dt) * rng.standard_normal(n))

    def bounds(self, scale):
        return [scale.amplitude(np.log(3.0 / scale.tau_max), 0.5)]

    def starting_guess(self, tau, avar, m, dt):
        return {"rate_random_walk": np.sqrt(1.5 * avar[-1] / tau[-1])}

    def datasheet_rows(self, sensor):
        if sensor == "gyro":
            return {"rate_random_walk": ("rate_random_walk", lambda v: v * DEG * 3600.0**1.5,
                                         "deg/h/sqrt(h)", "RRW")}
        return {"acceleration_random_walk": ("rate_random_walk", lambda v: v * 3600.0**1.5,
                                             "m/s/h/sqrt(h)", "AcRW")}

    def kalibr_random_walk2(self, draws, tau_max):
        return draws["rate_random_walk"] ** 2

    def amplitude2(self, params):
        return np.asarray(params["rate_random_walk"], float) ** 2

    def structure_sums(self, n, dt):
        """``D = dt (n - n^3) / 6``; with ``T_n = n (n + 1) / 2`` (``sum l^3 = T_n^2``),
        ``F = dt (T_n - T_n^2) / 6`` and ``G = dt (C / 6 - C (3 n^2 + 6 n + 1) / 60) / 6``,
        ``C = n (n + 1) (n + 2)`` (exact)."""
        scale = Fraction(dt) / 6
        t, cube = Fraction(n * (n + 1), 2), n * (n + 1) * (n + 2)
        return (scale * (n - n**3), scale * (t - t * t),
                scale * (Fraction(cube, 6) - Fraction(cube * (3 * n * n + 6 * n + 1), 60)))

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        if bias_start == "calibrated":
            return super().unit_drift(order, k, dt, bias_start, n_cal)
        return dt ** (2 * order + 1) * gm_sum(order, k, np.zeros_like(k))

    def nav_filter(self, params, dt, *, n_cal=None):
        """State ``y_i`` itself, zero at the start (``y_0 = 0``, as :meth:`drift_variance`); a
        calibrated error annihilates the walk's level: starting the window at zero is exact."""
        step = float(params["rate_random_walk"]) * np.sqrt(dt)
        return nav_system([[1.0]], [[step]], [1.0], [0.0], [[0.0]])


RANDOM_WALK = _RandomWalk("random_walk", ("rate_random_walk",), {"rate_random_walk": "{u}/sqrt(s)"},
                          "rate random walk", "slow", selection=("optional",), kalibr="random_walk",
                          short_label="rate random walk", worst_axis=("rate_random_walk",),
                          parameter_labels={"rate_random_walk": "rate random walk"})
