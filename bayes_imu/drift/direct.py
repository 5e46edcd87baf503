"""The drift the record itself shows: a drift-space adequacy check and bands honest within the
record.

For a calibrated outage (``bias_start="calibrated"``) of attitude or velocity the error is a
fixed contrast of the phase record, and of position a fixed contrast of the phase record and its
running sum, whose mean squares the log measures without a model
(:mod:`bayes_imu.allan.contrast`, ``V_hat``; unbiased for any noise with stationary increments).
Under a model, ``V_hat ~ V chi2_nu / nu`` with ``V`` the model's mean-square drift and ``nu`` the
EDF of :func:`bayes_imu.noise.contrast_covariance.contrast_edf`.

The check (:func:`drift_check`), per requested horizon the record covers: the posterior
predictive p-value ``p = 2 min(u, 1 - u)``, ``u = mean_i F_nu(nu V_hat / V_i)`` over posterior
draws ``V_i`` (model-averaged, as the bands). Over horizons, Simes' combination
``min_i n p_(i) / i`` (valid under the positive dependence of nested horizons) is compared with
:data:`DRIFT_ALPHA`.

Honest bands (:func:`honest_quantiles`; derivation in docs/reference.md, "Bands the record
measures"): within the record, each lower quantile ``q < 1/2`` of the band is the smaller of the
model's and the direct one, ``sqrt(nu V_hat / chi2_nu^{-1}(1 - q))``, each upper quantile the larger
(the median stays the model's). The band then contains the data's own interval for the true drift,
which covers it with probability ``1 - 2 q`` whatever the noise (given ``nu``), so the band covers
at least that often whether or not the model is right. The interval's ``nu`` is the model's EDF
capped at :func:`record_edf_floor`, the number of disjoint contrasts the record holds (a bound that
needs no model: the model's EDF is right only where the model is). Beyond the record the band is
the model's
extrapolation alone (:attr:`bayes_imu.drift.bands.DriftBands.extrapolated`).
"""

from dataclasses import dataclass

import numpy as np

from .._lazy import LazyModule
from .closed_forms import QUANTITY_ORDER
from ..allan.contrast import contrast_stride
from ..noise.contrast_covariance import contrast_edf

special = LazyModule("scipy.special")

__all__ = [
    "DriftCheck",
    "drift_check",
    "direct_contrasts",
    "direct_edf",
    "honest_quantiles",
    "upper_envelope",
    "record_drift_check",
    "unmeasured_reason",
    "same_window",
    "record_edf_floor",
    "DRIFT_ALPHA",
]

#: false-alarm rate of the drift-space check on a correct model
DRIFT_ALPHA = 0.05
#: posterior draws of the predictive p-value
_CHECK_DRAWS = 1000
#: outages per decade at which the EDF is computed exactly (interpolated between)
_EDF_PER_DECADE = 4


