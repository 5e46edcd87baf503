"""Parameter intervals that include the spread between parts of the record ("repeatability").

A fit's posterior describes the record as if its noise were one stationary process: on a long
log its intervals shrink as ``1/sqrt(n)``. Real MEMS noise is not quite stationary (warm-up,
temperature): the first and the second half of an ADIS16405 log give angle random walks 1%
apart whose "this record" intervals are +-0.25% wide. The interval a user copies must hold for
the sensor, not only for the record; this module measures that in the record itself.

**Between-part intervals (measured; applied to every record).** The ``K`` consecutive parts of
the stationarity check (:class:`bayes_imu.allan.estimator.SegmentAllan`, ``K = 4``) each read
every term's Allan-variance scale: with ``r_k = ln avar_k - mean_j ln avar_j`` over the part
sizes the check keeps, ``w_T = AVAR_T / AVAR`` the term's share of the fitted model's Allan
variance (posterior median) and ``C`` the covariance of one part's ``ln avar`` under that
model (:func:`~bayes_imu.noise.avar_covariance.avar_covariance`), the generalised least-squares
scale of the term in part ``k`` is ``d_k = w' C^-1 r_k / (w' C^-1 w)``, with sampling standard
deviation ``1 / sqrt(w' C^-1 w)`` under the model (:func:`part_reads`). A parameter that scales
as ``AVAR^p`` (``p = 1`` a variance, ``1/2`` an amplitude or density, ``0`` a time constant,
left alone) then has ``K`` readings ``p d_k`` of its log, and the batch-means (Student-t)
90% interval of the record's mean, half-width ``h_B = t_{K-1}(0.95) sd(p d) / sqrt(K)``, holds
whether the parts differ by sampling alone or also by a change of the sensor. It is combined
with the posterior's own half-width ``h_P`` (of the log draws) as the wider of the two: each
draw is multiplied by ``exp(e z)``, ``z`` deterministic normal scores (:func:`normal_scores`:
no random state), ``e = sqrt(max(0, h_B^2 - h_P^2)) / z_0.95`` (:func:`between_parts_sd`),
so that the widened half-width is about ``max(h_B, h_P)``. On a stationary log the price is
the Student-t factor of four parts where the posterior is as sharp as the parts; the coverage
of the truth and the widths are measured in docs/validation/honesty.md
(``scripts/repeatability_coverage.py``).

Groups read together: ``noise_density`` by the short-term terms a Kalibr density stands for,
``white_noise_density`` by the white term, the Kalibr random walk by the bias and slow terms,
every other parameter by its own term.

**Fallback (the old spread rule).** A term the parts cannot read (its per-part sampling
standard deviation above :data:`MAX_READ_SD` in ``ln AVAR``: a bias or random walk that
shows only beyond a quarter of a part) keeps its record interval, unless the stationarity
check flags the record: then each draw is multiplied by ``exp(z p s)``, ``s`` the between-part
standard deviation of ``ln AVAR`` beyond sampling
(:attr:`~bayes_imu.inference.stationarity.Stationarity.spread`) at its largest (the short-term
terms: at the shortest size), inflated to its one-sided 90% upper confidence bound under a
chi-square with ``K - 1`` degrees of freedom (``s^2 (K - 1) / chi2_{K-1}(0.1)``), so that a
record whose parts happen to agree does not claim more repeatability than four parts show.
"""

from dataclasses import dataclass

import numpy as np

from .._lazy import LazyModule
from ..noise.avar_covariance import avar_covariance
from ..noise.avar_forms import PARAMETER_UNITS
from ..noise.model import REGISTRY

special = LazyModule("scipy.special")

__all__ = ["PartReads", "part_reads", "between_parts_sd", "widen", "group_of", "kalibr_group",
           "repeatability_spread", "repeatability_draws", "normal_scores", "SPREAD_CONFIDENCE",
           "MAX_READ_SD", "INTERVAL_MASS"]

#: one-sided confidence of the upper bound on the between-part spread
SPREAD_CONFIDENCE = 0.9
#: per-part sampling standard deviation of a term's ln AVAR scale above which the parts cannot
#: read it
MAX_READ_SD = 0.5
#: probability mass of the intervals printed (q05-q95)
INTERVAL_MASS = 0.9
#: parameters read at the shortest averaging time: those of the short-term terms (their role)
_SHORT = {p for t in REGISTRY.values() if t.role == "short_term" for p in t.parameters} | {
    "noise_density", "white_noise_density"}
#: additive-recurrence steps of the score streams (fractional parts of irrational numbers)
_STEPS = (0.6180339887498949, 0.7548776662466927, 0.5698402909980532, 0.4142135623730951)


