"""The bayes_imu exception and warning family.

Every error the package raises on purpose derives from :class:`BayesIMUError`, so a
caller (and the command-line interface) can catch the whole family in one place.
The subclasses also derive from the matching built-in exception so that code written
against ``ValueError`` / ``RuntimeError`` keeps working.
"""

__all__ = [
    "UnmeasuredWarning",
    "BayesIMUError",
    "InputError",
    "ModelError",
    "ConvergenceError",
    "ConvergenceWarning",
]


class BayesIMUError(Exception):
    """Base class of every error raised on purpose by bayes_imu."""


class InputError(BayesIMUError, ValueError):
    """Input data or arguments that cannot be used (file, column, value, option)."""


class ModelError(BayesIMUError, ValueError):
    """Model parameters outside the domain where a formula or model is defined."""


class ConvergenceError(BayesIMUError, RuntimeError):
    """A numerical procedure (optimiser, sampler) failed in a way that cannot be hidden."""


class ConvergenceWarning(UserWarning):
    """The sampler ran, but its diagnostics say the result is not yet trustworthy."""


class UnmeasuredWarning(UserWarning):
    """Drift bands asked at semantics the record did not measure: they are the model's alone."""
