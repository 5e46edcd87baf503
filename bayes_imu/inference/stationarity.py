"""Is the sensor's noise the same throughout the record? The between-segment check and spread.

A model fitted to one record predicts the drift of a *later* outage only if the noise is
stationary. Real MEMS logs often are not (warm-up, temperature): the Allan deviation at long
averaging times then differs between parts of the record by more than its sampling error, and a
band fitted to the whole record is too narrow for the next hour of the same sensor.

The check (:func:`stationarity_check`) compares the Allan variance of ``K`` consecutive
equal segments (:class:`bayes_imu.allan.estimator.SegmentAllan`, default ``K = 4``). Under the
fitted model each segment's estimate at cluster size ``m`` is ``AVAR(m) chi2_nu / nu`` with
``nu = 2 AVAR^2 / Var`` from the exact AVAR covariance of a segment
(:func:`bayes_imu.noise.avar_covariance.avar_covariance`), so ``ln avar_k(m)`` has variance
``v(m) = psi'(nu / 2)`` (trigamma) and, segments being (nearly) independent,
``Q(m) = sum_k (ln avar_k - mean)^2 / v(m)`` is approximately ``chi2_{K-1}``. Sizes whose
segment EDF is below :data:`MIN_SEGMENT_EDF` (the log-chi-squared is far from normal there) are
left out. The p-value is Bonferroni's ``min(1, n_tau min_m p(m))`` over the sizes kept
(conservative under the correlation between sizes); the log is flagged non-stationary when
it is below :data:`STATIONARITY_ALPHA`.

The spread: the between-segment variance of ``ln avar`` beyond sampling,
``s^2(m) = max(0, S^2(m) - v(m))`` (method of moments, ``S^2`` the sample variance over
the segments), made non-decreasing in ``m`` (a changing sensor moves long averaging times at
least as much as short ones; conservative). Drift bands of a flagged fit
(:func:`bayes_imu.drift.bands.drift_draws`) multiply each draw's 1-sigma drift at horizon ``t`` by
``exp(z s(t) / 2)``, ``z ~ N(0, 1)``: a later outage may fall in a noisier or a quieter part
of the sensor's life, by as much as the record's own parts differ. ``s(t)`` is interpolated
in ``ln tau`` and held constant beyond the sizes checked.
"""

from dataclasses import dataclass

import numpy as np

from .._lazy import LazyModule
from ..noise.avar_covariance import avar_covariance, equivalent_dof

special = LazyModule("scipy.special")

__all__ = [
    "Stationarity",
    "stationarity_check",
    "segment_test",
    "STATIONARITY_ALPHA",
    "MIN_SEGMENT_EDF",
]

#: false-alarm rate of the stationarity check on a stationary log
STATIONARITY_ALPHA = 0.01
#: segment EDF below which a cluster size is left out of the check
MIN_SEGMENT_EDF = 10.0