def normal_scores(n, stream=0):
    """``n`` deterministic standard normal scores: ``Phi^-1(frac(1/2 + (i + 1/2) a))`` for an
    irrational step ``a`` (one per stream), equidistributed in (0, 1) like a random sample's
    uniform scores but with no random state."""
    u = np.mod(
        0.5 + (np.arange(n) + 0.5) * _STEPS[stream % len(_STEPS)] + 0.1 * (stream // len(_STEPS)),
        1.0,
    )
    return special.ndtri(u)


def _power(name):
    unit = PARAMETER_UNITS.get(name, "1")
    if unit in ("s", "Hz"):
        return 0.0
    return 1.0 if unit.startswith("({u})^2") else 0.5


@dataclass(frozen=True)
class PartReads:
    """What the parts of a record say about each term's Allan-variance scale (module docstring).

    Attributes
    ----------
    log_dev : (n_parts, n_tau) ndarray
        ``ln avar_k - mean_j ln avar_j`` of each part at the sizes the stationarity check kept.
    shares : dict
        Term name -> ``(n_tau,)`` share ``AVAR_T / AVAR`` of the fitted model (posterior median).
    precision : (n_tau, n_tau) ndarray
        Inverse covariance of one part's ``ln avar`` under that model.
    """

    log_dev: np.ndarray
    shares: dict
    precision: np.ndarray

    @property
    def n_parts(self):
        return int(self.log_dev.shape[0])

    def read(self, terms):
        """``(d, sd)``: the ``(n_parts,)`` generalised least-squares ln-AVAR scales of the terms
        together, and one part's sampling standard deviation of a scale; ``None`` when the
        model has none of ``terms``."""
        present = [self.shares[t] for t in terms if t in self.shares]
        if not present:
            return None
        w = np.sum(present, axis=0)
        cw = self.precision @ w
        info = float(w @ cw)
        if not info > 0:
            return None
        return self.log_dev @ cw / info, 1.0 / np.sqrt(info)


def part_reads(model, params, stationarity, n_segment, rate_hz):
    """:class:`PartReads` of a fit: ``model`` at one parameter point ``params`` (dict of float),
    the record's :class:`~bayes_imu.inference.stationarity.Stationarity` (its parts' Allan
    deviations), ``n_segment`` samples per part at ``rate_hz`` [Hz]. ``None`` without parts."""
    if stationarity is None or stationarity.tau_s.size == 0 or stationarity.n_segments < 2:
        return None
    m = np.round(np.asarray(stationarity.tau_s) * rate_hz).astype(np.int64)
    total = model.avar(m, params)
    shares = {t: model.term_avar(t, m, params) / total for t in model.terms}
    cov = avar_covariance(model, params, m, n_segment) / np.outer(total, total)
    log_avar = 2.0 * np.log(stationarity.segment_adev)
    precision = np.linalg.pinv(cov, rcond=1e-12, hermitian=True)
    return PartReads(log_avar - log_avar.mean(axis=0), shares, precision)


def between_parts_sd(readings, log_draws, mass=INTERVAL_MASS):
    """Extra standard deviation ``e`` of the log of a parameter whose parts read ``readings``
    (``(n_parts,)`` logs), given the posterior's log draws: ``sqrt(max(0, h_B^2 - h_P^2)) / z``
    (module docstring), ``z`` the normal quantile of the interval's upper end."""
    k = readings.size
    upper = 0.5 + 0.5 * mass
    h_b = special.stdtrit(k - 1, upper) * np.std(readings, ddof=1) / np.sqrt(k)
    lo, hi = np.quantile(log_draws, [1.0 - upper, upper])
    h_p = 0.5 * (hi - lo)
    return float(np.sqrt(max(0.0, h_b * h_b - h_p * h_p)) / special.ndtri(upper))


def kalibr_group(model, role):
    """The terms of ``model`` with Kalibr role ``role`` (``"noise_density"``: the short-term terms
    a Kalibr noise density stands for; ``"random_walk"``: the bias and slow terms)."""
    return tuple(t.name for t in model.components if t.kalibr == role)


def group_of(name, model):
    """``(terms, power)``: the terms that read parameter ``name`` of ``model`` together and the
    power of AVAR it scales with (module docstring); ``((), 0)`` for a parameter of no term."""
    if name == "noise_density":
        return kalibr_group(model, "noise_density"), 0.5
    if name == "white_noise_density":
        return ("white",), 0.5
    owner = [t.name for t in model.components if name in t.parameters]
    return (tuple(owner), _power(name)) if owner else ((), 0.0)


def widen(draws, terms, power, reads, stationarity, stream=0, *, short=False):
    """Draws of a parameter (scaling as ``AVAR^power``, read by ``terms`` together) widened by
    the repeatability between parts (module docstring); ``short`` picks the fallback spread of
    the short-term terms."""
    draws = np.asarray(draws, dtype=float)
    if power == 0.0 or not terms:
        return draws
    read = None if reads is None else reads.read(terms)
    if read is not None and read[1] <= MAX_READ_SD:
        e = between_parts_sd(power * read[0], np.log(draws))
    else:
        e = power * repeatability_spread(stationarity)[0 if short else 1]
    if e == 0.0:
        return draws
    return draws * np.exp(e * normal_scores(draws.size, stream).reshape(draws.shape))


def repeatability_spread(stationarity):
    """``(short, long)`` between-part standard deviations of ``ln AVAR`` (0 for a stationary log),
    at their upper confidence bound (module docstring)."""
    if stationarity is None or stationarity.stationary or stationarity.spread.size == 0:
        return 0.0, 0.0
    k = stationarity.n_segments
    inflate = np.sqrt((k - 1) / (2.0 * special.gammaincinv((k - 1) / 2.0, 1.0 - SPREAD_CONFIDENCE)))
    return float(stationarity.spread[0] * inflate), float(stationarity.spread.max() * inflate)


def repeatability_draws(name, draws, stationarity, stream=0, *, reads=None, model=None):
    """Draws of parameter ``name`` widened by the repeatability between parts (module docstring):
    measured by ``reads`` (:func:`part_reads`) where the parts read the parameter's terms, else
    the fallback spread of a flagged record. Without ``reads`` and ``model`` only the fallback."""
    if model is None:
        return widen(draws, (name,), _power(name), None, stationarity, stream, short=name in _SHORT)
    terms, power = group_of(name, model)
    return widen(draws, terms, power, reads, stationarity, stream, short=name in _SHORT)
