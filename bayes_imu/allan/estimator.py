"""Fully overlapping Allan variance of rate data, with Greenhall-Riley confidence intervals.

References
----------
NIST SP1065: W. J. Riley, *Handbook of Frequency Stability Analysis* (2008), eq 14
(overlapping Allan variance), sec 5.3 (confidence intervals), sec 5.6 (noise ID).
Greenhall & Riley, "Uncertainty of stability variances based on finite differences",
35th PTTI (2003): equivalent degrees of freedom (eqs 7-10, Tables 1-3).
Riley & Greenhall, "Power law noise identification using the lag 1 autocorrelation",
18th EFTF (2004).
"""

from dataclasses import dataclass, replace

import numpy as np
from .._lazy import LazyModule

special = LazyModule("scipy.special")  # chi-squared quantiles without importing scipy.stats

from .contrast import DEFAULT_CONTRAST_SPAN_S, PhaseContrasts, phase_contrasts
from .kernels import allan_sums, lag1_deltas, second_difference_sums
from .._progress import progress_bar
from ..errors import InputError
from ..io.readers import SI_UNITS, positive_number

__all__ = ["AllanResult", "SegmentAllan", "allan_variance", "check_sensor",
           "cluster_sizes", "greenhall_edf", "identify_noise",
           "segment_allan", "segment_plan", "DEFAULT_SEGMENTS"]

#: consecutive equal segments whose Allan variances the stationarity check compares
DEFAULT_SEGMENTS = 4

_J_MAX = 100
_MIN_ID_POINTS = 30
#: averages below which an identified noise type is not trusted for the EDF (:func:`carried_edf`):
#: the lag-1 autocorrelation's standard error ~1/sqrt(n) is 0.18 at 30 averages, enough to put
#: 2 delta a whole step off (Riley & Greenhall 2004 give 30 as the least to identify at all)
_TRUSTED_ID_POINTS = 100
_MAX_ID_POINTS = 2**18  # lag-1 ACF standard error ~ 1/sqrt(n) = 0.002: ample to pick an integer
_ALPHAS = (-2, -1, 0, 1, 2)
_MAX_SEGMENT_TAUS = 40


@dataclass(frozen=True)
class SegmentAllan:
    """Allan variance of each of ``n_segments`` consecutive, equal, non-overlapping parts of a log.

    The stationarity check (:mod:`bayes_imu.inference.stationarity`) compares them: a sensor whose
    noise changes during the record (warm-up, temperature) gives segments that differ by more than
    their sampling error.

    Attributes
    ----------
    m : ndarray of int, shape (n_tau,)
        Cluster sizes (those of the whole log up to a quarter of a segment).
    avar : ndarray, shape (n_segments, n_tau)
        Overlapping Allan variance of each segment (units**2), SP1065 eq 14.
    n_samples : int
        Samples per segment (the last ``n mod n_segments`` samples of the log are left out).
    """

    m: np.ndarray
    avar: np.ndarray
    n_samples: int

    @property
    def n_segments(self):
        return int(self.avar.shape[0])


