"""Population fit: what a *new unit* of an IMU model will do, from logs of several units.

A bound derived from one unit does not hold for the next one: units of one model differ
by 5-20% in noise density. :func:`fit_population` fits the logs of several units (or long
sessions of one unit) jointly with a hierarchical model on the natural-log parameters
``phi`` (:mod:`bayes_imu.noise` parameter units):

* unit ``u`` has its own ``phi_u``, drawn from the population
  ``N(mu, diag(sigma^2))`` truncated to the prior box of the single-unit fit;
* ``mu`` is uniform on the prior box; each population spread ``sigma_d`` (standard deviation
  of ``ln`` parameter ``d`` across units: 0.1 is a 10% unit-to-unit spread) has a
  half-normal prior of scale ``spread_scale`` (default 1, a factor e: weakly informative);
* the per-unit likelihood is the Allan-variance likelihood of :mod:`bayes_imu.inference.likelihood`.

The structure (which terms) is common: every unit is fitted alone (:func:`bayes_imu.fit_allan`),
the candidate models that carry posterior mass in any unit are scored on every unit
(:func:`bayes_imu.inference.fit.score_models`), and the structure is chosen from the summed log
evidences (the evidence that all units share it) by the selection rule of
:func:`bayes_imu.inference.selection.select`.

Sampling. The population posterior is sampled by emcee (vectorised, 2 x n_par dimensions),
with each unit's likelihood integrated over its single-unit posterior draws (importance
sampling, Hogg, Myers & Bovy 2010, ApJ 725, 2166): with a uniform single-unit prior pi_u,

    p(d_u | mu, sigma) proportional to  mean_n N_trunc(phi_un; mu, sigma) / pi_u(phi_un).

This is exact as the number of draws grows and lets every unit keep the full non-Gaussian
posterior of its own fit (discrepancy-widened fits included: the discrepancy is a per-unit
nuisance, integrated out in each unit's draws, not pooled). Each unit's pooled posterior is
its draws reweighted by the population; a new unit's parameters are drawn from
``N(mu, sigma^2)`` for each population draw (the posterior predictive), and go through
the same drift variances as a single fit (:func:`bayes_imu.drift.bands.drift_bands` accepts a
:class:`UnitPosterior`).

Ordered Gauss-Markov time constants: new-unit draws that break the order are redrawn; the
truncation mass ignores the order (a small approximation where the two boxes overlap).
"""

import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from .._lazy import LazyModule

special = LazyModule("scipy.special")

from .._version import __version__
from ..allan.estimator import AllanResult
from ..errors import BayesIMUError, ConvergenceWarning, InputError
from .fit import FitResult, fit_allan, score_models
from .sampling import autocorr_time, burn_and_thin, ensemble_sampler, long_enough
from .likelihood import default_bounds
from ..noise.avar_forms import PARAMETER_UNITS, NoiseModel
from .selection import CandidateScore, select

__all__ = ["PopulationResult", "UnitPosterior", "fit_population", "SPREAD_BOUNDS"]

