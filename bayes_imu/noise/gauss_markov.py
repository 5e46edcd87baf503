"""First-order Gauss-Markov processes: the bias terms and the high-frequency correlated term.

A stationary AR(1) ``b_k = phi b_{k-1} + w_k``, ``phi = exp(-dt/T)``, variance ``s^2``
(paper eq 4 sampled exactly). Three terms share this module, told apart by their prior on
``T`` and by what they mean:

``hf_correlated`` (``correlated_variance``, ``correlated_time_constant``)
    a fast component, ``dt <= T <= 50 dt``: sensor bandwidth, internal filtering, the
    "hump" of MEMS logs at 0.01-0.1 s. It is short-term noise, not a bias: at averaging
    times ``tau >> T`` it is white noise of density ``sqrt(dt s^2 (1 + phi)/(1 - phi))``,
    which :attr:`bayes_imu.inference.fit.FitResult` adds to the white term's noise density.
``gauss_markov`` (``bias_variance``, ``time_constant``)
    a wandering bias, ``3 dt <= T <= record / 4``;
``gauss_markov_2`` (``bias_variance_2``, ``time_constant_2``)
    a second, slower bias on the same box (GMWM practice for MEMS gyros).

In one model the time constants are ordered, ``hf < gauss_markov < gauss_markov_2``
(:func:`bayes_imu.noise.model.NoiseModel.ordered`), which removes label switching.

AVAR (``x = dt/T``)::

    AVAR(m) = s^2 [m (1 - phi^2) - phi (1 - phi^m)(3 - phi^m)] / (m^2 (1 - phi)^2)

below ``m x = 0.1`` from its exact Taylor series ``-x^3 sum_n (-x)^(n-3) b_n(m) / n!`` with
integer coefficients ``b_n(m) = 4 (m+1)^n - (2m+1)^n - m 2^n - 3`` (exact arithmetic), whose
leading term is the random-walk limit ``s^2 x (2m^2 + 1)/(3m)``.

Structure function ``D(k) = s^2 [k (1 - phi^2) - 2 phi (1 - phi^k)] / (1 - phi)^2`` (the
variance of a sum of ``k`` consecutive samples), series below ``k x = 0.5``.

Drift of the Euler integral, ``a = 1 - phi`` (:mod:`bayes_imu.noise.euler_sums`, ``c_r`` and
``V_r``)::

    zero        s^2 a (2 - a) dt^(2r) V_r(k, a)                    (paper eqs 16, 22, 29)
    stationary  + s^2 dt^(2r) c_r(k)^2
    calibrated  stationary + s^2 dt^(2r) [P^2 D(N)/(s^2 N^2) - 2 P c_r(k) S_N / N]

with ``P = k`` (r = 1) or ``k (k-1)/2`` (r = 2), the weight of the estimated bias, and
``S_N = sum_{j=1}^N phi^j`` from ``Cov(b_i, b_{-j}) = s^2 phi^(i+j)``. The calibrated form
cancels the constant part of a slow bias; the time-constant prior (at most a quarter of the
record) bounds that cancellation to a few digits.
"""

from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np

from dataclasses import dataclass

from .euler_sums import gm_terms_broadcast
from ._base import CovarianceTail, Term, nav_system
from .quantities import DEG, UG

__all__ = ["HF_CORRELATED", "GAUSS_MARKOV", "GAUSS_MARKOV_2", "gm_avar", "gm_structure"]

_AVAR_SWITCH = 0.1  # m dt/T below which the AVAR uses its series
_AVAR_TERMS = 13  # (2 * 0.1)^13 / 16! ~ 4e-23
_SWITCH = 0.5
_SERIES_TERMS = 24
GM_PEAK = 0.3  # ~max over tau of a Gauss-Markov AVAR / s^2 (continuous value 0.30)
#: time-constant box of each kind: (lowest in samples, highest in samples or None, highest as a
#: record fraction)
HF_T_SAMPLES = (1.0, 50.0)
BIAS_T_MIN_SAMPLES = 3.0
BIAS_T_MAX_RECORD = 0.25


