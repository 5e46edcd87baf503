"""Vibration line: a sinusoid of random phase, ``y_k = A sin(2 pi f k dt + phi)``, ``phi ~ U(0, 2
pi)``.

Parameters ``vibration_frequency`` ``f`` [Hz] (between one cycle per record and the Nyquist
frequency ``1/(2 dt)``) and ``vibration_amplitude`` ``A`` [u]: a mechanical or electrical line
(a pump, a fan, a motor, a dither) on a static log, the hump of an Allan deviation that no
power-law or Gauss-Markov term follows. Random phase makes it a stationary process with
autocovariance ``(A^2/2) cos(omega l)``, ``omega = 2 pi f dt``.

With ``x = omega / 2 = pi f dt`` and ``D_n = sin(n x) / sin(x)`` (the Dirichlet kernel: the sum
of ``n`` consecutive samples of ``e^{i omega t}`` has modulus ``|D_n|``), every linear functional
``sum_t w_t y_t`` has variance ``(A^2/2) |sum_t w_t e^{i omega t}|^2``, whence, exactly for
sampled data:

* structure function ``D(k) = (A^2/2) D_k^2 = A^2 sin^2(k x) / (2 sin^2 x)``;
* AVAR ``(4 D(m) - D(2m)) / (2 m^2) = A^2 sin^4(m x) / (m^2 sin^2 x)`` (the continuous
  ``A^2 sin^4(pi f tau) / (pi f tau)^2`` of IEEE Std 952 as ``dt -> 0``), peak ``0.5251 A^2``
  near ``tau = 0.371 / f``, zeros at whole periods;
* drift (``v = dt sum_{t<k} e_t``, ``p = dt sum_{j<k} v_j``, ``n = k - 1``, ``N`` the calibration
  window, ``r = k/N``, ``c = k(k-1)/(2N)``, ``E_n = 1 - D_n/n``)::

      order 1, zero / stationary   (A^2/2) dt^2 D_k^2
      order 1, calibrated          (A^2/2) dt^2 [k^2 (E_N - E_k)^2 + 4 r D_k D_N sin^2((k+N) x/2)]
                                   = (A^2/2) dt^2 [(k (E_N - E_k) + 2 r D_N sin^2((k+N) x/2))^2
                                                   + (r D_N sin((k+N) x))^2]  (evaluated)
      order 2                      (A^2/2) dt^4 (Re^2 + Im^2) / (4 sin^2 x)
          Re = n E_n + 2 D_n sin^2((n+1) x/2) [+ 2 c sin^2(N x)]
          Im = -D_n sin((n+1) x)               [+ c sin(2 N x)]

  (the bracketed parts for the calibrated start). ``"zero"`` and ``"stationary"`` are the same:
  a line is not switched on by the outage. The calibrated forms cancel at small ``f t``; they
  are evaluated from ``C(u) = 1 - sin(u)/u`` (series below ``|u| = 0.5``): ``E_n = (C(n x) -
  C(x)) / (1 - C(x))`` and the calibrated ``Im = n (n+1) x [S(2Nx) S(x) - S(nx) S((n+1)x)] / S(x)``
  with ``S = 1 - C`` expanded so that only differences of the small ``C`` remain.

Covariance of the AVAR estimates: the line's correlation never decays, and its amplitude is
fixed, so its tail is of the ``"deterministic"`` kind: the estimates spread through the line's
cross terms with the noise, summed over every lag of the record, and not through the line's own
fourth moments (:func:`bayes_imu.noise.avar_covariance.exact_pair_sums`). Treated as a Gaussian
process of the same covariance (a line of Rayleigh amplitude, kind ``"generic"``) its estimates
would have about two degrees of freedom where it dominates, and a fit would not pin the line
(a real ADIS16405 gyro z log: the sampler wandered over the whole frequency box).
"""

from math import factorial

import numpy as np

from ._base import Term, nav_system
from .quantities import DEG, G

__all__ = ["VIBRATION", "sinc_complement"]