@dataclass(frozen=True)
class AllanResult:
    """Overlapping Allan variance and its confidence interval, one entry per cluster size.

    Attributes
    ----------
    tau : ndarray, shape (n_tau,)
        Averaging time ``m / rate_hz`` (s).
    m : ndarray of int, shape (n_tau,)
        Cluster sizes (samples per average).
    avar, adev : ndarray, shape (n_tau,)
        Allan variance (units**2) and deviation (units) of the rate data.
    n_terms : ndarray of int
        Number of second differences averaged, ``n_samples + 1 - 2 m``.
    edf : ndarray
        Equivalent degrees of freedom (Greenhall & Riley) of ``alpha``; where ``alpha`` was
        identified from fewer than 100 cluster averages (or carried from a shorter size), the
        smallest of ``alpha - 1 .. alpha + 1`` (:func:`carried_edf`): too few averages to tell
        the noise type, so the interval is that of the least certain neighbouring type (a
        white-rate tail read as flicker phase gave intervals 5x too narrow).
    alpha : ndarray of int
        Power-law exponent of the rate PSD used for the EDF: 2 white phase /
        quantization, 0 white rate (angle / velocity random walk), -1 flicker (bias
        instability), -2 random walk (rate random walk).
    avar_low, avar_high : ndarray
        Chi-squared interval on ``avar`` at ``confidence`` (SP1065 eq 45).
    confidence : float
    rate_hz : float
        Sample rate of the input (Hz).
    n_samples : int
        Number of rate samples.
    segments : SegmentAllan or None
        The Allan variance of consecutive parts of the log (``None`` when not computed: Allan
        tables, out-of-core runs, ``segments=0``, logs too short).
    sensor : {"gyro", "accel"} or None
        The sensor kind of the samples, when known (:mod:`bayes_imu.noise.quantities`); set by
        :func:`allan_variance`'s ``sensor`` or :meth:`with_sensor`, carried by every result
        built on this one instead of being read back from a unit string.
    contrasts : PhaseContrasts or None
        The calibrated-outage error measured directly from the log
        (:mod:`bayes_imu.allan.contrast`; ``None`` when not computed: Allan tables, out-of-core
        runs, ``contrast_span_s=None``).
    """

    tau: np.ndarray
    m: np.ndarray
    avar: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    avar_low: np.ndarray
    avar_high: np.ndarray
    confidence: float
    rate_hz: float
    n_samples: int
    segments: SegmentAllan = None
    sensor: str = None
    contrasts: PhaseContrasts = None

    def __post_init__(self):
        check_sensor(self.sensor)

    def with_sensor(self, sensor):
        """The same result with its sensor kind set (``"gyro"``, ``"accel"`` or ``None``)."""
        return replace(self, sensor=check_sensor(sensor))

    def scaled(self, factor):
        """The Allan variance of ``factor * y`` (a unit conversion): every variance, the segments'
        included, times ``factor**2``."""
        if factor == 1.0:
            return self
        f2 = factor * factor
        segments = (
            self.segments
            if self.segments is None
            else replace(self.segments, avar=self.segments.avar * f2)
        )
        contrasts = self.contrasts if self.contrasts is None else self.contrasts.scaled(factor)
        return replace(
            self,
            avar=self.avar * f2,
            adev=self.adev * abs(factor),
            avar_low=self.avar_low * f2,
            avar_high=self.avar_high * f2,
            segments=segments,
            contrasts=contrasts,
        )

    @property
    def duration_s(self):
        """Length of the record (s): ``n_samples / rate_hz``."""
        return self.n_samples / self.rate_hz

    @property
    def adev_low(self):
        """Lower end of the interval on the Allan deviation (units)."""
        return np.sqrt(self.avar_low)

    @property
    def adev_high(self):
        """Upper end of the interval on the Allan deviation (units)."""
        return np.sqrt(self.avar_high)


def cluster_sizes(m, n_samples):
    """Cluster sizes for a grid name or an explicit integer array.

    ``"octave"``: 1, 2, 4, ...; ``"decade"``: 1, 2, 4, 10, 20, 40, 100, ...; ``"all"``:
    every integer (cost grows as ``n_samples * n_tau``). Named grids stop at
    ``n_samples / 4`` (as Stable32); explicit sizes may go up to ``n_samples / 2``.
    """
    if isinstance(m, str):
        limit = n_samples // 4
        if m == "octave":
            grid = 2 ** np.arange(int(np.log2(max(limit, 1))) + 1)
        elif m == "decade":
            grid = np.array([f * 10**e for e in range(20) for f in (1, 2, 4)])
        elif m == "all":
            grid = np.arange(1, limit + 1)
        else:
            raise InputError(
                f"m={m!r}: expected 'octave', 'decade', 'all' or an array of cluster sizes"
            )
        grid = grid[grid <= limit]
        if grid.size == 0:
            raise InputError(
                f"{n_samples} samples: too few for an Allan variance (at least 4 needed for "
                f"m='{m}')"
            )
        return grid.astype(np.int64)
    grid = np.asarray(m)
    if grid.ndim != 1 or grid.size == 0 or not np.issubdtype(grid.dtype, np.number):
        raise InputError(f"m={m!r}: expected a non-empty 1-D array of integer cluster sizes")
    if np.any(grid != np.round(grid)) or np.any(grid < 1) or np.any(2 * grid > n_samples):
        raise InputError(
            f"m={m!r}: expected whole cluster sizes 1 <= m <= n_samples/2 = {n_samples // 2}"
        )
    if np.any(np.diff(grid) <= 0):
        raise InputError(f"m={m!r}: expected strictly increasing cluster sizes")
    return grid.astype(np.int64)


