"""Convergence diagnostics of MCMC draws: rank-normalised split R-hat, bulk and tail ESS.

The definitions of Vehtari, Gelman, Simpson, Carpenter & Buerkner, "Rank-normalization,
folding, and localization: an improved R-hat for assessing convergence of MCMC", Bayesian
Analysis 16 (2021), as ArviZ computes them (``az.rhat``, ``az.ess(method="bulk" / "tail")``;
``tests/test_diagnostics.py`` checks them against ArviZ), here in numpy so that a fit needs
neither ArviZ nor its import time (ArviZ is used where ``posterior.nc`` is written):

* each chain is split in half; draws are replaced by the normal scores of their average
  ranks over all chains, ``Phi^-1((r - 3/8) / (S + 1/4))``;
* R-hat is the larger of the classic R-hat of those scores and of the scores of the draws
  folded about their median;
* ESS is ``S / tau`` with ``tau = -1 + 2 sum_t rho_t`` over Geyer's initial monotone
  sequence of autocorrelations (FFT autocovariances, combined over chains);
  bulk: of the scores; tail: the smaller of the ESS of the indicators
  ``x <= q_0.05`` and ``x <= q_0.95``.
"""

import numpy as np

from .._lazy import LazyModule

special = LazyModule("scipy.special")

__all__ = ["rhat", "ess_bulk", "ess_tail", "summary"]


def _split(draws):
    """``(2 n_chains, n_draws // 2)``: the first and the last half of each chain."""
    draws = np.atleast_2d(np.asarray(draws, dtype=float))
    half = draws.shape[1] // 2
    return np.concatenate([draws[:, :half], draws[:, draws.shape[1] - half:]], axis=0)


def _average_ranks(x):
    """Ranks 1..S of every value over the whole array, ties given their average rank."""
    flat = x.ravel()
    order = np.argsort(flat, kind="mergesort")
    ordered = flat[order]
    first = np.concatenate([[True], ordered[1:] != ordered[:-1]])
    group = np.cumsum(first) - 1
    counts = np.bincount(group)
    ranks = np.empty(flat.size)
    ranks[order] = (np.flatnonzero(first) + (counts + 1) / 2.0)[group]
    return ranks.reshape(x.shape)


def _normal_scores(x):
    """Blom's normal scores of the ranks, ``Phi^-1((r - 3/8) / (S + 1/4))``."""
    return special.ndtri((_average_ranks(x) - 0.375) / (x.size + 0.25))


def _classic_rhat(x):
    n = x.shape[1]
    between = n * np.var(x.mean(axis=1), ddof=1)
    within = np.mean(np.var(x, axis=1, ddof=1))
    return float(np.sqrt((between / within + n - 1) / n))


def rhat(draws):
    """Rank-normalised split R-hat of ``draws`` ``(n_chains, n_draws)`` (module docstring)."""
    x = _split(draws)
    folded = np.abs(x - np.median(x))
    return max(_classic_rhat(_normal_scores(x)), _classic_rhat(_normal_scores(folded)))


def _autocov(x):
    """Autocovariance of each row at every lag (FFT, divided by the row length)."""
    n = x.shape[1]
    size = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x - x.mean(axis=1, keepdims=True), n=size, axis=1)
    return np.fft.irfft(f * np.conjugate(f), n=size, axis=1)[:, :n] / n


def _ess(x):
    """ESS of ``x`` ``(n_chains, n_draws)`` by Geyer's initial monotone sequence."""
    m, n = x.shape
    if np.ptp(x) < np.finfo(float).resolution:
        return float(x.size)
    acov = _autocov(x)
    mean_var = np.mean(acov[:, 0]) * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n
    if m > 1:
        var_plus += np.var(x.mean(axis=1), ddof=1)
    rho = 1.0 - (mean_var - acov.mean(axis=0)) / var_plus
    rho[0] = 1.0
    kept = np.zeros(n)
    kept[:2] = rho[:2]
    t = 1  # initial positive sequence: pairs (rho_{t+1}, rho_{t+2}) while their sum is positive
    even, odd = 1.0, rho[1]
    while t < n - 3 and even + odd > 0.0:
        even, odd = rho[t + 1], rho[t + 2]
        if even + odd >= 0.0:
            kept[t + 1], kept[t + 2] = even, odd
        t += 2
    last = t - 2
    if even > 0.0:
        kept[last + 1] = even
    t = 1  # initial monotone sequence
    while t <= last - 2:
        if kept[t + 1] + kept[t + 2] > kept[t - 1] + kept[t]:
            kept[t + 1] = kept[t + 2] = (kept[t - 1] + kept[t]) / 2.0
        t += 2
    tau = -1.0 + 2.0 * np.sum(kept[: last + 1]) + np.sum(kept[last + 1: last + 2])
    size = m * n
    return float(size / max(tau, 1.0 / np.log10(size)))


def ess_bulk(draws):
    """Bulk effective sample size of ``draws`` ``(n_chains, n_draws)`` (module docstring)."""
    return _ess(_normal_scores(_split(draws)))


def ess_tail(draws, prob=(0.05, 0.95)):
    """Tail effective sample size: the smaller ESS of the indicators of the ``prob`` quantiles."""
    draws = np.atleast_2d(np.asarray(draws, dtype=float))
    return min(_ess(_split(draws <= np.quantile(draws, p))) for p in prob)


def summary(chain):
    """``rhat_max``, ``ess_bulk_min``, ``ess_tail_min`` over the parameters of ``chain``
    ``(n_draws, n_chains, n_par)`` (emcee's layout)."""
    per = [np.transpose(chain[:, :, i]) for i in range(chain.shape[2])]
    return {"rhat_max": max(rhat(d) for d in per), "ess_bulk_min": min(ess_bulk(d) for d in per),
            "ess_tail_min": min(ess_tail(d) for d in per)}
