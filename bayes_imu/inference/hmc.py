"""Hamiltonian Monte Carlo on several independent chains at once (the population sampler).

A smooth log density of a few tens of parameters with its gradient, vectorised over rows,
sampled by HMC (Neal 2011, "MCMC using Hamiltonian dynamics", Handbook of MCMC ch. 5): every
chain takes its own leapfrog trajectory, all chains advance together (one call of the density
per leapfrog step for all of them). Warm-up adapts the step size by dual averaging towards an
acceptance of :data:`TARGET_ACCEPT` (Hoffman & Gelman 2014, JMLR 15, 1593, algorithm 5) and a
diagonal mass matrix from the chains' variances (two windows). Each trajectory is about
:data:`TRAJECTORY` standard deviations long (a quarter period of a Gaussian), its number of steps
jittered by up to 50% against periodic orbits.

The chains are independent, so convergence is judged by chains as the textbook asks: split
R-hat (Gelman et al. 2013, BDA3 eq 11.4) and the effective number of draws from the chains'
autocorrelation time (:func:`bayes_imu.inference.sampling.autocorr_time`). Sampling continues in
blocks until every parameter has R-hat below ``rhat_max`` and more than ``ess_min`` effective
draws, or ``max_steps``.
"""

from dataclasses import dataclass

import numpy as np

from .sampling import autocorr_time

__all__ = [
    "HMCResult",
    "sample_hmc",
    "split_rhat",
    "effective_draws",
    "TARGET_ACCEPT",
    "TRAJECTORY",
]

#: acceptance rate the step size is adapted to
TARGET_ACCEPT = 0.8
#: trajectory length in (mass-scaled) standard deviations: a quarter period of a Gaussian
TRAJECTORY = 0.5 * np.pi
#: most leapfrog steps of one trajectory
MAX_LEAPFROG = 128
#: sampling iterations between convergence checks
BLOCK = 100


@dataclass(frozen=True)
class HMCResult:
    """Draws and diagnostics of :func:`sample_hmc`.

    Attributes
    ----------
    chain : ndarray, shape (n_steps, n_chains, n_par)
        Draws after warm-up.
    rhat : ndarray, shape (n_par,)
        Split R-hat of each parameter.
    ess : ndarray, shape (n_par,)
        Effective number of draws of each parameter.
    autocorr_time : ndarray, shape (n_par,)
        Integrated autocorrelation time (iterations).
    accept : float
        Mean acceptance probability after warm-up.
    step_size : float
    n_warmup : int
    converged : bool
    """

    chain: np.ndarray
    rhat: np.ndarray
    ess: np.ndarray
    autocorr_time: np.ndarray
    accept: float
    step_size: float
    n_warmup: int
    converged: bool


