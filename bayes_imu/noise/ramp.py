"""Rate ramp: a deterministic trend ``y_k = R dt k`` of unknown sign, ``R`` [u/s].

AVAR ``R^2 tau^2 / 2`` (exact for sampled data: every second difference of the phase is
``R dt m^2``). A deterministic term has no structure function of its own: it enters the
mean of the AVAR estimates only (its cross term with the noise in their covariance is left
out, which understates the spread of the long-``tau`` estimates when the ramp dominates
them). Drift (a deterministic error, counted as its square): from a zero start (the ramp
crosses zero at the outage) ``R dt^2 k (k-1) / 2`` and ``R dt^3 k (k-1)(k-2) / 6``;
calibrated start (the mean of the ``N`` previous samples, ``-R dt (N+1)/2``, removed)
``R dt^2 k (k + N) / 2`` and ``R dt^3 [k(k-1)(k-2)/6 + (N+1) k (k-1) / 4]``.
"""

import numpy as np

from ._base import Term, nav_system
from .quantities import DEG, UG

__all__ = ["RAMP"]


class _Ramp(Term):
    tail_kind = "none"  # deterministic: no structure function (module docstring)
    simulated_start = "zero"

    avar_power = 2

    def avar(self, mf, params, dt):
        return 0.5 * (np.asarray(params["rate_ramp"], float)[..., None] * mf * dt) ** 2

    def structure(self, k, params, dt):
        return np.zeros(np.shape(k))

    def simulate(self, params, n, dt, rng):
        return params["rate_ramp"] * dt * np.arange(n, dtype=float)

    def bounds(self, scale):
        return [scale.amplitude(np.log(2.0 / scale.tau_max**2), 0.5)]

    def starting_guess(self, tau, avar, m, dt):
        return {"rate_ramp": 0.3 * np.sqrt(2.0 * avar[-1]) / tau[-1]}

    def datasheet_rows(self, sensor):
        if sensor == "gyro":
            return {"rate_ramp": ("rate_ramp", lambda v: v * DEG * 3600.0**2, "deg/h^2",
                                  "rate ramp")}
        return {"rate_ramp": ("rate_ramp", lambda v: v * UG * 3600.0, "ug/h", "acceleration ramp")}

    def amplitude2(self, params):
        return np.asarray(params["rate_ramp"], float) ** 2

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        if bias_start == "calibrated":
            n = np.asarray(n_cal, float)
            err = (
                k * (k + n) / 2.0
                if order == 1
                else k * (k - 1.0) * (k - 2.0) / 6.0 + (n + 1.0) * k * (k - 1.0) / 4.0
            )
        else:
            err = k * (k - 1.0) / 2.0 if order == 1 else k * (k - 1.0) * (k - 2.0) / 6.0
        return (dt ** (order + 1) * err) ** 2

    def nav_filter(self, params, dt, *, n_cal=None):
        """Deterministic state (level, step) ``(R dt i, R dt)``: its "covariance" is the outer
        product of the start, so the variance is the squared error, as :meth:`drift_variance`."""
        step = float(params["rate_ramp"]) * dt
        start = np.array([0.0, step])
        cal = np.array([-float(n_cal or 0) * step, step])
        return nav_system([[1.0, 1.0], [0.0, 1.0]], np.zeros((2, 1)), [1.0, 0.0], [0.0],
                          np.outer(start, start), p_calibration=np.outer(cal, cal))


RAMP = _Ramp("ramp", ("rate_ramp",), {"rate_ramp": "{u}/s"}, "rate ramp", "slow",
             selection=("extension",), kalibr="none", short_label="rate ramp",
             parameter_labels={"rate_ramp": "rate ramp"})
