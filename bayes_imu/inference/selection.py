"""Posterior mode, Bayesian evidence and model selection ("model only what a scene needs").

Evidence ``Z = int L(theta) pi(theta) dtheta`` of each candidate is estimated by
*defensive importance sampling* (Hesterberg 1995) in unbounded coordinates
``u = logit((phi - lo) / (hi - lo))`` of the log-parameters ``phi``: in ``u`` the uniform
prior becomes a product of standard logistic densities, so the posterior always has an
interior mode even when a term is unsupported and its amplitude runs to the prior's lower
edge (where a Laplace approximation in ``phi`` fails). The proposal is a mixture of a
Student-t (4 dof) centred on the mode with the inverse-Hessian covariance (inflated by
1.5^2) and, with weight 0.3, the prior itself; the estimate is unbiased and consistent,
and its standard error is reported.

Which candidates get importance sampling (the evidences that can matter): every candidate's
mode is found first, with the Laplace approximation of its evidence in ``u``,
``log p(u*) + n/2 log 2 pi - 1/2 log det H`` (H the negative Hessian there, eigenvalues
floored as for the proposal); importance sampling then runs in decreasing order of that
estimate. A candidate keeps its Laplace estimate (``method="laplace"``) when it is more than
:data:`LAPLACE_SCREEN` nats below the largest importance-sampled evidence so far and a pilot
of :data:`PILOT_DRAWS` draws from the importance proposal agrees (:func:`can_skip`): no draw
denser than the mode (an optimiser that stopped short makes the Laplace estimate far too low:
68-1320 nats on some real gyro candidates) and the pilot's estimate that far below too.
``scripts/laplace_screen.py`` checks the rule on the shipped synthetic logs and 37 real channels:
every candidate it would skip has an importance-sampled evidence far below the best
(``docs/reference.md``), so it could not change the selection, and its posterior probability is
below the model average's 1e-3 floor.

Selection rule: the candidate with the largest evidence, except that a candidate with
fewer terms is preferred while its log evidence is within ``threshold`` nats (default 1)
plus twice the Monte Carlo standard error of the difference of the best one — extra terms
must earn a Bayes factor above ``e``, beyond the estimation noise. The selected model is the
answer to "which terms does this sensor need"; drift numbers average over every candidate
with its posterior probability (:func:`model_probabilities`).

Candidates (:func:`candidate_terms`, :func:`extensions`): every ``white + subset`` of the
four IEEE terms (quantization, bias instability, Gauss-Markov bias, rate random walk), then
a stepwise evidence search over the terms real MEMS logs add (filtered white noise, a
high-frequency correlated term, a second Gauss-Markov bias, a rate ramp, a vibration line;
each term's :attr:`~bayes_imu.noise.Term.selection`): from the best candidate so far, each
single addition is scored; the search moves to the best addition while it gains more than
the selection threshold, then goes backward: it scores each single removal from where it stopped and
moves to the best one while that stays within the selection margin of the best evidence so far
(below), until none does. A simpler model the selection rule would prefer is thereby scored even
when it lies two or more removals from where the forward steps stopped (on real ADIS16405 logs the
forward steps can add two terms, neither needed on its own).

Adequacy (:func:`adequacy`): the whitened residuals of ``log avar`` under the likelihood's
own covariance, at the posterior's best draw, are ``N(0, I)`` when the model is right; their
sum of squares is referred to ``chi2(n_tau - n_par)`` (a plug-in goodness-of-fit p-value,
uniform under the model: tests check it), and the cluster size with the largest residual is
reported. A posterior piled against a prior bound is flagged too.
"""

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from .._lazy import LazyModule
from ..noise import REGISTRY

optimize = LazyModule("scipy.optimize")
special = LazyModule("scipy.special")
linalg = LazyModule("scipy.linalg")

__all__ = [
    "CandidateScore",
    "Adequacy",
    "ModeResult",
    "EvidenceResult",
    "candidate_terms",
    "extensions",
    "posterior_mode",
    "newton_mode",
    "log_evidence",
    "laplace_log_evidence",
    "select",
    "within_margin",
    "model_probabilities",
    "adequacy",
    "at_prior_bound",
    "negative_hessian",
    "finite_negative_hessian",
    "to_phi",
    "can_skip",
    "LAPLACE_SCREEN",
]