def sample_hmc(
    log_prob_grad,
    start,
    rng,
    *,
    max_steps=4000,
    n_warmup=200,
    rhat_max=1.01,
    ess_min=400.0,
    monitor=None,
):
    """Sample ``log_prob_grad`` from the rows of ``start`` ``(n_chains, n_par)`` (module docstring).

    ``log_prob_grad(x)`` takes ``(k, n_par)`` and returns the log density ``(k,)`` (``-inf``
    outside the support) and its gradient ``(k, n_par)``. ``max_steps``: the most sampling
    iterations per chain after the ``n_warmup`` warm-up ones. ``monitor``: a map of rows
    ``(k, n_par) -> (k, n_par)`` to the quantities whose R-hat and effective draws decide and
    that the chain returns (the sampler's coordinates where ``None``).
    """
    x = np.array(start, dtype=float)
    n_chains, n_par = x.shape
    logp, grad = log_prob_grad(x)
    if not np.all(np.isfinite(logp)):
        raise ValueError("sample_hmc: every starting row must have a finite log density")
    inv_mass = np.ones(n_par)
    step = _initial_step(log_prob_grad, x, logp, grad, inv_mass, rng)
    # warm-up: step size throughout, the mass matrix from the chains at 40% and 70% of it
    windows = (int(0.4 * n_warmup), int(0.7 * n_warmup))
    adapt = _DualAveraging(step)
    history = []
    for i in range(n_warmup):
        x, logp, grad, accept = _transition(log_prob_grad, x, logp, grad, adapt.step, inv_mass, rng)
        adapt.update(accept)
        history.append(x.copy())
        if i + 1 in windows:
            recent = np.concatenate(history[len(history) // 2 :])
            inv_mass = np.maximum(np.var(recent, axis=0), 1e-12)
            history = []
            adapt = _DualAveraging(_initial_step(log_prob_grad, x, logp, grad, inv_mass, rng))
    step = adapt.final()
    draws, accepts = [], []
    converged = False
    while len(draws) < max_steps:
        for _ in range(min(BLOCK, max_steps - len(draws))):
            x, logp, grad, accept = _transition(log_prob_grad, x, logp, grad, step, inv_mass, rng)
            draws.append(x.copy())
            accepts.append(accept)
        chain = np.array(draws)
        if monitor is not None:
            chain = monitor(chain.reshape(-1, n_par)).reshape(chain.shape)
        with np.errstate(
            invalid="ignore", divide="ignore"
        ):  # a chain that never moved: NaN, not converged
            rhat, taus = split_rhat(chain), autocorr_time(chain)
        taus = np.where(np.isfinite(taus), taus, np.inf)
        rhat = np.where(np.isfinite(rhat), rhat, np.inf)
        ess = effective_draws(chain, taus)
        if np.all(rhat < rhat_max) and np.all(ess > ess_min):
            converged = True
            break
    return HMCResult(
        chain, rhat, ess, taus, float(np.mean(accepts)), float(step), int(n_warmup), converged
    )


def split_rhat(chain):
    """Split R-hat of each parameter of ``chain`` ``(steps, chains, parameters)``: every chain cut
    in
    two halves, each half a chain (Gelman et al. 2013, Bayesian Data Analysis, 3rd ed., eq 11.4):
    ``sqrt(((n - 1) / n W + B / n) / W)``, ``W`` the mean within-chain variance and ``B / n`` the
    variance of the chains' means."""
    n = chain.shape[0] // 2
    halves = np.concatenate([chain[:n], chain[n : 2 * n]], axis=1)
    within = np.mean(np.var(halves, axis=0, ddof=1), axis=0)
    between = np.var(np.mean(halves, axis=0), axis=0, ddof=1)
    return np.sqrt(((n - 1) / n * within + between) / within)


def effective_draws(chain, taus):
    """Effective draws of each parameter: steps x chains / integrated autocorrelation time."""
    return chain.shape[0] * chain.shape[1] / np.maximum(np.asarray(taus, dtype=float), 1.0)


def _transition(log_prob_grad, x, logp, grad, step, inv_mass, rng):
    """One HMC transition of every chain: jittered step count, leapfrog, Metropolis accept."""
    n_chains = x.shape[0]
    n_leap = int(np.clip(np.ceil(TRAJECTORY / step * rng.uniform(0.5, 1.5)), 1, MAX_LEAPFROG))
    p = rng.standard_normal(x.shape) / np.sqrt(inv_mass)
    h0 = -logp + 0.5 * np.sum(p * p * inv_mass, axis=1)
    xn, pn, gn, lpn = x.copy(), p.copy(), grad, logp
    alive = np.ones(n_chains, bool)
    for _ in range(n_leap):
        pn = pn + 0.5 * step * gn
        xn = xn + step * inv_mass * pn
        lpn, gn = log_prob_grad(xn)
        alive &= np.isfinite(lpn)
        gn = np.where(alive[:, None], gn, 0.0)  # a chain that left the support is rejected below
        pn = pn + 0.5 * step * gn
    h1 = np.where(alive, -lpn + 0.5 * np.sum(pn * pn * inv_mass, axis=1), np.inf)
    with np.errstate(over="ignore", invalid="ignore"):
        accept = np.where(alive, np.minimum(1.0, np.exp(np.minimum(h0 - h1, 0.0))), 0.0)
    accept = np.nan_to_num(accept, nan=0.0)
    take = rng.uniform(size=n_chains) < accept
    x = np.where(take[:, None], xn, x)
    logp = np.where(take, lpn, logp)
    grad = np.where(take[:, None], gn, grad)
    return x, logp, grad, float(np.mean(accept))


def _initial_step(log_prob_grad, x, logp, grad, inv_mass, rng):
    """A first step size: halved or doubled until one leapfrog step accepts about half (Hoffman &
    Gelman
    2014, algorithm 4, over all chains)."""
    p = rng.standard_normal(x.shape) / np.sqrt(inv_mass)

    def accept_of(eps):
        pn = p + 0.5 * eps * grad
        xn = x + eps * inv_mass * pn
        lpn, gn = log_prob_grad(xn)
        pn = pn + 0.5 * eps * np.where(np.isfinite(lpn)[:, None], gn, 0.0)
        dh = (logp - 0.5 * np.sum(p * p * inv_mass, axis=1)) - (
            lpn - 0.5 * np.sum(pn * pn * inv_mass, axis=1)
        )
        with np.errstate(over="ignore", invalid="ignore"):
            return float(np.mean(np.nan_to_num(np.exp(np.minimum(-dh, 0.0)), nan=0.0)))

    step = 0.1
    if accept_of(step) > 0.5:
        while accept_of(2.0 * step) > 0.5 and step < 1e3:
            step *= 2.0
        return step
    while accept_of(step) <= 0.5 and step > 1e-8:
        step *= 0.5
    return step


class _DualAveraging:
    """Step size by dual averaging (Hoffman & Gelman 2014, eqs 5-6: gamma 0.05, t0 10,
    kappa 0.75)."""

    def __init__(self, step):
        self.mu = np.log(10.0 * step)
        self.step = step
        self.bar = 0.0
        self.log_bar = np.log(step)
        self.t = 0

    def update(self, accept):
        self.t += 1
        eta = 1.0 / (self.t + 10.0)
        self.bar = (1.0 - eta) * self.bar + eta * (TARGET_ACCEPT - accept)
        log_step = self.mu - np.sqrt(self.t) / 0.05 * self.bar
        weight = self.t**-0.75
        self.log_bar = weight * log_step + (1.0 - weight) * self.log_bar
        self.step = float(np.exp(log_step))

    def final(self):
        return float(np.exp(self.log_bar))
