"""How long to record: predicted 90% intervals of parameters and drift versus record length.

The answer is the Fisher information of the Allan-variance likelihood the fit itself uses
(``likelihood="correlated"``, :class:`bayes_imu.inference.likelihood.LogPosterior`): a
normal likelihood on ``log AVAR`` at the octave cluster sizes a record of ``N`` samples
gets (1, 2, 4, ... up to ``N / 4``), with the exact covariance of the estimates
(:func:`bayes_imu.noise.avar_covariance.avar_covariance`) at the planning point. With
``J = d log AVAR / d log theta`` and ``W`` the likelihood's whitening matrix,
``F = (W J)' (W J)`` and the posterior covariance of the log-parameters is predicted as
``F^-1`` (flat prior in log space, the fit's own). The 90% interval of a parameter is then
``theta exp(+-1.645 sd)``, reported as its width ratio ``q95 / q05 = exp(3.29 sd)``; the
drift's (1-sigma drift at a horizon, bias calibrated before the outage as in the reports)
by the delta method on ``log sigma(t)``.

Why Fisher rather than simulate-and-fit: a plan over eight record lengths costs
milliseconds, against minutes of sampling per length (a 48 h log at 100 Hz is 17 million
samples); ``scripts/validate_plan.py`` checks the prediction against simulate-and-fit
(docs/validation/plan.md). What it leaves out: prior bounds (a parameter the record cannot
identify has a prior-limited interval, narrower than predicted), model selection (the plan
is for the pilot's model), and non-stationarity.
"""

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ..allan.estimator import cluster_sizes
from ..errors import InputError
from ..inference.likelihood import LogPosterior
from ..noise import NoiseModel
from ..noise.avar_covariance import avar_covariance
from .bands import DEFAULT_CALIBRATION_S
from .closed_forms import QUANTITY_ORDER

__all__ = ["PlanResult", "plan_record_length", "plan_from_fit", "DEFAULT_LENGTHS_S", "Z90",
           "MAX_PLAN_SAMPLES", "PilotCheck", "pilot_check", "PILOT_EXCESS"]

#: default record lengths: 10 min, 30 min, 1 h, 2 h, 4 h, 8 h, 24 h, 48 h [s]
#: longest record a plan predicts, in samples (48 h at 1.5 kHz; the covariance of the Allan
#: variance needs tables of a few bytes per sample: 1e9 s at 100 Hz asked for 512 GiB, issue 37)
MAX_PLAN_SAMPLES = 2**28
DEFAULT_LENGTHS_S = (600.0, 1800.0, 3600.0, 7200.0, 14400.0, 28800.0, 86400.0, 172800.0)
#: standard normal 95% quantile (half-width of a 90% interval in sd)
Z90 = 1.6448536269514722
_STEP = 1e-4


@dataclass(frozen=True)
class PlanResult:
    """Predicted 90% intervals versus record length.

    Attributes
    ----------
    lengths_s : (n_len,) record lengths [s].
    names : tuple of str
        Parameter names (``model.parameter_names``).
    point : dict
        Name -> the planning value (u units of the parameter).
    log_sd : (n_len, n_par)
        Predicted posterior sd of each ``ln(parameter)``.
    horizons_s : (n_h,) drift horizons [s].
    quantity : str or None
    drift : (n_h,) the 1-sigma drift at the planning point [u s^order].
    drift_log_sd : (n_len, n_h)
        Predicted posterior sd of ``ln sigma(t)``.
    rate_hz : float
    """

    lengths_s: np.ndarray
    names: tuple
    point: dict
    log_sd: np.ndarray
    horizons_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    quantity: str = None
    drift: np.ndarray = field(default_factory=lambda: np.zeros(0))
    drift_log_sd: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    rate_hz: float = float("nan")

    @property
    def width90(self):
        """``(n_len, n_par)`` predicted ``q95 / q05`` of each parameter."""
        return np.exp(2.0 * Z90 * self.log_sd)

    @property
    def drift_width90(self):
        """``(n_len, n_h)`` predicted ``q95 / q05`` of the drift at each horizon."""
        return np.exp(2.0 * Z90 * self.drift_log_sd)

    def rows(self):
        """Table rows: dicts with ``length_s``, ``what``, ``value`` (planning point), ``q05``,
        ``q95``, ``width90``."""
        out = []
        for i, length in enumerate(self.lengths_s):
            for j, name in enumerate(self.names):
                v, s = self.point[name], self.log_sd[i, j]
                out.append(
                    {
                        "length_s": float(length),
                        "what": name,
                        "value": v,
                        "q05": v * np.exp(-Z90 * s),
                        "q95": v * np.exp(Z90 * s),
                        "width90": float(np.exp(2 * Z90 * s)),
                    }
                )
            for j, t in enumerate(self.horizons_s):
                v, s = float(self.drift[j]), self.drift_log_sd[i, j]
                out.append(
                    {
                        "length_s": float(length),
                        "what": f"{self.quantity} drift at {t:g} s",
                        "value": v,
                        "q05": v * np.exp(-Z90 * s),
                        "q95": v * np.exp(Z90 * s),
                        "width90": float(np.exp(2 * Z90 * s)),
                    }
                )
        return out