#: terms of the exhaustive first round and terms added by the stepwise search, in registry
#: order, from each term's declared :attr:`~bayes_imu.noise.Term.selection`
OPTIONAL_TERMS = tuple(name for name, t in REGISTRY.items() if "optional" in t.selection)
EXTENSION_TERMS = tuple(name for name, t in REGISTRY.items() if "extension" in t.selection)
#: terms every candidate has
BASE_MODEL = tuple(name for name, t in REGISTRY.items() if "base" in t.selection)
#: p-value below which a fit is inadequate
ADEQUACY_ALPHA = 0.01
#: a parameter is "at a prior bound" when this fraction of draws lies in the outer BOUND_EDGE of its
#: box
BOUND_FRACTION = 0.10
BOUND_EDGE = 0.02
_T_DOF = 4.0
#: nats below the best importance-sampled evidence beyond which a Laplace estimate is final
LAPLACE_SCREEN = 10.0
#: importance draws of the pilot that confirms a screened candidate (:func:`can_skip`)
PILOT_DRAWS = 256
_PRIOR_WEIGHT = 0.3
_INFLATE = 1.5
#: mode search (:func:`newton_mode`): largest gradient component at a mode, in ``u``
MODE_GTOL = 1e-5
#: central-difference steps in ``u`` of the mode search's gradient and Hessian
GRADIENT_STEP = 1e-6
HESSIAN_STEP = 1e-4
#: step fractions the mode search's line search tries, all in one likelihood call
LINE_FRACTIONS = 0.5 ** np.arange(8)
#: a Newton search ending with a larger gradient component is continued by BFGS
POLISH_GRADIENT = 1e-3


@dataclass(frozen=True)
class CandidateScore:
    """Evidence of one candidate model.

    Attributes
    ----------
    terms : tuple of str
    log_evidence : float
        Natural log of the marginal likelihood (nats).
    log_evidence_se : float
        Monte Carlo standard error of ``log_evidence``.
    ess : float
        Effective sample size of the importance weights.
    mode : ndarray, shape (n_par,)
        Posterior mode in log-parameters (maximum of the density in ``u``).
    method : {"importance", "laplace"}
        How ``log_evidence`` was estimated: by importance sampling, or (a candidate ruled out by
        the Laplace screen, module docstring) by the Laplace approximation alone, ``se`` and
        ``ess`` then 0.
    """

    terms: tuple
    log_evidence: float
    log_evidence_se: float
    ess: float
    mode: np.ndarray
    method: str = "importance"


@dataclass(frozen=True)
class ModeResult:
    """Posterior mode: ``u`` (unbounded coordinates), ``phi`` (log-parameters),
    ``neg_log_density``."""

    u: np.ndarray
    phi: np.ndarray
    neg_log_density: float


@dataclass(frozen=True)
class EvidenceResult:
    """Importance-sampling evidence: ``log_z``, its ``se``, ``ess``, the draws ``u``, their
    ``log_w`` and ``log_density`` (the unnormalised log posterior density of each draw in ``u``)."""

    log_z: float
    se: float
    ess: float
    u: np.ndarray
    log_w: np.ndarray
    log_density: np.ndarray = None


@dataclass(frozen=True)
class Adequacy:
    """Goodness of fit of a posterior (module docstring).

    Attributes
    ----------
    adequate : bool
        ``p_value >= ADEQUACY_ALPHA`` and no parameter at a prior bound.
    p_value : float
    statistic : float
        Sum of squared whitened residuals.
    dof : int
        ``n_tau - n_par`` (at least 1).
    residuals : (n_tau,) ndarray
        Whitened residuals, in cluster-size order (each the innovation of ``log avar`` at
        that size given the shorter ones).
    worst_tau_s : float
        Averaging time of the largest absolute residual [s].
    at_prior_bound : tuple of str
        ``"name (lower)"`` / ``"name (upper)"`` for every parameter piled against its box.
    """

    adequate: bool
    p_value: float
    statistic: float
    dof: int
    residuals: np.ndarray
    worst_tau_s: float
    at_prior_bound: tuple

    def to_dict(self):
        return {
            "adequate": bool(self.adequate),
            "p_value": float(self.p_value),
            "statistic": float(self.statistic),
            "dof": int(self.dof),
            "worst_tau_s": float(self.worst_tau_s),
            "at_prior_bound": list(self.at_prior_bound),
        }


