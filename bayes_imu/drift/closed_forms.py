"""Variance of Euler-integrated sensor noise: attitude, velocity and position drift.

Two layers:

* :func:`euler_variance` is the paper's discrete result (Wall & Bevly, eqs 5, 11, 16, 22,
  29) in the paper's own convention, exact and numerically stable. The printed eqs 11,
  19, 28 and 29 contain errors; the corrected forms are derived and verified in
  ``docs/errata.md``.
* :func:`drift_sigma` is the physical layer: white noise given as a per-sample variance
  or a noise density, a first-order Gauss-Markov bias given by its stationary variance
  ``sigma_b**2`` (paper eq 4) and time constant ``tau``, and optionally a rate random
  walk, mapped to the 1-sigma drift of the integrated quantity versus time.

All functions broadcast over every array argument: pass posterior draws of shape
``(n_draws, 1)`` and times of shape ``(n_times,)`` to get ``(n_draws, n_times)``.
"""

from dataclasses import dataclass

import numpy as np

from ..noise.quantities import QUANTITIES
from ..noise.euler_sums import gm_coefficient, gm_sum, gm_sum_broadcast
from ..errors import InputError, ModelError

__all__ = [
    "QUANTITY_ORDER",
    "DriftResult",
    "euler_variance",
    "drift_sigma",
    "noise_density_to_variance",
    "noise_variance_to_density",
    "gauss_markov_driving_variance",
]

#: integration order of each navigation quantity (attitude from a gyro; velocity and
#: position from an accelerometer)
QUANTITY_ORDER = {name: q.order for name, q in QUANTITIES.items()}
_SOURCES = ("white", "gauss_markov")
_BIAS_STARTS = ("zero", "stationary")
#: bias starts of the closed forms (the noise terms add "calibrated")
DRIFT_BIAS_STARTS = _BIAS_STARTS
#: SI unit of each integrated quantity
SI_OUTPUT_UNITS = {name: q.si_unit for name, q in QUANTITIES.items()}
_DISCRETIZATIONS = ("exact", "euler")
_MAX_STEPS = 2.0**53


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise InputError(f"{name}={value!r}: expected one of {', '.join(map(repr, allowed))}")


def _as_steps(k):
    k = np.asarray(k, dtype=float)
    bad = ~np.isfinite(k) | (k < 0) | (k != np.round(k)) | (k > _MAX_STEPS)
    if np.any(bad):
        raise InputError(f"k={k[bad].flat[0]!r}: expected whole step counts 0 <= k <= 2**53")
    return k


def _positive(name, value, *, allow_zero=False, allow_inf=False):
    value = np.asarray(value, dtype=float)
    ok = (value >= 0) if allow_zero else (value > 0)
    ok &= ~np.isnan(value) & (np.isfinite(value) | allow_inf)
    if not np.all(ok):
        expected = "non-negative" if allow_zero else "positive"
        raise ModelError(f"{name}={value[~ok].flat[0]!r}: expected a {expected} finite number")
    return value


