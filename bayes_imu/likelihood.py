"""Priors and likelihoods of Allan variance data, vectorised over walkers.

Likelihoods (choice measured in ``scripts/bench_calibration.py``, see README):

``"correlated"`` (default)
    Multivariate normal on ``log avar`` with the exact covariance of the overlapping
    estimates under the model (:mod:`bayes_imu.avar_covariance`), evaluated once at a
    reference parameter point: EDF ``nu_i = 2 AVAR_i^2 / Var_i``, correlation ``rho_ij``.
    Each ``avar_i / AVAR_i`` is close to ``chi2(nu_i) / nu_i``, so ``log avar_i`` has mean
    ``log AVAR_i + psi(nu_i/2) - log(nu_i/2)`` (digamma) and variance ``psi'(nu_i/2)``
    (trigamma); the log-scale covariance is ``rho_ij sqrt(psi'_i psi'_j)``.
``"independent"``
    Product of gamma densities with the Greenhall EDF of the Allan result: the common
    approach, kept as the baseline the calibration study shows to be overconfident.

Priors: every parameter is sampled as its natural logarithm with a uniform (proper)
prior on a box (:func:`default_bounds`), i.e. log-uniform in the parameter.
"""

from dataclasses import dataclass

import numpy as np
from scipy import special

from .avar_covariance import avar_covariance
from .errors import InputError
from .models import NoiseModel

__all__ = ["LIKELIHOODS", "default_bounds", "LogPosterior"]

LIKELIHOODS = ("correlated", "copula", "independent")
#: decades below the smallest / above the largest observed AVAR that a term may reach
PRIOR_DECADES_BELOW = 4.0
PRIOR_DECADES_ABOVE = 1.0
#: Gauss-Markov time constant range, in samples (low) and fraction of the record (high)
TIME_CONSTANT_MIN_SAMPLES = 3.0
TIME_CONSTANT_MAX_RECORD = 0.25
_MAX_SCORE = float(-special.ndtri(np.finfo(float).tiny))  # 37.5: normal score of the smallest probability
_GM_PEAK = 0.3  # ~max over tau of a Gauss-Markov AVAR / sigma_b^2 (continuous value 0.30)


def default_bounds(model, allan):
    """Box of the log-parameters, shape ``(n_par, 2)`` (natural log of the parameter units).

    Each amplitude is bounded so that its term's largest Allan variance over the fitted
    grid lies between ``10**-4`` times the smallest and ``10**1`` times the largest
    observed value; the time constant between 3 samples and a quarter of the record.
    """
    lo = np.log(np.min(allan.avar)) - PRIOR_DECADES_BELOW * np.log(10.0)
    hi = np.log(np.max(allan.avar)) + PRIOR_DECADES_ABOVE * np.log(10.0)
    dt = 1.0 / allan.rate_hz
    tau_min, tau_max = float(allan.tau[0]), float(allan.tau[-1])
    # log(parameter) = log(term peak AVAR) + shift; amplitude parameters entering squared get / 2
    rules = {
        "noise_variance": (np.log(allan.m[0]), 1.0),
        "quantization": (np.log(tau_min**2 / 3.0), 0.5),
        "bias_instability": (np.log(np.pi / (2.0 * np.log(2.0))), 0.5),
        "bias_variance": (-np.log(_GM_PEAK), 1.0),
        "rate_random_walk": (np.log(3.0 / tau_max), 0.5),
    }
    rows = []
    for name in model.parameter_names:
        if name == "time_constant":
            rows.append((np.log(TIME_CONSTANT_MIN_SAMPLES * dt), np.log(TIME_CONSTANT_MAX_RECORD * allan.n_samples * dt)))
        else:
            shift, power = rules[name]
            rows.append(((lo + shift) * power, (hi + shift) * power))
    return np.array(rows)