def candidate_terms(optional=OPTIONAL_TERMS):
    """All models ``white + any subset of optional``, simplest first."""
    out = []
    for k in range(len(optional) + 1):
        out += [BASE_MODEL + c for c in combinations(optional, k)]
    return out


def extensions(terms):
    """Candidates one stepwise addition away from ``terms`` (module docstring), in a fixed order."""
    out = []
    for term in EXTENSION_TERMS:
        if term in terms or not set(REGISTRY[term].requires) <= set(terms):
            continue
        out.append(tuple(terms) + (term,))
    return out


def reductions(terms):
    """Candidates one removal away from ``terms`` (base terms stay; a term another one requires,
    gauss_markov for gauss_markov_2, goes only with it)."""
    out = []
    for term in terms:
        if "base" in REGISTRY[term].selection or any(term in REGISTRY[t].requires for t in terms):
            continue
        out.append(tuple(t for t in terms if t != term))
    return out


def model_probabilities(scores):
    """Posterior probability of each candidate from its evidence (equal prior odds over the
    candidates scored)."""
    log_z = np.array([s.log_evidence for s in scores])
    return np.exp(log_z - special.logsumexp(log_z))


def at_prior_bound(post, log_samples):
    """Names of parameters whose draws pile against a bound of the prior box (module docstring)."""
    out = []
    names = list(post.model.parameter_names) + (["model_discrepancy"] if post.discrepancy else [])
    for i, name in enumerate(names):
        lo, hi = post.bounds[i]
        edge = BOUND_EDGE * (hi - lo)
        if np.mean(log_samples[:, i] < lo + edge) > BOUND_FRACTION:
            out.append(f"{name} (lower)")
        if np.mean(log_samples[:, i] > hi - edge) > BOUND_FRACTION:
            out.append(f"{name} (upper)")
    return tuple(out)


def adequacy(post, log_theta, tau, log_samples=None):
    """:class:`Adequacy` of the model at log-parameters ``log_theta`` (the best draw).

    ``post`` is the likelihood without the discrepancy term; ``log_samples`` (draws x
    parameters, log scale) are checked against the prior box.
    """
    n_model = len(post.model.parameter_names)
    r = np.asarray(post.residuals(np.asarray(log_theta, float)[:n_model]), float)
    stat = float(np.sum(r * r))
    dof = max(1, r.size - n_model)
    p = float(special.chdtrc(dof, stat))  # chi-squared survival function
    bound = at_prior_bound(post, log_samples[:, :n_model]) if log_samples is not None else ()
    worst = float(np.asarray(tau)[int(np.argmax(np.abs(r)))])
    return Adequacy(bool(p >= ADEQUACY_ALPHA and not bound), p, stat, dof, r, worst, bound)


def to_phi(u, bounds):
    """Log-parameters from unbounded coordinates ``u`` (logistic map onto the prior box)."""
    return bounds[:, 0] + (bounds[:, 1] - bounds[:, 0]) * special.expit(u)


def _to_u(phi, bounds):
    frac = (phi - bounds[:, 0]) / (bounds[:, 1] - bounds[:, 0])
    return special.logit(np.clip(frac, 1e-9, 1 - 1e-9))


def _log_density_u(post, u):
    """Log posterior density in ``u`` (likelihood x logistic prior), vectorised."""
    u = np.atleast_2d(u)
    # log sigma(u)(1 - sigma(u)) = -(|u| + 2 log1p(e^-|u|)): the two log(1 + e^x) terms, as numpy's
    # logaddexp writes them, in a third of its time (importance sampling evaluates this for every
    # draw)
    size = np.abs(u)
    tail = np.log1p(np.exp(-size))
    log_jac = -((size + tail) + tail).sum(axis=-1)
    return post.log_likelihood(to_phi(u, post.bounds)) + log_jac


