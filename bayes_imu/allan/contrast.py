"""The calibrated-outage error measured directly from the record: unequal-span phase contrasts.

An outage of ``k`` samples after a calibration window of ``N`` samples (the bias taken as the
plain mean of the window, :mod:`bayes_imu.noise._base`) leaves an attitude (or velocity) error

    e_j / dt = x_{j+k} - x_j - r (x_j - x_{j-N}),    r = k / N,

a fixed contrast of three points of the phase record ``x_j = sum_{i<j} y_i``. For ``k = N`` it is
the second difference of the Allan variance (``E e^2 = 2 tau^2 AVAR(tau)``, ``tau = N dt``);
otherwise it is its unequal-span generalisation. Whatever the noise (any process with stationary
increments, random walks and flicker included, since the contrast annihilates constants and
linear trends of ``x``), the overlapping average over every start ``j``

    V_hat(k) = dt^2 / M sum_{j=N}^{n-k} e_j^2,    M = n - N - k + 1,

is an unbiased estimate of the mean-square error ``E e^2`` the drift bands predict: it needs no
model. Starts closer than a 32nd of the span ``k + N`` carry almost the same error, so the average
takes every ``max(1, (k + N) // 32)``-th start (the EDF counts exactly the starts used); a record of
``n`` samples then costs ``O(32 n / (k + N))`` per outage instead of ``O(n)``. Its sampling
distribution (the EDF) does depend on the noise and is computed from a model's structure function
(:func:`bayes_imu.noise.contrast_covariance.contrast_edf`).

:func:`phase_contrasts` evaluates ``V_hat`` on a log-spaced grid of outage lengths (one vectorised
strided pass each over the phase record the Allan variance already builds), up to spans ``k + N`` of
half the record; :meth:`PhaseContrasts.at` interpolates between grid points in log-log.

Position (order 2). The velocity error integrated once more (the Euler sums of
:func:`bayes_imu.noise._base.calibrated_contrast`) is, with ``c = k (k - 1) / (2 N)``,

    p_j / dt^2 = sum_{i=1}^{k-1} x_{j+i} - (k - 1 + c) x_j + c x_{j-N}
               = S_{j+k} - S_{j+1} - (k - 1 + c) x_j + c x_{j-N},    S_m = sum_{i<m} x_i,

a fixed contrast of the phase record and its running sum ``S`` (built once, ``O(n)``, about the
phase's mean: the contrast annihilates constants and linear trends of ``x``, so neither the
mean nor the offset of ``S`` changes it). Its overlapping mean square over the same strided starts,
``V_hat_2(k) = dt^4 / M sum_j p_j^2``, is unbiased for the position bands' ``E p^2`` whatever the
noise (:attr:`PhaseContrasts.mean_square_2`; :meth:`PhaseContrasts.of_order`). ``p = 0`` at
``k = 1``, so position is measured from ``k = 2`` on. A record the compiled kernels sum in parallel
(:func:`bayes_imu.allan.kernels.position_mean_squares`) keeps ``S`` only every 8 samples, as a
compensated pair, and reads each window as the difference of two such pairs and at most seven
samples at each end: exact to the rounding of the window's own samples instead of the running sum's
magnitude (a running sum of 1e7 samples rounds at ``1e-16 |S|``), in about a sixth of the time and a
quarter of the memory.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .kernels import contrast_mean_squares, position_mean_squares

__all__ = [
    "PhaseContrasts",
    "phase_contrasts",
    "running_phase_sum",
    "contrast_mean_square",
    "position_mean_square",
    "contrast_stride",
    "DEFAULT_CONTRAST_SPAN_S",
    "CONTRASTS_PER_DECADE",
    "MAX_SPAN_FRACTION",
    "STARTS_PER_SPAN",
]

#: calibration window of the contrasts computed with every Allan variance [s] (the drift bands'
#: default)
DEFAULT_CONTRAST_SPAN_S = 60.0
#: outage lengths per decade of the grid
CONTRASTS_PER_DECADE = 6
#: longest span ``k + N`` measured, as a fraction of the record
MAX_SPAN_FRACTION = 0.5
#: starts averaged per span ``k + N`` (the step between starts is the span / this, at least 1)
STARTS_PER_SPAN = 32


@dataclass(frozen=True)
class PhaseContrasts:
    """Direct estimates of the calibrated-outage mean-square error (attitude / velocity, order 1).

    Attributes
    ----------
    k : (n_k,) ndarray of int
        Outage lengths [samples].
    n_cal : int
        Calibration window [samples].
    mean_square : (n_k,) ndarray
        ``V_hat(k)`` [u^2 s^2] (module docstring).
    n_terms : (n_k,) ndarray of int
        Starts averaged (every :func:`contrast_stride`-th of the ``n - N - k + 1``).
    rate_hz : float
    n_samples : int
    mean_square_2 : (n_k,) ndarray or None
        ``V_hat_2(k)`` [u^2 s^4], the position (order 2) error's mean square over the same starts
        (0 at ``k = 1``; ``None`` where not computed, e.g. a fit saved before it was).
    order : int
        Integration order :attr:`mean_square` measures (1; 2 for :meth:`of_order`'s view).
    """

    k: np.ndarray
    n_cal: int
    mean_square: np.ndarray
    n_terms: np.ndarray
    rate_hz: float
    n_samples: int
    mean_square_2: np.ndarray = None
    order: int = 1

    @property
    def calibration_s(self):
        return self.n_cal / self.rate_hz

    @property
    def t_s(self):
        return self.k / self.rate_hz

    def scaled(self, factor):
        """The contrasts of ``factor * y`` (a unit conversion)."""
        from dataclasses import replace

        f2 = factor * factor
        second = None if self.mean_square_2 is None else self.mean_square_2 * f2
        return replace(self, mean_square=self.mean_square * f2, mean_square_2=second)

    def of_order(self, order):
        """The contrasts of integration ``order`` as a :class:`PhaseContrasts` whose
        :attr:`mean_square` is that order's (order 2: the outages ``k >= 2`` of
        :attr:`mean_square_2`), or ``None`` where that order was not measured."""
        from dataclasses import replace

        if order == self.order:
            return self
        if order != 2 or self.order != 1 or self.mean_square_2 is None:
            return None
        keep = self.k >= 2
        return replace(self, k=self.k[keep], mean_square=self.mean_square_2[keep],
                       n_terms=self.n_terms[keep], mean_square_2=None, order=2)

    def covers(self, t):
        """``(n_t,)`` bool: outages ``t`` [s] within the measured grid."""
        t = np.asarray(t, dtype=float)
        if self.k.size == 0:
            return np.zeros(t.shape, dtype=bool)
        k = np.round(t * self.rate_hz)
        return (k >= self.k[0]) & (k <= self.k[-1])

    def at(self, t):
        """``V_hat`` at outages ``t`` [s], interpolated in log-log between grid points (``nan``
        outside)."""
        t = np.asarray(t, dtype=float)
        inside = self.covers(t)
        out = np.full(t.shape, np.nan)
        if inside.any():
            k = np.round(t[inside] * self.rate_hz)
            out[inside] = np.exp(np.interp(np.log(k), np.log(self.k), np.log(self.mean_square)))
        return out



def contrast_stride(k, n_cal):
    """Step between the starts averaged: ``max(1, (k + N) // STARTS_PER_SPAN)`` samples."""
    return np.maximum(1, (np.asarray(k, dtype=np.int64) + int(n_cal)) // STARTS_PER_SPAN)


def contrast_mean_square(x, k, n_cal, stride=1):
    """``V_hat / dt^2`` for outage ``k`` and window ``n_cal`` from a phase record ``x`` ``(n +
    1,)``, averaged over the starts ``N, N + stride, ...``.

    ``x`` is the running sum of the rate about any constant (the contrast annihilates it).
    """
    n = x.size - 1
    k, n_cal, stride = int(k), int(n_cal), int(stride)
    if k < 1 or n_cal < 1 or k + n_cal > n:
        raise InputError(
            f"outage {k} + calibration {n_cal} samples: expected 1 <= each, sum <= {n}"
        )
    r = k / n_cal
    mid = x[n_cal:n + 1 - k:stride]
    e = (
        x[n_cal + k :: stride][: mid.size]
        - (1.0 + r) * mid
        + r * x[: n + 1 - n_cal - k : stride][: mid.size]
    )
    return float(np.dot(e, e)) / e.size


def position_mean_square(x, k, n_cal, stride=1, *, s=None, mean=None):
    """``V_hat_2 / dt^4`` (module docstring, position) for outage ``k`` and window ``n_cal`` from a
    phase record ``x`` ``(n + 1,)``, over the starts ``N, N + stride, ..., <= n - k`` (those of
    :func:`contrast_mean_square`).

    ``s`` ``(n + 2,)`` is the running sum of ``x`` about its mean with a leading 0
    (:func:`running_phase_sum`) and ``mean`` that mean (``x.mean()``), both computed once for every
    outage (a pass over a long record each).
    """
    n = x.size - 1
    k, n_cal, stride = int(k), int(n_cal), int(stride)
    if k < 1 or n_cal < 1 or k + n_cal > n:
        raise InputError(
            f"outage {k} + calibration {n_cal} samples: expected 1 <= each, sum <= {n}"
        )
    mean = x.mean() if mean is None else mean  # the phase about the mean ``s`` is the sum of
    s = running_phase_sum(x, mean) if s is None else s
    c = k * (k - 1) / (2.0 * n_cal)
    mid = x[n_cal:n + 1 - k:stride] - mean
    m = mid.size
    e = (
        (s[n_cal + k:: stride][:m] - s[n_cal + 1:: stride][:m])
        - (k - 1 + c) * mid
        + c * (x[: n + 1 - n_cal - k : stride][:m] - mean)
    )
    return float(np.dot(e, e)) / m


def running_phase_sum(x, mean=None):
    """``S_m = sum_{i<m} (x_i - mean x)`` ``(n + 2,)`` with ``S_0 = 0``: the running sum the
    position contrast reads (the mean taken out first for precision; ``mean``: ``x.mean()`` where
    already computed). Summed into its own array (no copy of the sums)."""
    mean = x.mean() if mean is None else mean
    out = np.empty(x.size + 1)
    out[0] = 0.0
    np.cumsum(x - mean, out=out[1:])
    return out


def _mean_squares(x, ks, n_cal, strides):
    """``contrast_mean_square`` of each outage: one compiled call on a long record
    (:func:`bayes_imu.allan.kernels.contrast_mean_squares`, issue 39), else one at a time."""
    if _compiled_valid(x, ks, n_cal):
        compiled = contrast_mean_squares(x, ks, n_cal, strides)
        if compiled is not None:
            return compiled
    return np.array([contrast_mean_square(x, kk, n_cal, st) for kk, st in zip(ks, strides)])


def _both_mean_squares(x, ks, n_cal, strides, pairs=None):
    """``(contrast_mean_square, position_mean_square)`` of each outage: compiled passes on a
    long record (:func:`bayes_imu.allan.kernels.position_mean_squares`; the phase contrasts' the
    same bits as :func:`_mean_squares`'), else numpy's, one outage at a time (the running sum
    computed once)."""
    if not ks.size:
        return np.zeros(0), np.zeros(0)
    if _compiled_valid(x, ks, n_cal):
        compiled = position_mean_squares(x, ks, n_cal, strides, pairs)
        if compiled is not None:
            return compiled[:, 0], compiled[:, 1]
    mean = x.mean()
    s = running_phase_sum(x, mean)
    return (_mean_squares(x, ks, n_cal, strides),
            np.array([position_mean_square(x, kk, n_cal, st, s=s, mean=mean)
                      for kk, st in zip(ks, strides)]))


def _compiled_valid(x, ks, n_cal):
    """Every outage valid for the compiled passes (an invalid one is reported by numpy's)."""
    n = x.size - 1
    return bool(ks.size) and ks.min() >= 1 and n_cal >= 1 and ks.max() + n_cal <= n


def contrast_grid(
    n_samples, n_cal, per_decade=CONTRASTS_PER_DECADE, max_fraction=MAX_SPAN_FRACTION
):
    """Whole-sample outage lengths from 1 to ``max_fraction n - N``, ``per_decade`` per decade."""
    top = int(np.floor(max_fraction * n_samples)) - int(n_cal)
    if top < 1:
        return np.zeros(0, dtype=np.int64)
    count = max(2, int(np.ceil(np.log10(top) * per_decade)) + 1)
    return np.unique(np.round(np.geomspace(1.0, top, count))).astype(np.int64)


def phase_contrasts(y=None, *, rate_hz, calibration_s=DEFAULT_CONTRAST_SPAN_S, x=None, k=None,
                    position=True, pairs=None):
    """:class:`PhaseContrasts` of rate samples ``y`` (or of their phase record ``x``).

    Parameters
    ----------
    y : (n,) array_like, optional
        Rate samples [u].
    rate_hz : float
    calibration_s : float
        Calibration window [s] (rounded to whole samples).
    x : (n + 1,) ndarray, optional
        The phase record ``cumsum`` of ``y`` about its mean, with a leading 0 (what the Allan
        variance builds); given instead of ``y``.
    k : array_like of int, optional
        Outage lengths [samples]; default :func:`contrast_grid`.
    position : bool
        Whether to measure the position (order 2) drift too (``False`` for a gyro: its
        :attr:`~PhaseContrasts.mean_square_2` is then ``None``).
    pairs : ((len(x) - 1) // 8 + 1, 2) ndarray, optional
        With ``x``: the sums of ``x[1:]`` in blocks of 8 samples in ``pairs[1:, 0]`` where already
        summed (:func:`bayes_imu.allan.kernels.allan_sums`' ``blocks``), read by the position
        contrasts of a long record instead of summed again (the same sums to rounding; the table
        is overwritten).

    Returns
    -------
    PhaseContrasts
        Attitude / velocity (order 1) and position (order 2, :attr:`PhaseContrasts.mean_square_2`)
        mean squares; empty (``k.size == 0``) when the window is longer than half the record.
    """
    if x is None:
        y = np.asarray(y, dtype=np.float64)
        x = np.concatenate(([0.0], np.cumsum(y - y.mean())))
    n = x.size - 1
    n_cal = int(round(calibration_s * rate_hz))
    if n_cal < 1:
        raise InputError(
            f"calibration={calibration_s!r} s: expected at least one sample ({1.0 / rate_hz:g} s)"
        )
    ks = contrast_grid(n, n_cal) if k is None else np.asarray(k, dtype=np.int64)
    strides = contrast_stride(ks, n_cal)
    ms2 = None
    if position:
        ms, ms2 = _both_mean_squares(x, ks, n_cal, strides, pairs)
        ms2 = ms2.reshape(ks.shape) / rate_hz**4
    else:
        ms = _mean_squares(x, ks, n_cal, strides)
    ms = ms / rate_hz**2
    return PhaseContrasts(
        ks, n_cal, ms.reshape(ks.shape), (n - n_cal - ks) // strides + 1, float(rate_hz), int(n),
        ms2,
    )
