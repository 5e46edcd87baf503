"""bayes_imu: Bayesian characterization of inertial sensors.

Data flow: ``io -> allan -> noise -> fit / population -> drift / bands -> report -> cli``.
"""

from ._version import __version__
from .allan.estimator import AllanResult, allan_variance
from .allan.autocorr import AutocorrelationResult, autocorrelation_fit
from .drift.closed_forms import (
    QUANTITY_ORDER,
    DriftResult,
    drift_sigma,
    euler_variance,
    gauss_markov_driving_variance,
    noise_density_to_variance,
    noise_variance_to_density,
)
from .errors import BayesIMUError, ConvergenceError, ConvergenceWarning, InputError, ModelError
from .inference.fit import FitResult, fit, fit_allan
from .noise.avar_forms import TERMS, NoiseModel
from .noise.simulate import simulate_log
from .drift.bands import DriftBands, drift_bands, drift_draws
from .drift.nav_bands import NavigationBands, navigation_bands
from .inference.population import PopulationResult, UnitPosterior, fit_population
from .report.scene import build_report, read_scene

__all__ = [
    "__version__",
    "BayesIMUError",
    "InputError",
    "ModelError",
    "ConvergenceError",
    "ConvergenceWarning",
    "AllanResult",
    "allan_variance",
    "AutocorrelationResult",
    "autocorrelation_fit",
    "TERMS",
    "NoiseModel",
    "simulate_log",
    "FitResult",
    "fit",
    "fit_allan",
    "DriftBands",
    "drift_bands",
    "drift_draws",
    "NavigationBands",
    "navigation_bands",
    "fit_population",
    "PopulationResult",
    "UnitPosterior",
    "read_scene",
    "build_report",
    "QUANTITY_ORDER",
    "DriftResult",
    "drift_sigma",
    "euler_variance",
    "gauss_markov_driving_variance",
    "noise_density_to_variance",
    "noise_variance_to_density",
]