def posterior_mode(post, starts):
    """Mode of the density in ``u`` from several starting log-parameter vectors: a
    :class:`ModeResult`.

    From each start, :func:`newton_mode` (a Newton search on finite-difference derivatives, a
    few vectorised likelihood calls per step); where it ends with a gradient above
    :data:`POLISH_GRADIENT` (a kink or wall it cannot step over: an edge of the ordered time
    constants), BFGS goes on from there. The densest end point of all starts is the mode.
    """
    best = None
    for phi0 in np.atleast_2d(starts):
        u0 = _to_u(np.asarray(phi0, float), post.bounds)
        if not np.isfinite(_log_density_u(post, u0)[0]):
            continue
        u, fun, grad = newton_mode(post, u0)
        if np.max(np.abs(grad)) > POLISH_GRADIENT:
            res = optimize.minimize(
                _neg_log_density,
                u,
                args=(post,),
                jac=_neg_gradient,
                method="BFGS",
                options={"gtol": MODE_GTOL, "maxiter": 2000},
            )
            if res.fun < fun:
                u, fun = res.x, float(res.fun)
        if best is None or fun < best[1]:
            best = (u, fun)
    if best is None:
        from ..errors import ConvergenceError

        raise ConvergenceError(
            f"model {post.model.terms}: no starting point has a finite posterior density"
        )
    return ModeResult(best[0], to_phi(best[0], post.bounds), float(best[1]))


def newton_mode(post, u0, *, gtol=None, max_iter=100, max_step=4.0):
    """Local minimum of ``-log density`` in ``u`` by Newton steps from ``u0``.

    Each step is ``-V diag(1/|w|) V' g`` for the eigen-decomposition ``H = V diag(w) V'`` of the
    Hessian (absolute eigenvalues, floored at 1e-6 of the largest: a descent direction where
    ``H`` is indefinite, Dauphin et al. 2014), at most ``max_step`` long, with a backtracking
    (Armijo) line search over the step fractions :data:`LINE_FRACTIONS`. The gradient and
    Hessian are central differences (steps :data:`GRADIENT_STEP`, :data:`HESSIAN_STEP`), all
    ``n^2 + 3n + 1`` points in one vectorised likelihood call; the full step's stencil travels
    with the line search's points, so an accepted full step costs one call. Ends when the
    largest gradient component is below ``gtol`` (default :data:`MODE_GTOL`), when the step
    cannot lower the density by more than rounding, or after ``max_iter`` steps.

    Returns ``(u, neg_log_density, gradient)`` at the end point. It replaced BFGS from each start
    (the search before): on the mode searches of fits of six real ADIS16405 channels
    (296 searches, 721 starts) it was faster and ended denser on 13 searches (by up to 3900 nats:
    BFGS had stopped at another local mode) and less dense on one (by 5.8 nats); on the synthetic
    bench log the same modes (``scripts/study_speed_options.py --modes``; timings:
    docs/speed_under_load.md#sampler).
    """
    gtol = MODE_GTOL if gtol is None else gtol
    offsets, derivatives = _stencil(u0.size)
    n_stencil = offsets.shape[0]
    u = np.asarray(u0, float)
    fun, grad, hess = derivatives(_neg_density(post, u + offsets))
    for _ in range(max_iter):
        if np.max(np.abs(grad)) < gtol:
            break
        w, v = np.linalg.eigh(hess)
        w = np.abs(w)
        w = np.maximum(w, 1e-6 * w.max() + 1e-12)
        step = -v @ ((v.T @ grad) / w)
        length = np.linalg.norm(step)
        if length > max_step:
            step *= max_step / length
        slope = grad @ step
        if -slope < 1e-12 * (1.0 + abs(fun)):  # no decrease beyond rounding left
            break
        values = _neg_density(
            post, np.vstack([u + step + offsets, u + LINE_FRACTIONS[1:, None] * step])
        )
        trial = np.concatenate([values[:1], values[n_stencil:]])
        accept = trial <= fun + 1e-4 * LINE_FRACTIONS * slope
        if accept[0]:
            u = u + step
            fun, grad, hess = derivatives(values[:n_stencil])
            continue
        k = int(np.argmax(accept)) if accept.any() else int(np.argmin(trial))
        if not trial[k] < fun:
            break
        u = u + LINE_FRACTIONS[k] * step
        fun, grad, hess = derivatives(_neg_density(post, u + offsets))
    return u, float(fun), grad


