r"""Independent check that the package's MCMC sampler gives reproducible posteriors on hard scenes.

Written from first principles for an independent validation (docs/validation/sampler.md). The
scene generator below uses numpy only and does not import ``bayes_imu``; only the fitting part
(:func:`run_scene`) calls the package's public API (``allan_variance``, ``fit_allan``).

Scene (rate samples ``y_k`` at period ``dt``, arbitrary unit u): a sum of independent terms

* ``White(sigma)``: ``y_k = sigma e_k``.
* ``Quantization(q)``: differenced white phase ``y_k = (q / dt)(u_k - u_{k-1})`` (q in u s,
  AVAR ``3 q^2 / tau^2``).
* ``GaussMarkov(s2, tau)``: stationary AR(1) with exact step ``a = exp(-dt / tau)``,
  ``x_0 ~ N(0, s2)``, ``x_k = a x_{k-1} + sqrt(s2 (1 - a^2)) e_k``; two of them, time constants
  a factor 3-30 apart.
* ``RandomWalk(k)``: rate random walk ``y_k = y_{k-1} + k sqrt(dt) e_k`` (k in u/sqrt(s),
  AVAR ``k^2 dt (2 m^2 + 1) / (6 m)``).

Exact Allan variance of every term from its variogram ``g(l) = E (y_{i+l} - y_i)^2``: the
overlapping AVAR at cluster size m is half the variance of the contrast ``w`` = (-1/m) x m then
(+1/m) x m, and since ``sum w = 0``,
``Var(sum w_i y_i) = -1/2 sum_ij w_i w_j g(i - j) = -sum_{l=1}^{2m-1} c(l) g(l)``
with ``c(l) = sum_i w_i w_{i+l} = (2 max(m - l, 0) - min(l, 2m - l)) / m^2``. So
``AVAR(m) = -1/2 sum_{l=1}^{2m-1} c(l) g(l)``; g: white ``2 sigma^2``; quantization
``6 (q/dt)^2`` at l = 1, ``4 (q/dt)^2`` beyond; Gauss-Markov ``2 s2 (1 - a^l)``; random walk
``k^2 dt l``. ``tests/test_validate_sampler_scenes.py`` checks this against brute-force
quadratic forms of the covariance matrix and a Monte Carlo of the simulators.

Scene draw (each from ``np.random.SeedSequence([seed, 39])``): rate log-uniform 100-400 Hz,
n = 2^18, 2^19 or 2^20 samples, white sigma log-uniform 1e-3-1e-1 u; time-constant ratio
log-uniform 3-30; the faster bias's time constant log-uniform between max(20 dt, 0.05 s) and
T / (50 ratio) (T the record length), so the slower one peaks (at ~1.9 tau) below T / 26; each
bias's strength such that its ADEV peak stands d decades, d ~ U(0.3, 1.5), above the ADEV of the
short-term terms below it (white, quantization, and the faster bias for the slower one) at the
tau of that peak; with probability 0.6 a rate random walk whose AVAR equals the slower bias's at
c x its peak tau, c log-uniform 1-4 (its rise overlaps the slower bump); with probability 0.4 a
quantization whose AVAR equals the white's at m_x samples, m_x log-uniform 1-8.

Usage::

    nice -n 19 python scripts/validate_sampler.py --seeds 0-15 --out docs/validation/sampler_dev
    nice -n 19 python scripts/validate_sampler.py --held-out --n 14 \
        --out docs/validation/sampler_held_out

Development seeds are below 20_000_000; the held-out range starts at 20_000_000 and runs only with
``--held-out``.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HELD_OUT_START = 20_000_000
SEED_TAG = 39
QUANTILES = (0.05, 0.5, 0.95)

# --------------------------------------------------------------------------------------------
# terms: simulators and exact Allan variance
# --------------------------------------------------------------------------------------------


def contrast_acf(m):
    """c(l) = sum_i w_i w_{i+l} for l = 0..2m-1 of the Allan contrast at cluster size m."""
    l = np.arange(2 * m, dtype=float)
    return (2.0 * np.maximum(m - l, 0.0) - np.minimum(l, 2 * m - l)) / float(m) ** 2


def avar_from_variogram(gamma, m):
    """AVAR(m) = -1/2 sum_{l=1}^{2m-1} c(l) g(l), ``gamma`` a function of integer lags (array)."""
    c = contrast_acf(int(m))
    lags = np.arange(1, 2 * int(m))
    return float(-0.5 * np.dot(c[1:], gamma(lags)))


@dataclass(frozen=True)
class White:
    sigma: float
    name = "white"

    def simulate(self, n, dt, rng):
        return self.sigma * rng.standard_normal(n)

    def variogram(self, lags, dt):
        return np.where(np.asarray(lags) == 0, 0.0, 2.0 * self.sigma ** 2)

    def cov(self, i, j, dt):
        return np.where(i == j, self.sigma ** 2, 0.0)


@dataclass(frozen=True)
class Quantization:
    q: float
    name = "quantization"

    def simulate(self, n, dt, rng):
        u = rng.standard_normal(n + 1)
        return (self.q / dt) * np.diff(u)

    def variogram(self, lags, dt):
        lags = np.abs(np.asarray(lags))
        c = (self.q / dt) ** 2
        return np.where(lags == 0, 0.0, np.where(lags == 1, 6.0 * c, 4.0 * c))

    def cov(self, i, j, dt):
        c = (self.q / dt) ** 2
        d = np.abs(i - j)
        return np.where(d == 0, 2.0 * c, np.where(d == 1, -c, 0.0))


def ar1_filter(e, a, x0):
    """x_k = a x_{k-1} + e_k for k = 0..n-1 with x_{-1} = x0, exactly, numpy only (blocked).

    Within a block of L samples, x_{b+j} = a^(j+1) (x_{b-1} + sum_{i<=j} a^(-(i+1)) e_{b+i}); the
    block is short enough that a^(-L) <= e^30, so the scaled partial sums keep full precision.
    """
    n = e.size
    if a == 0.0:
        return np.array(e, dtype=float)
    out = np.empty(n)
    la = -math.log(a)
    block = n if la * n <= 30.0 else max(1, int(30.0 / la))
    prev = x0
    for b in range(0, n, block):
        seg = e[b:b + block]
        j = np.arange(1, seg.size + 1)
        up = np.exp(j * la)           # a^(-j)
        down = np.exp(-j * la)        # a^j
        out[b:b + seg.size] = down * (prev + np.cumsum(seg * up))
        prev = out[b + seg.size - 1]
    return out


@dataclass(frozen=True)
class GaussMarkov:
    s2: float     # stationary variance (u^2)
    tau: float    # time constant (s)
    name = "gauss_markov"

    def a(self, dt):
        return math.exp(-dt / self.tau)

    def simulate(self, n, dt, rng):
        a = self.a(dt)
        x0 = math.sqrt(self.s2) * rng.standard_normal()
        e = math.sqrt(self.s2 * (1.0 - a * a)) * rng.standard_normal(n)
        # x_0 is the stationary draw itself: x_0 = x0, x_k = a x_{k-1} + e_k for k >= 1
        out = np.empty(n)
        out[0] = x0
        if n > 1:
            out[1:] = ar1_filter(e[1:], a, x0)
        return out

    def variogram(self, lags, dt):
        lags = np.abs(np.asarray(lags, dtype=float))
        return -2.0 * self.s2 * np.expm1(lags * math.log(self.a(dt)))

    def cov(self, i, j, dt):
        return self.s2 * self.a(dt) ** np.abs(i - j)


@dataclass(frozen=True)
class RandomWalk:
    k: float      # u / sqrt(s)
    name = "random_walk"

    def simulate(self, n, dt, rng):
        return np.cumsum(self.k * math.sqrt(dt) * rng.standard_normal(n))

    def variogram(self, lags, dt):
        return self.k ** 2 * dt * np.abs(np.asarray(lags, dtype=float))

    def cov(self, i, j, dt):
        # y_i = sum_{r<=i} k sqrt(dt) e_r, indices from 0: Cov = k^2 dt (min(i, j) + 1)
        return self.k ** 2 * dt * (np.minimum(i, j) + 1.0)


def term_avar(term, m, dt):
    return avar_from_variogram(lambda l: term.variogram(l, dt), m)


@dataclass(frozen=True)
class Scene:
    seed: int
    rate_hz: float
    n: int
    terms: tuple
    bump_decades: tuple   # (fast, slow) ADEV height of each bias above the terms below it
    ratio: float          # tau_slow / tau_fast
    rw_overlap: float     # c: RW AVAR = slow-bias AVAR at c x its peak tau (nan without RW)

    @property
    def dt(self):
        return 1.0 / self.rate_hz

    @property
    def record_s(self):
        return self.n * self.dt

    def avar(self, m, which=None):
        terms = self.terms if which is None else which
        return sum(term_avar(t, m, self.dt) for t in terms)

    def simulate(self):
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, SEED_TAG, 1]))
        return sum(t.simulate(self.n, self.dt, rng) for t in self.terms)

    def package_terms(self):
        names = ["white"]
        if any(isinstance(t, Quantization) for t in self.terms):
            names.append("quantization")
        names += ["gauss_markov", "gauss_markov_2"]
        if any(isinstance(t, RandomWalk) for t in self.terms):
            names.append("random_walk")
        return tuple(names)

    def truth(self):
        """Parameter values named as the package's docs name them (docs/reference.md)."""
        out = {}
        gms = [t for t in self.terms if isinstance(t, GaussMarkov)]
        for t in self.terms:
            if isinstance(t, White):
                out["noise_variance"] = t.sigma ** 2
            elif isinstance(t, Quantization):
                out["quantization"] = t.q
            elif isinstance(t, RandomWalk):
                out["rate_random_walk"] = t.k
        out["gm_fast_s2"], out["gm_fast_tau"] = gms[0].s2, gms[0].tau
        out["gm_slow_s2"], out["gm_slow_tau"] = gms[1].s2, gms[1].tau
        return out

    def describe(self):
        t = self.truth()
        parts = [f"R={self.rate_hz:.0f}Hz", f"n=2^{int(round(math.log2(self.n)))}",
                 f"tau={t['gm_fast_tau']:.3g}/{t['gm_slow_tau']:.3g}s (x{self.ratio:.1f})",
                 f"bumps={self.bump_decades[0]:.2f}/{self.bump_decades[1]:.2f}dec"]
        if "rate_random_walk" in t:
            parts.append(f"RW(c={self.rw_overlap:.2f})")
        if "quantization" in t:
            parts.append("Q")
        return " ".join(parts)


