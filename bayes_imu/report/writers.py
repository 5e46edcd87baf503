"""The files of a fit, an Allan run, a batch and a drift run, written from result objects.

:class:`FitRequest` is the frozen request of one fit of a log (what ``bayes-imu fit`` parses and
``fit-batch`` hands every log: a :class:`~bayes_imu.allan.pipeline.LogSource` and the fit and
drift options). The writers take results (:class:`~bayes_imu.allan.estimator.AllanResult`,
:class:`~bayes_imu.inference.fit.FitResult`, :class:`~bayes_imu.drift.bands.DriftBands`), never
an ``argparse`` namespace: ``allan.csv`` (:func:`write_allan_csv`), ``drift.csv`` and ``drift.png``
(:func:`drift_outputs`, :func:`write_drift`), ``summary.json`` (assembled here alone:
:func:`axis_summary`, :func:`fit_summary`, :func:`population_summary`), ``batch.json``
(:func:`batch_summary`) and the ``drift`` command's ``drift.csv`` (:func:`write_sigma_csv`).
Every file is written into a staging folder the caller holds (:mod:`bayes_imu.report.output`).
"""

import json
from dataclasses import dataclass

import numpy as np

from .._version import __version__
from ..allan.pipeline import LogSource
from ..drift.bands import DEFAULT_CALIBRATION_S, SENSOR_QUANTITIES, default_times, drift_bands
from ..drift.bands import integrated_unit
from ..drift.display import DISPLAY_CHOICES, display_unit
from ..errors import InputError
from ..inference.likelihood import LIKELIHOODS
from ..noise.model import WORST_AXIS

__all__ = [
    "FitRequest",
    "DriftOutput",
    "write_json",
    "write_allan_csv",
    "drift_outputs",
    "drift_check_summary",
    "write_drift",
    "axis_summary",
    "fit_summary",
    "worst_axis",
    "population_summary",
    "batch_summary",
    "write_sigma_csv",
]


#: longest drift time of a fit's bands when no times are given [s]
DEFAULT_HORIZON_S = 3600.0


@dataclass(frozen=True)
class FitRequest:
    """One fit of a log, as ``bayes-imu fit`` runs it (every option of ``fit`` but where to write).

    Attributes
    ----------
    source : LogSource
        The log and how to read it.
    seed : int
        Random seed (recorded in the outputs).
    terms : "auto" or tuple of str
        Model selection, or these noise terms.
    likelihood, discrepancy : str
        :func:`~bayes_imu.inference.fit.fit_allan`'s options.
    sensor : {"gyro", "accel"} or None
        Also the drift outputs: attitude (gyro), velocity and position (accel).
    horizon : float
        Longest drift time (s).
    bias_start : str
        Bias at the start of the outage (:func:`~bayes_imu.drift.bands.drift_bands`).
    calibration : float
        Calibration window (s) of ``bias_start="calibrated"``.
    models : {"averaged", "selected"}
        Drift from every candidate model by probability, or the selected model alone.
    times : tuple of float or None
        Drift rows at exactly these times (s) instead of a log grid up to ``horizon``.
    display_units : {"si", "deg"}
        Units of the drift outputs.
    datasheet : tuple or None
        ``(path, kind, values)`` of a vendor datasheet to check the fit against
        (:mod:`bayes_imu.noise.datasheet_check`).
    """

    source: LogSource
    seed: int = 0
    terms: object = "auto"
    likelihood: str = LIKELIHOODS[0]
    discrepancy: str = "auto"
    sensor: str = None
    horizon: float = DEFAULT_HORIZON_S
    bias_start: str = "calibrated"
    calibration: float = DEFAULT_CALIBRATION_S
    models: str = "averaged"
    times: tuple = None
    display_units: str = "si"
    datasheet: tuple = None

    def __post_init__(self):
        # before the log is read: degrees are a gyro's (an accelerometer's drift has no angle)
        if self.display_units not in DISPLAY_CHOICES:
            raise InputError(f"display_units={self.display_units!r}: expected one of "
                             f"{', '.join(DISPLAY_CHOICES)}")
        if self.times is not None and self.horizon != DEFAULT_HORIZON_S:
            raise InputError(f"horizon={self.horizon:g} and times: give one (times: drift rows at "
                             "exactly those times; horizon: a log grid up to it)")
        if self.display_units == "deg" and self.sensor == "accel":
            raise InputError("display_units='deg' shows a gyro's rates and angles in degrees; an "
                             "accelerometer (sensor='accel') has none: use 'si'")


@dataclass(frozen=True)
class DriftOutput:
    """The drift bands of a fit in their display units, and their values at the horizon.

    Attributes
    ----------
    bands : tuple of DriftBands
        One per quantity of the sensor, scaled to ``units``.
    units : tuple of str
        Display unit of each band.
    at_horizon : dict
        Per quantity: q05/q50/q95 of the 1-sigma drift at the last time and how it was computed
        (``summary.json``'s ``drift``).
    """

    bands: tuple
    units: tuple
    at_horizon: dict