def _log_avar_jacobian(post, log_theta):
    """``(n_tau, n_par)`` central differences of ``log AVAR`` in each log-parameter."""
    steps = np.eye(log_theta.size) * _STEP
    up = post.model_log_avar(log_theta + steps)
    down = post.model_log_avar(log_theta - steps)
    return ((up - down) / (2.0 * _STEP)).T


def _log_drift(model, theta, k, order, n_cal):
    params = model.unpack(theta)
    total = sum(
        t.drift_variance(order, k, params, model.dt, bias_start="calibrated", n_cal=n_cal)
        for t in model.components
    )
    return 0.5 * np.log(total)


def _fisher(model, params, n_samples):
    m = cluster_sizes("octave", int(n_samples))
    theta = np.array([params[p] for p in model.parameter_names], float)
    avar = model.avar(m, params)
    cov = avar_covariance(model, params, m, int(n_samples))
    allan = SimpleNamespace(m=m, avar=avar, n_samples=int(n_samples))
    bounds = np.column_stack([np.log(theta) - 1.0, np.log(theta) + 1.0])
    post = LogPosterior.from_covariance(model, allan, cov, avar, bounds)
    wj = post.whiten @ _log_avar_jacobian(post, np.log(theta))
    return wj.T @ wj


def plan_record_length(
    model,
    params,
    *,
    lengths_s=DEFAULT_LENGTHS_S,
    horizons_s=(),
    quantity=None,
    calibration_s=DEFAULT_CALIBRATION_S,
):
    """Predicted posterior spread of each parameter (and drift) for records of ``lengths_s``.

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        The planning point (a pilot fit's medians, or datasheet values), units of the model.
    lengths_s : sequence of float
        Record lengths [s]; each must give at least 16 samples.
    horizons_s : sequence of float
        Drift horizons [s] (needs ``quantity``).
    quantity : {"attitude", "velocity", "position"}, optional
    calibration_s : float
        Bias calibration window before an outage [s].

    Returns
    -------
    PlanResult
    """
    if not isinstance(model, NoiseModel):
        raise InputError("model: expected a NoiseModel")
    missing = [
        p
        for p in model.parameter_names
        if not (p in params and np.isfinite(params[p]) and params[p] > 0)
    ]
    if missing:
        raise InputError(f"params: expected positive values of {', '.join(missing)}")
    lengths = np.asarray(lengths_s, float)
    n = np.round(lengths / model.dt)
    if lengths.ndim != 1 or lengths.size == 0 or np.any(~np.isfinite(lengths) | (n < 16)):
        raise InputError(
            f"lengths={lengths_s!r}: expected record lengths of at least 16 samples "
            f"({16 * model.dt:g} s)"
        )
    if np.any(n > MAX_PLAN_SAMPLES):  # the AVAR covariance's tables grow with the record
        raise InputError(
            f"lengths={tuple(lengths_s)[:8]!r}: expected records of at most "
            f"{MAX_PLAN_SAMPLES:.4g} samples ({MAX_PLAN_SAMPLES * model.dt:.4g} s at this rate)"
        )
    horizons = np.asarray(horizons_s, float)
    if horizons.size and (
        quantity not in QUANTITY_ORDER or np.any(~np.isfinite(horizons) | (horizons < model.dt))
    ):
        raise InputError(
            f"horizons={horizons_s!r}, quantity={quantity!r}: expected horizons of at least "
            "one sample "
            f"and a quantity ({', '.join(QUANTITY_ORDER)})"
        )
    theta = np.array([params[p] for p in model.parameter_names], float)
    k = np.round(horizons / model.dt)
    n_cal = float(np.round(calibration_s / model.dt))
    grad = np.zeros((k.size, theta.size))
    if k.size:
        order = QUANTITY_ORDER[quantity]
        for j in range(theta.size):
            step = np.zeros(theta.size)
            step[j] = _STEP
            grad[:, j] = (
                _log_drift(model, theta * np.exp(step), k, order, n_cal)
                - _log_drift(model, theta * np.exp(-step), k, order, n_cal)
            ) / (2 * _STEP)
    log_sd, drift_sd = [], []
    for count in n:
        cov = np.linalg.inv(_fisher(model, dict(zip(model.parameter_names, theta)), count))
        log_sd.append(np.sqrt(np.diag(cov)))
        drift_sd.append(np.sqrt(np.einsum("hi,ij,hj->h", grad, cov, grad)))
    drift = (
        np.exp(_log_drift(model, theta, k, QUANTITY_ORDER[quantity], n_cal))
        if k.size
        else np.zeros(0)
    )
    return PlanResult(
        lengths,
        model.parameter_names,
        dict(zip(model.parameter_names, theta.tolist())),
        np.array(log_sd),
        horizons,
        quantity if k.size else None,
        drift,
        np.array(drift_sd).reshape(lengths.size, k.size),
        1.0 / model.dt,
    )


