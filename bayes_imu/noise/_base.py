"""The interface every noise term implements, and the exact drift contrasts they share.

A term is a stochastic (or, for the ramp, deterministic) component of the rate samples
``y_k`` at period ``dt``. Everything the package knows about it sits in its own module of
:mod:`bayes_imu.noise`, on one :class:`Term` object:

* ``avar(mf, params, dt)``: the exact expected overlapping Allan variance of sampled data at
  cluster sizes ``m`` (``tau = m dt``), broadcast ``(...,) x (n_tau,) -> (..., n_tau)``;
* ``structure(k, params, dt)``: the phase structure function ``D(k)`` (a generalised
  covariance of ``x_k = sum_{t<k} y_t``, in ``u^2``) from which the covariance of the AVAR
  estimates is built (:mod:`bayes_imu.noise.avar_covariance`), plus ``gm_components`` and
  ``flicker_level`` for the exact tails of that covariance;
* ``simulate(params, n, dt, rng)``: an exact draw of the discrete process;
* ``drift_variance(order, k, params, dt, bias_start, n_cal)``: the exact variance (mean
  square) of its Euler-integrated error (attitude or velocity ``r = 1``, position ``r = 2``);
* ``bounds(scale)``: its prior box in log-parameters.

Drift semantics (``bias_start``), with the paper's Euler integral of ``e_i = y_i - b_hat``
(``v_k = dt sum_{i<k} e_i``, ``p_k = dt sum_{j<k} v_j``):

``"zero"``
    the process starts at zero at the outage (the paper), ``b_hat = 0``;
``"stationary"``
    a stationary process is in its stationary distribution, ``b_hat = 0``;
``"calibrated"``
    ``b_hat`` is the plain mean of the ``N`` samples just before the outage. The error is
    then a contrast of the phase record ``x`` that annihilates constants and linear trends,
    so its variance is ``-1/2 sum_pq a_p a_q D(|p - q|)`` for every term, random walk and
    flicker included (:func:`calibrated_contrast`).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Term", "PriorScale", "calibrated_contrast", "BIAS_STARTS", "ROLES", "nav_system"]

#: drift semantics (see the module docstring)
BIAS_STARTS = ("zero", "stationary", "calibrated")
#: what a term means to a navigation engineer: short-term noise (sets the noise density),
#: a bias that wanders, or a slow drift of the rate
ROLES = ("short_term", "bias", "slow")


def calibrated_contrast(structure, order, k, n_cal):
    """Variance of the calibrated-start error contrast, in phase units (multiply by ``dt**(2 order)``).

    Parameters
    ----------
    structure : callable
        ``D(l)`` for an array of non-negative integer lags (scalar parameters).
    order : {1, 2}
    k : (n_t,) float
        Outage lengths in samples.
    n_cal : float or (n_t,) float
        Calibration window in samples (``>= 1``).

    Returns
    -------
    (n_t,) ndarray

    Notes
    -----
    Order 1 (``v_k / dt = x_k - x_0 - (k/N)(x_0 - x_{-N})``, three phase points)::

        Var = (1 + r) D(k) - r D(k + N) + r (1 + r) D(N),   r = k / N

    Order 2 (``p_k / dt^2 = sum_{j<k} (x_j - x_0) - c (x_0 - x_{-N})``, ``c = k(k-1)/(2N)``,
    weights ``a_0 = -(k-1) - c``, ``a_j = 1`` for ``1 <= j < k``, ``a_{-N} = c``)::

        Var = -[G(k-2) + a_0 F(k-1) + c (F(N+k-1) - F(N)) + a_0 c D(N)]

    with ``F(n) = sum_{l=1}^n D(l)`` and ``G(n) = sum_{l=1}^n F(l)``, accumulated in
    extended precision from one table of ``D``.
    """
    k = np.asarray(k, dtype=float)
    n = np.broadcast_to(np.asarray(n_cal, dtype=float), k.shape)
    if order == 1:
        r = k / n
        out = (1.0 + r) * structure(k) - r * structure(k + n) + r * (1.0 + r) * structure(n)
        return np.where(k > 0, out, 0.0)
    top = int(np.max(k + n)) + 1 if k.size else 1
    table = np.asarray(structure(np.arange(top + 1, dtype=float)), dtype=np.longdouble)
    f = np.cumsum(table)  # F(n) (D(0) = 0)
    g = np.cumsum(f)
    ki = k.astype(np.int64)
    ni = n.astype(np.int64)
    c = k * (k - 1.0) / (2.0 * n)
    a0 = -(k - 1.0) - c

    def at(arr, idx):
        return np.where(idx >= 0, arr[np.clip(idx, 0, None)], 0.0)

    out = -(at(g, ki - 2) + a0 * at(f, ki - 1) + c * (at(f, ni + ki - 1) - at(f, ni)) + a0 * c * at(table, ni))
    return np.where(k > 1, np.asarray(out, dtype=float), 0.0)


@dataclass(frozen=True)
class PriorScale:
    """What a term's prior box is scaled from: the observed Allan variance and the record.

    Attributes
    ----------
    log_lo, log_hi : float
        Natural logs of the lowest and highest Allan variance a term may reach over the
        fitted grid (``10**-4`` times the smallest, ``10**1`` times the largest observed).
    dt : float
        Sample period [s].
    tau_min, tau_max : float
        Shortest and longest fitted averaging times [s].
    m_min : float
        Smallest cluster size.
    record_s : float
        Duration of the record [s].
    """

    log_lo: float
    log_hi: float
    dt: float
    tau_min: float
    tau_max: float
    m_min: float
    record_s: float

    def amplitude(self, shift, power):
        """Box ``((lo + shift) power, (hi + shift) power)``: ``log(parameter) = power (log AVAR peak + shift)``."""
        return ((self.log_lo + shift) * power, (self.log_hi + shift) * power)


@dataclass(frozen=True)
class Term:
    """One noise term (see the module docstring for the interface).

    Attributes
    ----------
    name : str
    parameters : tuple of str
        Parameter names in sampling order.
    units : dict
        Parameter name -> unit template (``{u}`` is the rate unit).
    label : str
        IEEE Std 952 / navigation name.
    role : str
        One of :data:`ROLES`.
    """

    name: str
    parameters: tuple
    units: dict
    label: str
    role: str

    # --- interface, overridden by each term ---------------------------------------------
    def avar(self, mf, params, dt):  # pragma: no cover - abstract
        raise NotImplementedError

    def structure(self, k, params, dt):  # pragma: no cover - abstract
        raise NotImplementedError

    def simulate(self, params, n, dt, rng):  # pragma: no cover - abstract
        raise NotImplementedError

    def bounds(self, scale):  # pragma: no cover - abstract
        raise NotImplementedError

    def drift_variance(self, order, k, params, dt, *, bias_start="zero", n_cal=None):
        """Mean-square drift ``(..., n_t)`` [u^2 s^(2 order)] for parameters ``(...)`` and steps ``k`` ``(n_t,)``.

        The default serves terms whose drift is linear in one squared amplitude
        (:meth:`unit_drift`); the Gauss-Markov terms override it.
        """
        amplitude = self.amplitude2(params)
        return np.asarray(amplitude, float)[..., None] * self.unit_drift(order, k, dt, bias_start, n_cal)

    # --- helpers of terms linear in a squared amplitude ---------------------------------
    def gm_components(self, params, dt):
        """``[(sigma^2, dt/T), ...]`` of the Gauss-Markov parts (scalar parameters), for covariance tails."""
        return []

    def flicker_level(self, params):
        """``h = B^2 / pi`` of a flicker part (scalar parameters), for covariance tails."""
        return 0.0

    def amplitude2(self, params):
        """The squared amplitude the drift is proportional to."""
        raise NotImplementedError  # pragma: no cover

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        """Drift variance at unit squared amplitude ``(n_t,)``; default: the calibrated contrast."""
        unit = {p: 1.0 for p in self.parameters}
        return dt ** (2 * order) * calibrated_contrast(lambda lag: self.structure(lag, unit, dt) / self.amplitude2(unit),
                                                       order, k, n_cal)

    def parameter_units(self, unit):
        return {p: self.units[p].format(u=unit) for p in self.parameters}

    # --- navigation channel (:mod:`bayes_imu.drift.navigation`) --------------------------
    def nav_filter(self, params, dt, *, n_cal=None):  # pragma: no cover - abstract
        """The sampled output as a linear state-space system driven by i.i.d. standard normals.

        ``s_{i+1} = F s_i + G eps_i``, ``y_i = H s_i + D eps_i``; a dict of ``F (..., s, s)``,
        ``G (..., s, e)``, ``H (..., s)``, ``D (..., e)`` and the state covariances at the
        start: ``P_zero``, ``P_stationary`` (at the outage) and ``P_calibration`` (``n_cal``
        samples before it), with the same semantics as :meth:`drift_variance`.
        """
        raise NotImplementedError

    def nav_variance(self, loop, k, params, dt, *, bias_start="calibrated", n_cal=None):
        """Variance ``(..., n_t, 3)`` of (tilt [rad^2], velocity [(m/s)^2], position [m^2]) of
        a navigation channel (``loop``, a :class:`bayes_imu.drift.navigation.NavLoop`) driven by
        this term after ``k`` ``(n_t,)`` samples; ``n_cal`` is the calibration window in samples.

        The default serves terms linear in one squared amplitude: the exact propagation of
        :meth:`nav_filter` at unit amplitude, scaled.
        """
        unit = {p: 1.0 for p in self.parameters}

        def compute():
            system = self.nav_filter(unit, dt, n_cal=n_cal)
            return loop.linear_variance(system, k, dt, bias_start=bias_start, n_cal=n_cal)

        v = loop.unit_variance(self.name, compute, k, dt, bias_start, n_cal)
        return np.asarray(self.amplitude2(params), float)[..., None, None] * v


def nav_system(f, g, h, d, p_zero, p_stationary=None, p_calibration=None):
    """The dict :meth:`Term.nav_filter` returns (start covariances default to ``p_zero``)."""
    p_stationary = p_zero if p_stationary is None else p_stationary
    p_calibration = p_stationary if p_calibration is None else p_calibration
    arrays = (f, g, h, d, p_zero, p_stationary, p_calibration)
    keys = ("F", "G", "H", "D", "P_zero", "P_stationary", "P_calibration")
    return {key: np.asarray(value, float) for key, value in zip(keys, arrays)}