@lru_cache(maxsize=64)
def _series_coefficients(grid):
    """``c[j, i] = -b_{j+3}(m_i) / ((j+3)! m_i^j)``, exact rationals rounded once; ``grid`` is the
    cluster sizes' float64 bytes (a cheap cache key: a likelihood calls :func:`gm_avar` with one
    grid)."""
    ms = [int(v) for v in np.frombuffer(grid)]
    out = np.empty((_AVAR_TERMS, len(ms)))
    for i, m in enumerate(ms):
        for j in range(_AVAR_TERMS):
            n = j + 3
            b = 4 * (m + 1) ** n - (2 * m + 1) ** n - m * 2**n - 3
            out[j, i] = float(Fraction(-b, factorial(n) * m**j))
    return out


_avar_kernel = None  # set on first use (:func:`_kernel`)


def gm_avar(mf, variance, time_constant, dt):
    """Exact AVAR ``(..., n_tau)`` of a sampled Gauss-Markov process (module docstring).

    ``variance`` and ``time_constant`` broadcast together (shape ``...``); ``mf`` is the grid of
    cluster sizes (1-D). The exponentials are numpy's, the rest a compiled loop that takes one
    branch per element (series or closed form) in the same order of operations as the
    array expression it replaced, so the values are the same to the bit (numpy's ``expm1``
    may differ from the C library's in the last bits, which the closed form's cancellation
    near the switch amplifies to ~1e-13).
    """
    mf = np.ascontiguousarray(mf, float)
    coeffs = _series_coefficients(mf.tobytes())
    s2, t = np.asarray(variance, float), np.asarray(time_constant, float)
    if s2.shape != t.shape:
        s2, t = np.broadcast_arrays(s2, t)
    x = (dt / t.reshape(-1))[:, None]
    with np.errstate(over="ignore"):  # m dt/T beyond the largest float: e^-inf = 0
        fy = -np.expm1(-(mf * x))
    out = np.empty(fy.shape)
    _kernel()(mf, coeffs, np.ascontiguousarray(s2.reshape(-1)), x.ravel(), (-np.expm1(-x)).ravel(),
              (-np.expm1(-2.0 * x)).ravel(), fy, _AVAR_SWITCH, out)
    return out.reshape(s2.shape + mf.shape)


def _kernel():
    """The compiled AVAR rows (:func:`bayes_imu.noise._sources.avar_rows`, through
    :func:`bayes_imu.allan.kernels.compiled_kernel`)."""
    global _avar_kernel
    if _avar_kernel is None:
        from ..allan.kernels import compiled_kernel

        _avar_kernel = compiled_kernel("avar_rows", f"{__package__}._sources")
    return _avar_kernel


def gm_structure(k, s2, x):
    """``D(k)``, broadcast over ``k``, ``s2`` and ``x = dt/T``; series below ``k x = 0.5``."""
    k, s2, x = np.broadcast_arrays(
        np.asarray(k, float), np.asarray(s2, float), np.asarray(x, float)
    )
    fx = -np.expm1(-x)
    out = np.zeros(k.shape)
    big = k * x > _SWITCH
    kb, xb, fb = k[big], x[big], fx[big]
    out[big] = (kb * -np.expm1(-2.0 * xb) - 2.0 * (1.0 - fb) * -np.expm1(-kb * xb)) / (fb * fb)
    # series: (x/f)^2 sum_{n>=2} (-x)^(n-2) e_n(k)/n!, e_n = 2 (k+1)^n - 2 - k 2^n, scaled by
    # k^(n-2)
    small = ~big & (k > 0)
    ks, xs, fs = k[small], x[small], fx[small]
    z = -ks * xs
    poly = np.zeros(ks.shape)
    for n in range(_SERIES_TERMS + 1, 1, -1):
        e = (2.0 * (ks + 1.0) ** n - 2.0 - ks * 2.0**n) / (factorial(n) * ks ** (n - 2))
        poly = poly * z + e
    ratio = np.where(xs > 0, xs / np.where(fs > 0, fs, 1.0), 1.0)
    out[small] = ratio * ratio * poly
    return s2 * out


