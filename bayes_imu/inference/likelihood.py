"""Priors and likelihoods of Allan variance data, vectorised over walkers.

Likelihoods (choice measured in ``scripts/bench_calibration.py``, see README):

``"correlated"`` (default)
    Multivariate normal on ``log avar`` with the exact covariance of the overlapping
    estimates under the model (:mod:`bayes_imu.noise.avar_covariance`), evaluated once at a
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
from .._lazy import LazyModule

special = LazyModule("scipy.special")

from ..noise.avar_covariance import avar_covariance
from ..errors import InputError
from ..noise import NoiseModel, PriorScale

__all__ = ["LIKELIHOODS", "default_bounds", "prior_scale", "ordered_log_mass", "LogPosterior"]

LIKELIHOODS = ("correlated", "copula", "independent")
#: decades below the smallest / above the largest observed AVAR that a term may reach
PRIOR_DECADES_BELOW = 4.0
PRIOR_DECADES_ABOVE = 1.0
#: log of the model-discrepancy standard deviation (relative error on the Allan variance)
DISCREPANCY_BOUNDS = (float(np.log(1e-3)), float(np.log(3.0)))
#: normal score of the smallest positive float probability, -ndtri(tiny) (checked in
#: tests/test_likelihood.py)
_MAX_SCORE = 37.5193793471445


def prior_scale(allan):
    """The :class:`~bayes_imu.noise.PriorScale` of an Allan result."""
    return PriorScale(
        log_lo=float(np.log(np.min(allan.avar)) - PRIOR_DECADES_BELOW * np.log(10.0)),
        log_hi=float(np.log(np.max(allan.avar)) + PRIOR_DECADES_ABOVE * np.log(10.0)),
        dt=1.0 / allan.rate_hz,
        tau_min=float(allan.tau[0]),
        tau_max=float(allan.tau[-1]),
        m_min=float(allan.m[0]),
        record_s=allan.n_samples / allan.rate_hz,
    )


def default_bounds(model, allan):
    """Box of the log-parameters, shape ``(n_par, 2)`` (natural log of the parameter units).

    Each amplitude is bounded so that its term's largest Allan variance over the fitted
    grid lies between ``10**-4`` times the smallest and ``10**1`` times the largest
    observed value; time constants as each term states (:mod:`bayes_imu.noise`). The
    model-discrepancy row, when used, is :data:`DISCREPANCY_BOUNDS`
    (:meth:`LogPosterior.with_discrepancy`).
    """
    scale = prior_scale(allan)
    return np.array([row for t in model.components for row in t.bounds(scale)], dtype=float)


def ordered_log_mass(bounds, order):
    """``log P(phi_i1 < phi_i2 < ...)`` for independent uniforms on the rows ``order`` of
    ``bounds``.

    The prior of ordered time constants is the box prior restricted to the ordered region,
    renormalised by this mass (so evidences stay comparable). Computed by propagating the
    chain's cumulative probability on a fine grid (error ~1e-9).
    """
    if len(order) < 2:
        return 0.0
    lo = min(bounds[i, 0] for i in order)
    hi = max(bounds[i, 1] for i in order)
    grid = np.linspace(lo, hi, 200001)
    step = grid[1] - grid[0]
    cdf = None
    for i in order:
        a, b = bounds[i]
        density = np.where((grid >= a) & (grid <= b), 1.0 / (b - a), 0.0)
        if cdf is None:
            mass_below = density
        else:
            mass_below = density * cdf  # density of this variable with all previous ones below it
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (mass_below[1:] + mass_below[:-1]) * step)])
    return float(np.log(cdf[-1]))


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
    discrepancy : bool
        The last log-parameter is the log standard deviation ``s`` of a model-discrepancy
        error on ``log avar``: the log-scale covariance becomes ``C + s^2 I``, evaluated
        through the eigen-decomposition ``C = V diag(lam) V'`` (``eig_values``,
        ``eig_vectors``), so each walker costs one product.
    order : tuple of int
        Log-parameters that must increase (ordered Gauss-Markov time constants); the prior
        is the box restricted to that order, renormalised by ``log_order_mass``.
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
    discrepancy: bool = False
    eig_values: np.ndarray = None
    eig_vectors: np.ndarray = None
    order: tuple = ()
    log_order_mass: float = 0.0

    def __post_init__(self):
        if self.evaluate is None:
            object.__setattr__(self, "evaluate", self.model.avar_evaluator(self.m))
        if not self.order and len(self.model.ordered) > 1:
            object.__setattr__(self, "order", self.model.ordered)
            object.__setattr__(
                self, "log_order_mass", ordered_log_mass(self.bounds, self.model.ordered)
            )
        # the uniform prior's log density inside the box, and its edges, computed once (not per
        # call)
        object.__setattr__(
            self, "_log_prior_inside", -float(np.sum(np.log(self.bounds[:, 1] - self.bounds[:, 0])))
        )
        object.__setattr__(self, "_low", np.ascontiguousarray(self.bounds[:, 0]))
        object.__setattr__(self, "_high", np.ascontiguousarray(self.bounds[:, 1]))
        # the observed log AVAR less the log-scale bias (the residual's fixed part), and the
        # discrepancy likelihood's constant: computed once, not per call
        object.__setattr__(self, "_centre", self.log_avar - self.offset)
        object.__setattr__(self, "_half_log_2pi", 0.5 * np.size(self.m) * np.log(2.0 * np.pi))
        n_model = len(self.model.parameter_names)
        if self.bounds.shape[0] != n_model + int(self.discrepancy):
            raise InputError(
                f"prior box has {self.bounds.shape[0]} rows: the model has {n_model} parameters"
                + (" plus the discrepancy" if self.discrepancy else "")
            )

    def with_discrepancy(self):
        """The same likelihood with a model-discrepancy parameter appended (``"correlated"``
        only)."""
        if self.kind != "correlated":
            raise InputError(
                f"likelihood={self.kind!r}: the model-discrepancy term needs 'correlated'"
            )
        if self.discrepancy:
            return self
        chol = np.linalg.inv(self.whiten)  # whiten = chol^-1 (lower triangular)
        values, vectors = np.linalg.eigh(chol @ chol.T)
        bounds = np.vstack([self.bounds, DISCREPANCY_BOUNDS])
        return LogPosterior(
            self.model,
            bounds,
            self.m,
            self.log_avar,
            self.kind,
            self.whiten,
            self.offset,
            self.shape,
            self.norm,
            self.evaluate,
            True,
            np.clip(values, 0.0, None),
            vectors,
            self.order,
            self.log_order_mass,
        )

    def residuals(self, log_theta):
        """Whitened residuals ``(..., n_tau)`` of ``log avar`` under this likelihood's covariance.

        Standard normal and independent at the true parameters when the model is right
        (``"correlated"``; for the others, the normal scores of the gamma marginals).
        With the discrepancy term, whitened by ``C + s^2 I`` at that draw's ``s``.
        """
        log_theta = np.asarray(log_theta, float)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            mu = self.model_log_avar(log_theta)
        if self.kind != "correlated":
            return _normal_scores(self.shape, self.shape * np.exp(self.log_avar - mu))
        res = self.log_avar - mu - self.offset
        if not self.discrepancy:
            return res @ self.whiten.T
        s2 = np.exp(2.0 * log_theta[..., -1:])
        return (res @ self.eig_vectors) / np.sqrt(self.eig_values + s2)

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
            return cls(
                model, bounds, allan.m, log_avar, "copula", precision, np.zeros(k), shape, norm
            )
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
        n_model = self.bounds.shape[0] - int(self.discrepancy)
        return np.log(self.evaluate(np.exp(np.asarray(log_theta)[..., :n_model])))

    def log_likelihood(self, log_theta):
        """Log likelihood ``(...)`` (no prior)."""
        log_theta = np.asarray(log_theta, float)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            mu = self.model_log_avar(log_theta)
        if self.kind == "correlated" and self.discrepancy:
            var = self.eig_values + np.exp(2.0 * log_theta[..., -1:])
            r = (self._centre - mu) @ self.eig_vectors
            r *= r
            r /= var
            r += np.log(var)
            out = -0.5 * r.sum(axis=-1) - self._half_log_2pi
        elif self.kind == "correlated":
            r = (self._centre - mu) @ self.whiten.T
            r *= r
            out = self.norm - 0.5 * r.sum(axis=-1)
        else:
            # gamma(shape, scale = AVAR / shape) density of each observed avar
            with np.errstate(over="ignore", invalid="ignore"):
                y = self.shape * np.exp(self.log_avar - mu)
            out = self.norm + np.sum(-self.shape * mu - y, axis=-1)
            if self.kind == "copula":
                z = _normal_scores(self.shape, y)
                out = out - 0.5 * np.sum((z @ self.whiten) * z, axis=-1)
        if self.order:
            # each ordered time constant above the one before (b > a exactly where b - a > 0)
            order = self.order
            increasing = log_theta[..., order[1]] > log_theta[..., order[0]]
            for a, b in zip(order[1:-1], order[2:]):
                increasing = increasing & (log_theta[..., b] > log_theta[..., a])
            out = np.where(increasing, out - self.log_order_mass, -np.inf)
        return np.where(np.isfinite(out), out, -np.inf)

    def in_prior(self, log_theta):
        return ((log_theta >= self._low) & (log_theta <= self._high)).all(axis=-1)

    def log_prior(self, log_theta):
        """Uniform density on the box of log-parameters."""
        return np.where(
            self.in_prior(np.asarray(log_theta, float)), self._log_prior_inside, -np.inf
        )

    def __call__(self, log_theta):
        """Log posterior (unnormalised), ``-inf`` outside the prior box; emcee
        ``vectorize=True``."""
        log_theta = np.asarray(log_theta, float)
        ok = self.in_prior(log_theta)
        if ok.all():  # the usual case: every point inside the box
            return self._log_prior_inside + self.log_likelihood(log_theta)
        out = np.full(ok.shape, -np.inf)
        if ok.any():
            out[ok] = self._log_prior_inside + self.log_likelihood(log_theta[ok])
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