@dataclass(frozen=True)
class DriftCheck:
    """Drift-space adequacy check of a fit at the horizons its record covers.

    Attributes
    ----------
    t_s : (n_t,) ndarray
        Horizons checked [s].
    direct, direct_low, direct_high : (n_t,) ndarray
        1-sigma drift measured from the record and its 90% interval [unit x s] (EDF
        :attr:`edf_interval`: what the honest band contains).
    edf : (n_t,) ndarray
        EDF of the direct estimate under the fitted model (the check's null).
    model_q05, model_q50, model_q95 : (n_t,) ndarray
        The model's band there [unit x s] (before any honest widening).
    p_value : (n_t,) ndarray
        Posterior predictive p-value per horizon (module docstring).
    p_combined : float
        Simes' combination over horizons.
    calibration_s : float
    edf_interval : (n_t,) ndarray
        EDF of the record's interval: :attr:`edf` capped at :func:`record_edf_floor`.
    """

    t_s: np.ndarray
    direct: np.ndarray
    direct_low: np.ndarray
    direct_high: np.ndarray
    edf: np.ndarray
    model_q05: np.ndarray
    model_q50: np.ndarray
    model_q95: np.ndarray
    p_value: np.ndarray
    p_combined: float
    calibration_s: float
    edf_interval: np.ndarray = None

    def scaled(self, factor):
        """The same check in another unit (drift values times ``factor``)."""
        from dataclasses import replace

        f = abs(factor)
        return replace(
            self,
            direct=self.direct * f,
            direct_low=self.direct_low * f,
            direct_high=self.direct_high * f,
            model_q05=self.model_q05 * f,
            model_q50=self.model_q50 * f,
            model_q95=self.model_q95 * f,
        )

    def _edf_interval(self):
        return self.edf if self.edf_interval is None else self.edf_interval

    @property
    def adequate(self):
        return bool(not (self.p_combined < DRIFT_ALPHA))

    @property
    def worst_t_s(self):
        return float(self.t_s[np.argmin(self.p_value)]) if self.t_s.size else float("nan")

    def to_dict(self, unit=None, factor=1.0):
        """JSON-ready (drift values times ``factor``, in ``unit``)."""
        rows = [{"t_s": float(t), "direct": float(d * factor), "direct_q05": float(lo * factor),
                 "direct_q95": float(hi * factor), "edf": float(e), "model_q05": float(a * factor),
                 "model_q50": float(b * factor), "model_q95": float(c * factor),
                 "p_value": float(p), "edf_interval": float(ei)}
                for t, d, lo, hi, e, a, b, c, p, ei in zip(
                    self.t_s, self.direct, self.direct_low, self.direct_high, self.edf,
                    self.model_q05, self.model_q50, self.model_q95, self.p_value,
                    self._edf_interval())]
        return {
            "adequate": self.adequate,
            "p_value": float(self.p_combined),
            "alpha": DRIFT_ALPHA,
            "worst_t_s": self.worst_t_s,
            "calibration_s": float(self.calibration_s),
            "unit": unit,
            "horizons": rows,
        }


def same_window(contrasts, calibration_s):
    """Whether the record's contrasts were measured for this calibration window [s] (in samples)."""
    return round(calibration_s * contrasts.rate_hz) == contrasts.n_cal


def direct_contrasts(fit, quantity, bias_start, calibration_s):
    """The fit's record contrasts of ``quantity``'s integration order (attitude / velocity: 1,
    position: 2, :meth:`~bayes_imu.allan.contrast.PhaseContrasts.of_order`) when they answer these
    drift semantics, else ``None``."""
    contrasts = getattr(getattr(fit, "allan", None), "contrasts", None)
    if (contrasts is None or bias_start != "calibrated" or quantity not in QUANTITY_ORDER
            or contrasts.k.size == 0 or not same_window(contrasts, calibration_s)):
        return None
    contrasts = contrasts.of_order(QUANTITY_ORDER[quantity])
    return None if contrasts is None or contrasts.k.size == 0 else contrasts


def _reference_point(fit):
    """``(NoiseModel, params)``: the median draw of the most probable model-averaged component."""
    from ..noise import NoiseModel

    parts = [(NoiseModel(c.terms, fit.model.dt), c.samples, c.probability) for c in fit.mixture]
    if not parts:
        parts = [(fit.model, fit.samples[:, :len(fit.model.parameter_names)], 1.0)]
    model, samples, _ = max(parts, key=lambda p: p[2])
    return model, model.unpack(np.median(samples, axis=0))