def drift_check_summary(result, request, unit, drift=None):
    """``summary.json``'s ``adequacy.drift``: the drift the record shows against the bands
    (:mod:`bayes_imu.drift.direct`), and the check itself (``None`` where nothing is measured).

    The check of the first band that has one when ``drift`` (a :class:`DriftOutput`) was computed,
    else the attitude-unit check at the request's horizons. An accelerometer's position band
    (integration order 2, measured by the record too) adds its own check as ``position``.
    """
    from ..drift.direct import record_drift_check, unmeasured_reason

    reason = unmeasured_reason(result, request.bias_start, request.calibration)
    check = shown = None
    extra = {}
    if drift is not None:
        found = [(b.check, u, b.quantity) for b, u in zip(drift.bands, drift.units)
                 if b.check is not None]
        check, shown = found[0][:2] if found else (None, None)
        extra = {q: {"available": True, **c.to_dict(u)} for c, u, q in found[1:]
                 if q == "position"}
    elif reason is None:
        t = (np.array(request.times) if request.times is not None
             else default_times(result.model.dt, request.horizon))
        check = record_drift_check(result, t, calibration_s=request.calibration,
                                   models=request.models, rng=request.seed)
        shown = integrated_unit(unit, "attitude")
    if check is None:
        why = reason or "no requested horizon within the spans the log measures"
        return {"available": False, "reason": why}, None
    return {"available": True, **check.to_dict(shown), **extra}, check


def write_json(path, doc):
    """``doc`` as indented JSON (no NaN: a non-finite number is an error, not invalid JSON)."""
    path.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")