@dataclass(frozen=True)
class Stationarity:
    """Between-segment check of a log (module docstring).

    Attributes
    ----------
    stationary : bool
        ``p_value >= STATIONARITY_ALPHA``.
    p_value : float
    worst_tau_s : float
        Averaging time with the smallest per-size p-value (the strongest evidence) [s].
    tau_s : (n_tau,) ndarray
        Averaging times checked [s].
    segment_adev : (n_segments, n_tau) ndarray
        Each segment's Allan deviation there [u].
    spread : (n_tau,) ndarray
        Between-segment standard deviation of ``ln avar`` beyond sampling, non-decreasing.
    p_each : (n_tau,) ndarray or None
        The p-value of each size on its own (before Bonferroni).
    alpha : float
        The false-alarm rate ``stationary`` was decided at (summary.json ``alpha``: a p of 0.011
        passes at the default 0.01).
    """

    stationary: bool
    p_value: float
    worst_tau_s: float
    tau_s: np.ndarray
    segment_adev: np.ndarray
    spread: np.ndarray
    p_each: np.ndarray = None
    alpha: float = STATIONARITY_ALPHA

    @property
    def n_segments(self):
        return int(self.segment_adev.shape[0])

    def drift_log_sd(self, t):
        """Standard deviation of ``ln sigma_drift`` a later outage of length ``t`` [s] adds:
        ``s(t) / 2``, zero for a stationary log."""
        t = np.asarray(t, dtype=float)
        if self.stationary:
            return np.zeros_like(t)
        x = np.log(np.clip(t, self.tau_s[0], self.tau_s[-1]))
        return 0.5 * np.interp(x, np.log(self.tau_s), self.spread)

    def largest_ratio(self):
        """Ratio of the largest to the smallest segment Allan deviation at :attr:`worst_tau_s`."""
        a = self.segment_adev[:, int(np.argmin(np.abs(self.tau_s - self.worst_tau_s)))]
        return float(a.max() / a.min())

    def spread_factor(self):
        """Largest 1-sigma factor on the Allan deviation between parts, ``exp(max s / 2)`` (1 if
        none)."""
        return float(np.exp(0.5 * self.spread.max())) if self.spread.size else 1.0

    def to_dict(self):
        return {"stationary": bool(self.stationary), "p_value": float(self.p_value),
                "alpha": float(self.alpha),
                "worst_tau_s": float(self.worst_tau_s), "n_segments": self.n_segments,
                "adev_ratio_at_worst_tau": self.largest_ratio(),
                "adev_spread_factor": self.spread_factor(),
                "spread_ln_avar": {f"{t:g}": float(s) for t, s in zip(self.tau_s, self.spread)}}


def stationarity_check(allan, model, params, *, alpha=STATIONARITY_ALPHA):
    """:class:`Stationarity` of the log behind ``allan`` under ``model`` at ``params``.

    Parameters
    ----------
    allan : AllanResult
        With :attr:`~bayes_imu.allan.estimator.AllanResult.segments`.
    model : NoiseModel
    params : dict of float
        One parameter point (the selected model's best draw).
    alpha : float
        False-alarm rate.

    Returns
    -------
    Stationarity or None
        ``None`` when the log has no segments or no size has enough segment EDF.
    """
    seg = allan.segments
    if seg is None:
        return None
    edf = equivalent_dof(
        model.avar(seg.m, params), avar_covariance(model, params, seg.m, seg.n_samples)
    )
    return segment_test(seg, edf, allan.rate_hz, alpha=alpha)


def segment_test(segments, edf, rate_hz, *, alpha=STATIONARITY_ALPHA):
    """The test of the module docstring on the parts' Allan variances, given each part's EDF per
    size.

    Parameters
    ----------
    segments : SegmentAllan
    edf : (n_tau,) array
        Equivalent degrees of freedom of one part's Allan variance at each size of ``segments.m``
        (from the fitted model, or from a power-law noise type).
    rate_hz : float
    alpha : float

    Returns
    -------
    Stationarity or None
        ``None`` when no size has enough EDF.
    """
    edf = np.asarray(edf, dtype=float)
    keep = (edf >= MIN_SEGMENT_EDF) & np.all(segments.avar > 0, axis=0)
    if not keep.any():
        return None
    k = segments.n_segments
    log_avar = np.log(segments.avar[:, keep])
    v = special.polygamma(1, edf[keep] / 2.0)
    dev2 = np.sum((log_avar - log_avar.mean(axis=0)) ** 2, axis=0)
    p_each = special.chdtrc(k - 1, dev2 / v)  # chi-squared survival function
    p = float(min(1.0, p_each.size * p_each.min()))
    excess = np.maximum(0.0, dev2 / (k - 1) - v)
    tau = segments.m[keep] / rate_hz
    return Stationarity(
        p >= alpha,
        p,
        float(tau[int(np.argmin(p_each))]),
        tau,
        np.sqrt(segments.avar[:, keep]),
        np.sqrt(np.maximum.accumulate(excess)),
        p_each,
        float(alpha),
    )