#: max over u of sin(u)^4 / u^2 (at tan u = 2u, u = 1.1656): the AVAR peak of a line is about this
#: times A^2
AVAR_PEAK = 0.5251
_SWITCH = 0.5  # |u| below which C(u) = 1 - sin(u)/u is summed from its series
_TERMS = 10  # 0.5^20 / 21! ~ 2e-26


def sinc_complement(u):
    """``C(u) = 1 - sin(u)/u`` without cancellation: its series ``sum_j (-1)^(j+1) u^(2j)/(2j+1)!``
    below ``|u| = 0.5``, the closed form above (at most ~1.4 digits lost at the switch)."""
    u = np.asarray(u, dtype=float)
    small = np.abs(u) < _SWITCH
    z = np.where(small, u, 0.0) ** 2
    series = np.zeros(u.shape)
    for j in range(_TERMS, 0, -1):
        series = series * z + (-1.0) ** (j + 1) / factorial(2 * j + 1)
    series = series * z
    with np.errstate(invalid="ignore", divide="ignore"):
        direct = 1.0 - np.sin(u) / np.where(small, 1.0, u)
    return np.where(small, series, direct)


def _half_phase(params, dt):
    return np.pi * np.asarray(params["vibration_frequency"], float) * dt


class _Vibration(Term):
    tail_kind = "deterministic"
    simulated_start = "stationary"

    def avar(self, mf, params, dt):
        x = _half_phase(params, dt)
        sx = np.sin(x)
        weight = (np.asarray(params["vibration_amplitude"], float) / sx) ** 2
        s = np.sin(mf * x[..., None])  # A^2 sin^4(m x) / (m sin x)^2, in place
        s *= s
        s *= s
        s = s * weight[..., None]  # the parameters' shapes broadcast (either may be a scalar)
        s /= mf * mf
        return s

    def structure(self, k, params, dt):
        x = _half_phase(params, dt)
        s = np.sin(np.asarray(k, float) * x) / np.sin(x)
        return 0.5 * params["vibration_amplitude"] ** 2 * s * s

    def simulate(self, params, n, dt, rng):
        phase = rng.uniform(0.0, 2.0 * np.pi)
        omega = 2.0 * np.pi * params["vibration_frequency"] * dt
        return params["vibration_amplitude"] * np.sin(omega * np.arange(n, dtype=float) + phase)

    def bounds(self, scale):
        return [
            (np.log(1.0 / scale.record_s), np.log(0.5 / scale.dt)),
            scale.amplitude(-np.log(AVAR_PEAK), 0.5),
        ]

    def starting_guess(self, tau, avar, m, dt):
        # the strongest hump: a point of ``avar m`` (flat for white noise) above the level it falls
        # back to within the next three octaves (a line's AVAR falls as 1/tau^2 past its peak,
        # while bias terms only rise); the line peaks at tau = 0.371 / f with 0.5251 A^2
        g = avar * m
        n = g.size
        floor = np.array(
            [max(g[0], g[i + 1 : i + 4].min()) if i + 1 < n else np.inf for i in range(n)]
        )
        i = int(np.argmax(g / floor))
        excess = avar[i] - floor[i] / m[i]
        amplitude = np.sqrt(excess / AVAR_PEAK) if excess > 0 else 0.1 * np.sqrt(avar.min())
        return {
            "vibration_frequency": min(0.371 / tau[i], 0.45 / dt),
            "vibration_amplitude": amplitude,
        }

    def datasheet_rows(self, sensor):
        if sensor == "gyro":
            amplitude = (
                "vibration_amplitude",
                lambda v: v * DEG,
                "deg/s",
                "vibration line amplitude",
            )
        else:
            amplitude = (
                "vibration_amplitude",
                lambda v: v / (G * 1e-3),
                "mg",
                "vibration line amplitude",
            )
        return {
            "vibration_frequency": (
                "vibration_frequency",
                lambda v: v,
                "Hz",
                "vibration line frequency",
            ),
            "vibration_amplitude": amplitude,
        }

    def _drift_variance(self, order, k, params, dt, bias_start, n_cal):
        x = _half_phase(params, dt)[..., None]
        a2 = 0.5 * np.asarray(params["vibration_amplitude"], float)[..., None] ** 2
        k = np.asarray(k, dtype=float)
        sx = np.sin(x)
        cx = sinc_complement(x)
        calibrated = bias_start == "calibrated"
        big_n = np.asarray(n_cal, float) if calibrated else None
        if order == 1:
            dk = np.sin(k * x) / sx
            out = dk * dk
            if calibrated:
                dn = np.sin(big_n * x) / sx
                ek = (sinc_complement(k * x) - cx) / (1.0 - cx)
                en = (sinc_complement(big_n * x) - cx) / (1.0 - cx)
                r = k / big_n
                # |W|^2 as a sum of two squares (never negative; the docstring's form, expanded,
                # went to -1e-18 by rounding where both windows hold whole periods)
                theta = (k + big_n) * x
                out = (k * (en - ek) + 2.0 * r * dn * np.sin(0.5 * theta) ** 2) ** 2 + (
                    r * dn * np.sin(theta)
                ) ** 2
            return np.where(k >= 1, a2 * dt**2 * out, 0.0)
        n = np.maximum(k - 1.0, 0.0)
        dn = np.sin(n * x) / sx
        en = (sinc_complement(n * x) - cx) / (1.0 - cx)
        re = n * en + 2.0 * dn * np.sin(0.5 * (n + 1.0) * x) ** 2
        im = -dn * np.sin((n + 1.0) * x)
        if calibrated:
            c = n * (n + 1.0) / (2.0 * big_n)
            re = re + 2.0 * c * np.sin(big_n * x) ** 2
            ca, cc, cd = (
                sinc_complement(2.0 * big_n * x),
                sinc_complement(n * x),
                sinc_complement((n + 1.0) * x),
            )
            im = n * (n + 1.0) * x * ((cc + cd - cc * cd) - (ca + cx - ca * cx)) / (1.0 - cx)
        return np.where(k >= 2, a2 * dt**4 * (re * re + im * im) / (4.0 * sx * sx), 0.0)

    def nav_filter(self, params, dt, *, n_cal=None):
        """State ``A (sin theta_i, cos theta_i)``, ``theta_i = omega i + phi``, turned by ``omega``
        each sample, undriven; ``y_i`` its first component. Random phase: the state covariance is
        ``(A^2/2) I`` at every start (a line is not switched on by the outage), batched over
        draws."""
        omega = 2.0 * np.pi * np.asarray(params["vibration_frequency"], float) * dt
        a2 = 0.5 * np.asarray(params["vibration_amplitude"], float) ** 2
        omega, a2 = np.broadcast_arrays(omega, a2)
        c, s = np.cos(omega), np.sin(omega)
        turn = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)
        cov = a2[..., None, None] * np.eye(2)
        h = np.broadcast_to(np.array([1.0, 0.0]), omega.shape + (2,))
        return nav_system(
            turn, np.zeros(omega.shape + (2, 1)), h, np.zeros(omega.shape + (1,)), cov
        )

    def nav_variance(self, loop, k, params, dt, *, bias_start="calibrated", n_cal=None):
        """Exact propagation of :meth:`nav_filter` for every draw at once."""
        return loop.linear_variance(
            self.nav_filter(params, dt), k, dt, bias_start=bias_start, n_cal=n_cal
        )


VIBRATION = _Vibration(
    "vibration",
    ("vibration_frequency", "vibration_amplitude"),
    {"vibration_frequency": "Hz", "vibration_amplitude": "{u}"},
    "vibration line (sinusoid)",
    "short_term",
    selection=("extension",),
    kalibr="none",
    parameter_labels={
        "vibration_frequency": "vibration frequency",
        "vibration_amplitude": "vibration amplitude",
    },
)