def _neg_density(post, u):
    """``-log density`` at the rows of ``u``, ``+inf`` where it is not finite."""
    value = -_log_density_u(post, u)
    return np.where(np.isfinite(value), value, np.inf)


def _stencil(n):
    """Offsets of the central-difference stencil in ``n`` dimensions and the function that turns the
    values there into ``(value, gradient, Hessian)`` (non-finite differences, next to a wall, read
    as 0)."""
    eye = np.eye(n)
    i, j = np.triu_indices(n, 1)
    pair = eye[i] + eye[j]
    hg, hh = GRADIENT_STEP, HESSIAN_STEP
    offsets = np.vstack(
        [np.zeros((1, n)), hg * eye, -hg * eye, hh * eye, -hh * eye, hh * pair, -hh * pair]
    )

    def derivatives(values):
        f0 = values[0]
        gp, gm, hp, hm = (values[1 + k * n: 1 + (k + 1) * n] for k in range(4))
        pp, mm = values[1 + 4 * n: 1 + 4 * n + i.size], values[1 + 4 * n + i.size:]
        with np.errstate(invalid="ignore"):
            grad = (gp - gm) / (2.0 * hg)
            hess = np.diag((hp - 2.0 * f0 + hm) / hh**2)
            # f(x+a+b) - f(x+a) - f(x+b) + 2 f(x) - f(x-a) - f(x-b) + f(x-a-b) = 2 h^2 H_ab + O(h^4)
            hess[i, j] = hess[j, i] = (pp - hp[i] - hp[j] + 2.0 * f0 - hm[i] - hm[j] + mm) / (
                2.0 * hh * hh
            )
        return f0, np.where(np.isfinite(grad), grad, 0.0), np.where(np.isfinite(hess), hess, 0.0)

    return offsets, derivatives


def _neg_log_density(u, post):
    value = -float(_log_density_u(post, u)[0])
    return value if np.isfinite(value) else 1e300


def _neg_gradient(u, post, step=GRADIENT_STEP):
    """Central differences, all 2n points in one vectorised likelihood call."""
    eye = step * np.eye(u.size)
    vals = _log_density_u(post, np.vstack([u + eye, u - eye]))
    with np.errstate(invalid="ignore"):  # -inf - -inf next to a hard edge: no slope there
        grad = -(vals[: u.size] - vals[u.size :]) / (2.0 * step)
    return np.where(np.isfinite(grad), grad, 0.0)


def negative_hessian(log_density, x0, step=1e-3):
    """``-d2 log_density / dx2`` at ``x0`` by central differences, all points in one vectorised
    call."""
    n = x0.size
    pts, pairs = [], []
    for i in range(n):
        for j in range(i, n):
            for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                d = np.zeros(n)
                d[i] += si * step
                d[j] += sj * step
                pts.append(x0 + d)
            pairs.append((i, j))
    vals = np.asarray(log_density(np.array(pts))).reshape(-1, 4)
    h = np.zeros((n, n))
    with np.errstate(invalid="ignore"):  # non-finite next to a hard edge: the caller handles it
        for (i, j), (pp, pm, mp, mm) in zip(pairs, vals):
            h[i, j] = h[j, i] = -(pp - pm - mp + mm) / (4 * step * step)
    return h


def finite_negative_hessian(log_density, x0, step=1e-3):
    """:func:`negative_hessian` at a point that may sit next to a hard edge (ordered time
    constants, the prior box): the step is shrunk tenfold, up to three times, until every entry is
    finite; entries still non-finite are dropped (zero, unit diagonal)."""
    for _ in range(4):
        h = negative_hessian(log_density, x0, step)
        if np.all(np.isfinite(h)):
            return h
        step /= 10.0
    bad = ~np.isfinite(h)
    h = np.where(bad, 0.0, h)
    h[np.diag(np.diag(bad))] = 1.0
    return h


def _hessian_cov(post, u0, step=1e-3):
    """Inverse of the numerical Hessian of ``-log density`` at ``u0`` (eigenvalues floored)."""
    h = finite_negative_hessian(lambda u: _log_density_u(post, u), u0, step)
    w, v = np.linalg.eigh(h)
    # a flat direction is bounded by the logistic prior (curvature >= ~0.1)
    w = np.clip(w, 1e-2, None)
    return (v / w) @ v.T


