"""bayes_imu: Bayesian characterization of inertial sensors.

Data flow: ``io -> allan -> noise -> fit / population -> drift / bands -> report -> cli``.
"""

from ._version import __version__
from .allan import AllanResult, allan_variance
from .autocorr import AutocorrelationResult, autocorrelation_fit
from .drift import (
    QUANTITY_ORDER,
    DriftResult,
    drift_sigma,
    euler_variance,
    gauss_markov_driving_variance,
    noise_density_to_variance,
    noise_variance_to_density,
)
from .errors import BayesIMUError, ConvergenceError, ConvergenceWarning, InputError, ModelError
from .fit import FitResult, fit, fit_allan
from .models import TERMS, NoiseModel
from .simulate import simulate_log
from .bands import DriftBands, drift_bands, drift_draws
from .population import PopulationResult, UnitPosterior, fit_population
from .report import build_report, read_scene

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