def direct_edf(fit, contrasts, t):
    """EDF of the record's direct estimate at outages ``t`` [s] under the fit's reference point:
    exact at up to :data:`_EDF_PER_DECADE` outages per decade spanning ``t``, interpolated in
    log-log between them (the EDF is smooth in the outage length); the contrasts'
    :attr:`~bayes_imu.allan.contrast.PhaseContrasts.order` says which contrast."""
    model, params = _reference_point(fit)
    k = np.round(np.asarray(t, dtype=float) * contrasts.rate_hz)
    lo, hi = k.min(), k.max()
    nodes = np.unique(
        np.round(np.geomspace(lo, hi, max(2, int(np.log10(hi / lo) * _EDF_PER_DECADE) + 2)))
    )
    order = getattr(contrasts, "order", 1)
    if nodes.size >= k.size:
        return contrast_edf(model, params, k, contrasts.n_cal, contrasts.n_samples,
                            contrast_stride(k, contrasts.n_cal), order=order)
    edf = contrast_edf(model, params, nodes, contrasts.n_cal, contrasts.n_samples,
                       contrast_stride(nodes, contrasts.n_cal), order=order)
    return np.exp(np.interp(np.log(k), np.log(nodes), np.log(edf)))


def record_edf_floor(contrasts, t):
    """The EDF the record supports without a model at outages ``t`` [s]: ``floor(n / (k + N))``,
    the number of disjoint contrasts (spans ``k + N`` samples) in the ``n``-sample record, at
    least 1 (either order: the position contrast's span ``k - 1 + N`` is shorter still).

    The overlapping average is the mean of the ``k + N`` disjoint-start averages (one per offset),
    which are identically distributed, so its variance is at most one of theirs (Cauchy-Schwarz);
    a disjoint average of ``D`` squared contrasts has EDF ``D`` when they are uncorrelated (Gaussian
    contrasts: ``Var e^2 = 2 V^2``). For noises without spectral lines the contrasts of disjoint
    spans are nearly uncorrelated (the contrast annihilates constants and trends of the phase): the
    exact EDF is 1.75-37 times this floor (``scripts/edf_floor_ratio.py``; about 2 for a random walk
    of the rate or a slow bias, up to the strided starts' count for white noise far from ``k = N``).
    A conservative cap on a model's EDF, which can be far too large when the model misses a slow
    term.
    """
    k = np.round(np.asarray(t, dtype=float) * contrasts.rate_hz)
    return np.maximum(1.0, np.floor(contrasts.n_samples / (k + contrasts.n_cal)))


def honest_quantiles(quantiles, total, mean_square, edf):
    """The band's quantiles widened to contain the record's own interval (module docstring).

    Parameters
    ----------
    quantiles : (n_q,) probabilities
    total : (n_q, n_t) the model's quantiles of the 1-sigma drift
    mean_square, edf : (n_t,) the direct estimate (``nan`` where not measured) and its EDF

    Returns
    -------
    (n_q, n_t) ndarray
    """
    q = np.asarray(quantiles, dtype=float)[:, None]
    nu = np.where(np.isfinite(mean_square), edf, 1.0)
    # P(chi2_nu > c) = q
    direct = np.sqrt(nu * mean_square / special.gammainccinv(nu / 2.0, q) / 2.0)
    lower = np.where(np.isfinite(direct), np.minimum(total, direct), total)
    upper = np.where(np.isfinite(direct), np.maximum(total, direct), total)
    return np.where(q < 0.5, lower, np.where(q > 0.5, upper, total))


def upper_envelope(quantiles, band, t):
    """The band with its upper quantiles (``q > 0.5``) made non-decreasing in outage time: each the
    largest it is at ``t`` or any shorter outage.

    The record's interval widens the band where the record measures the drift, most at the longest
    horizons it measures (where it holds only a few disjoint spans); just beyond them the band is
    the model's again, whose upper edge can lie below the widened one: a band that would claim
    more certainty about a longer outage, which the record did not support about a shorter one.
    The drift error of a longer outage is not smaller (its variance grows with the outage for
    every noise term but a vibration line, whose ripple this covers): the upper edge is carried
    forward until the model's overtakes it. Lower quantiles and the median are unchanged.

    Parameters
    ----------
    quantiles : (n_q,) probabilities
    band : (n_q, n_t) quantiles of the 1-sigma drift
    t : (n_t,) outage times [s]

    Returns
    -------
    (n_q, n_t) ndarray
    """
    out = np.array(band, dtype=float, copy=True)
    up = np.flatnonzero(np.asarray(quantiles, dtype=float) > 0.5)
    order = np.argsort(np.asarray(t, dtype=float), kind="stable")
    for i in up:
        out[i, order] = np.maximum.accumulate(out[i, order])
    return out


