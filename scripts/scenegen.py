"""Independent random scenes and exact truths for validating drift bands (issues 35 and 36).

Written from first principles for the independent validation; it does not import
``bayes_imu`` and shares no code with it (numpy and scipy only).

A *scene* is a noise process for rate samples ``y_k`` at period ``dt`` (units u, e.g. rad/s):
a sum of independent terms, each with an exact discrete-time simulator and an exact
evaluator of ``Var(sum_i w_i y_i)`` for a weight vector ``w`` whose entries sum to zero (a
*contrast*: constants, and so the arbitrary level of a random walk, drop out):

* ``White(sigma)``: ``y_k = sigma e_k``; ``Var = sigma^2 sum w^2``.
* ``Quantization(q)``: differenced white phase, ``y_k = (q / dt) (u_k - u_{k-1})``
  (``q`` in u s, Allan variance ``3 q^2 / tau^2``); ``Var = (q/dt)^2 sum (w_j - w_{j+1})^2``
  over the zero-padded ``w``.
* ``FilteredWhite(sigma, length)``: a moving average (boxcar low-pass) of ``length`` white
  samples, ``y_k = sigma / sqrt(L) sum_{j<L} e_{k-j}``; ``Var = sigma^2 / L sum_m c_m^2``
  with ``c = w * ones(L)`` (full convolution).
* ``GaussMarkov(sigma, tau)``: stationary AR(1) with the exact step ``a = exp(-dt/tau)``,
  ``x_0 ~ N(0, sigma^2)``, ``x_k = a x_{k-1} + sigma sqrt(1 - a^2) e_k``. With
  ``G_m = sum_{i >= m} w_i a^(i-m)`` (a backward recursion), ``sum w_i x_i = x_0 G_0 +
  sum_{m>=1} e_m' G_m``, so ``Var = sigma^2 (G_0^2 + (1 - a^2) sum_{m>=1} G_m^2)``.
* ``Flicker``: a sum of Gauss-Markov processes with log-spaced time constants
  ``tau_j = tau_min r^j`` (``per_decade`` per decade, ``r = 10^(1/per_decade)``) and equal
  variances ``s^2``: its one-sided PSD is ``~ s^2 / (Delta f)`` with ``Delta = ln r``, i.e.
  1/f with ``h_{-1} = s^2 / Delta`` between ``1/(2 pi tau_max)`` and ``1/(2 pi tau_min)``,
  an Allan deviation floor ``sqrt(2 ln 2 h_{-1})`` there (ripple of a few % at 2 per decade).
* ``RandomWalk(k)``: rate random walk ``y_k = y_{k-1} + k sqrt(dt) e_k`` (``k`` in
  u/sqrt(s), Allan variance ``k^2 tau / 3``); with ``W_m = sum_{i>=m} w_i``,
  ``Var = k^2 dt sum_{m>=1} W_m^2`` (the level ``y_0`` is annihilated by the contrast).
* ``Ramp(rate)``: ``y_k = rate k dt`` (deterministic; a random sign is drawn by the
  generator); its mean square is ``(rate dt sum_i w_i i)^2``.

Every evaluator is O(n) and exact up to rounding; ``brute_force_quad`` builds the full
covariance (or variogram) matrix for small cases, and ``tests/test_scenegen.py`` checks both
and a Monte Carlo of the simulators.

Calibrated-outage drift (the package's documented semantics, README and docs/reference.md
"Drift semantics": the bias estimate is the plain mean of the ``N`` samples just before
the outage, the error is the paper's Euler integral of rate minus estimate; Euler
recursion ``v_k = v_{k-1} + dt x_{k-1}``, ``p_k = p_{k-1} + dt v_{k-1}``). With the
calibration samples at indices ``-N..-1`` and the outage at ``0..k-1``:
``e1 = dt sum_{i<k} (y_i - b)`` and ``e2 = dt sum_{j<k} dt sum_{i<j} (y_i - b)``, i.e. the
weights ``dt`` and ``dt^2 (k - 1 - i)`` on the outage samples and ``-(their sum) / N`` on each
calibration sample (``drift_weights``). The overlapping Allan variance at ``m`` samples is
half the variance of the contrast ``(+1/m) x m`` after ``(-1/m) x m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

__all__ = [
    "White", "Quantization", "FilteredWhite", "GaussMarkov", "Flicker", "RandomWalk", "Ramp",
    "Scene", "FAMILIES", "make_scene", "scene_seed", "drift_weights", "avar_weights",
    "quad", "brute_force_quad", "drift_truth", "avar_truth", "overlapping_avar",
    "calibrated_errors", "horizons",
]


def _reverse_ar1(w, a):
    """G_m = w_m + a G_{m+1} along the last axis (G_n = 0)."""
    return signal.lfilter([1.0], [1.0, -a], w[..., ::-1], axis=-1)[..., ::-1]


@dataclass(frozen=True)
class White:
    """White noise of standard deviation ``sigma`` per sample (u); density sigma sqrt(dt)."""

    sigma: float

    def simulate(self, n, dt, rng, reps=()):
        return self.sigma * rng.standard_normal((*reps, n))

    def quad(self, w, dt):
        return self.sigma ** 2 * float(np.dot(w, w))

    def acov(self, lags, dt):
        return np.where(lags == 0, self.sigma ** 2, 0.0)


@dataclass(frozen=True)
class Quantization:
    """Differenced white phase: ``y_k = (q/dt)(u_k - u_{k-1})``; ``q`` in u s."""

    q: float

    def simulate(self, n, dt, rng, reps=()):
        u = rng.standard_normal((*reps, n + 1))
        return (self.q / dt) * np.diff(u, axis=-1)

    def quad(self, w, dt):
        d = np.diff(np.concatenate(([0.0], w, [0.0])))
        return (self.q / dt) ** 2 * float(np.dot(d, d))

    def acov(self, lags, dt):
        c = (self.q / dt) ** 2
        return np.where(lags == 0, 2 * c, np.where(np.abs(lags) == 1, -c, 0.0))


@dataclass(frozen=True)
class FilteredWhite:
    """Boxcar moving average of ``length`` white samples; sample standard deviation ``sigma``."""

    sigma: float
    length: int

    def simulate(self, n, dt, rng, reps=()):
        e = rng.standard_normal((*reps, n + self.length - 1))
        c = np.cumsum(e, axis=-1)
        c = np.concatenate((np.zeros((*reps, 1)), c), axis=-1)
        return self.sigma / math.sqrt(self.length) * (c[..., self.length:] - c[..., :-self.length])

    def quad(self, w, dt):
        c = np.convolve(w, np.ones(self.length))
        return self.sigma ** 2 / self.length * float(np.dot(c, c))

    def acov(self, lags, dt):
        m = np.abs(lags)
        return np.where(m < self.length, self.sigma ** 2 * (self.length - m) / self.length, 0.0)


@dataclass(frozen=True)
class GaussMarkov:
    """Stationary first-order Gauss-Markov bias: standard deviation ``sigma`` (u), ``tau`` (s)."""

    sigma: float
    tau: float

    def _a(self, dt):
        return math.exp(-dt / self.tau), -math.expm1(-2 * dt / self.tau)

    def simulate(self, n, dt, rng, reps=()):
        a, one_minus_a2 = self._a(dt)
        e = rng.standard_normal((*reps, n))
        e[..., 1:] *= math.sqrt(one_minus_a2)
        return self.sigma * signal.lfilter([1.0], [1.0, -a], e, axis=-1)

    def quad(self, w, dt):
        a, one_minus_a2 = self._a(dt)
        g = _reverse_ar1(np.asarray(w, float), a)
        return self.sigma ** 2 * (g[0] ** 2 + one_minus_a2 * float(np.dot(g[1:], g[1:])))

    def acov(self, lags, dt):
        return self.sigma ** 2 * np.exp(-np.abs(lags) * dt / self.tau)


@dataclass(frozen=True)
class Flicker:
    """1/f-like bias: equal-variance Gauss-Markov processes, log-spaced time constants."""

    sigma_each: float
    tau_min: float
    tau_max: float
    per_decade: float = 2.0
    parts: tuple = field(init=False, repr=False)

    def __post_init__(self):
        n = max(1, int(round(self.per_decade * math.log10(self.tau_max / self.tau_min)))) + 1
        taus = np.geomspace(self.tau_min, self.tau_max, n)
        object.__setattr__(self, "parts", tuple(GaussMarkov(self.sigma_each, t) for t in taus))

    @property
    def h_minus1(self):
        """Nominal flicker level of the band (one-sided PSD x f), u^2."""
        return self.sigma_each ** 2 / math.log(10 ** (1 / self.per_decade))

    def simulate(self, n, dt, rng, reps=()):
        return sum(p.simulate(n, dt, rng, reps) for p in self.parts)

    def quad(self, w, dt):
        return sum(p.quad(w, dt) for p in self.parts)

    def acov(self, lags, dt):
        return sum(p.acov(lags, dt) for p in self.parts)


@dataclass(frozen=True)
class RandomWalk:
    """Rate random walk of coefficient ``k`` (u/sqrt(s)): increments ``k sqrt(dt) e``."""

    k: float

    def simulate(self, n, dt, rng, reps=()):
        e = rng.standard_normal((*reps, n))
        e[..., 0] = 0.0
        return self.k * math.sqrt(dt) * np.cumsum(e, axis=-1)

    def quad(self, w, dt):
        tail = np.cumsum(np.asarray(w, float)[::-1])[::-1]
        return self.k ** 2 * dt * float(np.dot(tail[1:], tail[1:]))

    def cov(self, i, j, dt):
        """Covariance of the simulated samples (``y_0 = 0``)."""
        return self.k ** 2 * dt * np.minimum(i, j)


@dataclass(frozen=True)
class Ramp:
    """Deterministic ramp ``y_k = rate k dt`` (u/s)."""

    rate: float

    def simulate(self, n, dt, rng, reps=()):
        return np.broadcast_to(self.rate * dt * np.arange(n), (*reps, n)).copy()

    def quad(self, w, dt):
        return (self.rate * dt * float(np.dot(w, np.arange(len(w))))) ** 2

    def cov(self, i, j, dt):
        """Second moment of the samples."""
        return (self.rate * dt) ** 2 * i * j


@dataclass(frozen=True)
class Scene:
    """One random scene: terms, rate, record length, calibration window, its family and seed."""

    family: str
    seed: int
    rate_hz: float
    n: int
    calibration_s: float
    terms: tuple

    @property
    def dt(self):
        return 1.0 / self.rate_hz

    @property
    def record_s(self):
        return self.n * self.dt

    @property
    def n_calibration(self):
        return int(round(self.calibration_s * self.rate_hz))

    def simulate(self, rng, reps=(), n=None):
        """Samples, shape ``(*reps, n)``, drawn term by term from ``rng``."""
        n = self.n if n is None else n
        return sum(t.simulate(n, self.dt, rng, reps) for t in self.terms)

    def describe(self):
        return " + ".join(repr(t) for t in self.terms)


# --------------------------------------------------------------------------- weights and truths

def drift_weights(k, n_cal, dt, order, *, scheme="euler"):
    """Weights on samples ``-N..k-1`` of the calibrated-outage error of the given order.

    ``scheme="euler"``: ``e1 = dt sum_{i<k} (y_i - b)``, ``e2 = dt^2 sum_{i<k} (k-1-i)(y_i - b)``
    (the paper's forward Euler). ``"zoh"``: exact double integral of the sample held
    over its period, ``dt^2 (k - i - 1/2)`` (order 1 is the same in both).
    """
    i = np.arange(k, dtype=float)
    if order == 1:
        out = np.full(k, dt)
    elif order == 2:
        out = dt * dt * ((k - 1 - i) if scheme == "euler" else (k - i - 0.5))
    else:
        raise ValueError(f"order must be 1 or 2, got {order!r}")
    return np.concatenate((np.full(n_cal, -out.sum() / n_cal), out))


def avar_weights(m):
    """Contrast whose variance is twice the Allan variance at ``m`` samples."""
    return np.concatenate((np.full(m, -1.0 / m), np.full(m, 1.0 / m)))


def quad(terms, w, dt):
    """Exact ``E[(sum w_i y_i)^2]`` of a sum of independent terms (``w`` a contrast)."""
    return sum(t.quad(np.asarray(w, float), dt) for t in terms)


def brute_force_quad(terms, w, dt):
    """``w^T C w`` from the full n x n matrices (small ``n`` only): independent check."""
    w = np.asarray(w, float)
    idx = np.arange(len(w))
    i, j = np.meshgrid(idx, idx, indexing="ij")
    total = 0.0
    for t in terms:
        c = t.cov(i, j, dt) if hasattr(t, "cov") else t.acov(i - j, dt)
        total += float(w @ c @ w)
    return total


def drift_truth(scene, t_s, order, *, scheme="euler", terms=None):
    """Exact 1-sigma calibrated-outage error at times ``t_s`` (whole samples), unit u s^order."""
    dt, n_cal = scene.dt, scene.n_calibration
    terms = scene.terms if terms is None else terms
    out = []
    for t in np.atleast_1d(t_s):
        k = int(round(t / dt))
        out.append(math.sqrt(quad(terms, drift_weights(k, n_cal, dt, order, scheme=scheme), dt)))
    return np.array(out)


def avar_truth(scene, m):
    """Exact expected overlapping Allan variance at cluster sizes ``m`` (samples), u^2."""
    return np.array([quad(scene.terms, avar_weights(int(mm)), scene.dt) / 2 for mm in m])


def overlapping_avar(y, m, dt):
    """Overlapping Allan variance of ``y`` (last axis) at cluster sizes ``m`` (own estimator)."""
    y = np.asarray(y, float)
    x = np.concatenate((np.zeros((*y.shape[:-1], 1)), np.cumsum(y - y.mean(-1, keepdims=True),
                                                                  axis=-1)), axis=-1)
    out = []
    for mm in m:
        d = x[..., 2 * mm:] - 2 * x[..., mm:-mm] + x[..., :-2 * mm]
        out.append(np.mean(d * d, axis=-1) / (2 * mm * mm))
    return np.stack(out, axis=-1)


def calibrated_errors(y, n_cal, k, dt):
    """(e1, e2) of the outage starting at sample ``n_cal`` of ``y`` (last axis), by definition."""
    b = y[..., :n_cal].mean(-1, keepdims=True)
    r = y[..., n_cal:n_cal + k] - b
    v = dt * np.concatenate((np.zeros((*r.shape[:-1], 1)), np.cumsum(r, axis=-1)), axis=-1)
    p = dt * np.sum(v[..., :k], axis=-1)       # p_k = dt sum_{j<k} v_j
    return v[..., k], p


def horizons(scene, n_h=8, t_min=1.0):
    """Whole-sample horizons log-spaced from ``t_min`` to a quarter of the record (s)."""
    t = np.geomspace(t_min, scene.record_s / 4, n_h)
    k = np.unique(np.maximum(1, np.round(t * scene.rate_hz)).astype(int))
    return k / scene.rate_hz


# --------------------------------------------------------------------------- the generator

RATES = (50.0, 100.0, 200.0, 400.0, 1000.0)
CALIBRATIONS = (10.0, 30.0, 60.0, 120.0)


def _lu(rng, lo, hi):
    """Log-uniform draw in [lo, hi] (``lo`` when a short record makes ``hi < lo``)."""
    return float(math.exp(rng.uniform(math.log(lo), math.log(max(lo, hi)))))


def _gm(rng, n_white, tau, lo, hi):
    """A Gauss-Markov bias whose Allan deviation near tau is 10^U(lo, hi) x the white's there."""
    return GaussMarkov(n_white / math.sqrt(tau) * 10 ** rng.uniform(lo, hi), tau)


def _rrw(rng, n_white, t_lo, t_hi):
    """A rate random walk crossing the white Allan deviation at a log-uniform time (s)."""
    return RandomWalk(n_white * math.sqrt(3.0) / _lu(rng, t_lo, t_hi))


def _flicker(rng, n_white, rec, t_lo, t_hi):
    """Flicker crossing the white Allan deviation at a log-uniform time in [t_lo, t_hi] (s)."""
    tx = _lu(rng, t_lo, t_hi)
    per_decade = 2.0
    floor = n_white / math.sqrt(tx)                       # Allan deviation floor
    h = floor ** 2 / (2 * math.log(2))
    s = math.sqrt(h * math.log(10 ** (1 / per_decade)))
    return Flicker(s, max(tx / 30, 0.05), 3 * rec, per_decade)


def _quant(rng, n_white, dt):
    return Quantization(n_white * math.sqrt(_lu(rng, 2 * dt, 30 * dt) / 3.0))


def _filtered(rng, sigma_white):
    length = int(rng.integers(2, 33))
    rho = _lu(rng, 0.3, 3.0)                          # its low-frequency PSD / the white's
    return FilteredWhite(sigma_white * math.sqrt(rho / length), length)


def _ramp(rng, n_white, rec):
    tx = _lu(rng, rec / 10, rec)
    return Ramp(float(rng.choice((-1, 1))) * n_white * math.sqrt(2.0 / tx ** 3))


def _family_terms(family, rng, n_white, dt, rec):
    sigma_w = n_white / math.sqrt(dt)
    white = White(sigma_w)
    if family == "white+gm":
        return (white, _gm(rng, n_white, _lu(rng, 1.0, rec / 10), 0.3, 1.5))
    if family == "gm+rrw":
        tau = _lu(rng, 2.0, rec / 20)
        return (white, _gm(rng, n_white, tau, 0.2, 1.0), _rrw(rng, n_white, 3 * tau, 30 * tau))
    if family == "two_gm":
        tau1 = _lu(rng, 0.5, rec / 200)
        tau2 = tau1 * 10 ** rng.uniform(0.8, 1.2)
        return (white, _gm(rng, n_white, tau1, 0.2, 1.0), _gm(rng, n_white, tau2, 0.2, 1.0))
    if family == "weak_flicker":
        return (white, _flicker(rng, n_white, rec, rec / 100, rec / 4))
    if family == "white+quant":
        return (white, _quant(rng, n_white, dt))
    if family == "filtered+gm":
        return (White(sigma_w * 10 ** rng.uniform(-1, -0.3)), _filtered(rng, sigma_w),
                _gm(rng, n_white, _lu(rng, 1.0, rec / 10), 0.3, 1.5))
    if family == "random_mix":
        return _random_mix(rng, white, n_white, dt, rec)
    if family == "gm_rrw_overlap":
        tau = _lu(rng, 2.0, rec / 20)
        return (white, _gm(rng, n_white, tau, 0.0, 0.6), _rrw(rng, n_white, tau, 3 * tau))
    if family == "faint_flicker":
        return (white, _flicker(rng, n_white, rec, rec / 4, 2 * rec))
    if family == "three_gm":
        tau1 = _lu(rng, 0.3, rec / 1000)
        steps = [0.0, rng.uniform(0.8, 1.2), rng.uniform(0.8, 1.2)]
        taus = [tau1 * 10 ** float(x) for x in np.cumsum(steps)]
        return (white, *(_gm(rng, n_white, t, 0.0, 0.8) for t in taus))
    raise ValueError(f"unknown family {family!r}; expected one of {FAMILIES}")


def _random_mix(rng, white, n_white, dt, rec):
    terms = [white]
    if rng.random() < 0.4:
        terms.append(_quant(rng, n_white, dt))
    if rng.random() < 0.3:
        terms.append(_filtered(rng, white.sigma))
    for _ in range(int(rng.integers(0, 4))):
        terms.append(_gm(rng, n_white, _lu(rng, 0.2, rec / 4), -0.3, 1.3))
    if rng.random() < 0.3:
        terms.append(_flicker(rng, n_white, rec, rec / 300, rec))
    if rng.random() < 0.4:
        terms.append(_rrw(rng, n_white, 5.0, 2 * rec))
    if rng.random() < 0.2:
        terms.append(_ramp(rng, n_white, rec))
    if len(terms) == 1:
        terms.append(_gm(rng, n_white, _lu(rng, 0.2, rec / 4), -0.3, 1.3))
    return tuple(terms)


#: labelled families; "white+gm" is a control the candidate models contain exactly; the last
#: three (added after the first baseline, so the first seven's scenes are unchanged) sit in the
#: ambiguous corners: a bias and a random walk of the same time scale, flicker that crosses the
#: white noise only beyond the record, three biases a decade apart
FAMILIES = ("white+gm", "gm+rrw", "two_gm", "weak_flicker", "white+quant", "filtered+gm",
            "random_mix", "gm_rrw_overlap", "faint_flicker", "three_gm")


def scene_seed(family, seed):
    """The ``SeedSequence`` of a (family, seed) pair: independent streams per family."""
    return np.random.SeedSequence([int(seed), FAMILIES.index(family), 35])


def make_scene(family, seed, *, max_log2n=20.0):
    """Draw one scene of ``family`` from its own generator (seeded by ``scene_seed``).

    Rate from {50, 100, 200, 400, 1000} Hz; ``n = 2^U(16, max_log2n)`` samples; white density
    log-uniform 1e-4 to 1e-2 u/sqrt(Hz); calibration window from {10, 30, 60, 120} s, at most
    an eighth of the record; the family's terms at strengths drawn relative to the white noise.
    """
    rng = np.random.default_rng(scene_seed(family, seed))
    rate = float(rng.choice(RATES))
    n = int(round(2 ** rng.uniform(16.0, max_log2n)))
    dt = 1.0 / rate
    rec = n * dt
    cal = [c for c in CALIBRATIONS if c <= rec / 8] or [CALIBRATIONS[0]]
    cal_s = float(rng.choice(cal))
    n_white = _lu(rng, 1e-4, 1e-2)
    terms = _family_terms(family, rng, n_white, dt, rec)
    return Scene(family, int(seed), rate, n, cal_s, terms)
