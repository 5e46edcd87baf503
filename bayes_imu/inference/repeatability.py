"""Parameter intervals that include the spread between parts of the record ("repeatability").

A fit's posterior describes the record as if its noise were one stationary process: on a long
log its intervals shrink as ``1/sqrt(n)``. When the between-segment check
(:mod:`bayes_imu.inference.stationarity`) finds that the noise changes between parts of the
record, a later stretch of the same sensor (the next hour, the other half of the log) differs
from this record by about as much as the parts differ from each other, and intervals of "this
record" are too narrow for it.

The "repeatability between parts" draws multiply each posterior draw of an amplitude parameter
by ``exp(z p s)``, ``z ~ N(0, 1)`` one per draw: ``s`` is the between-part standard deviation of
``ln AVAR`` beyond sampling (:attr:`~bayes_imu.inference.stationarity.Stationarity.spread`) and
``p`` the power of AVAR the parameter scales with (1 for a variance, 1/2 for an amplitude or a
density; 0 for a time constant, which is left alone). The spread is read at the shortest
averaging time checked for the short-term terms (white, quantization, filtered white and the
noise densities: they set the Allan variance there) and at the largest spread for the biases and
slow terms (the spread is non-decreasing in tau, so this is conservative). Each half of the
record gets the same deterministic normal scores ``z`` (:func:`normal_scores`: an equidistributed
sequence mapped through the normal quantile, one stream per parameter, no random state); the
posterior draws are in chain order, unrelated to the scores' order. For a stationary log the
repeatability draws are the record's.

An ``s`` estimated from four parts is itself uncertain: it is inflated to its one-sided 90%
upper confidence bound under a chi-square with ``K - 1`` degrees of freedom for the
between-part variance (``s^2 (K - 1) / chi2_{K-1}(0.1)``), so that a record whose parts happen
to agree closely does not claim more repeatability than four parts can show.
"""

import numpy as np

from .._lazy import LazyModule
from ..noise.avar_forms import PARAMETER_UNITS
from ..noise.model import REGISTRY

special = LazyModule("scipy.special")

__all__ = ["repeatability_spread", "repeatability_draws", "normal_scores", "SPREAD_CONFIDENCE"]

#: one-sided confidence of the upper bound on the between-part spread
SPREAD_CONFIDENCE = 0.9
#: parameters read at the shortest averaging time: those of the short-term terms (their role)
_SHORT = {p for t in REGISTRY.values() if t.role == "short_term" for p in t.parameters} | {
    "noise_density", "white_noise_density"}
#: additive-recurrence steps of the score streams (fractional parts of irrational numbers)
_STEPS = (0.6180339887498949, 0.7548776662466927, 0.5698402909980532, 0.4142135623730951)


def normal_scores(n, stream=0):
    """``n`` deterministic standard normal scores: ``Phi^-1(frac(1/2 + (i + 1/2) a))`` for an
    irrational step ``a`` (one per stream), equidistributed in (0, 1) like a random sample's
    uniform scores but with no random state."""
    u = np.mod(0.5 + (np.arange(n) + 0.5) * _STEPS[stream % len(_STEPS)] + 0.1 * (stream // len(_STEPS)), 1.0)
    return special.ndtri(u)


def _power(name):
    unit = PARAMETER_UNITS.get(name, "1")
    if unit in ("s", "Hz"):
        return 0.0
    return 1.0 if unit.startswith("({u})^2") else 0.5


def repeatability_spread(stationarity):
    """``(short, long)`` between-part standard deviations of ``ln AVAR`` (0 for a stationary log),
    at their upper confidence bound (module docstring)."""
    if stationarity is None or stationarity.stationary or stationarity.spread.size == 0:
        return 0.0, 0.0
    k = stationarity.n_segments
    inflate = np.sqrt((k - 1) / (2.0 * special.gammaincinv((k - 1) / 2.0, 1.0 - SPREAD_CONFIDENCE)))
    return float(stationarity.spread[0] * inflate), float(stationarity.spread.max() * inflate)


def repeatability_draws(name, draws, stationarity, stream=0):
    """Draws of parameter ``name`` widened by the between-part spread (module docstring)."""
    short, long = repeatability_spread(stationarity)
    s = short if name in _SHORT else long
    power = _power(name)
    draws = np.asarray(draws, dtype=float)
    if s == 0.0 or power == 0.0:
        return draws
    z = normal_scores(draws.size, stream).reshape(draws.shape)
    return draws * np.exp(z * power * s)