@dataclass(frozen=True)
class LogPosterior:
    """Log posterior of the log-parameters, vectorised: ``(..., n_par) -> (...)``.

    Attributes
    ----------
    model : NoiseModel
    bounds : (n_par, 2) ndarray
        Uniform prior box of the log-parameters.
    m : (n_tau,) int
    log_avar : (n_tau,) observed log Allan variance.
    kind : str
    whiten : (n_tau, n_tau) ndarray
        Inverse Cholesky factor of the log-scale covariance (``"correlated"``).
    offset : (n_tau,) digamma bias ``psi(nu/2) - log(nu/2)``.
    shape : (n_tau,) gamma shapes ``nu/2``.
    norm : float
        Constant of the log likelihood.
    evaluate : callable
        The model's Allan variance at ``m`` (:meth:`NoiseModel.avar_evaluator`).
    """

    model: NoiseModel
    bounds: np.ndarray
    m: np.ndarray
    log_avar: np.ndarray
    kind: str
    whiten: np.ndarray
    offset: np.ndarray
    shape: np.ndarray
    norm: float
    evaluate: object = None

    def __post_init__(self):
        if self.evaluate is None:
            object.__setattr__(self, "evaluate", self.model.avar_evaluator(self.m))

    @classmethod
    def build(cls, model, allan, *, kind="correlated", reference=None, bounds=None):
        """Likelihood for ``allan`` under ``model``; ``reference`` (dict) sets the covariance.

        ``reference`` may belong to a larger model (a dict with that model's parameters
        and a ``"_model"`` key); the covariance is then computed under that model.
        """
        if kind not in LIKELIHOODS:
            raise InputError(f"likelihood={kind!r}: expected one of {', '.join(LIKELIHOODS)}")
        bounds = default_bounds(model, allan) if bounds is None else np.asarray(bounds, float)
        log_avar = np.log(allan.avar)
        k = allan.m.size
        if kind == "independent":
            shape = allan.edf / 2.0
            norm = _gamma_norm(shape, log_avar)
            return cls(model, bounds, allan.m, log_avar, kind, np.eye(k), np.zeros(k), shape, norm)
        if reference is None:
            raise InputError(f"likelihood={kind!r} needs a reference parameter point")
        ref_model = reference.get("_model", model)
        cov = avar_covariance(ref_model, reference, allan.m, allan.n_samples)
        ref_avar = ref_model.avar(allan.m, reference)
        return cls.from_covariance(model, allan, cov, ref_avar, bounds, kind=kind)

    @classmethod
    def from_covariance(cls, model, allan, cov, ref_avar, bounds, *, kind="correlated"):
        """Correlated likelihood from an AVAR covariance matrix and the AVAR it belongs to."""
        sd = np.sqrt(np.diag(cov))
        rho = cov / np.outer(sd, sd)
        nu = 2.0 * ref_avar**2 / np.diag(cov)
        k = allan.m.size
        log_avar = np.log(allan.avar)
        if kind == "copula":
            # Gaussian copula: exact gamma marginals, correlation of the normal scores = rho;
            # the log density of the copula is -log|R|/2 - z'(R^-1 - I)z/2 (whiten = R^-1 - I)
            shape = nu / 2.0
            chol = np.linalg.cholesky(rho)
            norm = _gamma_norm(shape, log_avar) - float(np.sum(np.log(np.diag(chol))))
            precision = np.linalg.inv(rho) - np.eye(k)
            return cls(model, bounds, allan.m, log_avar, "copula", precision, np.zeros(k), shape, norm)
        trig = special.polygamma(1, nu / 2.0)
        log_cov = rho * np.sqrt(np.outer(trig, trig))
        chol = np.linalg.cholesky(log_cov)
        whiten = np.linalg.inv(chol)
        offset = special.digamma(nu / 2.0) - np.log(nu / 2.0)
        norm = float(-np.sum(np.log(np.diag(chol))) - 0.5 * k * np.log(2.0 * np.pi))
        return cls(model, bounds, allan.m, log_avar, "correlated", whiten, offset, nu / 2.0, norm)

    @property
    def n_par(self):
        return self.bounds.shape[0]

    def model_log_avar(self, log_theta):
        """``log AVAR`` of the model at log-parameters ``(..., n_par)`` -> ``(..., n_tau)``."""
        return np.log(self.evaluate(np.exp(log_theta)))

    def log_likelihood(self, log_theta):
        """Log likelihood ``(...)`` (no prior)."""
        log_theta = np.asarray(log_theta, float)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            mu = self.model_log_avar(log_theta)
        if self.kind == "correlated":
            r = (self.log_avar - mu - self.offset) @ self.whiten.T
            out = self.norm - 0.5 * np.sum(r * r, axis=-1)
        else:
            # gamma(shape, scale = AVAR / shape) density of each observed avar
            with np.errstate(over="ignore", invalid="ignore"):
                y = self.shape * np.exp(self.log_avar - mu)
            out = self.norm + np.sum(-self.shape * mu - y, axis=-1)
            if self.kind == "copula":
                z = _normal_scores(self.shape, y)
                out = out - 0.5 * np.sum((z @ self.whiten) * z, axis=-1)
        return np.where(np.isfinite(out), out, -np.inf)

    def in_prior(self, log_theta):
        return np.all((log_theta >= self.bounds[:, 0]) & (log_theta <= self.bounds[:, 1]), axis=-1)

    def log_prior(self, log_theta):
        """Uniform density on the box of log-parameters."""
        width = np.sum(np.log(self.bounds[:, 1] - self.bounds[:, 0]))
        return np.where(self.in_prior(np.asarray(log_theta, float)), -width, -np.inf)

    def __call__(self, log_theta):
        """Log posterior (unnormalised), ``-inf`` outside the prior box; emcee ``vectorize=True``."""
        log_theta = np.asarray(log_theta, float)
        lp = self.log_prior(log_theta)
        ok = np.isfinite(lp)
        out = np.full(lp.shape, -np.inf)
        if np.any(ok):
            out[ok] = lp[ok] + self.log_likelihood(log_theta[ok])
        return out


def _gamma_norm(shape, log_avar):
    """Constant part of the gamma(shape, AVAR / shape) log density of the observed AVARs."""
    return float(np.sum(shape * np.log(shape) - special.gammaln(shape) + (shape - 1.0) * log_avar))


def _normal_scores(shape, y):
    """``Phi^-1(P(shape, y))`` (regularised lower incomplete gamma), exact and always finite.

    Each tail is computed from its own incomplete gamma function, so the score is exact
    down to tail probabilities of 1e-308 (``|z| = 37.5``); beyond, where the probability
    underflows, it is held at that value (continuous), and the gamma marginals alone
    steer an optimiser back, instead of a ``-inf`` plateau.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        lower = special.gammainc(shape, y)
        upper = special.gammaincc(shape, y)
        z = np.where(lower < 0.5, special.ndtri(lower), -special.ndtri(upper))
    return np.clip(z, -_MAX_SCORE, _MAX_SCORE)