def plan_from_fit(fit, **options):
    """:func:`plan_record_length` at a pilot fit's posterior medians (its selected model)."""
    params = {p: float(np.median(fit.draws(p))) for p in fit.model.parameter_names}
    return plan_record_length(fit.model, params, **options)


#: a pilot's own interval this much wider than predicted at its length is reported
PILOT_EXCESS = 1.25


@dataclass(frozen=True)
class PilotCheck:
    """A pilot's own 90% intervals against the plan's prediction at the pilot's length.

    Attributes
    ----------
    length_s : float
        The pilot's record length [s].
    names : tuple of str
    record : (n_par,) ndarray
        Upper half-width ``q95 / q50 - 1`` of each parameter's 90% interval from the record alone
        (summary.json ``parameters_this_record``; the model discrepancy included where the fit
        was widened): what the plan predicts, where the model describes the log.
    reported : (n_par,) ndarray
        The same as the pilot reports it (summary.json ``parameters``: the repeatability between
        the record's parts included).
    predicted : (n_par,) ndarray
        The plan's ``exp(1.645 sd) - 1`` at the pilot's length.
    stationary : bool
        The pilot's stationarity check passed (its parts agree).
    widened : bool
        The pilot's fit needed a model discrepancy (its adequacy check failed).
    """

    length_s: float
    names: tuple
    record: np.ndarray
    reported: np.ndarray
    predicted: np.ndarray
    stationary: bool = True
    widened: bool = False

    def ratio(self, which="record"):
        """``(n_par,)`` the pilot's log half-widths (``"record"`` or ``"reported"``) over the
        predicted ones (``> 1``: the pilot is wider)."""
        return np.log1p(getattr(self, which)) / np.log1p(self.predicted)

    def warning(self, label):
        """A line for the user where the pilot's record-alone interval of some parameter is
        :data:`PILOT_EXCESS` times or more as wide as predicted (the model discrepancy), or where
        the pilot failed its stationarity check and reports intervals that much wider (its
        parts' spread); else ``None``. (Intervals widened by the parts' spread of a log that passed
        its check are not flagged: four parts' scatter often exceeds the posterior by chance.)"""
        # the record-alone interval wider than the Fisher prediction: the model discrepancy where
        # the fit was widened, else the posterior itself (several models averaged, or a skewed or
        # weakly identified parameter) against the plan's local Gaussian approximation
        record_why = ("the model discrepancy its fit needed" if self.widened else
                      "its posterior departs from the plan's Gaussian approximation (several "
                      "models averaged, or a skewed or weakly identified parameter)")
        for which, why in (("record", record_why),
                           ("reported", "the spread between the log's parts, which its "
                                        "stationarity check flagged")):
            if which == "reported" and self.stationary:
                continue
            ratio = self.ratio(which)
            worst = int(np.argmax(ratio))
            if ratio[worst] >= PILOT_EXCESS:
                width = getattr(self, which)[worst]
                return (
                    f"[{label}] at the pilot's own length ({self.length_s / 3600.0:.3g} h) its "
                    f"90% interval of {self.names[worst]} is {ratio[worst]:.1f}x as wide as this "
                    f"plan predicts there (+{100 * width:.3g}% against "
                    f"+{100 * self.predicted[worst]:.3g}%): {why}, which the plan leaves out and a "
                    "longer record need not shrink; read the plan's widths as lower bounds"
                )
        return None

    def to_dict(self):
        return {"length_s": float(self.length_s), "stationary": bool(self.stationary),
                "widened": bool(self.widened),
                "record_upper_halfwidth": dict(zip(self.names, map(float, self.record))),
                "reported_upper_halfwidth": dict(zip(self.names, map(float, self.reported))),
                "predicted_upper_halfwidth": dict(zip(self.names, map(float, self.predicted)))}


def pilot_check(fit, *, calibration_s=DEFAULT_CALIBRATION_S):
    """:class:`PilotCheck` of a pilot fit: its intervals from the record alone
    (:meth:`~bayes_imu.inference.fit.FitResult.quantiles`) and as it reports them
    (:meth:`~bayes_imu.inference.fit.FitResult.repeatability_quantiles`, summary.json's
    ``parameters``) against :func:`plan_from_fit` at its own record length.

    The plan is the Fisher information of the record-alone likelihood at the pilot's medians; a
    pilot whose record disagrees between its parts, or whose fit needed a model discrepancy,
    reports wider intervals than that at its own length, and no plan should promise narrower ones
    there. The check says by how much (``scripts/validate_plan.py`` checks the prediction itself
    against simulate-and-fit)."""
    names = tuple(fit.model.parameter_names)
    at = plan_from_fit(fit, lengths_s=[fit.record_s], calibration_s=calibration_s)
    alone, reported = fit.quantiles(), fit.repeatability_quantiles()
    record = np.array([alone[n][2] / alone[n][1] - 1.0 for n in names])
    wide = np.array([reported[n][2] / reported[n][1] - 1.0 for n in names])
    steady = getattr(fit, "stationarity", None)
    return PilotCheck(float(fit.record_s), names, record, wide, np.expm1(Z90 * at.log_sd[0]),
                      steady is None or bool(steady.stationary), bool(fit.widened))