def _importance(post, loc, cov, n_draws, rng):
    """One defensive importance-sampling pass: an :class:`EvidenceResult`."""
    t = _StudentT(loc, cov, _T_DOF)
    n_prior = int(round(_PRIOR_WEIGHT * n_draws))
    u = np.vstack([t.rvs(n_draws - n_prior, rng), rng.logistic(size=(n_prior, loc.size))])
    log_prior_u = np.sum(_logistic_logpdf(u), axis=-1)
    log_q = np.logaddexp(
        np.log1p(-_PRIOR_WEIGHT) + t.logpdf(u), np.log(_PRIOR_WEIGHT) + log_prior_u
    )
    log_density = _log_density_u(post, u)
    log_w = log_density - log_q
    log_z = special.logsumexp(log_w) - np.log(n_draws)
    w = np.exp(log_w - log_w.max())
    ess = w.sum() ** 2 / np.sum(w * w)
    # delta-method standard error of the log of a sample mean
    se = float(np.std(w) / (np.sqrt(n_draws) * np.mean(w))) if np.mean(w) > 0 else np.inf
    return EvidenceResult(float(log_z), se, float(ess), u, log_w, log_density)


class _StudentT:
    """Multivariate Student t (location ``loc``, shape matrix ``shape``, ``df`` degrees of freedom),
    the importance proposal: scipy.stats.multivariate_t's algorithm (Hofert 2013, eq 3: a normal
    draw divided by sqrt(chi2_df / df); density from the eigendecomposition of ``shape``), written
    here so that a fit does not import scipy.stats (slow to import); tested to give scipy's draws
    and
    densities."""

    def __init__(self, loc, shape, df):
        self.loc, self.shape, self.df = np.asarray(loc, float), np.asarray(shape, float), float(df)
        s, v = linalg.eigh(self.shape)
        keep = s > 1e6 * np.finfo(float).eps * np.max(np.abs(s))  # numerically non-zero eigenvalues
        self.whiten = v * np.sqrt(np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0))
        self.log_pdet = np.sum(np.log(s[keep]))

    def rvs(self, size, rng):
        """``(size, n)`` draws from the Generator ``rng``."""
        x = rng.chisquare(self.df, size=size) / self.df
        z = rng.multivariate_normal(np.zeros(self.loc.size), self.shape, size=size)
        return self.loc + z / np.sqrt(x)[..., None]

    def logpdf(self, u):
        """Log density at the rows of ``u`` ``(..., n)``."""
        maha = np.square(np.dot(u - self.loc, self.whiten)).sum(axis=-1)
        df, dim = self.df, self.loc.size
        t = 0.5 * (df + dim)
        return (
            special.gammaln(t)
            - special.gammaln(0.5 * df)
            - dim / 2.0 * np.log(df * np.pi)
            - 0.5 * self.log_pdet
            - t * np.log(1 + (1.0 / df) * maha)
        )


def _logistic_logpdf(u):
    """Log density of the standard logistic distribution (the prior in ``u``), overflow-free."""
    y = -np.abs(u)
    return y - 2.0 * special.log1p(np.exp(y))


def _stopped_short(post, u_mode, log_density):
    """Whether draws of these log densities are denser than ``u_mode``: the optimiser stopped short
    of the mode."""
    return bool(np.max(log_density) > _log_density_u(post, u_mode)[0] + 1e-6)


def laplace_log_evidence(post, u_mode):
    """Laplace approximation of ``log Z`` at the mode ``u_mode`` (in ``u``) and the covariance it
    uses.

    Returns ``(log_z, cov)``: ``log p(u*) + n/2 log(2 pi) + 1/2 log det cov``, ``cov`` the inverse
    negative Hessian of the log density with its eigenvalues floored (:func:`log_evidence`'s
    proposal, before inflation).
    """
    cov = _hessian_cov(post, u_mode)
    _, log_det = np.linalg.slogdet(cov)
    log_z = float(
        _log_density_u(post, u_mode)[0] + 0.5 * u_mode.size * np.log(2.0 * np.pi) + 0.5 * log_det
    )
    return log_z, cov


