"""The paper's second identification tool: autocorrelation of the low-pass-filtered signal.

Wall & Bevly, eq 4 and Fig 1: the Gauss-Markov bias has ``R(T) = sigma_b**2 exp(-T/tau)``;
filtering the raw signal removes most of the wide-band noise, and a fit of eq 4 to the
sample autocorrelation gives ``sigma_b**2`` and ``tau``.

Caveat (paper, and Brown & Hwang): the sample autocorrelation of a record of length ``T``
is biased and very noisy unless ``T`` is many times ``tau``; the relative standard error of
the variance estimate is about ``sqrt(2 tau / T)``. A ``UserWarning`` is raised below
``T = 100 tau``. The Allan-variance fit (``bayes_imu.inference.fit``) is the better tool.
"""

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["AutocorrelationResult", "autocorrelation_fit"]


@dataclass(frozen=True)
class AutocorrelationResult:
    """Fit of eq 4 to the sample autocorrelation.

    Attributes
    ----------
    lag_s : ndarray
        Lags (s) of the fitted autocorrelation.
    acf : ndarray
        Biased sample autocorrelation of the filtered, mean-removed signal (units**2).
    bias_variance : float
        ``sigma_b**2`` (units**2).
    time_constant : float
        ``tau`` (s).
    record_over_tau : float
        Record length over ``tau``; below ~100 the estimates are unreliable.
    cutoff_hz : float
        Low-pass cut-off used (Hz).
    """

    lag_s: np.ndarray
    acf: np.ndarray
    bias_variance: float
    time_constant: float
    record_over_tau: float
    cutoff_hz: float


def autocorrelation_fit(y, *, rate_hz, cutoff_hz=None, max_lag_s=None):
    """Fit ``R(T) = sigma_b**2 exp(-T/tau)`` (eq 4) to the autocorrelation of filtered data.

    Parameters
    ----------
    y : array_like
        Rate samples.
    rate_hz : float
        Sample rate (Hz).
    cutoff_hz : float, optional
        Zero-phase 4th-order Butterworth low-pass cut-off; default ``rate_hz / 50``.
    max_lag_s : float, optional
        Largest lag fitted; default: three times the lag where the autocorrelation first
        falls below ``1/e`` of its value at the first fitted lag (at most a tenth of the record).
    """
    from scipy import optimize, signal

    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1 or y.size < 64 or not np.all(np.isfinite(y)):
        raise InputError("y: expected a 1-D array of at least 64 finite rate samples")
    if not rate_hz > 0:
        raise InputError(f"rate_hz={rate_hz!r}: expected a positive number (Hz)")
    cutoff_hz = rate_hz / 50.0 if cutoff_hz is None else float(cutoff_hz)
    if not 0 < cutoff_hz < rate_hz / 2:
        raise InputError(
            f"cutoff_hz={cutoff_hz!r}: expected 0 < cutoff < rate_hz/2 = {rate_hz / 2}"
        )
    sos = signal.butter(4, cutoff_hz, fs=rate_hz, output="sos")
    z = signal.sosfiltfilt(sos, y - y.mean())
    n = z.size
    spectrum = np.fft.rfft(z, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n] / n
    first = int(np.ceil(2.0 * rate_hz / cutoff_hz))  # skip lags still shaped by the filter
    if max_lag_s is None:
        below = np.nonzero(acf[first:] < acf[first] / np.e)[0]
        reach = (below[0] if below.size else n // 10) * 3
        last = min(first + max(reach, 8), n // 10)
    else:
        last = min(int(max_lag_s * rate_hz), n - 1)
    if last <= first + 3:
        raise InputError("y: record too short for an autocorrelation fit at this cut-off")
    lags = np.arange(first, last) / rate_hz
    target = acf[first:last]
    tau0 = max(lags[-1] / 3, 1.0 / rate_hz)

    def model(t, log_var, log_tau):
        return np.exp(log_var - t / np.exp(log_tau))

    start = (np.log(max(target[0], 1e-300)) + lags[0] / tau0, np.log(tau0))
    try:
        (log_var, log_tau), _ = optimize.curve_fit(model, lags, target, p0=start, maxfev=5000)
    except RuntimeError as exc:
        raise InputError(
            f"y: the autocorrelation does not decay like exp(-T/tau) ({exc})"
        ) from None
    tau = float(np.exp(log_tau))
    ratio = n / rate_hz / tau
    if ratio < 100:
        warnings.warn(
            f"record is {ratio:.0f} time constants long; autocorrelation estimates of sigma_b^2 "
            "and tau need ~100 or more (relative error ~ sqrt(2 tau / T))",
            UserWarning,
            stacklevel=2,
        )
    return AutocorrelationResult(
        lag_s=lags, acf=target, bias_variance=float(np.exp(log_var)), time_constant=tau,
        record_over_tau=float(ratio), cutoff_hz=cutoff_hz,
    )