def _lu(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _grid(n, lo=1):
    """Dense log grid of cluster sizes (for locating peaks), up to n // 8."""
    return np.unique(np.round(np.geomspace(lo, max(lo + 1, n // 8), 120)).astype(int))


def _peak(gm, others, n, dt):
    """(m at the bias's ADEV peak above the others, AVAR_gm, AVAR_others) on a dense grid."""
    ms = _grid(n)
    ms = ms[(ms * dt > 0.5 * gm.tau) & (ms * dt < 8 * gm.tau)]
    g = np.array([term_avar(gm, m, dt) for m in ms])
    mp = int(ms[np.argmax(g)])  # the GM term's own ADEV peak (near 1.89 tau)
    o = sum(term_avar(t, mp, dt) for t in others)
    return mp, term_avar(gm, mp, dt), o


def make_scene(seed):
    """Draw scene ``seed`` from ``SeedSequence([seed, 39])`` (numpy only, no bayes_imu)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), SEED_TAG]))
    rate = _lu(rng, 100.0, 400.0)
    n = 2 ** int(rng.integers(18, 21))
    dt = 1.0 / rate
    rec = n * dt
    sigma = _lu(rng, 1e-3, 1e-1)
    ratio = _lu(rng, 3.0, 30.0)
    lo = max(20 * dt, 0.05)
    hi = rec / (50.0 * ratio)
    tau_fast = _lu(rng, lo, hi)
    tau_slow = ratio * tau_fast
    d_fast, d_slow = rng.uniform(0.3, 1.5, size=2)
    has_rw = bool(rng.uniform() < 0.6)
    c_rw = _lu(rng, 1.0, 4.0)
    has_q = bool(rng.uniform() < 0.4)
    m_q = _lu(rng, 1.0, 8.0)

    base = [White(sigma)]
    if has_q:
        # 3 q^2 / (m dt)^2 = sigma^2 / m at m = m_q
        base.append(Quantization(math.sqrt(sigma ** 2 * dt ** 2 * m_q / 3.0)))
    # scale each bias so that its ADEV peak is d decades above the terms below it
    unit = GaussMarkov(1.0, tau_fast)
    mp, g, o = _peak(unit, base, n, dt)
    fast = GaussMarkov(10 ** (2 * d_fast) * o / g, tau_fast)
    unit = GaussMarkov(1.0, tau_slow)
    mp2, g, o = _peak(unit, base + [fast], n, dt)
    slow = GaussMarkov(10 ** (2 * d_slow) * o / g, tau_slow)
    terms = base + [fast, slow]
    if has_rw:
        m_x = max(1, int(round(c_rw * mp2)))
        # k^2 dt (2 m^2 + 1) / (6 m) = AVAR_slow(m_x)
        a_slow = term_avar(slow, m_x, dt)
        k = math.sqrt(a_slow * 6 * m_x / (dt * (2 * m_x ** 2 + 1)))
        terms.append(RandomWalk(k))
    return Scene(int(seed), rate, n, tuple(terms), (float(d_fast), float(d_slow)), ratio,
                 c_rw if has_rw else float("nan"))


def overlapping_avar(y, m):
    """Fully overlapping AVAR of rate samples at cluster size m (numpy; for the tests)."""
    c = np.concatenate(([0.0], np.cumsum(y)))
    s = c[m:] - c[:-m]                      # sums over m samples
    d = (s[m:] - s[:-m]) / m                # difference of adjacent cluster means
    return 0.5 * float(np.mean(d * d))


# --------------------------------------------------------------------------------------------
# fitting and comparison (the only part that uses bayes_imu)
# --------------------------------------------------------------------------------------------

Z05 = 1.6448536269514722
PHI_Z05 = math.exp(-0.5 * Z05 ** 2) / math.sqrt(2 * math.pi)
# Monte Carlo sd of a normal quantile from ESS draws, in posterior sd:
# sqrt(p(1-p)) / phi(z) / sqrt(ESS)
MC_FACTOR = {0.5: math.sqrt(0.25) / (1 / math.sqrt(2 * math.pi)),
             0.05: math.sqrt(0.05 * 0.95) / PHI_Z05, 0.95: math.sqrt(0.05 * 0.95) / PHI_Z05}

DIAG_KEYS = ("converged", "tempered", "n_steps", "ess_bulk_min", "ess_tail_min", "ess_mean_min",
             "rhat_max", "rhat_mean_max", "autocorr_time", "jump_components", "jump_acceptance",
             "jump_pilot_steps", "steps_before_tempering", "swap_acceptance",
             "independence_acceptance", "independence_share")


def _scalar(v):
    if isinstance(v, (list, tuple, np.ndarray)):
        a = np.asarray(v, dtype=float).ravel()
        return float(np.max(a)) if a.size else float("nan")
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if v is None:
        return ""
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def _fit(bi, allan, terms, seed):
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = bi.fit_allan(allan, terms=terms, rng=seed)
    wall = time.perf_counter() - t0
    warns = sorted({type(w.message).__name__ for w in caught})
    return fit, wall, warns


def _log_draws(fit):
    names = list(fit.model.parameter_names)
    s = np.asarray(fit.samples, dtype=float)
    if s.shape[1] > len(names):  # widened: model_discrepancy appended (docs)
        names = names + ["model_discrepancy"]
    return {nm: np.log(s[:, i]) for i, nm in enumerate(names)}


def batch_means_se(fit, name_index, p, q, n_batches=20):
    """Monte Carlo sd of the p-quantile ``q`` of one log-parameter, by batch means of the walkers'
    mean indicator 1[x <= q] over the kept (thinned) draws, divided by the density at q.

    Independent of the package's ESS: it uses only ``fit.chains.chain`` (n_draws, n_walkers,
    n_par, log-parameters) and treats the walkers' mean as one chain, which no exchange of
    states between walkers can make look better than it is.
    """
    se_p = indicator_se(fit, name_index, q, n_batches)
    if not np.isfinite(se_p):
        return float("nan")
    x = np.asarray(fit.chains.chain)[:, :, name_index]
    d = 0.025
    lo, hi = np.quantile(x, [max(p - d, 0.005), min(p + d, 0.995)])
    dens = (min(p + d, 0.995) - max(p - d, 0.005)) / (hi - lo) if hi > lo else float("nan")
    return se_p / dens


def _ess_fit(fit):
    """The smallest of the package's ESS numbers for a fit (bulk, tail, walkers' mean)."""
    d = fit.diagnostics
    v = [float(d[k]) for k in ("ess_bulk_min", "ess_tail_min", "ess_mean_min")
         if k in d and d[k] is not None and np.isfinite(d[k])]
    return min(v) if v else float("nan")


def indicator_se(fit, name_index, q, n_batches=20):
    """Batch-means Monte Carlo sd of P(x <= q) (walkers' mean as one chain; see batch_means_se)."""
    ch = getattr(fit, "chains", None)
    if ch is None:
        return float("nan")
    x = np.asarray(ch.chain)[:, :, name_index]
    t = x.shape[0]
    b = min(n_batches, t // 5)
    if b < 4:
        return float("nan")
    ind = (x <= q).mean(axis=1)[: (t // b) * b].reshape(b, -1).mean(axis=1)
    return float(np.std(ind, ddof=1) / math.sqrt(b))


def ks_distance(a, b):
    """Two-sample Kolmogorov-Smirnov distance between the two seeds' draws (probability scale:
    unlike |diff|/sd it does not shrink when a posterior with several regions has a large sd)."""
    a, b = np.sort(a), np.sort(b)
    grid = np.concatenate((a, b))
    fa = np.searchsorted(a, grid, side="right") / a.size
    fb = np.searchsorted(b, grid, side="right") / b.size
    return float(np.max(np.abs(fa - fb)))


def _diag(fit, wall, warns):
    d = dict(fit.diagnostics)
    row = {k: _scalar(d[k]) if k in d else "" for k in DIAG_KEYS}
    row["wall_s"] = round(wall, 2)
    row["widened"] = bool(getattr(fit, "widened", False))
    row["adequate"] = bool(fit.adequacy.adequate)
    row["adequacy_p"] = float(fit.adequacy.p_value)
    row["n_draws"] = int(np.asarray(fit.samples).shape[0])
    row["warnings"] = ";".join(warns)
    return row


def run_scene(scene, bi):
    y = scene.simulate()
    t0 = time.perf_counter()
    allan = bi.allan_variance(y, rate_hz=scene.rate_hz)
    allan_s = time.perf_counter() - t0
    terms = scene.package_terms()
    fits = {}
    for seed in (1, 2):
        fits[seed] = _fit(bi, allan, terms, seed)
    auto = _fit(bi, allan, "auto", 1)

    la, lb = _log_draws(fits[1][0]), _log_draws(fits[2][0])
    da, db = _diag(*fits[1]), _diag(*fits[2])
    ess = [x for x in (da["ess_bulk_min"], db["ess_bulk_min"],
                       da["ess_mean_min"], db["ess_mean_min"])
           if isinstance(x, float) and x > 0]
    ess_min = min(ess) if ess else float("nan")
    truth = scene.truth()
    rows = []
    ess_fit = [_ess_fit(fits[k][0]) for k in (1, 2)]
    for idx, name in enumerate(la):
        if name not in lb:
            continue
        a, b = la[name], lb[name]
        pooled = np.concatenate((a, b))
        sd = math.sqrt(0.5 * (np.var(a) + np.var(b)))
        qa, qb = np.quantile(a, QUANTILES), np.quantile(b, QUANTILES)
        tv = _truth_for(name, truth)
        ks = ks_distance(a, b)
        for p, x, z in zip(QUANTILES, qa, qb):
            diff = (x - z) / sd if sd > 0 else float("nan")
            mc = MC_FACTOR[p] * math.sqrt(2.0 / ess_min) if ess_min == ess_min else float("nan")
            bm = [batch_means_se(f, idx, p, q) if idx < len(f.model.parameter_names)
                  else float("nan")
                  for f, q in ((fits[1][0], x), (fits[2][0], z))]
            bm_sd = math.sqrt(bm[0] ** 2 + bm[1] ** 2) / sd if sd > 0 else float("nan")
            # probability scale: each seed's CDF at the pooled draws' p-quantile
            qp = float(np.quantile(pooled, p))
            fa, fb = float(np.mean(a <= qp)), float(np.mean(b <= qp))
            pse_ess = math.sqrt(p * (1 - p) * (1 / ess_fit[0] + 1 / ess_fit[1]))
            pbm = [indicator_se(f, idx, qp) if idx < len(f.model.parameter_names) else float("nan")
                   for f in (fits[1][0], fits[2][0])]
            pse_bm = math.sqrt(pbm[0] ** 2 + pbm[1] ** 2)
            rows.append({
                "seed": scene.seed, "parameter": name, "quantile": p,
                "log_q_seed1": float(x), "log_q_seed2": float(z), "pooled_sd": sd,
                "diff_over_sd": diff, "abs_diff_over_sd": abs(diff),
                "mc_sd_expected": mc, "z_vs_mc": abs(diff) / mc if mc == mc else float("nan"),
                "mc_sd_batch_means": bm_sd,
                "z_vs_batch_means": abs(diff) / bm_sd if bm_sd > 0 else float("nan"),
                "ks_distance": ks,
                "cdf_seed1_at_pooled_q": fa, "cdf_seed2_at_pooled_q": fb, "cdf_diff": fa - fb,
                "cdf_se_from_ess": pse_ess, "cdf_z_ess": abs(fa - fb) / pse_ess,
                "cdf_se_batch_means": pse_bm,
                "cdf_z_batch_means": abs(fa - fb) / pse_bm if pse_bm > 0 else float("nan"),
                "log_truth": math.log(tv) if tv else "",
            })
    worst = max(rows, key=lambda r: r["abs_diff_over_sd"])
    auto_terms = tuple(auto[0].model.terms)
    scene_row = {
        "seed": scene.seed, "scene": scene.describe(), "rate_hz": round(scene.rate_hz, 2),
        "n": scene.n, "record_s": round(scene.record_s, 1), "fixed_terms": "+".join(terms),
        "auto_terms": "+".join(auto_terms), "auto_matches": set(auto_terms) == set(terms),
        "auto_wall_s": round(auto[1], 2),
        "auto_tempered": _scalar(auto[0].diagnostics.get("tempered")),
        "auto_converged": _scalar(auto[0].diagnostics.get("converged")),
        "allan_s": round(allan_s, 2),
        "max_abs_diff_over_sd": worst["abs_diff_over_sd"],
        "worst_parameter": f"{worst['parameter']}@q{int(round(100 * worst['quantile'])):02d}",
        "ess_min_used": ess_min,
    }
    for tag, d in (("s1", da), ("s2", db)):
        for k, v in d.items():
            scene_row[f"{tag}_{k}"] = v
    return scene_row, rows


def _truth_for(name, truth):
    """The generating value under the package's parameter names, where the mapping is plain."""
    if name in truth:
        return truth[name]
    mapping = {"bias_variance": "gm_fast_s2", "time_constant": "gm_fast_tau",
               "bias_variance_2": "gm_slow_s2", "time_constant_2": "gm_slow_tau"}
    return truth.get(mapping.get(name, ""), None)


def replicate_study(scene, bi, k):
    """Fit the fixed model at rng seeds 1..k; per parameter and quantile, the spread of the
    quantile over seeds (in pooled posterior sd) beside the Monte Carlo sd each fit implies."""
    y = scene.simulate()
    allan = bi.allan_variance(y, rate_hz=scene.rate_hz)
    terms = scene.package_terms()
    fits = [_fit(bi, allan, terms, seed) for seed in range(1, k + 1)]
    draws = [_log_draws(f) for f, _, _ in fits]
    names = [nm for nm in draws[0] if all(nm in d for d in draws)]
    out = []
    for idx, name in enumerate(names):
        sd = math.sqrt(np.mean([np.var(d[name]) for d in draws]))
        pooled = np.concatenate([d[name] for d in draws])
        for p in QUANTILES:
            qs = np.array([np.quantile(d[name], p) for d in draws])
            bm = np.array([batch_means_se(f, idx, p, q) for (f, _, _), q in zip(fits, qs)])
            qp = float(np.quantile(pooled, p))
            cdf = np.array([np.mean(d[name] <= qp) for d in draws])
            ess = np.array([_ess_fit(f) for f, _, _ in fits])
            out.append({
                "seed": scene.seed, "parameter": name, "quantile": p, "n_fits": k,
                "quantile_sd_over_seeds": float(np.std(qs, ddof=1) / sd),
                "quantile_range_over_seeds": float((qs.max() - qs.min()) / sd),
                "batch_means_sd_mean": float(np.nanmean(bm) / sd),
                "cdf_sd_over_seeds": float(np.std(cdf, ddof=1)),
                "cdf_sd_from_ess": float(np.mean(np.sqrt(p * (1 - p) / ess))),
                "cdf_values": " ".join(f"{c:.4f}" for c in cdf),
                "quantile_values": " ".join(f"{q:.3f}" for q in qs),
            })
    diag = [{"seed": scene.seed, "rng": i + 1, **_diag(*f)} for i, f in enumerate(fits)]
    return out, diag


def parse_seeds(text):
    out = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def select_seeds(args):
    """The seeds to run; refuses the held-out range without ``--held-out`` (SystemExit 2)."""
    if args.held_out:
        if args.seeds:
            raise SystemExit("validate_sampler: --held-out takes --n, not --seeds")
        return [HELD_OUT_START + i for i in range(args.n)]
    seeds = parse_seeds(args.seeds or f"0-{args.n - 1}")
    bad = [s for s in seeds if s >= HELD_OUT_START or s < 0]
    if bad:
        print(f"validate_sampler: seeds {bad[:3]} are in the held-out range (>= {HELD_OUT_START}) "
              "or negative; refusing without --held-out", file=sys.stderr)
        raise SystemExit(2)
    return seeds


def summarise(scene_rows, rows, out=sys.stdout):
    a = np.array([r["abs_diff_over_sd"] for r in rows])
    p = lambda *x: print(*x, file=out)
    p(f"\n{len(scene_rows)} scenes, {len(rows)} (scene, parameter, quantile) comparisons")
    p(f"share |diff|/sd > 0.3: {np.mean(a > 0.3):.3f} ({int(np.sum(a > 0.3))}); "
      f"> 0.5: {np.mean(a > 0.5):.3f} ({int(np.sum(a > 0.5))}); max {a.max():.3f}")
    z = np.array([r["z_vs_batch_means"] for r in rows], dtype=float)
    z = z[np.isfinite(z)]
    p(f"|diff| / batch-means MC sd (about |N(0,1)| if both chains sample one law): "
      f"median {np.median(z):.2f} "
      f"(|N(0,1)|: 0.67), share > 3: {np.mean(z > 3):.3f} (0.003), max {z.max():.1f}")
    zc = np.array([r["cdf_z_ess"] for r in rows], dtype=float)
    zb = np.array([r["cdf_z_batch_means"] for r in rows], dtype=float)
    zb = zb[np.isfinite(zb)]
    p(f"probability scale |F1(q) - F2(q)| at the pooled quantile / its MC sd from the package's "
      f"ESS "
      f"(min of bulk, tail, mean): median {np.median(zc):.2f}, "
      f"share > 3: {np.mean(zc > 3):.3f}, max {zc.max():.1f}; "
      f"/ batch-means MC sd: median {np.median(zb):.2f}, "
      f"share > 3: {np.mean(zb > 3):.3f}, max {zb.max():.1f}")
    ks = {}
    for r in rows:
        ks[(r["seed"], r["parameter"])] = r["ks_distance"]
    kv = np.array(list(ks.values()))
    kmax = max(ks, key=ks.get)
    p(f"KS distance between the seeds' draws per (scene, parameter): median {np.median(kv):.3f}, "
      f"max {kv.max():.3f} (seed {kmax[0]} {kmax[1]}); share > 0.1: {np.mean(kv > 0.1):.3f}")
    for r in sorted(rows, key=lambda r: -r["abs_diff_over_sd"]):
        if r["abs_diff_over_sd"] <= 0.3:
            break
        p(f"  seed {r['seed']} {r['parameter']} q{r['quantile']}: {r['diff_over_sd']:+.3f} sd "
          f"({r['z_vs_mc']:.1f}x the ESS-based MC sd {r['mc_sd_expected']:.3f}, "
          f"{r['z_vs_batch_means']:.1f}x the batch-means MC sd {r['mc_sd_batch_means']:.3f}; "
          f"CDF {r['cdf_seed1_at_pooled_q']:.4f} vs {r['cdf_seed2_at_pooled_q']:.4f}, "
          f"{r['cdf_z_ess']:.1f}x its ESS-based sd)")
    fits = [(s, t) for s in scene_rows for t in ("s1", "s2")]
    temp = [s[f"{t}_tempered"] is True for s, t in fits]
    conv = [s[f"{t}_converged"] is True for s, t in fits]
    p(f"fixed-model fits tempered: {sum(temp)}/{len(fits)}; converged: {sum(conv)}/{len(fits)}")
    bad = [s for s in scene_rows if s["max_abs_diff_over_sd"] > 0.3]
    # (a local list: Python 3.11 allows no line break inside an f-string's braces)
    unconverged = [s['seed'] for s in bad
                   if not (s['s1_converged'] is True and s['s2_converged'] is True)]
    p(f"scenes with max |diff|/sd > 0.3: {[s['seed'] for s in bad]}; of those with an unconverged "
      f"fit: {unconverged}")
    p(f"auto selected the generating model in "
      f"{sum(s['auto_matches'] for s in scene_rows)}/{len(scene_rows)}")
    p("\nseed | scene | fixed terms | tempered s1/s2 | converged s1/s2 | n_steps s1/s2 "
      "| jump comp s1/s2 "
      "| wall s1/s2 [s] | max |diff|/sd (parameter) | auto terms")
    for s in scene_rows:
        p(f"{s['seed']} | {s['scene']} | {s['fixed_terms']} | "
          f"{s['s1_tempered']}/{s['s2_tempered']} | "
          f"{s['s1_converged']}/{s['s2_converged']} | {s['s1_n_steps']}/{s['s2_n_steps']} | "
          f"{s['s1_jump_components']}/{s['s2_jump_components']} | "
          f"{s['s1_wall_s']}/{s['s2_wall_s']} | "
          f"{s['max_abs_diff_over_sd']:.3f} ({s['worst_parameter']}) | {s['auto_terms']}")


def _write(path, rows):
    if not rows:
        return
    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", help="development seeds, e.g. 0-13 or 0,3,5 (below 20_000_000)")
    ap.add_argument("--n", type=int, default=14, help="number of scenes (default 14)")
    ap.add_argument("--held-out", action="store_true",
                    help=f"run the held-out range {HELD_OUT_START}.. (--n scenes)")
    ap.add_argument("--out", default="validate_sampler",
                    help="output prefix: PREFIX_scenes.csv, PREFIX_quantiles.csv")
    ap.add_argument("--describe", action="store_true", help="print the scenes and exit (no fits)")
    ap.add_argument("--replicates", type=int, default=0,
                    help="instead of the pair of fits: fit each scene's fixed model at rng 1..K "
                         "(PREFIX_replicates.csv, PREFIX_replicate_fits.csv)")
    args = ap.parse_args(argv)
    seeds = select_seeds(args)
    if args.describe:
        for s in seeds:
            print(s, make_scene(s).describe())
        return 0
    import bayes_imu as bi  # only here: the generator above does not need the package

    if args.replicates:
        rep, dia = [], []
        for s in seeds:
            scene = make_scene(s)
            print(f"scene {s}: {scene.describe()}", flush=True)
            r, d = replicate_study(scene, bi, args.replicates)
            rep.extend(r)
            dia.extend(d)
            _write(f"{args.out}_replicates.csv", rep)
            _write(f"{args.out}_replicate_fits.csv", dia)
            for x in r:
                print(f"  {x['parameter']:>16} q{x['quantile']:.2f}: "
                      f"sd over seeds {x['quantile_sd_over_seeds']:.3f} "
                      f"(batch means {x['batch_means_sd_mean']:.3f}); "
                      f"CDF sd over seeds {x['cdf_sd_over_seeds']:.4f} "
                      f"(from ESS {x['cdf_sd_from_ess']:.4f})", flush=True)
            print("  fits: " + "; ".join(f"rng {x['rng']} T={x['tempered']} C={x['converged']} "
                                         f"steps={x['n_steps']:.0f} {x['wall_s']}s" for x in d),
                  flush=True)
        return 0

    scene_rows, rows = [], []
    for s in seeds:
        scene = make_scene(s)
        print(f"scene {s}: {scene.describe()}", flush=True)
        srow, qrows = run_scene(scene, bi)
        scene_rows.append(srow)
        rows.extend(qrows)
        print(f"  tempered {srow['s1_tempered']}/{srow['s2_tempered']} converged "
              f"{srow['s1_converged']}/{srow['s2_converged']} "
              f"steps {srow['s1_n_steps']}/{srow['s2_n_steps']} "
              f"wall {srow['s1_wall_s']}/{srow['s2_wall_s']}/{srow['auto_wall_s']} s; "
              f"max |diff|/sd "
              f"{srow['max_abs_diff_over_sd']:.3f} ({srow['worst_parameter']}); "
              f"auto {srow['auto_terms']}",
              flush=True)
        _write(f"{args.out}_scenes.csv", scene_rows)
        _write(f"{args.out}_quantiles.csv", rows)
    summarise(scene_rows, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
