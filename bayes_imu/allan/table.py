"""An Allan-deviation table from elsewhere (a datasheet, Stable32, allan_variance_ros, imu_utils) as
an
:class:`~bayes_imu.allan.estimator.AllanResult`, so that it can be fitted like one computed here.

A table gives ``tau`` (s) and the Allan deviation (or variance), and sometimes the equivalent
degrees of freedom (EDF) of each value. The likelihood needs the EDF (or the record length,
from which the Greenhall EDF follows, :func:`bayes_imu.allan.estimator.greenhall_edf`, with each
point's noise type read from the local slope of the table). The assumption the intervals
rest on is returned with the result:

* an ``edf`` column: used as given;
* ``n_samples`` (the record's sample count) given: Greenhall EDF for the fully overlapping
  estimator;
* neither: the record is taken as the shortest the table allows, ``4 m_max`` samples (the
  octave grid's own limit), which gives the fewest degrees of freedom and so the widest,
  conservative intervals; give ``n_samples`` when it is known.

``tau`` must be whole numbers of sample periods at ``rate_hz`` (to a relative 1e-4, the
precision tables are printed with).
"""

import numpy as np

from .estimator import AllanResult, carried_edf, chi2_interval, check_options, greenhall_edf
from ..errors import InputError
from ..io.readers import read_columns, sniff_file

__all__ = ["read_allan_table", "allan_from_table"]


def allan_from_table(tau, adev, *, rate_hz, edf=None, n_samples=None, confidence=0.683):
    """:class:`AllanResult` and the assumption text from arrays (module docstring).

    Parameters
    ----------
    tau : array_like
        Averaging times (s), increasing, whole numbers of samples.
    adev : array_like
        Allan deviation at each ``tau`` (units of the rate).
    rate_hz : float
        Sample rate of the log the table came from (Hz).
    edf : array_like, optional
    n_samples : int, optional
        Samples in that log.
    confidence : float
        Of the intervals stored in the result.
    """
    rate_hz = check_options(rate_hz, confidence, "exact")
    tau = np.asarray(tau, float)
    adev = np.asarray(adev, float)
    if tau.ndim != 1 or tau.size < 2 or tau.shape != adev.shape:
        raise InputError(
            "Allan table: expected tau and adev columns of equal length (at least 2), got "
            f"{tau.size} and {adev.size}"
        )
    if not (np.all(np.isfinite(tau)) and np.all(tau > 0) and np.all(np.diff(tau) > 0)):
        raise InputError("Allan table: tau must be positive and increasing (seconds)")
    if not (np.all(np.isfinite(adev)) and np.all(adev > 0)):
        i = int(np.argmin(np.where(np.isfinite(adev), adev, -np.inf)))
        raise InputError(
            f"Allan table: adev={adev[i]!r} at tau = {tau[i]:g} s; expected positive numbers"
        )
    m_float = tau * rate_hz
    m = np.round(m_float).astype(np.int64)
    off = np.abs(m_float - m) > np.maximum(1e-3, 1e-4 * m_float)
    if off.any() or np.any(m < 1):
        i = int(np.argmax(off | (m < 1)))
        raise InputError(
            f"Allan table: tau = {tau[i]:g} s is {m_float[i]:.4g} samples at {rate_hz:g} Hz; "
            "expected whole numbers of samples (is rate_hz right?)"
        )
    if np.any(np.diff(m) <= 0):
        raise InputError(
            f"Allan table: two tau values round to the same cluster size at {rate_hz:g} Hz"
        )
    avar = adev**2
    # noise type of each point from the local slope mu of AVAR (alpha = -mu - 1, SP1065 Table 1)
    slope = np.gradient(np.log(avar), np.log(m))
    alpha = np.clip(np.round(-slope - 1.0), -2, 2).astype(np.int64)
    if edf is not None:
        edf = np.asarray(edf, float)
        if edf.shape != tau.shape or not np.all(np.isfinite(edf) & (edf > 0)):
            raise InputError("Allan table: the edf column must hold a positive number on every row")
        assumption = "EDF from the table's edf column"
        n = int(n_samples) if n_samples is not None else int(4 * m[-1])
    else:
        if n_samples is None:
            n = int(4 * m[-1])
            assumption = (
                f"record length unknown: taken as {n} samples (4 x the longest cluster size, the "
                "shortest record the table allows): the fewest degrees of freedom, the widest "
                "intervals; give the sample count if known"
            )
        else:
            n = int(n_samples)
            assumption = f"Greenhall EDF for a fully overlapping estimate from {n} samples"
        if n < 2 * m[-1] + 1:
            raise InputError(
                f"Allan table: {n} samples cannot give tau = {tau[-1]:g} s ({m[-1]} samples); "
                "expected at least twice the longest cluster size"
            )
        # the type read off the slope is no surer than a log's own identification where few
        # averages make the estimate: the same rule (the neighbours' smallest EDF there)
        edf = carried_edf(greenhall_edf(alpha, m, n + 1), alpha, m, n)
    low, high = chi2_interval(avar, edf, confidence)
    result = AllanResult(
        tau=m / rate_hz,
        m=m,
        avar=avar,
        adev=adev,
        n_terms=n + 1 - 2 * m,
        edf=edf,
        alpha=alpha,
        avar_low=low,
        avar_high=high,
        confidence=float(confidence),
        rate_hz=rate_hz,
        n_samples=n,
    )
    return result, assumption


def read_allan_table(path, *, rate_hz, n_samples=None, confidence=0.683):
    """Read a delimited text table with a header naming ``tau`` and ``adev`` (or ``avar``), and
    optionally ``edf``; returns ``(AllanResult, assumption)`` (:func:`allan_from_table`)."""
    names = [str(n) for n in sniff_file(path)["names"]]
    lower = {n.strip().lower(): n for n in names}
    if "tau" not in lower or not ({"adev", "avar"} & set(lower)):
        raise InputError(
            f"{path}: an Allan table needs a header with 'tau' and 'adev' (or 'avar') columns, "
            f"optionally 'edf'; found {', '.join(repr(n) for n in names[:8])}"
        )
    value = "adev" if "adev" in lower else "avar"
    wanted = [lower["tau"], lower[value]] + ([lower["edf"]] if "edf" in lower else [])
    # a flat ADEV (bias instability) is valid
    data = read_columns(path, columns=wanted, signal=False).values
    if value == "avar" and np.any(data[:, 1] <= 0):
        raise InputError(f"{path}: avar must be positive on every row")
    adev = data[:, 1] if value == "adev" else np.sqrt(data[:, 1])
    return allan_from_table(
        data[:, 0],
        adev,
        rate_hz=rate_hz,
        edf=data[:, 2] if data.shape[1] > 2 else None,
        n_samples=n_samples,
        confidence=confidence,
    )
