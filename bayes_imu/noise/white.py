"""White rate noise (angle / velocity random walk, IEEE Std 952).

``y_k`` i.i.d. with variance ``noise_variance`` ``q`` [u^2]; density ``N = sqrt(q dt)``.
AVAR ``q / m`` (SP1065 Table 3; ``N^2 / tau``), exact; ``D(k) = q k``.
Drift: ``q dt^2 k`` (paper eq 5) and ``q dt^4 (k-1) k (2k-1) / 6`` (eq 11 corrected) from a
zero or stationary start; calibrated start from the contrast of :mod:`._base`.
"""

from fractions import Fraction

import numpy as np

from ._base import Term, calibrated_contrast, nav_system
from .quantities import DEG

__all__ = ["WHITE"]


class _White(Term):
    tail_kind = "none"
    simulated_start = "stationary"

    avar_power = 1

    def avar(self, mf, params, dt):
        return np.asarray(params["noise_variance"], float)[..., None] / mf

    def structure(self, k, params, dt):
        return params["noise_variance"] * np.asarray(k, float)

    def simulate(self, params, n, dt, rng):
        return np.sqrt(params["noise_variance"]) * rng.standard_normal(n)

    def bounds(self, scale):
        return [scale.amplitude(np.log(scale.m_min), 1.0)]

    def starting_guess(self, tau, avar, m, dt):
        return {"noise_variance": avar[0] * m[0]}

    def datasheet_rows(self, sensor):
        # the noise density is the white term's with the short-term terms' white equivalents
        if sensor == "gyro":
            return {"angle_random_walk": ("noise_density", lambda v: v * DEG * 60.0, "deg/sqrt(h)",
                                          "ARW (white + short-term terms)")}
        return {"velocity_random_walk": ("noise_density", lambda v: v * 60.0, "m/s/sqrt(h)",
                                         "VRW (white + short-term terms)")}

    def amplitude2(self, params):
        return params["noise_variance"]

    def structure_sums(self, n, dt):
        """``D = n``, ``F = n (n + 1) / 2``, ``G = n (n + 1) (n + 2) / 6`` (exact)."""
        return Fraction(n), Fraction(n * (n + 1), 2), Fraction(n * (n + 1) * (n + 2), 6)

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        if bias_start == "calibrated":
            contrast = calibrated_contrast(lambda lag: np.asarray(lag, float), order, k, n_cal,
                                           sums=lambda n: self.structure_sums(n, dt))
            return dt ** (2 * order) * contrast
        shape = k if order == 1 else (k - 1.0) * k * (2.0 * k - 1.0) / 6.0
        return dt ** (2 * order) * np.where(k > 0, shape, 0.0)

    def nav_filter(self, params, dt, *, n_cal=None):
        """No state: ``y_i = sqrt(q) eps_i``."""
        sd = np.sqrt(float(params["noise_variance"]))
        return nav_system([[0.0]], [[0.0]], [0.0], [sd], [[0.0]])


WHITE = _White("white", ("noise_variance",), {"noise_variance": "({u})^2"},
               "angle/velocity random walk", "short_term", selection=("base",),
               kalibr="noise_density", short_label="white noise",
               worst_axis=("noise_variance", "noise_density"),
               parameter_labels={"noise_variance": "white noise variance"})
