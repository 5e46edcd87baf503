"""Drift credible bands: posterior draws pushed through the integrated-noise variances.

Each posterior draw gives a 1-sigma drift curve ``sigma(t)`` of the integrated quantity
(attitude from a gyro; velocity and position from an accelerometer): the sum over the
model's terms of each term's exact drift variance (:meth:`bayes_imu.noise.Term.drift_variance`,
paper eqs 5, 11, 16, 22, 29 corrected, and the exact forms of the other terms). The bands
are pointwise posterior quantiles of ``sigma(t)``.

Model uncertainty: by default (``models="averaged"``) the draws come from every candidate
model in proportion to its posterior probability
(:attr:`bayes_imu.inference.fit.FitResult.mixture`); ``models="selected"`` uses the selected model
alone.

Non-stationary logs: when the fit's between-segment check flags the record
(:mod:`bayes_imu.inference.stationarity`), each draw's drift is multiplied by ``exp(z s(t) / 2)``,
``z ~ N(0, 1)`` one per draw, so that the bands allow a later outage to fall in a part of the
sensor's life as different as the record's own parts are (``segment_spread=False`` leaves it out).

Bias semantics (``bias_start``, :mod:`bayes_imu.noise._base`): ``"calibrated"`` (the default of
every entry point, library and command line alike: the bias estimated as the mean of the
``calibration_s`` = 60 s before the outage), ``"zero"`` (the paper) and ``"stationary"``.
"""

from dataclasses import dataclass, field

import numpy as np

from .closed_forms import QUANTITY_ORDER
from .direct import (
    direct_contrasts,
    direct_edf,
    drift_check,
    honest_quantiles,
    record_edf_floor,
    same_window,
    upper_envelope,
)
from ..errors import InputError, UnmeasuredWarning
from ..noise import BIAS_STARTS, TERMS, NoiseModel
from ..noise.quantities import SENSORS

__all__ = [
    "SENSOR_QUANTITIES",
    "MODEL_CHOICES",
    "DEFAULT_CALIBRATION_S",
    "DriftBands",
    "drift_bands",
    "drift_draws",
    "default_times",
    "integrated_unit",
    "model_draws",
]

SENSOR_QUANTITIES = {name: s.quantities for name, s in SENSORS.items()}
MODEL_CHOICES = ("averaged", "selected")
#: default calibration window of the calibrated bias start [s]
DEFAULT_CALIBRATION_S = 60.0