def drift_check(fit, draws, contrasts, edf, edf_interval=None):
    """:class:`DriftCheck` from drift draws (:func:`bayes_imu.drift.bands.drift_draws` output).

    ``draws["t_s"]`` are the horizons; only those ``contrasts`` covers are checked. ``edf`` (the
    model's) gives the p-values, ``edf_interval`` (default ``edf``) the record's interval.
    """
    t = np.asarray(draws["t_s"], dtype=float)
    inside = contrasts.covers(t)
    total = draws["total"][:, inside]
    if total.shape[0] > _CHECK_DRAWS:
        total = total[np.linspace(0, total.shape[0] - 1, _CHECK_DRAWS).astype(int)]
    v_hat = contrasts.at(t[inside])
    nu = np.asarray(edf, dtype=float)[inside]
    u = np.mean(special.gammainc(nu / 2.0, nu * v_hat / (2.0 * total**2)), axis=0)
    p = np.minimum(1.0, 2.0 * np.minimum(u, 1.0 - u))
    order = np.sort(p)
    simes = float(np.min(order * p.size / np.arange(1, p.size + 1))) if p.size else 1.0
    band = np.quantile(draws["total"][:, inside], [0.05, 0.5, 0.95], axis=0)
    nu_i = nu if edf_interval is None else np.asarray(edf_interval, dtype=float)[inside]
    low = np.sqrt(nu_i * v_hat / (2.0 * special.gammainccinv(nu_i / 2.0, 0.05)))
    high = np.sqrt(nu_i * v_hat / (2.0 * special.gammainccinv(nu_i / 2.0, 0.95)))
    return DriftCheck(t[inside], np.sqrt(v_hat), low, high, nu, *band, p, min(1.0, simes),
                      contrasts.calibration_s, nu_i)


def unmeasured_reason(fit, bias_start, calibration_s, quantity="attitude"):
    """Why the record measures none of these drift semantics for ``quantity`` (``None`` where it
    does)."""
    contrasts = getattr(getattr(fit, "allan", None), "contrasts", None)
    if bias_start != "calibrated":
        return f"the record measures calibrated outages only (bias start {bias_start!r})"
    if contrasts is None:
        return "the log's samples were not kept (an Allan table, or a log read out of core)"
    if not same_window(contrasts, calibration_s):
        return (
            f"measured for a {contrasts.calibration_s:g} s calibration window, not "
            f"{calibration_s:g} s"
        )
    if contrasts.k.size == 0:
        return f"the log is shorter than twice the {calibration_s:g} s calibration window"
    if contrasts.of_order(QUANTITY_ORDER.get(quantity, 1)) is None:
        return f"the saved fit holds no measured {quantity} drift (saved before it was measured)"
    return None


def record_drift_check(
    fit,
    t,
    *,
    bias_start="calibrated",
    calibration_s=60.0,
    models="averaged",
    rng=None,
    max_draws=_CHECK_DRAWS,
    quantity="attitude",
):
    """The :class:`DriftCheck` of ``fit`` at horizons ``t`` [s] of ``quantity`` (attitude /
    velocity: order 1, position: order 2), or ``None`` where the record measures nothing of these
    semantics (:func:`unmeasured_reason`); ``max_draws`` posterior draws (a random subset,
    ``rng``)."""
    from .bands import drift_bands

    if unmeasured_reason(fit, bias_start, calibration_s, quantity) is not None:
        return None
    t = np.asarray(t, dtype=float)
    inside = fit.allan.contrasts.of_order(QUANTITY_ORDER[quantity]).covers(t)
    if not inside.any():
        return None
    return drift_bands(
        fit,
        t[inside],
        quantity=quantity,
        bias_start=bias_start,
        calibration_s=calibration_s,
        models=models,
        rng=rng,
        max_draws=max_draws,
    ).check