@dataclass(frozen=True)
class _GaussMarkov(Term):
    #: where its starting guess sits on the Allan variance curve: ``"fast"`` (a few samples),
    #: ``"minimum"`` (the curve's minimum) or ``"slow"`` (half the longest averaging time)
    start: str = "minimum"
    #: datasheet row prefix and description
    sheet: tuple = ("gauss_markov", "Gauss-Markov bias", "Gauss-Markov correlation time")
    #: whether a fit's mode search starts it at several time constants (:meth:`start_variants`)
    multi_start: bool = False

    tail_kind = "gauss_markov"
    simulated_start = "stationary"

    @property
    def variance_name(self):
        return self.parameters[0]

    @property
    def time_constant_name(self):
        return self.parameters[1]

    avar_group = "gauss_markov"

    def avar(self, mf, params, dt):
        return gm_avar(mf, params[self.variance_name], params[self.time_constant_name], dt)

    def avar_many(self, others, mf, params, dt):
        """One :func:`gm_avar` call for every Gauss-Markov term of a model (its rows are computed
        one by one, so each term's are the bits of its own call)."""
        terms = (self, *others)
        values = np.broadcast_arrays(*(np.asarray(params[t.variance_name], float) for t in terms),
                                     *(np.asarray(params[t.time_constant_name], float)
                                       for t in terms))
        k = len(terms)
        return list(gm_avar(mf, np.stack(values[:k]), np.stack(values[k:]), dt))

    def structure(self, k, params, dt):
        return gm_structure(k, params[self.variance_name], dt / params[self.time_constant_name])

    def covariance_tail(self, params, dt):
        part = (float(params[self.variance_name]), dt / float(params[self.time_constant_name]))
        return CovarianceTail("gauss_markov", gauss_markov=(part,))

    def starting_guess(self, tau, avar, m, dt):
        if self.start == "fast":
            values = (0.5 * avar[0], 2.0 * dt)
        elif self.start == "slow":
            values = (avar.min(), 0.5 * tau[-1])
        else:
            values = (avar.min(), tau[np.argmin(avar)])
        return dict(zip(self.parameters, values))

    def start_variants(self, tau, avar, *, pilot):
        """With :attr:`multi_start`: the time constant at a quarter, half and three quarters of
        the curve's averaging times (a fit's pilot search; later searches start from the pilot's
        mode and the half alone), each with a rough variance ``2 AVAR(1.9 T)`` read off the curve
        where a Gauss-Markov bias's Allan variance peaks (``tau ~ 1.9 T``)."""
        if not self.multi_start:
            return ({},)
        n = len(tau)
        picks = tau[[n // 4, n // 2, 3 * n // 4]] if pilot else [tau[n // 2]]
        return tuple({self.time_constant_name: t,
                      self.variance_name: 2.0 * np.interp(1.9 * t, tau, avar)} for t in picks)

    def datasheet_rows(self, sensor):
        prefix, what, when = self.sheet
        if sensor == "gyro":
            sigma = (self.variance_name, lambda v: np.sqrt(v) * DEG * 3600.0, "deg/h",
                     f"{what}, 1-sigma")
        else:
            sigma = (self.variance_name, lambda v: np.sqrt(v) * UG, "ug", f"{what}, 1-sigma")
        return {f"{prefix}_sigma": sigma,
                f"{prefix}_time_constant": (self.time_constant_name, lambda v: v, "s", when)}

    def kalibr_random_walk2(self, draws, tau_max):
        # the driving-noise density sqrt(2 sigma^2 / T): the random walk it behaves like for t << T
        return 2.0 * draws[self.variance_name] / draws[self.time_constant_name]

    def simulate(self, params, n, dt, rng):
        from scipy.signal import lfilter

        t = params[self.time_constant_name]
        phi = np.exp(-dt / t)
        s = np.sqrt(params[self.variance_name])
        w = s * np.sqrt(-np.expm1(-2.0 * dt / t)) * rng.standard_normal(n)
        b0 = s * rng.standard_normal()
        return lfilter([1.0], [1.0, -phi], w, zi=[phi * b0])[0]

    def time_constant_box(self, scale):
        if self.role == "short_term":
            return (np.log(HF_T_SAMPLES[0] * scale.dt), np.log(HF_T_SAMPLES[1] * scale.dt))
        return (np.log(BIAS_T_MIN_SAMPLES * scale.dt), np.log(BIAS_T_MAX_RECORD * scale.record_s))

    def bounds(self, scale):
        return [scale.amplitude(-np.log(GM_PEAK), 1.0), self.time_constant_box(scale)]

    def white_equivalent(self, params, dt):
        """Per-sample variance of the white noise this term looks like at ``tau >> T``: ``s^2
        (1+phi)/(1-phi)``."""
        x = dt / np.asarray(params[self.time_constant_name], float)
        return np.asarray(params[self.variance_name], float) * (2.0 + np.expm1(-x)) / -np.expm1(-x)

    def _drift_variance(self, order, k, params, dt, bias_start, n_cal):
        s2 = np.asarray(params[self.variance_name], float)[..., None]
        x = dt / np.asarray(params[self.time_constant_name], float)[..., None]
        a = -np.expm1(-x)
        k = np.asarray(k, dtype=float)
        calibrated = bias_start == "calibrated"
        out = gm_terms_broadcast(
            order, k, a, stationary=bias_start != "zero", coefficient=calibrated
        )
        if calibrated:
            out, c = out
            n = np.broadcast_to(np.asarray(n_cal, float), np.shape(k))
            weight = k if order == 1 else k * (k - 1.0) / 2.0
            s_n = (1.0 - a) * -np.expm1(-n * x) / a  # sum_{j=1}^N phi^j
            out = np.maximum(
                out + weight**2 * gm_structure(n, 1.0, x) / n**2 - 2.0 * weight * c * s_n / n, 0.0
            )
        # exactly 0 before the first full step
        return s2 * dt ** (2 * order) * np.where(k >= order, out, 0.0)

    def nav_filter(self, params, dt, *, n_cal=None):
        """``y_i = b_i``, ``b_{i+1} = phi b_i + s sqrt(1 - phi^2) eps_i``, batched over draws;
        ``b_0 = 0`` from a zero start (as :meth:`drift_variance`), else ``N(0, s^2)``."""
        s2 = np.asarray(params[self.variance_name], float)
        x = dt / np.asarray(params[self.time_constant_name], float)
        s2, x = np.broadcast_arrays(s2, x)
        col = (...,) + (None, None)
        stat = s2[col]
        drive = np.sqrt(s2 * -np.expm1(-2.0 * x))[col]
        ones = np.ones(s2.shape + (1,))
        return nav_system(np.exp(-x)[col], drive, ones, 0.0 * ones, np.zeros_like(stat), stat)

    def nav_variance(self, loop, k, params, dt, *, bias_start="calibrated", n_cal=None):
        """Exact propagation of :meth:`nav_filter` for every draw at once."""
        system = self.nav_filter(params, dt)
        return loop.linear_variance(system, k, dt, bias_start=bias_start, n_cal=n_cal)


HF_CORRELATED = _GaussMarkov("hf_correlated", ("correlated_variance", "correlated_time_constant"),
                             {"correlated_variance": "({u})^2", "correlated_time_constant": "s"},
                             "high-frequency correlated noise (bandwidth)", "short_term",
                             selection=("extension",), kalibr="noise_density", start="fast",
                             sheet=("fast_correlated", "fast correlated noise (sensor bandwidth)",
                                    "its correlation time"),
                             short_label="fast correlated noise",
                             parameter_labels={"correlated_variance": "fast correlated variance",
                                               "correlated_time_constant":
                                                   "fast correlated time constant"})
GAUSS_MARKOV = _GaussMarkov(
    "gauss_markov",
    ("bias_variance", "time_constant"),
    {"bias_variance": "({u})^2", "time_constant": "s"},
    "correlated (Gauss-Markov) bias",
    "bias",
    selection=("optional", "extension"),
    kalibr="random_walk",
    short_label="Gauss-Markov bias",
    exchangeable="gauss_markov",
    worst_axis=("bias_variance",),
    multi_start=True,
    parameter_labels={
        "bias_variance": "Gauss-Markov variance",
        "time_constant": "Gauss-Markov time constant",
    },
)
GAUSS_MARKOV_2 = _GaussMarkov("gauss_markov_2", ("bias_variance_2", "time_constant_2"),
                              {"bias_variance_2": "({u})^2", "time_constant_2": "s"},
                              "second, slower Gauss-Markov bias", "bias", selection=("extension",),
                              requires=("gauss_markov",), kalibr="random_walk", start="slow",
                              sheet=("gauss_markov_2", "second (slower) Gauss-Markov bias",
                                     "its correlation time"),
                              short_label="second Gauss-Markov bias", exchangeable="gauss_markov",
                              parameter_labels={"bias_variance_2": "2nd Gauss-Markov variance",
                                                "time_constant_2": "2nd time constant"})
