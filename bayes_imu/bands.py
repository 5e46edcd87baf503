"""Drift credible bands: posterior draws pushed through the integrated-noise variances.

Each posterior draw of a :class:`~bayes_imu.fit.FitResult` gives a 1-sigma drift curve
``sigma(t)`` of the integrated quantity (attitude from a gyro; velocity and position from
an accelerometer) from the exact, stable formulas of :func:`bayes_imu.drift.drift_sigma`
at the log's sample interval; the bands are pointwise posterior quantiles of ``sigma(t)``.

Terms and their drift (variances add; ``k = t/dt`` samples):

* ``white``, ``gauss_markov``, ``random_walk``: :func:`~bayes_imu.drift.drift_sigma`
  (paper eqs 5, 11, 16, 22, 29 corrected; bias started at zero or stationary);
* ``quantization`` (white angle / velocity noise of std ``Q``): exact, ``2 Q^2`` for a
  single integral, ``Q^2 dt^2 k (k + 1)`` for the double integral;
* ``bias_instability`` (flicker): it has no stationary drift variance (the process is not
  stationary), so it is bounded conservatively as a constant residual bias of standard
  deviation equal to its Allan deviation plateau ``B sqrt(2 ln2 / pi)``: ``sigma = b t``
  (single integral), ``b t^2 / 2`` (double). This is stated in every report.
"""

from dataclasses import dataclass

import numpy as np

from ._euler import drift_grid, gm_sum
from .drift import QUANTITY_ORDER, euler_variance
from .errors import InputError

__all__ = ["SENSOR_QUANTITIES", "DriftBands", "drift_bands", "drift_draws", "default_times", "integrated_unit"]

SENSOR_QUANTITIES = {"gyro": ("attitude",), "accel": ("velocity", "position")}
_FLICKER_PLATEAU = np.sqrt(2.0 * np.log(2.0) / np.pi)


@dataclass(frozen=True)
class DriftBands:
    """Posterior quantiles of the 1-sigma drift of one integrated quantity.

    Attributes
    ----------
    t_s : (n_t,) times (s), whole samples.
    quantity : str
    quantiles : (n_q,) probabilities.
    total : (n_q, n_t) quantiles of the total 1-sigma drift [unit x s^order].
    white, bias : (n_t,) posterior medians of the white-noise part and of the bias part
        (Gauss-Markov, random walk, bias instability), from at most 1000 evenly spaced draws
        (display aids; the bands themselves use every draw).
    crossover_s : float
        First time where the median bias part exceeds the median white part (``nan`` if never).
    bias_start : str
    record_s : float
        Duration of the fitted log (s); bands beyond it extrapolate the model (terms slower
        than the record, a long time constant or a random walk, are not identified there).
    """

    t_s: np.ndarray
    quantity: str
    quantiles: np.ndarray
    total: np.ndarray
    white: np.ndarray
    bias: np.ndarray
    crossover_s: float
    bias_start: str
    record_s: float = float("nan")

    @property
    def extrapolated(self):
        """``(n_t,)`` bool: times beyond the fitted log's duration."""
        return self.t_s > self.record_s

    def quantile(self, q):
        """Band at probability ``q`` (one of :attr:`quantiles`)."""
        idx = np.flatnonzero(np.isclose(self.quantiles, q))
        if idx.size == 0:
            raise InputError(f"quantile {q!r}: computed ones are {self.quantiles.tolist()}")
        return self.total[idx[0]]


def integrated_unit(unit, quantity):
    """Unit of the integrated quantity: ``deg/s`` -> ``deg``; ``m/s^2`` -> ``m/s`` or ``m``; else ``u s^n``."""
    order = QUANTITY_ORDER[quantity]
    known = {"rad/s": ("rad", "rad s"), "deg/s": ("deg", "deg s"), "deg/h": ("deg s/h", "deg s^2/h"),
             "m/s^2": ("m/s", "m"), "m/s2": ("m/s", "m")}
    if unit in known:
        return known[unit][order - 1]
    return f"{unit} s" if order == 1 else f"{unit} s^2"


def default_times(dt, horizon_s=3600.0, n=60):
    """Log-spaced whole-sample times from one sample to ``horizon_s`` (at least ``n`` distinct)."""
    if not (np.isfinite(horizon_s) and horizon_s > dt):
        raise InputError(f"horizon={horizon_s!r} s: expected a time longer than one sample ({dt} s)")
    k = np.unique(np.round(np.geomspace(1.0, horizon_s / dt, n)))
    extra = n
    while k.size < min(n, int(horizon_s / dt)):
        extra *= 2
        k = np.unique(np.round(np.geomspace(1.0, horizon_s / dt, extra)))
    return k * dt