def euler_variance(source, order, k, *, dt, noise_variance, time_constant=None):
    """Exact variance after ``k`` forward-Euler steps (paper convention).

    Zero initial state; ``b_k = A b_{k-1} + dt w_{k-1}`` with ``A = 1 - dt/tau``
    (eq 12); ``v_k = v_{k-1} + dt x_{k-1}`` (eq 18); ``p_k = p_{k-1} + dt v_{k-1}``
    (eqs 8, 24); ``w`` i.i.d. with variance ``noise_variance``; ``x = w`` (white) or
    ``x = b`` (Gauss-Markov).

    Parameters
    ----------
    source : {"white", "gauss_markov"}
    order : {0, 1, 2}
        0: the process itself; 1: single integral (attitude from a gyro, velocity from an
        accelerometer); 2: double integral (position).
    k : array_like of int
        Number of Euler steps, ``0 <= k <= 2**53``.
    dt : array_like of float
        Sample interval (s).
    noise_variance : array_like of float
        Variance of ``w`` (units**2). For ``"gauss_markov"`` this is the paper's driving
        noise variance ``sigma_omega**2``; see :func:`gauss_markov_driving_variance`.
    time_constant : array_like of float, optional
        ``tau`` (s), required for ``"gauss_markov"``. ``np.inf`` gives the random-walk
        limit ``A = 1``.

    Returns
    -------
    ndarray
        Variance, broadcast over all array arguments: white ``q`` (order 0), ``q dt**2 k``
        (eq 5), ``q dt**4 (k-1) k (2k-1) / 6`` (eq 11, corrected); Gauss-Markov
        ``q dt**(2r+2) sum_{n<k} c_r(n)**2`` (eqs 16, 22 and 29 corrected).

    Raises
    ------
    ModelError
        For ``dt >= 2 tau``: there ``|A| >= 1`` and the Euler recursion is unstable
        (its variance grows without bound), so no variance is returned.

    Notes
    -----
    Accurate to a few units in the last place (relative error < 1e-14 in the tests)
    for ``0 <= dt/tau < 2`` and every ``k``, including ``dt/tau`` down to 1e-300,
    ``A = 0`` and ``A < 0``.
    """
    _check_choice("source", source, _SOURCES)
    _check_choice("order", order, (0, 1, 2))
    k = _as_steps(k)
    dt = _positive("dt", dt)
    q = _positive("noise_variance", noise_variance, allow_zero=True)
    if source == "white":
        if time_constant is not None:
            raise InputError("time_constant: not used by source='white'; expected None")
        shape = [np.ones_like(k), k, (k - 1.0) * k * (2.0 * k - 1.0) / 6.0][order]
        shape = np.where(k == 0, 0.0, shape) if order else np.broadcast_to(shape, k.shape)
        return q * dt ** (2 * order) * shape
    if time_constant is None:
        raise InputError("time_constant: required for source='gauss_markov' (seconds, > 0)")
    tau = _positive("time_constant", time_constant, allow_inf=True)
    a = dt / tau
    _check_stable(a)
    return q * dt ** (2 * order + 2) * gm_sum(order, *np.broadcast_arrays(k, a))


def _check_stable(a):
    if np.any(a >= 2.0):
        bad = np.asarray(a)[np.asarray(a) >= 2.0].flat[0]
        raise ModelError(
            f"dt/time_constant={bad!r}: the forward-Euler Gauss-Markov recursion is unstable "
            "for dt >= 2*tau (|A| >= 1); expected dt/tau < 2"
        )


def noise_density_to_variance(noise_density, dt):
    """Per-sample white-noise variance ``N**2 / dt`` from a density ``N`` (units/sqrt(Hz))."""
    return np.asarray(noise_density, dtype=float) ** 2 / np.asarray(dt, dtype=float)


def noise_variance_to_density(noise_variance, dt):
    """Noise density ``sqrt(q dt)`` (units/sqrt(Hz)) from a per-sample variance ``q``."""
    return np.sqrt(np.asarray(noise_variance, dtype=float) * np.asarray(dt, dtype=float))


def _step_ratio(dt, tau, discretization):
    """``a = 1 - A`` of the discrete bias recursion."""
    ratio = dt / tau
    if discretization == "exact":
        return -np.expm1(-ratio)
    _check_stable(ratio)
    return ratio


def gauss_markov_driving_variance(bias_variance, time_constant, dt, *, discretization="exact"):
    """Driving-noise variance ``sigma_omega**2`` of eq 12 for a stationary variance ``sigma_b**2``.

    The discrete recursion ``b_k = A b_{k-1} + dt w_{k-1}`` has stationary variance
    ``dt**2 sigma_omega**2 / (1 - A**2)``, so ``sigma_omega**2 = sigma_b**2 a (2 - a) / dt**2``
    with ``a = 1 - A``. With ``discretization="exact"`` (default), ``A = exp(-dt/tau)``:
    the exact sampling of the continuous process ``db/dt = -b/tau + omega`` (eq 3) whose
    autocorrelation is eq 4; with ``"euler"``, ``A = 1 - dt/tau`` as in the paper. Both tend
    to the continuous PSD ``2 sigma_b**2 / tau`` times ``1/dt`` as ``dt -> 0``.
    """
    _check_choice("discretization", discretization, _DISCRETIZATIONS)
    a = _step_ratio(
        np.asarray(dt, dtype=float), np.asarray(time_constant, dtype=float), discretization
    )
    return np.asarray(bias_variance, dtype=float) * a * (2.0 - a) / np.asarray(dt, dtype=float) ** 2


