"""Stage 4, inference: an :class:`~bayes_imu.allan.AllanResult` in, posteriors out.

Owns the AVAR likelihoods (:mod:`~bayes_imu.inference.likelihood`), evidences, model selection
and the adequacy check (:mod:`~bayes_imu.inference.selection`), the stationarity check
(:mod:`~bayes_imu.inference.stationarity`), R-hat and ESS (:mod:`~bayes_imu.inference.diagnostics`),
the emcee ensemble (:mod:`~bayes_imu.inference.sampling`), the sampler and :class:`FitResult`
(:mod:`~bayes_imu.inference.fit`), the hierarchical population fit
(:mod:`~bayes_imu.inference.population`) and saved fits (:mod:`~bayes_imu.inference.archive`).
"""

from .fit import (
    FitResult,
    MixtureComponent,
    SamplerChains,
    fit,
    fit_allan,
    score_models,
    DISCREPANCY_MODES,
)
from .population import (
    PopulationResult,
    UnitPosterior,
    fit_population,
)

__all__ = [
    "FitResult",
    "MixtureComponent",
    "SamplerChains",
    "fit",
    "fit_allan",
    "score_models",
    "DISCREPANCY_MODES",
    "PopulationResult",
    "UnitPosterior",
    "fit_population",
]
