"""Sensor noise models: components, their exact Allan variance, and model sums.

Each component is a stochastic process for the rate samples ``y_k`` (gyro rate or
specific force) at sample period ``dt``. For each we give the expected overlapping Allan
variance at cluster size ``m`` (``tau = m dt``) *for sampled data*, exact where an exact
discrete form exists, and the phase structure function ``D(k)`` (a generalised
covariance of the integrated signal ``x_k = sum y``, in units of ``y**2``) from which
:mod:`bayes_imu.avar_covariance` builds the covariance of the estimates.

====================  =================================  ======================================  =====================
term                  parameters (units, y in [u])       AVAR(m), tau = m dt                     IEEE Std 952 name
====================  =================================  ======================================  =====================
``white``             ``noise_variance`` [u^2]           q / m  (exact)                          angle/velocity RW
``quantization``      ``quantization`` Q [u s]           3 Q^2 / tau^2  (exact, white angle)     quantization noise
``bias_instability``  ``bias_instability`` B [u]         2 ln2 B^2 / pi  (flicker, exact for      bias instability
                                                         its generalised covariance)
``gauss_markov``      ``bias_variance`` s^2 [u^2],       exact AR(1) form (below)                 correlated noise
                      ``time_constant`` T [s]
``random_walk``       ``rate_random_walk`` K [u/sqrt(s)] K^2 dt (2 m^2 + 1) / (6 m)  (exact)      rate random walk
====================  =================================  ======================================  =====================

Gauss-Markov (paper eq 4, sampled exactly: ``phi = exp(-dt/T)``, ``x = dt/T``)::

    AVAR(m) = s^2 [m (1 - phi^2) - phi (1 - phi^m)(3 - phi^m)] / (m^2 (1 - phi)^2)

The bracket loses all precision for ``m x << 1``; below ``m x = 0.1`` it is evaluated
from its exact Taylor series ``-x^3 sum_n (-x)^(n-3) b_n(m) / n!`` with integer
coefficients ``b_n(m) = 4 (m+1)^n - (2m+1)^n - m 2^n - 3`` (computed in exact
arithmetic), whose leading term gives the random-walk limit ``s^2 x (2m^2 + 1)/(3m)``.

All functions broadcast: parameters of shape ``(...)`` with ``m`` of shape ``(n_tau,)``
give ``(..., n_tau)``.
"""

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np

from .errors import InputError

__all__ = [
    "TERMS",
    "TERM_PARAMETERS",
    "NoiseModel",
    "white_avar",
    "quantization_avar",
    "bias_instability_avar",
    "gauss_markov_avar",
    "random_walk_avar",
    "structure_function",
]

#: parameter names of each term, in sampling order
TERM_PARAMETERS = {
    "white": ("noise_variance",),
    "quantization": ("quantization",),
    "bias_instability": ("bias_instability",),
    "gauss_markov": ("bias_variance", "time_constant"),
    "random_walk": ("rate_random_walk",),
}
TERMS = tuple(TERM_PARAMETERS)
#: unit of each parameter, given the unit ``u`` of the rate samples
PARAMETER_UNITS = {
    "noise_variance": "({u})^2",
    "noise_density": "{u}/sqrt(Hz)",
    "quantization": "{u} s",
    "bias_instability": "{u}",
    "bias_variance": "({u})^2",
    "time_constant": "s",
    "rate_random_walk": "{u}/sqrt(s)",
}
_SWITCH = 0.5
_SERIES_TERMS = 24
_AVAR_SWITCH = 0.1  # m dt/T below which the GM Allan variance uses its series
_AVAR_TERMS = 13  # (2 * 0.1)^13 / 16! ~ 4e-23
_FLICKER_FLAT = 2.0 * np.log(2.0) / np.pi


def _m_array(m):
    m = np.asarray(m)
    if m.ndim != 1 or m.size == 0 or not np.all(m >= 1) or not np.all(m == np.round(m)):
        raise InputError(f"cluster sizes m: expected a non-empty 1-D array of integers >= 1, got {m!r}")
    return m.astype(float)


def white_avar(m, noise_variance):
    """Allan variance of white rate noise, ``q / m`` (SP1065 Table 3; ARW N^2 / tau)."""
    return np.asarray(noise_variance, float)[..., None] / _m_array(m)


def quantization_avar(m, quantization, *, dt):
    """Allan variance of quantization noise (white angle noise of std ``Q``), ``3 Q^2 / tau^2``.

    Exact for sampled data: second differences of white angle noise have variance ``6 Q^2``.
    """
    tau = _m_array(m) * dt
    return 3.0 * np.asarray(quantization, float)[..., None] ** 2 / tau**2