@dataclass(frozen=True)
class DriftBands:
    """Posterior quantiles of the 1-sigma drift of one integrated quantity.

    Attributes
    ----------
    t_s : (n_t,) times (s), whole samples.
    quantity : str
    quantiles : (n_q,) probabilities.
    total : (n_q, n_t) quantiles of the total 1-sigma drift [unit x s^order].
    white, bias : (n_t,) posterior medians of the short-term part (white, filtered white,
        quantization, high-frequency correlated) and of the rest (biases, random walk, ramp)
        (display aids; the bands themselves use every draw).
    crossover_s : float
        First time where the median of the rest exceeds the median short-term part (``nan`` if
        never).
    bias_start : str
    record_s : float
        Duration of the fitted log (s); bands beyond it extrapolate the model (terms slower
        than the record, a long time constant or a random walk, are not identified there).
    terms : dict
        Term name -> ``(n_t,)`` posterior median of its 1-sigma contribution, over the draws
        of the models that have it.
    calibration_s : float
        Calibration window of ``bias_start="calibrated"`` (s), else ``nan``.
    models : str
        ``"averaged"`` or ``"selected"``.
    term_probability : dict
        Term name -> posterior probability that the sensor has it (share of the draws whose
        model has it; 1 for every term of a selected model).
    measured_s : float
        Longest horizon the record measures directly (calibrated attitude, velocity and position,
        :mod:`bayes_imu.drift.direct`): up to it ``total`` contains the record's own interval;
        beyond it the bands are the model's extrapolation. ``nan`` when nothing is measured;
        ``0`` when the record measured another calibration window than the one asked (the band
        is then the model's at every horizon, all marked :attr:`extrapolated`).
    model_total : (n_q, n_t) ndarray or None
        The model's quantiles before the record's interval was included (``None`` when equal).
    check : DriftCheck or None
        The drift-space adequacy check at the horizons measured.
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
    terms: dict = field(default_factory=dict)
    calibration_s: float = float("nan")
    models: str = "selected"
    term_probability: dict = field(default_factory=dict)
    measured_s: float = float("nan")
    model_total: np.ndarray = None
    check: object = None

    @property
    def extrapolated(self):
        """``(n_t,)`` bool: times where the band is the model's extrapolation: beyond the horizons
        the record measures (:attr:`measured_s`) where it measures any, else beyond the log."""
        return self.t_s > (self.measured_s if np.isfinite(self.measured_s) else self.record_s)

    def scaled(self, factor):
        """The same bands in another unit (every drift value times ``factor``)."""
        from dataclasses import replace

        return replace(
            self,
            total=self.total * factor,
            white=self.white * factor,
            bias=self.bias * factor,
            terms={n: v * factor for n, v in self.terms.items()},
            model_total=None if self.model_total is None else self.model_total * factor,
            check=None if self.check is None else self.check.scaled(factor),
        )

    def quantile(self, q):
        """Band at probability ``q`` (one of :attr:`quantiles`)."""
        idx = np.flatnonzero(np.isclose(self.quantiles, q))
        if idx.size == 0:
            raise InputError(f"quantile {q!r}: computed ones are {self.quantiles.tolist()}")
        return self.total[idx[0]]


def integrated_unit(unit, quantity):
    """Unit of the integrated quantity: ``deg/s`` -> ``deg``; ``m/s^2`` -> ``m/s`` or ``m``; else
    ``u s^n``."""
    order = QUANTITY_ORDER[quantity]
    known = {
        "rad/s": ("rad", "rad s"),
        "deg/s": ("deg", "deg s"),
        "deg/h": ("deg s/h", "deg s^2/h"),
        "m/s^2": ("m/s", "m"),
        "m/s2": ("m/s", "m"),
    }
    if unit in known:
        return known[unit][order - 1]
    return f"{unit} s" if order == 1 else f"{unit} s^2"


def default_times(dt, horizon_s=3600.0, n=60):
    """Log-spaced whole-sample times from one sample to ``horizon_s`` (at least ``n`` distinct)."""
    if not (np.isfinite(horizon_s) and horizon_s > dt):
        raise InputError(
            f"horizon={horizon_s!r} s: expected a time longer than one sample ({dt} s)"
        )
    k = np.unique(np.round(np.geomspace(1.0, horizon_s / dt, n)))
    extra = n
    while k.size < min(n, int(horizon_s / dt)):
        extra *= 2
        k = np.unique(np.round(np.geomspace(1.0, horizon_s / dt, extra)))
    return k * dt


def model_draws(fit, models="averaged"):
    """``[(NoiseModel, samples), ...]``: the mixture of candidates (``"averaged"``) or the selected
    model."""
    if models not in MODEL_CHOICES:
        raise InputError(f"models={models!r}: expected one of {', '.join(MODEL_CHOICES)}")
    if models == "selected" or not getattr(fit, "mixture", ()):
        return [(fit.model, fit.samples)]
    return [(NoiseModel(c.terms, fit.model.dt), c.samples) for c in fit.mixture]


def _check_times(t):
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1 or np.any(~np.isfinite(t) | (t < 0)):
        raise InputError("t: expected a 1-D array of finite times >= 0 (s)")
    return t


def drift_draws(
    fit,
    t,
    *,
    quantity,
    bias_start="calibrated",
    calibration_s=DEFAULT_CALIBRATION_S,
    models="averaged",
    max_draws=None,
    rng=None,
    component_draws=slice(None),
    segment_spread=True,
):
    """Per-draw 1-sigma drift of ``quantity`` at times ``t`` [s].

    ``segment_spread``: include the between-segment spread of a log flagged non-stationary
    (module docstring) in ``total``; the components are the model's alone.

    Returns
    -------
    dict
        ``t_s`` (whole samples) and ``total`` ``(n_draws, n_t)`` [unit x s^order]; for the draws
        selected by ``component_draws`` (default all): ``white`` (short-term part), ``bias``
        (the rest) and ``terms``, name -> 1-sigma contribution (``nan`` for draws of models
        without that term).
    """
    if quantity not in QUANTITY_ORDER:
        raise InputError(f"quantity={quantity!r}: expected one of {', '.join(QUANTITY_ORDER)}")
    if bias_start not in BIAS_STARTS:
        raise InputError(f"bias_start={bias_start!r}: expected one of {', '.join(BIAS_STARTS)}")
    dt = fit.model.dt
    if not (np.isfinite(calibration_s) and calibration_s >= dt):
        raise InputError(
            f"calibration={calibration_s!r} s: expected at least one sample ({dt:g} s)"
        )
    order = QUANTITY_ORDER[quantity]
    t = _check_times(t)
    k = np.round(t / dt)
    n_cal = float(np.round(calibration_s / dt))
    parts = model_draws(fit, models)
    n_all = sum(p[1].shape[0] for p in parts)
    rng = np.random.default_rng(rng)
    if max_draws is not None and n_all > max_draws:
        keep = np.sort(rng.choice(n_all, size=max_draws, replace=False))
        bounds = np.cumsum([0] + [p[1].shape[0] for p in parts])
        parts = [
            (m, s[keep[(keep >= lo) & (keep < hi)] - lo])
            for (m, s), lo, hi in zip(parts, bounds[:-1], bounds[1:])
        ]
        n_all = max_draws
    names = _term_order(parts)
    short, rest = np.zeros((n_all, k.size)), np.zeros((n_all, k.size))
    variances = {n: np.full((n_all, k.size), np.nan)[component_draws] for n in names}
    rows = np.arange(n_all)[component_draws]  # draws whose components are kept
    start = 0
    for model, samples in parts:
        stop = start + samples.shape[0]
        params = model.unpack(samples)
        mine = (rows >= start) & (rows < stop)
        for term in model.components:
            v = term.drift_variance(order, k, params, dt, bias_start=bias_start, n_cal=n_cal)
            (short if term.role == "short_term" else rest)[start:stop] += v
            variances[term.name][mine] = v[rows[mine] - start]
        start = stop
    total = np.sqrt(short + rest)
    steady = getattr(fit, "stationarity", None)
    if segment_spread and steady is not None and not steady.stationary:
        total = total * np.exp(rng.standard_normal((n_all, 1)) * steady.drift_log_sd(k * dt))
    return {
        # whole samples over the rate: 35 / 100 is the double nearest 0.35 (what outputs print),
        # 35 * 0.01 is 0.35000000000000003
        "t_s": k / (1.0 / dt),
        "total": total,
        "white": np.sqrt(short[component_draws]),
        "bias": np.sqrt(rest[component_draws]),
        "terms": {n: np.sqrt(v) for n, v in variances.items()},
    }


def _component_subset(n, limit=1000):
    """Every draw up to ``limit``, else an evenly spaced subset (component medians are display
    aids)."""
    return slice(None) if n <= limit else slice(None, None, int(np.ceil(n / limit)))


def _term_order(parts):
    present = {t for model, _ in parts for t in model.terms}
    return [t for t in TERMS if t in present]


def drift_bands(
    fit,
    t=None,
    *,
    quantity,
    bias_start="calibrated",
    calibration_s=DEFAULT_CALIBRATION_S,
    models="averaged",
    quantiles=(0.05, 0.5, 0.95),
    horizon_s=3600.0,
    max_draws=None,
    rng=None,
    segment_spread=True,
    honest=True,
):
    """Posterior quantiles of the 1-sigma drift of ``quantity`` at times ``t`` (s).

    Parameters
    ----------
    fit : FitResult
    t : array_like, optional
        Times (s); default :func:`default_times` up to ``horizon_s``. Given times are kept
        exactly (rounded to whole samples).
    quantity : {"attitude", "velocity", "position"}
    bias_start : {"calibrated", "zero", "stationary"}
        Default ``"calibrated"``, as the command line (module docstring).
    calibration_s : float
        Calibration window of ``"calibrated"`` (s), default 60.
    models : {"averaged", "selected"}
    quantiles : sequence of float
    max_draws : int, optional
        Use at most this many posterior draws (random subset, ``rng``).
    segment_spread : bool
        Widen the bands of a log flagged non-stationary by the spread between its parts
        (module docstring).
    honest : bool
        Where the record measures the drift (calibrated attitude, velocity or position, a fit of
        a log read in memory: :mod:`bayes_imu.drift.direct`), widen the band to contain the
        record's own interval and check the model against it (:attr:`DriftBands.check`).

    Returns
    -------
    DriftBands
        Units: the log's unit times s (attitude, velocity) or s^2 (position).
    """
    t = default_times(fit.model.dt, horizon_s) if t is None else t
    n = sum(s.shape[0] for _, s in model_draws(fit, models))
    sub = _component_subset(n if max_draws is None else min(n, max_draws))
    draws = drift_draws(
        fit,
        t,
        quantity=quantity,
        bias_start=bias_start,
        calibration_s=calibration_s,
        models=models,
        max_draws=max_draws,
        rng=rng,
        component_draws=sub,
        segment_spread=segment_spread,
    )
    q = np.asarray(quantiles, dtype=float)
    white = np.median(draws["white"], axis=0)
    bias = np.median(draws["bias"], axis=0)
    above = np.flatnonzero(bias > white)
    crossover = float(draws["t_s"][above[0]]) if above.size else float("nan")
    record = fit.record_s
    # each term's median over the draws whose model has it (a model-averaged median with zeros
    # for the other models would understate a term that few, but heavy, models carry)
    terms = {n: np.median(v[np.isfinite(v[:, 0])], axis=0) for n, v in draws["terms"].items()
             if np.isfinite(v[:, 0]).any()}
    probability = {
        n: float(np.mean(np.isfinite(v[:, 0]))) for n, v in draws["terms"].items() if n in terms
    }
    cal = float(calibration_s) if bias_start == "calibrated" else float("nan")
    total = np.quantile(draws["total"], q, axis=0)
    measured = (
        direct_part(fit, draws, quantity, bias_start, calibration_s, q, total) if honest else None
    )
    return DriftBands(
        draws["t_s"],
        quantity,
        q,
        total if measured is None else measured[0],
        white,
        bias,
        crossover,
        bias_start,
        record,
        terms,
        cal,
        models,
        probability,
        *((float("nan"), None, None) if measured is None else measured[1:]),
    )


def _warn_other_window(fit, quantity, bias_start, calibration_s):
    """Calibrated bands at a window other than the one the record measured:
    they are the model's alone (honest only within the model list), which the caller can mend.
    Returns whether it warned."""
    import warnings

    measured = getattr(getattr(fit, "allan", None), "contrasts", None)
    if (measured is None or bias_start != "calibrated" or same_window(measured, calibration_s)
            or measured.of_order(QUANTITY_ORDER[quantity]) is None):
        return False
    warnings.warn(
        f"the record measured its own drift for a {measured.calibration_s:g} s calibration "
        f"window, not the {calibration_s:g} s asked: these bands are the model's alone; "
        f"compute the Allan variance with contrast_span_s={calibration_s:g} for bands that "
        "contain what the record shows",
        UnmeasuredWarning,
        stacklevel=4,
    )
    return True


def direct_part(fit, draws, quantity, bias_start, calibration_s, q, total):
    """``(honest total, measured_s, model total, DriftCheck)``, or ``None`` where the record
    measures nothing of these drift semantics (:mod:`bayes_imu.drift.direct`); at a calibration
    window other than the one the record measured, the model's band with ``measured_s = 0`` (every
    horizon marked extrapolated) and a warning."""
    contrasts = direct_contrasts(fit, quantity, bias_start, calibration_s)
    if contrasts is None:
        if _warn_other_window(fit, quantity, bias_start, calibration_s):
            return total, 0.0, None, None
        return None
    t = draws["t_s"]
    inside = contrasts.covers(t)
    if not inside.any():
        return None
    edf = np.full(t.shape, np.nan)
    edf[inside] = direct_edf(fit, contrasts, t[inside])
    capped = np.minimum(edf, record_edf_floor(contrasts, t))
    check = drift_check(fit, draws, contrasts, edf, capped)
    honest = upper_envelope(q, honest_quantiles(q, total, contrasts.at(t), capped), t)
    return honest, float(contrasts.t_s[-1]), total, check