@dataclass(frozen=True)
class DriftResult:
    """1-sigma drift of an integrated sensor versus time, by noise source.

    Attributes
    ----------
    t_s : ndarray
        Times (s), rounded to whole samples.
    quantity : str
        ``"attitude"`` (rad or the gyro's angle unit), ``"velocity"`` (m/s) or
        ``"position"`` (m).
    white, bias, random_walk : ndarray
        1-sigma contribution of each source (output unit), broadcast shape.
    total : ndarray
        ``sqrt(white**2 + bias**2 + random_walk**2)`` (eqs 23 and 30).
    """

    t_s: np.ndarray
    quantity: str
    white: np.ndarray
    bias: np.ndarray
    random_walk: np.ndarray
    total: np.ndarray


def drift_sigma(
    t,
    *,
    quantity,
    dt,
    noise_variance=None,
    noise_density=None,
    bias_variance=0.0,
    time_constant=np.inf,
    random_walk=0.0,
    bias_start="zero",
    discretization="exact",
):
    """1-sigma attitude / velocity / position drift after integrating for ``t`` seconds.

    Parameters
    ----------
    t : array_like of float
        Integration times (s), ``>= 0``; rounded to whole samples ``k = round(t / dt)``.
    quantity : {"attitude", "velocity", "position"}
    dt : float or array_like
        Sample interval (s).
    noise_variance, noise_density : array_like, optional
        The white noise, as a per-sample variance (units**2) or a density
        (units/sqrt(Hz)); give exactly one (or neither for no white noise).
    bias_variance : array_like, default 0
        Stationary variance ``sigma_b**2`` of the Gauss-Markov bias (units**2, eq 4).
    time_constant : array_like, default inf
        Its correlation time ``tau`` (s).
    random_walk : array_like, default 0
        Rate random walk coefficient ``K`` (units/sqrt(s)): the bias increments by
        ``N(0, K**2 dt)`` each sample, Allan deviation ``K sqrt(T/3)``.
    bias_start : {"zero", "stationary"}
        ``"zero"``: the bias starts at 0 (the paper's convention). ``"stationary"``: it
        starts from its stationary distribution ``N(0, sigma_b**2)``, the conservative
        choice for a sensor switched on long before the outage.
    discretization : {"exact", "euler"}
        How the bias evolves between samples, see :func:`gauss_markov_driving_variance`.

    Returns
    -------
    DriftResult
    """
    _check_choice("quantity", quantity, tuple(QUANTITY_ORDER))
    _check_choice("bias_start", bias_start, _BIAS_STARTS)
    _check_choice("discretization", discretization, _DISCRETIZATIONS)
    if noise_variance is not None and noise_density is not None:
        raise InputError("noise_variance and noise_density: expected at most one of them")
    order = QUANTITY_ORDER[quantity]
    dt = _positive("dt", dt)
    t = np.asarray(t, dtype=float)
    if np.any(~np.isfinite(t) | (t < 0)):
        raise InputError(
            f"t={t[~np.isfinite(t) | (t < 0)].flat[0]!r}: expected finite times >= 0 (s)"
        )
    k = np.round(t / dt)
    if noise_density is not None:
        noise_variance = noise_density_to_variance(
            _positive("noise_density", noise_density, allow_zero=True), dt
        )
    q_white = 0.0 if noise_variance is None else noise_variance
    white = euler_variance("white", order, k, dt=dt, noise_variance=q_white)

    sigma_b2 = _positive("bias_variance", bias_variance, allow_zero=True)
    tau = _positive("time_constant", time_constant, allow_inf=True)
    a = _step_ratio(dt, tau, discretization)
    # q dt**2 = sigma_b**2 a (2 - a): the variance in units of dt**(2 order)
    bias = sigma_b2 * a * (2.0 - a) * dt ** (2 * order) * gm_sum_broadcast(order, k, a)
    if bias_start == "stationary":
        bias = (
            bias + sigma_b2 * (dt**order * gm_coefficient(order, *np.broadcast_arrays(k, a))) ** 2
        )

    k_rw = _positive("random_walk", random_walk, allow_zero=True)
    rw = k_rw**2 * dt ** (2 * order + 1) * gm_sum(order, *np.broadcast_arrays(k, np.zeros_like(k)))

    white, bias, rw = np.broadcast_arrays(white, bias, rw)
    return DriftResult(
        t_s=k * dt,
        quantity=quantity,
        white=np.sqrt(white),
        bias=np.sqrt(bias),
        random_walk=np.sqrt(rw),
        total=np.sqrt(white + bias + rw),
    )