def check_sensor(sensor):
    """``sensor`` if it is ``None`` or a sensor kind of :data:`bayes_imu.io.readers.SI_UNITS`,
    else :class:`InputError`."""
    if sensor is not None and sensor not in SI_UNITS:
        raise InputError(f"sensor={sensor!r}: expected one of {', '.join(SI_UNITS)} or None")
    return sensor


def allan_variance(
    y,
    *,
    rate_hz,
    m="octave",
    alpha=None,
    confidence=0.683,
    interval="exact",
    progress=False,
    segments=DEFAULT_SEGMENTS,
    contrast_span_s=DEFAULT_CONTRAST_SPAN_S,
    sensor=None,
):
    """Fully overlapping Allan variance of uniformly sampled rate data (SP1065 eq 14).

    Parameters
    ----------
    y : array_like, shape (n_samples,)
        Rate samples: gyro rate or specific force, any unit.
    rate_hz : float
        Sample rate (Hz).
    m : {"octave", "decade", "all"} or array_like of int
        Cluster sizes, see :func:`cluster_sizes`.
    alpha : int, array_like of int, or None
        Power-law noise type of the rate PSD for the EDF; ``None`` identifies it per
        cluster size by the lag-1 autocorrelation method (:func:`identify_noise`).
    confidence : float
        Two-sided probability of the chi-squared interval; 0.683 is Stable32's 1-sigma.
    interval : {"exact", "stable32"}
        Chi-squared quantiles from scipy (exact), or Stable32's approximation for
        EDF > 100 (to reproduce its tables digit for digit; off by up to ~1e-3).
    progress : bool
        Show a progress bar over cluster sizes on standard error (same numbers).
    segments : int
        Also compute the Allan variance of this many consecutive parts of the log
        (:class:`SegmentAllan`, for the stationarity check); 0 or 1 skips it.
    contrast_span_s : float or None
        Calibration window [s] of the calibrated-outage errors measured directly from the log
        (:class:`~bayes_imu.allan.contrast.PhaseContrasts`, for the drift-space check); ``None``
        skips them.
    sensor : {"gyro", "accel"} or None
        Sensor kind of the samples, recorded on the result (:attr:`AllanResult.sensor`). A gyro's
        contrasts leave out the position (order 2) drift, which only an accelerometer (or a log of
        unknown kind) needs.

    Returns
    -------
    AllanResult
    """
    check_sensor(sensor)
    y = _as_array(y)
    try:
        rate_hz = check_options(rate_hz, confidence, interval)
        ms = cluster_sizes(m, y.size)
    except InputError:
        _check_finite(y)  # a non-finite sample is named first, as before the options
        raise
    plan = segment_plan(ms, y.size, segments)
    contrasted = contrast_span_s is not None and contrast_span_s * rate_hz >= 1.0
    # a gyro has no position: its record's position drift is not measured (a pass over a long
    # record's blocks and strided reads of two more arrays)
    position = sensor != "gyro"
    with progress_bar(total=ms.size, desc="Allan variance", unit="tau", enabled=progress) as bar:
        # the running sum of y about its mean (precision), the sums of every size, those of the
        # parts for the stationarity check, the noise identification's phase samples and the
        # position contrasts' block sums, in one call
        got = allan_sums(
            y,
            ms,
            progress=bar.update,
            parts=None if plan is None else (segments, plan[1]),
            gather=None if alpha is not None else _starts_steps(ms, y.size),
            blocks=contrasted and position,
        )
    x, sums = got[:2]
    parts, points = got[2:4] if len(got) > 2 else (None, None)
    pairs = got[4] if len(got) > 4 else None
    if not (np.isfinite(x[-1]) and np.isfinite(sums).all()):
        # a non-finite sample makes the mean, hence the whole running sum, non-finite: the
        # samples are read again only then, to name it (no pass over every record for it)
        _check_finite(y)
    alphas = _identify(x, ms, y.size, points) if alpha is None else alpha
    result = assemble_result(ms, sums, alphas, y.size, rate_hz, confidence, interval,
                             identified=alpha is None)
    contrasts = None
    if contrasted:
        contrasts = phase_contrasts(x=x, rate_hz=rate_hz, calibration_s=contrast_span_s,
                                    position=position, pairs=pairs)
    segment = None
    if plan is not None:
        length, part_ms = plan
        segment = SegmentAllan(
            part_ms, np.array([avar_from_sums(row, part_ms, length) for row in parts]), length
        )
    return replace(result, segments=segment, contrasts=contrasts, sensor=sensor)