def bias_instability_avar(m, bias_instability):
    """Allan variance of flicker rate noise, ``2 ln2 B^2 / pi`` (IEEE Std 952 eq C.?; flat).

    Exact for the flicker process defined by the generalised covariance
    ``D(k) = -(B^2/pi) k^2 ln|k|`` (see :func:`structure_function`), which is what
    :mod:`bayes_imu.simulate` draws from.
    """
    m = _m_array(m)
    return _FLICKER_FLAT * np.asarray(bias_instability, float)[..., None] ** 2 * np.ones_like(m)


def random_walk_avar(m, rate_random_walk, *, dt):
    """Allan variance of a discrete rate random walk, ``K^2 dt (2 m^2 + 1) / (6 m)``.

    Increments have variance ``K^2 dt`` per sample; for large m this is ``K^2 tau / 3``.
    """
    m = _m_array(m)
    q = np.asarray(rate_random_walk, float)[..., None] ** 2 * dt
    return q * (2.0 * m * m + 1.0) / (6.0 * m)


@lru_cache(maxsize=64)
def _gm_series_coefficients(ms):
    """``c[j, i] = -b_{j+3}(m_i) / ((j+3)! m_i^j)``, exact rationals rounded once."""
    out = np.empty((_AVAR_TERMS, len(ms)))
    for i, m in enumerate(ms):
        for j in range(_AVAR_TERMS):
            n = j + 3
            b = 4 * (m + 1) ** n - (2 * m + 1) ** n - m * 2**n - 3
            out[j, i] = float(Fraction(-b, factorial(n) * m**j))
    return out


def gauss_markov_avar(m, bias_variance, time_constant, *, dt):
    """Exact Allan variance of a sampled first-order Gauss-Markov process (module docstring).

    Parameters
    ----------
    m : (n_tau,) int
    bias_variance : array_like, shape (...)
        Stationary variance ``sigma_b^2`` [u^2] (paper eq 4).
    time_constant : array_like, shape (...)
        ``T`` [s].
    dt : float
        Sample period [s].

    Returns
    -------
    (..., n_tau) ndarray
        Stable to full precision for ``dt/T`` from 1e-300 to large values.
    """
    mf = _m_array(m)
    return _gm_avar(mf, _gm_series_coefficients(tuple(int(v) for v in mf)), bias_variance, time_constant, dt)


def _gm_avar(mf, coeffs, bias_variance, time_constant, dt):
    s2 = np.asarray(bias_variance, float)[..., None]
    x = (dt / np.asarray(time_constant, float))[..., None]
    fx = -np.expm1(-x)
    y = mf * x
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        fy = -np.expm1(-y)
        closed = (mf * -np.expm1(-2.0 * x) - (1.0 - fx) * fy * (2.0 + fy)) / (mf * mf * fx * fx)
        # series: s^2 x (x/f(x))^2 P(m, y) / m^2, P a polynomial in -y (Horner)
        ys = -np.minimum(y, _AVAR_SWITCH)
        poly = coeffs[-1] * ys + coeffs[-2]
        for j in range(coeffs.shape[0] - 3, -1, -1):
            poly = poly * ys + coeffs[j]
        ratio = np.where(fx > 0, x / fx, 1.0)
        series = x * ratio * ratio * poly / (mf * mf)
    return s2 * np.where(y <= _AVAR_SWITCH, series, closed)


def structure_function(k, term, params, *, dt):
    """Phase structure function ``D(k)`` of one term, in sample units (``x = sum y``).

    A generalised covariance: for any contrasts ``a``, ``b`` annihilating constants and
    linear trends, ``Cov(sum a_p x_p, sum b_q x_q) = -1/2 sum a_p b_q D(p - q)``.

    Parameters
    ----------
    k : ndarray of int (>= 0)
    term : str
    params : dict of float
    dt : float

    Returns
    -------
    ndarray, same shape as ``k``, in [u^2].
    """
    k = np.asarray(k, dtype=float)
    if term == "white":
        return params["noise_variance"] * k
    if term == "quantization":
        return 2.0 * (params["quantization"] / dt) ** 2 * (k != 0)
    if term == "bias_instability":
        h = params["bias_instability"] ** 2 / np.pi
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(k > 0, -h * k * k * np.log(np.where(k > 0, k, 1.0)), 0.0)
    if term == "random_walk":
        q = params["rate_random_walk"] ** 2 * dt
        return q * (k - k**3) / 6.0
    if term == "gauss_markov":
        return _gm_structure(k, params["bias_variance"], dt / params["time_constant"])
    raise InputError(f"term {term!r}: expected one of {', '.join(TERMS)}")