def drift_draws(fit, t, *, quantity, bias_start="zero", max_draws=None, rng=None, white_draws=slice(None)):
    """Per-draw 1-sigma drift: dict with ``t_s`` and ``total``, ``white``, ``bias`` arrays ``(n_draws, n_t)``.

    ``white`` is computed for the draws selected by ``white_draws`` only (default all).
    One compiled pass over draws x times (:func:`bayes_imu._euler.drift_grid`), the same
    exact, stable formulas as :func:`bayes_imu.drift.drift_sigma` (tests compare them).
    """
    if quantity not in QUANTITY_ORDER:
        raise InputError(f"quantity={quantity!r}: expected one of {', '.join(QUANTITY_ORDER)}")
    if bias_start not in ("zero", "stationary"):
        raise InputError(f"bias_start={bias_start!r}: expected 'zero' or 'stationary'")
    order = QUANTITY_ORDER[quantity]
    samples = fit.samples
    if max_draws is not None and samples.shape[0] > max_draws:
        idx = np.random.default_rng(rng).choice(samples.shape[0], size=max_draws, replace=False)
        samples = samples[idx]
    p = fit.model.unpack(samples)
    zeros = np.zeros(samples.shape[0])
    dt = fit.model.dt
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if np.any(~np.isfinite(t) | (t < 0)):
        raise InputError("t: expected finite times >= 0 (s)")
    k = np.round(t / dt)
    scale = dt ** (2 * order)
    s2 = p.get("bias_variance", zeros)
    a = -np.expm1(-dt / p["time_constant"]) if "time_constant" in p else zeros
    white_scales = [p.get("noise_variance", zeros)]
    white_ks = [euler_variance("white", order, k, dt=dt, noise_variance=1.0)]
    if "quantization" in p:
        white_scales.append(p["quantization"] ** 2)
        white_ks.append(2.0 * (k > 0) if order == 1 else dt**2 * k * (k + 1.0))
    extra_scales = [p.get("rate_random_walk", zeros) ** 2]
    extra_ks = [dt ** (2 * order + 1) * gm_sum(order, k, np.zeros_like(k))]
    if "bias_instability" in p:
        extra_scales.append((_FLICKER_PLATEAU * p["bias_instability"]) ** 2)
        extra_ks.append((k * dt) ** (2 * order) / (1.0 if order == 1 else 4.0))
    stationary = s2 * scale if bias_start == "stationary" else zeros
    total, bias = drift_grid(order, k, a, s2 * a * (2.0 - a) * scale, stationary, np.array(white_scales),
                             np.array(white_ks), np.array(extra_scales), np.array(extra_ks))
    white = np.sqrt(np.array(white_scales).T[white_draws] @ np.array(white_ks))
    return {"t_s": k * dt, "total": total, "white": white, "bias": bias}


def _component_subset(n, limit=1000):
    """Every draw up to ``limit``, else an evenly spaced subset (component medians are display aids)."""
    return slice(None) if n <= limit else slice(None, None, int(np.ceil(n / limit)))


def drift_bands(fit, t=None, *, quantity, bias_start="zero", quantiles=(0.05, 0.5, 0.95), horizon_s=3600.0,
                max_draws=None, rng=None):
    """Posterior quantiles of the 1-sigma drift of ``quantity`` at times ``t`` (s).

    Parameters
    ----------
    fit : FitResult
    t : array_like, optional
        Times (s); default :func:`default_times` up to ``horizon_s``.
    quantity : {"attitude", "velocity", "position"}
    bias_start : {"zero", "stationary"}
    quantiles : sequence of float
    max_draws : int, optional
        Use at most this many posterior draws (random subset, ``rng``).

    Returns
    -------
    DriftBands
        Units: the log's unit times s (attitude, velocity) or s^2 (position).
    """
    t = default_times(fit.model.dt, horizon_s) if t is None else t
    n = fit.samples.shape[0] if max_draws is None else min(max_draws, fit.samples.shape[0])
    sub = _component_subset(n)
    draws = drift_draws(fit, t, quantity=quantity, bias_start=bias_start, max_draws=max_draws, rng=rng, white_draws=sub)
    q = np.asarray(quantiles, dtype=float)
    white = np.median(draws["white"], axis=0)
    bias = np.median(draws["bias"][sub], axis=0)
    above = np.flatnonzero(bias > white)
    crossover = float(draws["t_s"][above[0]]) if above.size else float("nan")
    record = fit.allan.duration_s if fit.allan is not None else float("nan")
    return DriftBands(draws["t_s"], quantity, q, np.quantile(draws["total"], q, axis=0), white, bias, crossover,
                      bias_start, record)