def _starts_steps(ms, n_samples):
    """``(starts, steps, counts)`` of the identification series' phase samples (``allan_sums``'
    ``gather``)."""
    starts, counts = identification_plan(ms, n_samples)
    return starts, ms, counts


def segment_plan(m, n_samples, n_segments=DEFAULT_SEGMENTS):
    """``(length, ms)``: the samples of each of ``n_segments`` parts of ``n_samples`` and the sizes
    of ``m`` their Allan variances take (:func:`segment_allan`); ``None`` where there are none."""
    n_segments = int(n_segments)
    if n_segments < 2:
        return None
    length = n_samples // n_segments
    ms = np.asarray(m, dtype=np.int64)
    ms = ms[ms <= length // 4]
    if ms.size == 0:
        return None
    if ms.size > _MAX_SEGMENT_TAUS:  # a dense grid ("all"): log-spaced sizes suffice for the check
        ms = np.unique(ms[np.round(np.geomspace(1, ms.size, _MAX_SEGMENT_TAUS)).astype(int) - 1])
    return length, ms


def segment_allan(y, m, n_segments=DEFAULT_SEGMENTS, *, x=None):
    """:class:`SegmentAllan` of ``n_segments`` consecutive parts of ``y`` at the sizes of ``m`` that
    fit (at most a quarter of a segment, as the named grids); ``None`` if none does or ``n_segments
    < 2``.

    ``x``: the running sum of ``y`` about any constant, with a leading 0 (what
    :func:`allan_variance` has built; ``y`` is then not read): each part's second differences are
    those of its slice of ``x`` (the constant cancels), so the parts cost their sums only, not
    another pass for their means and running sums (issue 39). The same values up to rounding (1e-15
    relative on the tests' records). :func:`allan_variance` itself has the parts' sums from the
    pass over the whole record (:func:`~bayes_imu.allan.kernels.allan_sums`' ``parts``)."""
    if x is None:
        y = _as_samples(y)
    plan = segment_plan(m, y.size if x is None else x.size - 1, n_segments)
    if plan is None:
        return None
    length, ms = plan
    avar = np.empty((int(n_segments), ms.size))
    for k in range(int(n_segments)):
        if x is None:
            sums = allan_sums(y[k * length:(k + 1) * length], ms)[1]
        else:
            sums = second_difference_sums(x[k * length:(k + 1) * length + 1], ms)
        avar[k] = avar_from_sums(sums, ms, length)
    return SegmentAllan(ms, avar, length)


def avar_from_sums(sums, ms, n_samples):
    """Overlapping Allan variance from the second-difference sums of ``n_samples`` rate samples
    (SP1065 eq 14): ``sums / (2 m^2 (n_samples + 1 - 2 m))``."""
    return sums / (2.0 * (n_samples + 1 - 2 * ms) * ms.astype(float) ** 2)


def check_options(rate_hz, confidence, interval):
    """Validated ``rate_hz`` (and the interval options) of an Allan variance computation."""
    rate_hz = positive_number("rate_hz", rate_hz, what="sample rate in Hz")
    if not 0 < confidence < 1:
        raise InputError(
            f"confidence={confidence!r}: expected a probability strictly between 0 and 1"
        )
    if interval not in ("exact", "stable32"):
        raise InputError(f"interval={interval!r}: expected 'exact' or 'stable32'")
    return rate_hz


def assemble_result(ms, sums, alpha, n_samples, rate_hz, confidence, interval, identified=False):
    """:class:`AllanResult` from the second-difference sums of each cluster size (SP1065 eq 14);
    ``identified``: ``alpha`` was identified from the record (:func:`identify_noise`), so where it
    was carried to a size with too few averages the EDF is the neighbours' smallest
    (:func:`carried_edf`)."""
    n_terms = n_samples + 1 - 2 * ms
    avar = avar_from_sums(sums, ms, n_samples)
    alphas = _alpha_array(alpha, ms.size)
    edf = greenhall_edf(alphas, ms, n_samples + 1)
    if identified:
        edf = carried_edf(edf, alphas, ms, n_samples)
    low, high = chi2_interval(avar, edf, confidence, interval)
    return AllanResult(
        tau=ms / rate_hz,
        m=ms,
        avar=avar,
        adev=np.sqrt(avar),
        n_terms=n_terms,
        edf=edf,
        alpha=alphas,
        avar_low=low,
        avar_high=high,
        confidence=float(confidence),
        rate_hz=rate_hz,
        n_samples=n_samples,
    )


def _as_samples(y):
    return _check_finite(_as_array(y))


def _as_array(y):
    """``y`` as a contiguous 1-D float array (not yet checked for finite values)."""
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:
        raise InputError(f"y: expected a 1-D array of rate samples, got shape {y.shape}")
    return np.ascontiguousarray(y)


def _check_finite(y):
    """``y``, or :class:`InputError` naming its first non-finite sample."""
    bad = ~np.isfinite(y)
    if bad.any():
        raise InputError(
            f"y: sample {int(np.argmax(bad))} is {y[bad][0]!r}; expected finite numbers"
        )
    return y


def _alpha_array(alpha, n):
    values = np.broadcast_to(np.asarray(alpha), (n,))
    if not np.all(np.isin(values, _ALPHAS)):
        raise InputError(f"alpha={alpha!r}: expected integers in {_ALPHAS} (or None to identify)")
    return values.astype(np.int64).copy()


def chi2_interval(avar, edf, confidence, interval="exact"):
    """Chi-squared interval on ``avar`` (SP1065 eq 45): ``edf avar / chi2`` at both tails."""
    tail = (1.0 - confidence) / 2.0
    # chi2 isf, ppf
    upper, lower = special.chdtri(edf, tail), 2.0 * special.gammaincinv(edf / 2.0, tail)
    if interval == "stable32":
        large = edf > 100  # Stable32 iterates exactly up to 100 degrees of freedom
        upper = np.where(large, _stable32_chi2(edf, tail), upper)
        lower = np.where(large, _stable32_chi2(edf, 1.0 - tail), lower)
    return edf * avar / upper, edf * avar / lower


def _stable32_chi2(edf, upper_tail):
    """Stable32's large-EDF chi-squared quantile: Abramowitz & Stegun 26.4.17 with 26.2.22.

    Reproduced to match Stable32's tables, including its coefficient 0.27601 where A&S
    print 0.27061 (found by A. Wallin, allantools); relative error up to ~1e-3 near
    EDF = 101, which is why ``interval="exact"`` is the default.
    """
    p = np.minimum(upper_tail, 1.0 - upper_tail)
    t = np.sqrt(-2.0 * np.log(p))
    x = t - (2.30753 + 0.27601 * t) / (1.0 + 0.99229 * t + 0.04481 * t * t)
    x = np.where(upper_tail <= 0.5, x, -x)
    h = 2.0 / (9.0 * edf)
    return edf * (1.0 - h + x * np.sqrt(h)) ** 3


# --- noise identification (Riley & Greenhall 2004) -------------------------------------

def identify_noise(x, ms, *, max_differences=2):
    """Power-law exponent of the rate PSD at each cluster size, lag-1 autocorrelation method.

    For each ``m`` the rate is averaged over non-overlapping clusters (from the running
    sum ``x``), a linear trend removed, and the series differenced ``d`` times until
    ``delta = r1 / (1 + r1) < 0.25`` (at most ``max_differences``); then
    ``alpha = -round(2 delta) - 2 d`` (Riley & Greenhall 2004, eqs 2-4), clipped to
    [-2, 2]. With fewer than 30 averages the value of the previous cluster size is
    kept (0, white rate noise, if there is none). At most the central 2**18 averages
    are used (bounded time and memory on long records). A record the JIT kernels sum takes one
    compiled call for every size (:func:`~bayes_imu.allan.kernels.lag1_deltas`, issue 39), whose
    deltas agree with numpy's steps (:func:`noise_from_phase_samples`) to about 1e-15.
    """
    return _identify(x, ms, x.size - 1, None, max_differences)


def identification_plan(ms, n_samples):
    """``(starts, counts)``: the first phase index and the number of averages of each size's
    identification series (:func:`identification_span`)."""
    ms = np.asarray(ms, dtype=np.int64)
    spans = np.array([identification_span(int(m), n_samples) for m in ms], dtype=np.int64)
    spans = spans.reshape(ms.size, 2)
    return spans[:, 0], (spans[:, 1] - 1 - spans[:, 0]) // ms


def _identify(x, ms, n_samples, points, max_differences=2):
    """:func:`identify_noise` of the phase record ``x``, or of the samples ``points = (values,
    offsets)`` that :func:`~bayes_imu.allan.kernels.allan_sums` gathered from it (the same bits)."""
    starts, counts = identification_plan(ms, n_samples)
    if points is None:
        compiled = lag1_deltas(x, ms, starts, counts, max_differences)  # a long record's
    else:
        compiled = lag1_deltas(
            points[0], ms, points[1], counts, max_differences, steps=np.ones_like(counts),
            n_samples=n_samples,
        )
    if compiled is None:
        samples = [x[a:a + c * int(m) + 1:int(m)] for m, a, c in zip(ms, starts, counts)]
        return noise_from_phase_samples(samples, ms, max_differences=max_differences)
    out = np.empty(len(ms), dtype=np.int64)
    previous = 0
    for i, (delta, d) in enumerate(compiled):
        if counts[i] >= _MIN_ID_POINTS:
            previous = _alpha_of(delta, d)
        out[i] = previous
    return out


def carried_edf(edf, alpha, ms, n_samples):
    """``edf`` with each size whose ``alpha`` rests on fewer than :data:`_TRUSTED_ID_POINTS`
    averages (identified from few, or carried from a shorter size where there are fewer than 30:
    :func:`identify_noise`) given the smallest Greenhall EDF of ``alpha - 1 .. alpha + 1`` (within
    -2 .. 2): the noise type there is not measured well, and one off by one changes the EDF
    several times over (the Xsens MTi-G log's white-rate tail taken as flicker phase: EDF 637,
    342, 173 at 30, 15 and 7.6 averages instead of 43.5, 20.7 and 9.3)."""
    _, counts = identification_plan(ms, n_samples)
    out = np.array(edf, dtype=float)
    for i in np.flatnonzero(counts < _TRUSTED_ID_POINTS):
        near = [a for a in (alpha[i] - 1, alpha[i], alpha[i] + 1) if -2 <= a <= 2]
        out[i] = min(_edf_one(int(a), int(ms[i]), int(n_samples) + 1) for a in near)
    return out


def identification_span(m, n_samples):
    """``(start, stop)`` of the phase indices ``start, start + m, ... < stop`` that
    :func:`identify_noise` uses for cluster size ``m`` (the central 2**18 averages at most)."""
    n_blocks = n_samples // m
    use = min(n_blocks, _MAX_ID_POINTS)
    start = (n_blocks - use) // 2 * m
    return start, start + use * m + 1


def noise_from_phase_samples(samples, ms, *, max_differences=2):
    """:func:`identify_noise` from the phase values at :func:`identification_span` of each ``m``.

    The cluster means and their detrended, differenced series are computed in two buffers of the
    longest series, reused for every size (numpy's temporaries of 2**18 values, fresh pages each,
    cost more than the arithmetic on them), and the time axis once per series length: the same
    operations in the same order, the same numbers as a series at a time (issue 39)."""
    out = np.empty(len(ms), dtype=np.int64)
    size = max([x_m.size - 1 for x_m in samples] + [0])
    means, spare = np.empty(size), np.empty(size)
    times = {}
    previous = 0
    for i, (m, x_m) in enumerate(zip(ms, samples)):
        n = x_m.size - 1
        if n >= _MIN_ID_POINTS:
            series = np.subtract(x_m[1:], x_m[:-1], out=means[:n])  # np.diff(x_m) / m
            series /= int(m)
            if n not in times:
                times[n] = _centred_times(n)
            previous = _lag1_alpha(series, max_differences, work=(times[n], spare[:n]))
        out[i] = previous
    return out


def _dot(a, b):
    """``sum(a * b)`` of two vectors by numpy's own loop: not BLAS, whose threads spin on a busy
    machine, where they made each product far slower (issue 39; timings:
    docs/speed_under_load.md#threads-on-a-busy-machine)."""
    return np.einsum("i,i->", a, b)


def _centred_times(n):
    """``arange(n) - (n - 1) / 2``: the time axis of a series of ``n`` values about its middle."""
    t = np.arange(n, dtype=float)
    t -= (n - 1) / 2.0
    return t


def _lag1_alpha(series, max_differences, *, work=None):
    """The exponent of one series (Riley & Greenhall 2004, eqs 2-4). ``work``: ``(t, spare)``, its
    :func:`_centred_times` and a buffer of its length; ``series`` is then overwritten."""
    return _alpha_of(*_lag1_delta(series, max_differences, work=work))


def _alpha_of(delta, d):
    """``alpha = -round(2 delta) - 2 d`` clipped to [-2, 2] (Riley & Greenhall 2004, eq 4)."""
    return int(np.clip(-np.round(2.0 * delta) - 2 * int(d), -2, 2))


def _lag1_delta(series, max_differences, *, work=None):
    """``(delta, d)`` of :func:`_lag1_alpha`: ``r1 / (1 + r1)`` of the series differenced ``d``
    times."""
    if work is None:
        series = np.array(series, dtype=float)
        work = (_centred_times(series.size), np.empty(series.size))
    t, spare = work
    z = series
    z -= z.mean()
    z -= np.multiply(t, _dot(t, z) / _dot(t, t), out=spare)  # remove the least-squares line
    d = 0
    while True:
        z -= z.mean()
        denom = _dot(z, z)
        r1 = _dot(z[:-1], z[1:]) / denom if denom > 0 else 0.0
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= max_differences:
            return delta, d
        z, spare = np.subtract(z[1:], z[:-1], out=spare[:z.size - 1]), z  # np.diff(z)
        d += 1


# --- equivalent degrees of freedom (Greenhall & Riley 2003) ----------------------------

_TABLE2 = {
    2: (35.0 / 18.0, 1.0),
    1: (790.0, 410.0),
    0: (2.0 / 3.0, 1.0 / 3.0),
    -1: (0.852, 0.375),
    -2: (1.079, 0.368),
}
_TABLE3_B = (15.23, 12.0)  # alpha = 1, d = 2


def _sw(t, alpha):
    """Eq 7: generalized autocovariance of the power-law phase increments (alpha in -2..2)."""
    t = np.abs(np.asarray(t, dtype=float))
    if alpha in (1, -1):
        log_t = np.log(np.where(t > 0, t, 1.0))
        return t ** (3 - alpha) * log_t
    return -t if alpha == 2 else t ** (3 - alpha)


def _sx(t, f, alpha):
    """Eq 8 with filter factor ``f`` (``inf`` for the limit ``m -> inf``)."""
    if np.isinf(f):
        return _sw(t, alpha + 2)
    return f**2 * (2 * _sw(t, alpha) - _sw(t - 1 / f, alpha) - _sw(t + 1 / f, alpha))


def _sz(t, f, alpha):
    """Eq 9 for d = 2 (Allan)."""
    return (
        6 * _sx(t, f, alpha)
        - 4 * _sx(t - 1, f, alpha)
        - 4 * _sx(t + 1, f, alpha)
        + _sx(t - 2, f, alpha)
        + _sx(t + 2, f, alpha)
    )


def _basic_sum(n_lags, n_terms, stride, f, alpha):
    """Eq 10."""
    j = np.arange(1, int(n_lags))
    total = _sz(0.0, f, alpha) ** 2 + (1 - n_lags / n_terms) * _sz(n_lags / stride, f, alpha) ** 2
    return total + np.sum(2 * (1 - j / n_terms) * _sz(j / stride, f, alpha) ** 2)


def greenhall_edf(alpha, m, n_phase):
    """Equivalent degrees of freedom of the fully overlapping Allan variance.

    Greenhall & Riley (2003) with d = 2, unmodified (F = m), overlapping (S = m).

    Parameters
    ----------
    alpha : array_like of int
        Noise exponents in [-2, 2] (rate PSD).
    m : array_like of int
        Cluster sizes.
    n_phase : int
        Number of phase points, ``n_samples + 1``.
    """
    alpha, m = np.broadcast_arrays(np.asarray(alpha, dtype=np.int64), np.asarray(m, dtype=np.int64))
    return np.array(
        [_edf_one(int(a), int(mm), int(n_phase)) for a, mm in zip(alpha, m)], dtype=float
    )


def _edf_one(alpha, m, n_phase):
    d = 2
    n_terms = n_phase - 2 * m  # M = 1 + floor(S (N - L) / m) with L = 2m + 1, S = m
    n_lags = min(n_terms, (d + 1) * m)  # J
    r = n_terms / m
    if alpha == 2:  # case 4
        if np.ceil(r) <= d:
            return 1.0 / (_basic_sum(n_terms, n_terms, m, m, 2) / (_sz(0.0, m, 2) ** 2 * n_terms))
        a0, a1 = _TABLE2[2]  # C(4d, 2d) / C(2d, d)**2 and d / 2
        return 1.0 / ((a0 - a1 / r) / n_terms)
    if alpha == 1:  # case 3
        b0, b1 = _TABLE3_B
        if n_lags <= _J_MAX:
            return 1.0 / (_basic_sum(n_lags, n_terms, m, m, 1) / (_sz(0.0, m, 1) ** 2 * n_terms))
        if r > d + 1:
            a0, a1 = _TABLE2[1]
            return 1.0 / ((a0 - a1 / r) / ((b0 + b1 * np.log(m)) ** 2 * r))
        mp = _J_MAX / r
        return 1.0 / (_basic_sum(_J_MAX, _J_MAX, mp, mp, 1) / ((b0 + b1 * np.log(m)) ** 2 * _J_MAX))
    # case 2: alpha <= 0
    if n_lags <= _J_MAX:
        f = m if m * (d + 1) <= _J_MAX else np.inf
        return 1.0 / (
            _basic_sum(n_lags, n_terms, m, f, alpha) / (_sz(0.0, f, alpha) ** 2 * n_terms)
        )
    if r > d + 1:
        a0, a1 = _TABLE2[alpha]
        return 1.0 / ((a0 - a1 / r) / r)
    mp = _J_MAX / r
    return 1.0 / (
        _basic_sum(_J_MAX, _J_MAX, mp, np.inf, alpha) / (_sz(0.0, np.inf, alpha) ** 2 * _J_MAX)
    )