def write_allan_csv(result, path, *, unit):
    """``allan.csv``: tau (s), cluster size, ADEV with its interval, EDF and the unit."""
    lines = ["tau,m,adev,adev_low,adev_high,edf,unit"]
    lines += [
        f"{t:.9g},{m},{a:.9g},{lo:.9g},{hi:.9g},{e:.6g},{unit}"
        for t, m, a, lo, hi, e in zip(
            result.tau, result.m, result.adev, result.adev_low, result.adev_high, result.edf
        )
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def drift_outputs(result, request, unit):
    """The drift bands ``request`` asks of ``result`` (a FitResult or UnitPosterior in ``unit``).

    Raises
    ------
    InputError
        ``display_units="deg"`` for a fit that is not a gyro in rad/s.
    """
    if request.display_units == "deg" and unit != "rad/s" and request.sensor == "gyro":
        raise InputError(
            f"display_units='deg' needs a gyro fitted in SI (give units); this fit is in {unit!r}"
        )
    t = (
        np.array(request.times)
        if request.times is not None
        else default_times(result.model.dt, request.horizon)
    )
    quantities = SENSOR_QUANTITIES[request.sensor]
    shown = [display_unit(integrated_unit(unit, q), request.display_units) for q in quantities]
    bands = [
        drift_bands(
            result,
            t,
            quantity=q,
            bias_start=request.bias_start,
            calibration_s=request.calibration,
            models=request.models,
            rng=request.seed,
        ).scaled(factor)
        for q, (_, factor) in zip(quantities, shown)
    ]
    at_horizon = {}
    for b, (u, _) in zip(bands, shown):
        at_horizon[b.quantity] = {
            "t_s": float(b.t_s[-1]),
            "q05": float(b.total[0][-1]),
            "q50": float(b.total[1][-1]),
            "q95": float(b.total[2][-1]),
            "unit": u,
            "record_s": b.record_s,
            "extrapolated": bool(b.extrapolated[-1]),
            "bias_start": b.bias_start,
            "calibration_s": None if np.isnan(b.calibration_s) else b.calibration_s,
            "models": b.models,
        }
    return DriftOutput(tuple(bands), tuple(u for u, _ in shown), at_horizon)


def write_drift(drift, folder, *, submit=None):
    """``drift.csv`` and ``drift.png`` of a :class:`DriftOutput` into ``folder``; the figure through
    ``submit(fn, *args, **kwargs)`` where given (the output process), else drawn here."""
    from .plots import plot_drift

    lines = ["t_s,quantity,q05,q50,q95,unit,extrapolated"]
    for b, u in zip(drift.bands, drift.units):
        lines += [
            # whole samples: exact
            f"{ti:.10g},{b.quantity},{lo:.9g},{med:.9g},{hi:.9g},{u},{str(x).lower()}"
            for ti, lo, med, hi, x in zip(b.t_s, *b.total, b.extrapolated)
        ]
    (folder / "drift.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    (submit or _call)(plot_drift, list(drift.bands), folder / "drift.png", units=list(drift.units))


def _call(fn, *args, **kwargs):
    return fn(*args, **kwargs)


def axis_summary(result, *, unit, info, column, drift=None):
    """``summary.json`` of one column's fit: the fit's own summary, what was read, and the drift."""
    summary = result.summary(unit=unit)
    summary.update(log=info["log"], column=column, unit=unit, input=info)
    if drift is not None:
        summary["drift"] = drift.at_horizon
    return summary


def fit_summary(axes, *, info, seed, folders=None):
    """``summary.json`` of a fit: the one axis's :func:`axis_summary`, or for several columns each
    axis's (with its sub-folder), the worst axis of each amplitude and drift, and what was read."""
    if len(axes) == 1:
        return next(iter(axes.values()))
    axes = {
        column: dict(summary, folder=folder)
        for (column, summary), folder in zip(axes.items(), folders)
    }
    return {
        "axes": axes,
        "worst_axis": worst_axis(axes),
        "input": info,
        "seed": seed,
        "bayes_imu_version": __version__,
    }


def worst_axis(axes):
    """Per amplitude parameter (each term's :attr:`~bayes_imu.noise.Term.worst_axis`), the
    largest upper (q95) value over the axes, and which axis; the same for each drift quantity."""
    worst = {}
    for name in WORST_AXIS:
        have = {c: s["parameters"][name] for c, s in axes.items() if name in s["parameters"]}
        if have:
            axis = max(have, key=lambda c: have[c]["q95"])
            worst[name] = {"q95": have[axis]["q95"], "axis": axis, "unit": have[axis]["unit"]}
    for quantity in ("attitude", "velocity", "position"):
        have = {c: s["drift"][quantity] for c, s in axes.items() if quantity in s.get("drift", {})}
        if have:
            axis = max(have, key=lambda c: have[c]["q95"])
            worst[f"drift_{quantity}"] = {**have[axis], "axis": axis}
    return worst


def population_summary(population, *, unit, column, infos, drift=None):
    """``summary.json`` of a population fit (``fit-population``)."""
    summary = population.summary(unit=unit)
    summary.update(column=column, unit=unit, logs=[i["log"] for i in infos], input=infos)
    if drift is not None:
        summary["drift"] = drift.at_horizon
    return summary


def fit_checks(summary):
    """What a fit's ``summary.json`` (one axis) says of its own reliability: ``converged`` (the
    sampler), ``adequate`` (the model describes the log; ``None`` where not checked) and
    ``stationary`` (the log's parts agree; ``None`` where not checked)."""
    adequacy = summary.get("adequacy") or {}
    stationarity = adequacy.get("stationarity") or {}
    return {"converged": bool(summary["diagnostics"]["converged"]),
            "adequate": adequacy.get("adequate"),
            "stationary": stationarity.get("stationary")}


def batch_summary(results, logs, folder, *, seconds, scheduler, seed):
    """``batch.json`` of a batch: each log's outcome, and the throughput (the fitted logs' samples
    are read from their ``summary.json`` in ``folder/<job name>``)."""
    samples = 0
    entries = []
    for r, log in zip(results, logs):
        entry = dict(r.to_json(), log=str(log))
        if r.fitted:
            summary = json.loads((folder / r.name / "summary.json").read_text())
            axes = summary["axes"] if "axes" in summary else {summary["column"]: summary}
            samples += sum(a["n_samples"] for a in axes.values())
            entry["checks"] = {column: fit_checks(a) for column, a in axes.items()}
        entries.append(entry)
    failed = [r for r in results if not r.fitted]
    flagged = [e["checks"] for e in entries if "checks" in e]
    return {
        "logs": entries,
        "n_logs": len(results),
        "n_failed": len(failed),
        # fitted logs with an axis whose sampler did not converge / whose model does not describe
        # it (each log's own summary.json says which and why)
        "n_unconverged": sum(any(not c["converged"] for c in f.values()) for f in flagged),
        "n_inadequate": sum(any(c["adequate"] is False for c in f.values()) for f in flagged),
        "seconds": seconds,
        "logs_per_minute": 60 * len(results) / seconds,
        "samples_per_second": samples / seconds,
        "scheduler": scheduler or "LocalCluster",
        "seed": seed,
        "bayes_imu_version": __version__,
    }


def write_sigma_csv(results, units, factors, path):
    """The ``drift`` command's ``drift.csv``: each
    :class:`~bayes_imu.drift.closed_forms.DriftResult` (one per quantity) times its display
    ``factor``, in its display unit."""
    lines = ["t_s,quantity,white,bias,random_walk,total,unit"]
    for result, unit, f in zip(results, units, factors):
        lines += [
            f"{ti:.6g},{result.quantity},{w * f:.9g},{b * f:.9g},{r * f:.9g},{tot * f:.9g},{unit}"
            for ti, w, b, r, tot in zip(
                result.t_s, result.white, result.bias, result.random_walk, result.total
            )
        ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