def can_skip(post, u_mode, laplace_z, hessian_cov, best, rng, *, screen=None, n_pilot=PILOT_DRAWS):
    """Whether a candidate's evidence may stay at its Laplace estimate ``laplace_z`` (module
    docstring).

    True when the Laplace estimate is more than ``screen`` (default :data:`LAPLACE_SCREEN`) nats
    below ``best`` and a pilot of ``n_pilot`` draws from the importance proposal agrees: none is
    denser than ``u_mode`` (else the optimiser stopped short of the mode, and the Laplace
    estimate may be far too low) and the pilot's own estimate is also that far below.
    """
    screen = LAPLACE_SCREEN if screen is None else screen
    if not laplace_z < best - screen:
        return False
    pilot = _importance(post, u_mode, _INFLATE**2 * hessian_cov, n_pilot, rng)
    return not _stopped_short(post, u_mode, pilot.log_density) and pilot.log_z < best - screen


def log_evidence(
    post, u_mode, *, n_draws=4000, rng=None, target_se=0.05, max_rounds=3, hessian_cov=None
):
    """Defensive importance-sampling estimate of ``log Z``: an :class:`EvidenceResult`.

    If an importance draw is denser than ``u_mode``, the optimiser stopped short of the mode:
    it is restarted from the densest draws and the first pass repeated around the new mode.
    While the standard error exceeds ``target_se`` (a posterior far from Gaussian in ``u``,
    typically an unsupported term, or a mode the optimiser stopped short of), the proposal is
    refitted to the weighted draws (mean and covariance, an adaptive-importance-sampling
    step, 4x as many draws), at most ``max_rounds`` times; the pass with the smallest standard
    error is returned. When the weight sits on too few draws to estimate a covariance
    (effective sample size below ``n_par + 2``), the refit is the previous proposal widened
    2x and recentred on the best draw. ``hessian_cov``: the inverse negative Hessian at ``u_mode``
    when already computed (:func:`laplace_log_evidence`).
    """
    rng = np.random.default_rng(rng)
    cov = _INFLATE**2 * (_hessian_cov(post, u_mode) if hessian_cov is None else hessian_cov)
    out = _importance(post, u_mode, cov, n_draws, rng)
    # a draw denser than the "mode" means the optimiser stopped short: restart it from the best
    # draws
    top = out.u[np.argsort(out.log_w)[-5:]]
    if _stopped_short(post, u_mode, _log_density_u(post, top)):
        u_mode = posterior_mode(
            post, np.vstack([to_phi(top, post.bounds), to_phi(u_mode, post.bounds)])
        ).u
        cov = _INFLATE**2 * _hessian_cov(post, u_mode)
        out = _importance(post, u_mode, cov, n_draws, rng)
    for _ in range(max_rounds):
        u, log_w, ess = out.u, out.log_w, out.ess
        if out.se <= target_se or not np.isfinite(log_w).any():
            break
        if ess >= u.shape[1] + 2:
            w = np.exp(log_w - log_w.max())
            w /= w.sum()
            mean, cov = (
                w @ u,
                _INFLATE**2 * (np.atleast_2d(np.cov(u.T, aweights=w)) + 1e-6 * np.eye(u.shape[1])),
            )
        else:
            mean, cov = u[np.argmax(log_w)], 4.0 * cov
        refit = _importance(post, mean, cov, 4 * n_draws, rng)
        if not refit.se < out.se:
            break
        out = refit
    return out


def within_margin(score, top, threshold=1.0):
    """Whether ``score``'s log evidence is within ``threshold`` plus twice the Monte Carlo standard
    error of the difference of ``top``'s (:class:`CandidateScore` both): the selection margin."""
    margin = threshold + 2.0 * np.hypot(score.log_evidence_se, top.log_evidence_se)
    return score.log_evidence >= top.log_evidence - margin


def select(scores, *, threshold=1.0):
    """Index of the selected candidate (rule in the module docstring).

    A candidate qualifies when its log evidence is within ``threshold`` plus twice the
    Monte Carlo standard error of the difference of the best one; the qualifying candidate
    with the fewest terms (then the larger evidence) is selected.
    """
    top = max(scores, key=lambda s: s.log_evidence)
    ok = [i for i, s in enumerate(scores) if within_margin(s, top, threshold)]
    return min(ok, key=lambda i: (len(scores[i].terms), -scores[i].log_evidence))
