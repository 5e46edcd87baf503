"""Overbounding filter parameters: the white + random-walk pair whose drift covers the posterior's.

A navigation filter (Kalibr, OpenVINS, VINS, GTSAM, MATLAB's ``imuSensor``) models a sensor
by two terms: white noise of density ``N`` [u/sqrt(Hz)] and a bias random walk of density
``K`` [u/s/sqrt(Hz)] (the IEEE Std 952 angle / velocity random walk and rate random walk).
A real sensor also has Gauss-Markov biases, flicker (bias instability) and non-stationarity,
which that model cannot represent: values read off an Allan plot then make the filter
overconfident, and the Kalibr wiki's advice is to inflate them "by 10x or more".

:func:`overbound` answers "by what factor": the pair ``(N, K)`` whose drift, with the
semantics a filter has (the bias estimated as the mean of the ``calibration_s`` seconds just
before the outage: ``bias_start="calibrated"``, :mod:`bayes_imu.noise._base`), is at least
the full posterior's upper credible drift (default the 95% quantile of the model-averaged
1-sigma drift as :func:`bayes_imu.drift.bands.drift_bands` gives it, the record's own measured
interval included where the record measures the drift) at every horizon ``t`` in
``[t_min, t_max]``, and minimal in this sense: with ``x = (q, K^2)`` (``q = N^2 / dt`` the
per-sample white variance) the two-term drift variance is linear, ``V(t) = q w(t) + K^2 r(t)``
(``w``, ``r`` the unit drifts of :data:`~bayes_imu.noise.white.WHITE` and
:data:`~bayes_imu.noise.random_walk.RANDOM_WALK`), so

    minimise  mean_i V(t_i) / U(t_i)^2   subject to  V(t_i) >= U(t_i)^2,  q, K^2 >= 0,

over log-spaced horizons ``t_i`` (the average relative excess of the variance over
``log t``), a linear programme in two unknowns. ``U`` is the posterior bound. The horizons
are refined (cutting planes: a twice denser grid, and a dense one around every horizon
where a constraint is nearly active) until no denser horizon is violated; the pair is then
raised by a relative margin of 1e-6 on the variance, for the horizons between grid points.
For an accelerometer the velocity and the position drift are both bounded.

The result is in the fit's unit; :attr:`OverboundResult.tight_s` lists the horizons where the
bound is tight (the constraint active): two where both terms are needed (the LP's vertex),
often where a Gauss-Markov bias or flicker bulges above the two-term shape.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, ModelError
from ..noise import REGISTRY
from .bands import DEFAULT_CALIBRATION_S, SENSOR_QUANTITIES, drift_bands
from .closed_forms import QUANTITY_ORDER

__all__ = ["OverboundResult", "overbound", "filter_drift", "DEFAULT_T_MAX_S"]

#: default longest horizon [s] (capped at the record's duration: beyond it the drift extrapolates)
DEFAULT_T_MAX_S = 3600.0
_MARGIN = 1e-6
_TIGHT = 1e-5


@dataclass(frozen=True)
class OverboundResult:
    """A white + random-walk pair that bounds a posterior's upper credible drift.

    Attributes
    ----------
    noise_density : float
        ``N`` [u/sqrt(Hz)] (continuous-time white-noise density, u the fit's rate unit).
    random_walk : float
        ``K`` [u/s/sqrt(Hz)] = [u/sqrt(s)] (continuous-time bias random-walk density).
    credibility : float
        Posterior probability of the bounded drift quantile (e.g. 0.95).
    t_s : (n_t,) ndarray
        Horizons of the final constraint grid [s] (whole samples).
    bound : dict
        Quantity -> ``(n_t,)`` the posterior's upper credible 1-sigma drift ``U`` at ``t_s``.
    filter : dict
        Quantity -> ``(n_t,)`` the pair's 1-sigma drift at ``t_s`` (``>= bound``).
    tight_s : tuple of (str, float)
        ``(quantity, horizon [s])`` where the bound is tight (relative variance excess below 1e-5).
    calibration_s : float
        Calibration window of the calibrated bias [s].
    """

    noise_density: float
    random_walk: float
    credibility: float
    t_s: np.ndarray
    bound: dict
    filter: dict
    tight_s: tuple
    calibration_s: float

    def factors(self, noise_density, random_walk):
        """``(N / noise_density, K / random_walk)``: factors over point values (same unit)."""

        def ratio(a, b):
            return float(a / b) if b > 0 else float("inf") if a > 0 else float("nan")

        return ratio(self.noise_density, noise_density), ratio(self.random_walk, random_walk)


def filter_drift(
    noise_density, random_walk, t, *, dt, quantity, calibration_s=DEFAULT_CALIBRATION_S
):
    """1-sigma calibrated-start drift ``(n_t,)`` of the two-term filter model at times ``t`` [s].

    ``noise_density`` N [u/sqrt(Hz)], ``random_walk`` K [u/sqrt(s)], sample period ``dt`` [s].
    """
    w, r = _unit_drifts(
        np.round(np.asarray(t, float) / dt), dt, QUANTITY_ORDER[quantity], calibration_s
    )
    return np.sqrt(noise_density**2 / dt * w + random_walk**2 * r)


def _unit_drifts(k, dt, order, calibration_s):
    n_cal = float(np.round(calibration_s / dt))
    w = REGISTRY["white"].unit_drift(order, k, dt, "calibrated", n_cal)
    r = REGISTRY["random_walk"].unit_drift(order, k, dt, "calibrated", n_cal)
    return w, r


def _grid(dt, t_min, t_max, n):
    return _grid_between(t_min / dt, t_max / dt, n)


def _upper(fit, k, dt, quantities, credibility, calibration_s, max_draws, rng):
    """The upper credible 1-sigma drift at steps ``k``, as ``drift.csv`` publishes it: the band of
    :func:`~bayes_imu.drift.bands.drift_bands`, which within the record contains the record's own
    measured interval (a filter tuned to it must bound what the log itself shows)."""
    out = {}
    for quantity in quantities:
        band = drift_bands(
            fit,
            k * dt,
            quantity=quantity,
            bias_start="calibrated",
            calibration_s=calibration_s,
            quantiles=(credibility,),
            max_draws=max_draws,
            rng=rng,
        )
        out[quantity] = np.asarray(band.total[0], float)
    return out


def _solve(rows):
    """The two-variable LP of the module docstring; ``rows`` ``(n, 2)``: ``a_i x >= 1``."""
    from scipy.optimize import linprog

    scale = 1.0 / np.max(rows, axis=0)  # variables of order one
    a = rows * scale
    res = linprog(
        np.mean(a, axis=0),
        A_ub=-a,
        b_ub=-np.ones(a.shape[0]),
        bounds=[(0, None)] * 2,
        method="highs",
    )
    if res.status != 0:
        raise ModelError(f"overbound: the linear programme failed ({res.message})")
    x = res.x * scale
    # the solver's tolerance may leave a constraint violated by ~1e-9: scale up to meet every one,
    # with a relative margin of 1e-6 on the variance for horizons between the grid's
    return x * max(1.0, float(np.max(1.0 / (rows @ x)))) * (1.0 + _MARGIN)


def overbound(
    fit,
    *,
    kind,
    t_min=None,
    t_max=None,
    credibility=0.95,
    calibration_s=DEFAULT_CALIBRATION_S,
    n_grid=120,
    max_draws=4000,
    rng=None,
):
    """The minimal white + random-walk pair bounding the posterior's upper credible drift.

    Parameters
    ----------
    fit : FitResult or UnitPosterior
        A fit (or a population's new-unit predictive), rate unit ``u``.
    kind : {"gyro", "accel"}
        Gyro: attitude drift; accelerometer: velocity and position drift.
    t_min, t_max : float, optional
        Horizon range [s]; default one sample period to ``min(3600 s, record)``.
    credibility : float
        Posterior probability of the bounded quantile, in (0.5, 1).
    calibration_s : float
        Calibration window of the calibrated bias [s].
    n_grid : int
        Log-spaced horizons of the first constraint grid (refined by cutting planes).
    max_draws : int or None
        Posterior draws used (a random subset, ``rng``); None: all.

    Returns
    -------
    OverboundResult
    """
    if kind not in SENSOR_QUANTITIES:
        raise InputError(f"kind={kind!r}: expected one of {', '.join(SENSOR_QUANTITIES)}")
    if not 0.5 < credibility < 1:
        raise InputError(f"credibility={credibility!r}: expected a probability in (0.5, 1)")
    dt = fit.model.dt
    record = getattr(fit, "record_s", float("nan"))
    t_min = dt if t_min is None else float(t_min)
    t_max = (
        (min(DEFAULT_T_MAX_S, record) if np.isfinite(record) else DEFAULT_T_MAX_S)
        if t_max is None
        else t_max
    )
    t_max = float(t_max)
    if not (np.isfinite(t_min) and np.isfinite(t_max) and dt <= t_min < t_max):
        raise InputError(
            f"t_min={t_min!r} s, t_max={t_max!r} s: expected one sample ({dt:g} s) <= t_min < t_max"
        )
    quantities = SENSOR_QUANTITIES[kind]
    seed = np.random.default_rng(rng).integers(2**63)  # the same draws at every horizon
    k = _grid(dt, t_min, t_max, n_grid)
    for _ in range(8):
        rows = _rows(fit, k, dt, quantities, credibility, calibration_s, max_draws, seed)
        flat = rows.reshape(-1, 2)
        x = _solve(flat[np.isfinite(flat[:, 0])])
        slack = np.nanmin(np.where(np.isfinite(rows[..., 0]), rows @ x, np.nan), axis=0)
        bad = _violations(
            fit,
            _near_tight(k, slack),
            x,
            dt,
            quantities,
            credibility,
            calibration_s,
            max_draws,
            seed,
        )
        if bad.size == 0:
            break
        k = np.union1d(k, bad)
    else:
        raise ModelError("overbound: the horizons did not settle after eight refinements")
    upper = _upper(fit, k, dt, quantities, credibility, calibration_s, max_draws, seed)
    drift = {
        q: filter_drift(
            np.sqrt(x[0] * dt),
            np.sqrt(x[1]),
            k * dt,
            dt=dt,
            quantity=q,
            calibration_s=calibration_s,
        )
        for q in quantities
    }
    tight = []
    for q in quantities:
        for t, f, u in zip(k * dt, drift[q], upper[q]):
            if (
                u > 0
                and f**2 <= u**2 * (1.0 + _TIGHT)
                and not (tight and tight[-1][0] == q and t < tight[-1][1] * 1.01)
            ):
                tight.append((q, float(t)))  # one per tight stretch (a refined grid is dense there)
    return OverboundResult(
        float(np.sqrt(x[0] * dt)),
        float(np.sqrt(x[1])),
        float(credibility),
        k * dt,
        upper,
        drift,
        tuple(tight),
        float(calibration_s),
    )


def _rows(fit, k, dt, quantities, credibility, calibration_s, max_draws, seed):
    """Constraint rows ``(n_quantities, n_k, 2)``: unit drifts over the bound's variance
    (``nan`` where it is 0)."""
    upper = _upper(fit, k, dt, quantities, credibility, calibration_s, max_draws, seed)
    rows = []
    for q in quantities:
        w, r = _unit_drifts(k, dt, QUANTITY_ORDER[q], calibration_s)
        u2 = np.where(upper[q] > 0, upper[q] ** 2, np.nan)
        rows.append(np.column_stack([w / u2, r / u2]))
    return np.stack(rows)


def _near_tight(k, slack, close=1e-3, n_local=40):
    """Horizons to check: the grid twice as dense, and ``n_local`` more between the neighbours of
    every horizon whose variance ratio (``slack``, ``(n_k,)``) is below ``1 + close`` (where a
    violation can hide)."""
    out = [_grid_between(k[0], k[-1], 2 * k.size)]
    for i in np.flatnonzero(slack < 1.0 + close):
        out.append(_grid_between(k[max(i - 1, 0)], k[min(i + 1, k.size - 1)], n_local))
    return np.unique(np.concatenate(out))


def _grid_between(lo, hi, n):
    k = np.unique(np.round(np.geomspace(lo, hi, n)))
    return k[k >= 1]


def _violations(fit, k, x, dt, quantities, credibility, calibration_s, max_draws, seed):
    """Horizons ``k`` (samples) where the pair's drift variance falls short of the bound's."""
    upper = _upper(fit, k, dt, quantities, credibility, calibration_s, max_draws, seed)
    bad = []
    for q in quantities:
        w, r = _unit_drifts(k, dt, QUANTITY_ORDER[q], calibration_s)
        bad.append(k[x[0] * w + x[1] * r < upper[q] ** 2 * (1.0 - 1e-12)])
    return np.unique(np.concatenate(bad))
