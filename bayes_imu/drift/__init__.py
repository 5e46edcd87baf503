"""Stage 5, drift: noise parameters (or posterior draws) in, drift of the integrated quantity out.

Owns the paper's closed forms of Euler-integrated noise and the datasheet-level
:func:`drift_sigma` (:mod:`~bayes_imu.drift.closed_forms`), the credible bands of a fit
(:mod:`~bayes_imu.drift.bands`), overbounding filter parameters
(:mod:`~bayes_imu.drift.overbound`), record-length plans (:mod:`~bayes_imu.drift.plan`) and
display units (:mod:`~bayes_imu.drift.display`). Each noise term's own drift variance lives
with the term (:mod:`bayes_imu.noise`).
"""

from .closed_forms import (
    QUANTITY_ORDER,
    DriftResult,
    euler_variance,
    drift_sigma,
    noise_density_to_variance,
    noise_variance_to_density,
    gauss_markov_driving_variance,
)
from .bands import (
    DriftBands,
    drift_bands,
    drift_draws,
)
from .navigation import NavLoop
from .nav_bands import NavigationBands, NavQuantity, longest_outage, navigation_bands
from .overbound import OverboundResult, overbound
from .plan import PlanResult, plan_from_fit, plan_record_length

__all__ = [
    "QUANTITY_ORDER",
    "DriftResult",
    "euler_variance",
    "drift_sigma",
    "noise_density_to_variance",
    "noise_variance_to_density",
    "gauss_markov_driving_variance",
    "DriftBands",
    "drift_bands",
    "drift_draws",
    "NavLoop",
    "NavigationBands",
    "NavQuantity",
    "navigation_bands",
    "OverboundResult",
    "overbound",
    "PlanResult",
    "plan_from_fit",
    "plan_record_length",
    "longest_outage",
]