def _gm_structure(k, s2, x):
    """``s^2 [k (1 - phi^2) - 2 phi (1 - phi^k)] / (1 - phi)^2``, series below ``k x = 0.5``."""
    k = np.asarray(k, dtype=float)
    fx = -np.expm1(-x)
    out = np.zeros(k.shape)
    big = k * x > _SWITCH
    kb = k[big]
    out[big] = (kb * -np.expm1(-2.0 * x) - 2.0 * (1.0 - fx) * -np.expm1(-kb * x)) / (fx * fx)
    # series: (x/f)^2 sum_{n>=2} (-x)^(n-2) e_n(k)/n!, e_n = 2 (k+1)^n - 2 - k 2^n, scaled by k^(n-2)
    small = ~big & (k > 0)
    ks = k[small]
    z = -ks * x
    poly = np.zeros(ks.shape)
    for n in range(_SERIES_TERMS + 1, 1, -1):
        e = (2.0 * (ks + 1.0) ** n - 2.0 - ks * 2.0**n) / (factorial(n) * ks ** (n - 2))
        poly = poly * z + e
    ratio = x / fx if x > 0 else 1.0
    out[small] = ratio * ratio * poly
    return s2 * out


@dataclass(frozen=True)
class NoiseModel:
    """A sum of noise terms for rate samples at period ``dt``.

    Attributes
    ----------
    terms : tuple of str
        Term names, a subset of :data:`TERMS` (kept in canonical order).
    dt : float
        Sample period [s].
    """

    terms: tuple
    dt: float

    def __post_init__(self):
        unknown = [t for t in self.terms if t not in TERM_PARAMETERS]
        if unknown or not self.terms or len(set(self.terms)) != len(self.terms):
            raise InputError(f"model terms {self.terms!r}: expected distinct names from {', '.join(TERMS)}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise InputError(f"dt={self.dt!r}: expected a positive sample period in seconds")
        object.__setattr__(self, "terms", tuple(t for t in TERMS if t in self.terms))

    @property
    def parameter_names(self):
        """Parameter names in sampling order."""
        return tuple(p for t in self.terms for p in TERM_PARAMETERS[t])

    def unpack(self, theta):
        """Split an array ``(..., n_par)`` into a dict name -> ``(...)``."""
        theta = np.asarray(theta, float)
        return {name: theta[..., i] for i, name in enumerate(self.parameter_names)}

    def term_avar(self, term, m, params):
        """Allan variance of one term, ``(..., n_tau)``."""
        dt = self.dt
        if term == "white":
            return white_avar(m, params["noise_variance"])
        if term == "quantization":
            return quantization_avar(m, params["quantization"], dt=dt)
        if term == "bias_instability":
            return bias_instability_avar(m, params["bias_instability"])
        if term == "gauss_markov":
            return gauss_markov_avar(m, params["bias_variance"], params["time_constant"], dt=dt)
        return random_walk_avar(m, params["rate_random_walk"], dt=dt)

    def avar(self, m, params):
        """Model Allan variance ``(..., n_tau)`` for parameters given as a dict or ``(..., n_par)``."""
        return self.avar_evaluator(m)(params)

    def avar_evaluator(self, m):
        """A fast function ``params -> (..., n_tau)`` for fixed cluster sizes ``m`` (validated once)."""
        mf = _m_array(m)
        dt = self.dt
        coeffs = _gm_series_coefficients(tuple(int(v) for v in mf)) if "gauss_markov" in self.terms else None
        fns = {
            "white": lambda p: p["noise_variance"][..., None] / mf,
            "quantization": lambda p: 3.0 * p["quantization"][..., None] ** 2 / (mf * dt) ** 2,
            "bias_instability": lambda p: _FLICKER_FLAT * p["bias_instability"][..., None] ** 2 * np.ones_like(mf),
            "gauss_markov": lambda p: _gm_avar(mf, coeffs, p["bias_variance"], p["time_constant"], dt),
            "random_walk": lambda p: p["rate_random_walk"][..., None] ** 2 * dt * (2.0 * mf * mf + 1.0) / (6.0 * mf),
        }
        chosen = [fns[t] for t in self.terms]

        def evaluate(params):
            if not isinstance(params, dict):
                params = self.unpack(params)
            params = {k: np.asarray(v, float) for k, v in params.items()}
            out = chosen[0](params)
            for fn in chosen[1:]:
                out = out + fn(params)
            return out

        return evaluate

    def structure_function(self, k, params):
        """Phase structure function of the sum (scalar parameters), see :func:`structure_function`."""
        return sum(structure_function(k, t, params, dt=self.dt) for t in self.terms)