#: bounds of the population spread sigma (standard deviation of a ln parameter across units)
SPREAD_BOUNDS = (1e-3, 5.0)
_LOG_2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True)
class UnitPosterior:
    """Parameter draws of one unit (or of a new unit): what drift bands and bounds need.

    Attributes
    ----------
    model : NoiseModel
    samples : ndarray, shape (n_draws, n_par)
        Physical parameters, ``model.parameter_names`` order.
    record_s : float
        Duration of the (shortest) log behind it (s): drift beyond it extrapolates.
    label : str
    discrepancy : ndarray, shape (n_draws,), or None
        Relative model-discrepancy error on the Allan variance (widened fits), else ``None``.
    """

    model: NoiseModel
    samples: np.ndarray
    record_s: float
    label: str = ""
    discrepancy: np.ndarray = None
    mixture: tuple = field(default=(), init=False)

    @property
    def parameter_names(self):
        return self.model.parameter_names

    def draws(self, name):
        """Draws of one parameter, or ``noise_density`` (short-term white equivalent, u/sqrt(Hz))."""
        if name == "noise_density":
            return np.sqrt(self.model.short_term_variance(self.samples) * self.model.dt)
        if name not in self.parameter_names:
            raise InputError(f"parameter {name!r}: the model {self.model.terms} has {', '.join(self.parameter_names)}")
        return self.samples[:, self.parameter_names.index(name)]

    def quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict name -> quantiles (parameters and ``noise_density``)."""
        return {n: np.quantile(self.draws(n), q) for n in self.parameter_names + ("noise_density",)}

    def predictive_avar(self, m, *, edf=None, n_draws=2000, rng=None):
        """Draws of the Allan variance a log of this unit would show, ``(n_draws, n_tau)``.

        The model Allan variance at each parameter draw, times the fitted model discrepancy
        (log-normal, independent per cluster size, when the fits were widened), times the
        estimation noise of a log with equivalent degrees of freedom ``edf`` (``chi2_edf / edf``;
        ``None`` leaves it out: the unit's true Allan variance).
        """
        rng = np.random.default_rng(rng)
        idx = rng.integers(self.samples.shape[0], size=n_draws)
        avar = self.model.avar(m, self.samples[idx])
        if self.discrepancy is not None:
            avar = avar * np.exp(self.discrepancy[idx, None] * rng.standard_normal(avar.shape))
        if edf is not None:
            edf = np.broadcast_to(np.asarray(edf, float), avar.shape[1:])
            avar = avar * rng.chisquare(edf, size=avar.shape) / edf
        return avar


@dataclass(frozen=True)
class PopulationResult:
    """Hierarchical posterior of several units of one sensor model.

    Attributes
    ----------
    model : NoiseModel
        The common structure.
    labels : tuple of str
    unit_fits : tuple of FitResult
        Each unit fitted alone with the common structure (single-unit posteriors).
    units : tuple of UnitPosterior
        Each unit's posterior under the population (partial pooling).
    mean : ndarray, shape (n_draws, n_par)
        Draws of the population mean ``mu`` of the ln parameters.
    spread : ndarray, shape (n_draws, n_par)
        Draws of the population spread ``sigma`` (standard deviation of each ln parameter).
    new_unit : UnitPosterior
        Posterior predictive of a new unit's parameters.
    structures : tuple of CandidateScore
        Summed evidence of each structure over the units (``log_evidence_se`` combined).
    per_unit_evidence : ndarray, shape (n_structures, n_units)
    selected : int
        Index of the chosen structure.
    diagnostics : dict
        ``autocorr_time``, ``n_steps``, ``n_walkers``, ``n_draws``, ``converged``, and the
        pooled draws' importance ``ess_min``.
    spread_scale : float
    seed : object
    """

    model: NoiseModel
    labels: tuple
    unit_fits: tuple
    units: tuple
    mean: np.ndarray
    spread: np.ndarray
    new_unit: UnitPosterior
    structures: tuple
    per_unit_evidence: np.ndarray
    selected: int
    diagnostics: dict
    spread_scale: float = 1.0
    seed: object = None

    @property
    def parameter_names(self):
        return self.model.parameter_names

    def spread_quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict parameter -> quantiles of the population spread sigma (ln units, ~ relative spread)."""
        return {n: np.quantile(self.spread[:, i], q) for i, n in enumerate(self.parameter_names)}

    def summary(self, *, unit="u"):
        """JSON-ready summary (``bayes-imu fit-population``'s ``summary.json``)."""
        from ..noise.datasheet import datasheet
        from ..noise.quantities import sensor_of_si_unit

        kind = sensor_of_si_unit(unit)

        def stats(draws, name):
            return {"median": float(np.median(draws)), "q05": float(np.quantile(draws, 0.05)),
                    "q95": float(np.quantile(draws, 0.95)), "unit": PARAMETER_UNITS.get(name, "1").format(u=unit)}

        def block(post):
            return {n: stats(post.draws(n), n) for n in post.parameter_names + ("noise_density",)}

        units = []
        for label, alone, pooled in zip(self.labels, self.unit_fits, self.units):
            units.append({"label": label, "n_samples": int(alone.allan.n_samples), "record_s": pooled.record_s,
                          "alone": {n: stats(alone.draws(n), n) for n in self.parameter_names + ("noise_density",)},
                          "pooled": block(pooled), "adequacy": alone.adequacy.to_dict(), "widened": bool(alone.widened)})
        population = {}
        for i, name in enumerate(self.parameter_names):
            population[name] = {"median": float(np.exp(np.median(self.mean[:, i]))),
                                "unit": PARAMETER_UNITS.get(name, "1").format(u=unit),
                                "spread_ln": {"median": float(np.median(self.spread[:, i])),
                                              "q05": float(np.quantile(self.spread[:, i], 0.05)),
                                              "q95": float(np.quantile(self.spread[:, i], 0.95))}}
        return {
            "model": list(self.model.terms),
            "what": "posterior predictive for a new unit of this sensor model (unit-to-unit spread included)",
            "new_unit": block(self.new_unit),
            "new_unit_datasheet": datasheet(self.new_unit, kind) if kind else None,
            "population": population,
            "units": units,
            # fixed terms (no selection) score no evidence: null, not NaN (invalid JSON)
            "structures": [{"model": list(s.terms), "log_evidence": _number(s.log_evidence),
                            "log_evidence_se": _number(s.log_evidence_se),
                            "per_unit": [_number(v) for v in self.per_unit_evidence[i]],
                            "selected": i == self.selected}
                           for i, s in enumerate(self.structures)],
            "spread_prior": f"half-normal, scale {self.spread_scale:g} (ln units)",
            "diagnostics": {k: (bool(v) if k == "converged" else int(v) if k in ("n_steps", "n_walkers", "n_draws")
                                else float(v)) for k, v in self.diagnostics.items()},
            "rate_hz": float(self.unit_fits[0].allan.rate_hz),
            "seed": self.seed if isinstance(self.seed, (int, type(None))) else str(self.seed),
            "bayes_imu_version": __version__,
        }


def fit_population(allans, *, labels=None, terms="auto", unit_fits=None, rng=None, threshold=1.0, spread_scale=1.0,
                   n_unit_draws=800, n_new=4000, max_steps=20000, progress=False):
    """Fit several units of one sensor model jointly (module docstring).

    Parameters
    ----------
    allans : sequence of AllanResult
        One Allan variance per unit (or per long session), all at one sample rate and in one unit.
    labels : sequence of str, optional
    terms : "auto" or sequence of str
        ``"auto"``: the common structure chosen by summed evidence; a sequence fixes it.
    unit_fits : sequence of FitResult, optional
        Single-unit ``terms="auto"`` fits of ``allans`` already made (reused, not refitted).
    rng : None, int or numpy.random.Generator
    threshold : float
        Selection threshold (nats) for the structure.
    spread_scale : float
        Scale of the half-normal prior of each population spread (ln units).
    n_unit_draws : int
        Draws per unit used in the importance-sampled likelihood.
    n_new : int
        Draws of the new-unit predictive.
    max_steps : int
    progress : bool

    Returns
    -------
    PopulationResult
    """
    allans = list(allans)
    if len(allans) < 2 or not all(isinstance(a, AllanResult) for a in allans):
        raise InputError(f"fit_population: expected at least 2 AllanResults (one per unit), got {len(allans)}")
    rate = allans[0].rate_hz
    for i, a in enumerate(allans):
        if not np.isclose(a.rate_hz, rate, rtol=1e-9):
            raise InputError(f"fit_population: unit {i + 1} is sampled at {a.rate_hz:g} Hz, unit 1 at {rate:g} Hz: "
                             "expected one sample rate")
    labels = tuple(labels) if labels is not None else tuple(f"unit {i + 1}" for i in range(len(allans)))
    if len(labels) != len(allans) or len(set(labels)) != len(labels):
        raise InputError(f"fit_population: expected {len(allans)} distinct labels, got {labels!r}")
    if not (np.isfinite(spread_scale) and spread_scale > 0):
        raise InputError(f"spread_scale={spread_scale!r}: expected a positive number")
    seed = rng
    rng = np.random.default_rng(rng)
    if unit_fits is None:
        unit_fits = [_unit_fit(label, a, rng=rng, progress=progress) for label, a in zip(labels, allans)]
    elif len(unit_fits) != len(allans) or not all(isinstance(f, FitResult) for f in unit_fits):
        raise InputError("unit_fits: expected one FitResult per Allan result")
    dt = 1.0 / rate
    if terms == "auto":
        structures, evidence, chosen = _choose_structure(allans, unit_fits, threshold, rng)
    else:
        model = NoiseModel(tuple(terms), dt)
        structures, evidence, chosen = (CandidateScore(model.terms, np.nan, np.nan, np.nan, np.empty(0)),), \
            np.full((1, len(allans)), np.nan), 0
    model = NoiseModel(structures[chosen].terms, dt)
    fits = [f if f.model.terms == model.terms else
            _unit_fit(label, a, terms=model.terms, discrepancy="always" if f.widened else "auto", rng=rng)
            for label, a, f in zip(labels, allans, unit_fits)]
    p = len(model.parameter_names)
    phis, boxes = [], []
    for a, f in zip(allans, fits):
        idx = rng.choice(f.samples.shape[0], size=min(n_unit_draws, f.samples.shape[0]), replace=False)
        phis.append(np.log(f.samples[idx, :p]))
        boxes.append(default_bounds(model, a))
    target = _HyperPosterior(phis, boxes, spread_scale)
    mean, spread, diagnostics = _sample_hyper(target, rng, max_steps)
    pooled, ess = [], []
    for label, a, f, phi, box in zip(labels, allans, fits, phis, boxes):
        draws, e = _pooled_draws(phi, box, mean, spread, rng)
        pooled.append(UnitPosterior(model, np.exp(draws), a.duration_s, label, _discrepancy(f, draws.shape[0], rng)))
        ess.append(e)
    diagnostics["ess_min"] = float(min(ess))
    new = _new_unit(model, mean, spread, target, n_new, rng)
    new_disc = None
    if any(f.widened for f in fits):  # a new unit's discrepancy: a random unit's (zero for adequate units)
        pool = np.concatenate([f.samples[:, p] if f.widened else np.zeros(f.samples.shape[0]) for f in fits])
        new_disc = pool[rng.integers(pool.size, size=new.shape[0])]
    record = float(min(a.duration_s for a in allans))
    new_unit = UnitPosterior(model, np.exp(new), record, "new unit", new_disc)
    return PopulationResult(model, labels, tuple(fits), tuple(pooled), mean, spread, new_unit, structures, evidence,
                            chosen, diagnostics, float(spread_scale), seed)


def _discrepancy(fit, n, rng):
    if not fit.widened:
        return None
    d = fit.samples[:, len(fit.model.parameter_names)]
    return d[rng.integers(d.size, size=n)]


def _choose_structure(allans, unit_fits, threshold, rng):
    """Candidate structures with posterior mass in any unit, scored on every unit; summed evidence."""
    seen = []
    for f in unit_fits:
        for terms in [f.model.terms] + [c.terms for c in f.mixture]:
            if tuple(terms) not in seen:
                seen.append(tuple(terms))
    evidence = np.empty((len(seen), len(allans)))
    se = np.empty_like(evidence)
    for j, (a, f) in enumerate(zip(allans, unit_fits)):
        scores = score_models(a, seen, widened=f.widened, likelihood=f.likelihood, rng=rng)
        evidence[:, j] = [s.log_evidence for s in scores]
        se[:, j] = [s.log_evidence_se for s in scores]
    summed = tuple(CandidateScore(t, float(evidence[i].sum()), float(np.sqrt(np.sum(se[i] ** 2))), np.nan, np.empty(0))
                   for i, t in enumerate(seen))
    chosen = select(summed, threshold=threshold) if len(summed) > 1 else 0
    return summed, evidence, chosen


@dataclass(frozen=True)
class _HyperPosterior:
    """Log posterior of ``x = (mu, ln sigma)``, vectorised over rows (module docstring)."""

    phis: list
    boxes: list
    spread_scale: float

    @property
    def n_par(self):
        return self.phis[0].shape[1]

    @cached_property
    def mean_box(self):
        """Box of ``mu``: the union of the units' prior boxes (computed once; the posterior is called every step)."""
        lo = np.min([b[:, 0] for b in self.boxes], axis=0)
        hi = np.max([b[:, 1] for b in self.boxes], axis=0)
        return np.column_stack([lo, hi])

    def __call__(self, x):
        x = np.atleast_2d(x)
        p = self.n_par
        mu, log_sigma = x[:, :p], x[:, p:]
        box = self.mean_box
        inside = np.all((mu >= box[:, 0]) & (mu <= box[:, 1]), axis=1) & np.all(
            (log_sigma >= np.log(SPREAD_BOUNDS[0])) & (log_sigma <= np.log(SPREAD_BOUNDS[1])), axis=1)
        out = np.full(x.shape[0], -np.inf)
        if not inside.any():
            return out
        mu, log_sigma = mu[inside], log_sigma[inside]
        sigma = np.exp(log_sigma)
        # half-normal prior on sigma, sampled in ln sigma (Jacobian sigma)
        lp = np.sum(-0.5 * (sigma / self.spread_scale) ** 2 + log_sigma, axis=1)
        for phi, b in zip(self.phis, self.boxes):
            lp = lp + unit_log_likelihood(phi, b, mu, sigma)
        out[inside] = lp
        return out


def log_truncated_normal(phi, box, mu, sigma):
    """``log N_trunc(phi_n; mu_w, sigma_w)``, shape ``(W, n)``: each draw under each population row.

    ``phi`` ``(n, p)``: one unit's ln-parameter draws; ``mu``, ``sigma`` ``(W, p)``; ``box`` ``(p, 2)``:
    the truncation (that unit's prior box).
    """
    z = (phi[None, :, :] - mu[:, None, :]) / sigma[:, None, :]
    norm = np.sum(np.log(sigma), axis=1) + 0.5 * phi.shape[1] * _LOG_2PI + log_box_mass(box, mu, sigma)
    return -0.5 * np.einsum("wnp,wnp->wn", z, z) - norm[:, None]


def unit_log_likelihood(phi, box, mu, sigma):
    """``log mean_n N_trunc(phi_n; mu, sigma)`` for each row of ``mu``, ``sigma`` ``(W, p)``.

    ``phi`` ``(n, p)``: one unit's single-fit posterior draws (ln parameters); ``box`` ``(p, 2)``:
    the truncation (that fit's prior box). Up to the constant ``-log pi_u``.
    """
    return special.logsumexp(log_truncated_normal(phi, box, mu, sigma), axis=1) - np.log(phi.shape[0])


def log_box_mass(box, mu, sigma):
    """``sum_d log P(a_d < N(mu_d, sigma_d) < b_d)`` for rows of ``mu``, ``sigma`` (stable in both tails)."""
    a = (box[:, 0] - mu) / sigma
    b = (box[:, 1] - mu) / sigma
    # P(a < Z < b) = Phi(b) - Phi(a) = Phi(-a) - Phi(-b); take the form away from the upper tail
    flip = a > 0
    hi = np.where(flip, -a, b)
    lo = np.where(flip, -b, a)
    log_hi, log_lo = special.log_ndtr(hi), special.log_ndtr(lo)
    return np.sum(log_hi + np.log1p(-np.exp(np.minimum(log_lo - log_hi, 0.0))), axis=1)


def _sample_hyper(target, rng, max_steps):
    p = target.n_par
    medians = np.array([np.median(phi, axis=0) for phi in target.phis])
    spread0 = np.clip(np.std(medians, axis=0, ddof=1), 0.01, 1.0)
    n_walkers = max(32, 4 * 2 * p)
    start = np.column_stack([medians.mean(axis=0) + 0.3 * spread0 * rng.standard_normal((n_walkers, p)),
                             np.log(spread0) + 0.3 * rng.standard_normal((n_walkers, p))])
    box = target.mean_box
    start[:, :p] = np.clip(start[:, :p], box[:, 0] + 1e-6, box[:, 1] - 1e-6)
    start[:, p:] = np.clip(start[:, p:], np.log(SPREAD_BOUNDS[0]) + 1e-6, np.log(SPREAD_BOUNDS[1]) - 1e-6)
    sampler = ensemble_sampler(target, start, rng, capacity=max_steps)
    state, tau_old, converged, tau_max = start, np.inf, False, np.nan
    while sampler.iteration < max_steps:
        state = sampler.run_mcmc(state, 500, progress=False)
        tau_max = float(np.max(autocorr_time(sampler.get_chain())))
        if long_enough(sampler.iteration, tau_max, tau_old):
            converged = True
            break
        tau_old = tau_max
    if not converged:
        warnings.warn(f"population sampler not converged after {sampler.iteration} steps (autocorrelation time "
                      f"{tau_max:.0f} steps); raise max_steps", ConvergenceWarning, stacklevel=3)
    burn, thin = burn_and_thin(tau_max)
    chain = sampler.get_chain(discard=burn, thin=thin, flat=True)
    diagnostics = {"autocorr_time": tau_max, "n_steps": sampler.iteration, "n_walkers": n_walkers,
                   "n_draws": chain.shape[0], "converged": converged}
    return chain[:, :p], np.exp(chain[:, p:]), diagnostics


def _pooled_draws(phi, box, mean, spread, rng, n_hyper=400):
    """One unit's draws reweighted by the population (mean over hyper draws); resampled, and the ESS."""
    pick = rng.choice(mean.shape[0], size=min(n_hyper, mean.shape[0]), replace=False)
    log_w = special.logsumexp(log_truncated_normal(phi, box, mean[pick], spread[pick]), axis=0)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    ess = 1.0 / np.sum(w * w)
    return phi[rng.choice(phi.shape[0], size=phi.shape[0], p=w)], ess


def _new_unit(model, mean, spread, target, n_new, rng):
    """Posterior predictive draws of a new unit's ln parameters (truncated to the box, ordered)."""
    box = target.mean_box
    order = list(model.ordered)
    rows = rng.integers(mean.shape[0], size=n_new)
    out = mean[rows] + spread[rows] * rng.standard_normal((n_new, mean.shape[1]))
    for _ in range(200):
        bad = np.any((out < box[:, 0]) | (out > box[:, 1]), axis=1)
        if len(order) > 1:
            bad |= np.any(np.diff(out[:, order], axis=1) <= 0, axis=1)
        if not bad.any():
            break
        out[bad] = mean[rows[bad]] + spread[rows[bad]] * rng.standard_normal((int(bad.sum()), mean.shape[1]))
    return np.clip(out, box[:, 0], box[:, 1])


def _number(value):
    """A float for JSON, ``None`` where it was not computed (NaN)."""
    value = float(value)
    return value if np.isfinite(value) else None


def _unit_fit(label, allan, **options):
    """:func:`fit_allan` of one unit; an error names the unit (one unfittable unit among several)."""
    try:
        return fit_allan(allan, **options)
    except BayesIMUError as exc:
        raise type(exc)(f"unit {label!r}: {exc}") from None
