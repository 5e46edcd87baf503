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

Sampling. Each unit's likelihood integrates over its single-unit posterior draws (importance
sampling, Hogg, Myers & Bovy 2010, ApJ 725, 2166): with a uniform single-unit prior pi_u,

    p(d_u | mu, sigma) proportional to  integral N_trunc(phi; mu, sigma) p_u(phi) / pi_u(phi) dphi,

with ``p_u`` the draws' kernel density estimate (Gaussian kernels, the draws shrunk so that its
mean and variances are theirs: Liu & West 2001; :func:`unit_density`): a mean of Gaussians over
the draws, smooth at every spread. Every unit keeps the non-Gaussian shape of its own fit
(discrepancy-widened fits included: the discrepancy is a per-unit nuisance, integrated out in
each unit's draws, not pooled). The posterior of ``(mu, ln sigma)`` (2 x n_par dimensions) is
sampled by Hamiltonian Monte Carlo on independent chains (:mod:`bayes_imu.inference.hmc`) until
every hyper-parameter has split R-hat < 1.01 and more than 400 effective draws (``diagnostics``;
a :class:`~bayes_imu.errors.ConvergenceWarning` otherwise, and ``fit-population`` exits with
status 4). Each unit's pooled posterior is its draws reweighted by the population; a new unit's
parameters are drawn from ``N(mu, sigma^2)`` for each population draw (the posterior
predictive), and go through the same drift variances as a single fit
(:func:`bayes_imu.drift.bands.drift_bands` accepts a :class:`UnitPosterior`).

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
from .hmc import sample_hmc
from .sampling import one_blas_thread
from .likelihood import default_bounds
from ..noise.avar_forms import PARAMETER_UNITS, NoiseModel
from .selection import CandidateScore, select

__all__ = ["PopulationResult", "UnitPosterior", "fit_population", "SPREAD_BOUNDS",
           "SPREAD_PRIOR_SHARE", "spread_prior_sd"]

#: bounds of the population spread sigma (standard deviation of a ln parameter across units)
SPREAD_BOUNDS = (1e-3, 5.0)
#: a spread whose posterior standard deviation is at least this share of its prior's is "mostly its
#: prior's" (:meth:`PopulationResult.spread_prior_share`): the units shrank its uncertainty by less
#: than a quarter
SPREAD_PRIOR_SHARE = 0.75


def spread_prior_sd(scale, bounds=SPREAD_BOUNDS):
    """Standard deviation of the spread's prior: a normal of scale ``scale`` truncated to
    ``bounds`` (the half-normal of the module docstring, within :data:`SPREAD_BOUNDS`).

    With ``a, b = bounds / scale``, ``Z = Phi(b) - Phi(a)``, the truncated standard normal has mean
    ``m = (phi(a) - phi(b)) / Z`` and variance ``1 + (a phi(a) - b phi(b)) / Z - m^2``.
    """
    a, b = bounds[0] / scale, bounds[1] / scale
    phi_a, phi_b = np.exp(-0.5 * a * a), np.exp(-0.5 * b * b)
    phi_a, phi_b = phi_a / np.sqrt(2.0 * np.pi), phi_b / np.sqrt(2.0 * np.pi)
    z = special.ndtr(b) - special.ndtr(a)
    m = (phi_a - phi_b) / z
    return float(scale * np.sqrt(1.0 + (a * phi_a - b * phi_b) / z - m * m))


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
        """Draws of one parameter, or ``noise_density`` (short-term white equivalent,
        u/sqrt(Hz))."""
        if name == "noise_density":
            return np.sqrt(self.model.short_term_variance(self.samples) * self.model.dt)
        if name not in self.parameter_names:
            raise InputError(
                f"parameter {name!r}: the model {self.model.terms} has "
                f"{', '.join(self.parameter_names)}"
            )
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
        ``autocorr_time``, ``n_steps`` (iterations per chain), ``n_walkers`` (chains), ``n_draws``,
        ``converged``, ``rhat_max`` and ``ess_hyper_min`` (over the hyper-parameters), ``accept``,
        and the pooled draws' importance ``ess_min``.
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

    def spread_prior_share(self):
        """Dict parameter -> posterior standard deviation of its spread ``sigma`` over the prior's
        (:func:`spread_prior_sd`): near 1 where the units barely measure how far they differ (two
        or three units, a poorly measured parameter), so that a new unit's bounds lean on the
        spread's prior; well below 1 where the data measured it. Parameters at or above
        :data:`SPREAD_PRIOR_SHARE` are warned of by the commands."""
        prior = spread_prior_sd(self.spread_scale)
        return {n: float(np.std(self.spread[:, i]) / prior)
                for i, n in enumerate(self.parameter_names)}

    def spread_quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict parameter -> quantiles of the population spread sigma (ln units, ~ relative
        spread)."""
        return {n: np.quantile(self.spread[:, i], q) for i, n in enumerate(self.parameter_names)}

    def summary(self, *, unit="u"):
        """JSON-ready summary (``bayes-imu fit-population``'s ``summary.json``)."""
        from ..noise.datasheet import datasheet
        from ..noise.quantities import sensor_of_si_unit

        kind = sensor_of_si_unit(unit)

        def stats(draws, name):
            return {
                "median": float(np.median(draws)),
                "q05": float(np.quantile(draws, 0.05)),
                "q95": float(np.quantile(draws, 0.95)),
                "unit": PARAMETER_UNITS.get(name, "1").format(u=unit),
            }

        def block(post):
            return {n: stats(post.draws(n), n) for n in post.parameter_names + ("noise_density",)}

        units = []
        for label, alone, pooled in zip(self.labels, self.unit_fits, self.units):
            units.append(
                {
                    "label": label,
                    "n_samples": int(alone.allan.n_samples),
                    "record_s": pooled.record_s,
                    "alone": {
                        n: stats(alone.draws(n), n)
                        for n in self.parameter_names + ("noise_density",)
                    },
                    "pooled": block(pooled),
                    "adequacy": alone.adequacy.to_dict(),
                    "widened": bool(alone.widened),
                }
            )
        population, share = {}, self.spread_prior_share()
        for i, name in enumerate(self.parameter_names):
            population[name] = {"median": float(np.exp(np.median(self.mean[:, i]))),
                                "unit": PARAMETER_UNITS.get(name, "1").format(u=unit),
                                "spread_ln": {"median": float(np.median(self.spread[:, i])),
                                              "q05": float(np.quantile(self.spread[:, i], 0.05)),
                                              "q95": float(np.quantile(self.spread[:, i], 0.95)),
                                              "sd_over_prior_sd": share[name]}}
        return {
            "model": list(self.model.terms),
            "what": "posterior predictive for a new unit of this sensor model (unit-to-unit spread "
                    "included)",
            "new_unit": block(self.new_unit),
            "new_unit_datasheet": datasheet(self.new_unit, kind) if kind else None,
            "population": population,
            "units": units,
            # fixed terms (no selection) score no evidence: null, not NaN (invalid JSON)
            "structures": [
                {
                    "model": list(s.terms),
                    "log_evidence": _number(s.log_evidence),
                    "log_evidence_se": _number(s.log_evidence_se),
                    "per_unit": [_number(v) for v in self.per_unit_evidence[i]],
                    "selected": i == self.selected,
                }
                for i, s in enumerate(self.structures)
            ],
            "spread_prior": f"half-normal, scale {self.spread_scale:g} (ln units)",
            # a chain that never moved has no finite R-hat: null in JSON
            "diagnostics": {
                k: (
                    bool(v)
                    if k == "converged"
                    else int(v)
                    if k in ("n_steps", "n_walkers", "n_draws")
                    else _number(v)
                )
                for k, v in self.diagnostics.items()
            },
            "rate_hz": float(self.unit_fits[0].allan.rate_hz),
            "seed": self.seed if isinstance(self.seed, (int, type(None))) else str(self.seed),
            "bayes_imu_version": __version__,
        }


def fit_population(
    allans,
    *,
    labels=None,
    terms="auto",
    unit_fits=None,
    rng=None,
    threshold=1.0,
    spread_scale=1.0,
    n_unit_draws=800,
    n_new=4000,
    max_steps=4000,
    progress=False,
):
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
        raise InputError(
            f"fit_population: expected at least 2 AllanResults (one per unit), got {len(allans)}"
        )
    rate = allans[0].rate_hz
    for i, a in enumerate(allans):
        if not np.isclose(a.rate_hz, rate, rtol=1e-9):
            raise InputError(
                f"fit_population: unit {i + 1} is sampled at {a.rate_hz:g} Hz, unit 1 at {rate:g} "
                "Hz: expected one sample rate"
            )
    labels = (
        tuple(labels) if labels is not None else tuple(f"unit {i + 1}" for i in range(len(allans)))
    )
    if len(labels) != len(allans) or len(set(labels)) != len(labels):
        raise InputError(f"fit_population: expected {len(allans)} distinct labels, got {labels!r}")
    if not (np.isfinite(spread_scale) and spread_scale > 0):
        raise InputError(f"spread_scale={spread_scale!r}: expected a positive number")
    seed = rng
    rng = np.random.default_rng(rng)
    if unit_fits is None:
        unit_fits = [
            _unit_fit(label, a, rng=rng, progress=progress) for label, a in zip(labels, allans)
        ]
    elif len(unit_fits) != len(allans) or not all(isinstance(f, FitResult) for f in unit_fits):
        raise InputError("unit_fits: expected one FitResult per Allan result")
    dt = 1.0 / rate
    if terms == "auto":
        structures, evidence, chosen = _choose_structure(allans, unit_fits, threshold, rng)
    else:
        model = NoiseModel(tuple(terms), dt)
        structures, evidence, chosen = (
            (CandidateScore(model.terms, np.nan, np.nan, np.nan, np.empty(0)),),
            np.full((1, len(allans)), np.nan),
            0,
        )
    model = NoiseModel(structures[chosen].terms, dt)
    fits = [
        f
        if f.model.terms == model.terms
        else _unit_fit(
            label, a, terms=model.terms, discrepancy="always" if f.widened else "auto", rng=rng
        )
        for label, a, f in zip(labels, allans, unit_fits)
    ]
    p = len(model.parameter_names)
    phis, boxes = [], []
    for a, f in zip(allans, fits):
        idx = rng.choice(
            f.samples.shape[0], size=min(n_unit_draws, f.samples.shape[0]), replace=False
        )
        phis.append(np.log(f.samples[idx, :p]))
        boxes.append(default_bounds(model, a))
    target = _HyperPosterior(phis, boxes, spread_scale)
    mean, spread, diagnostics = _sample_hyper(target, rng, max_steps)
    pooled, ess = [], []
    for label, a, f, phi, box in zip(labels, allans, fits, phis, boxes):
        draws, e = _pooled_draws(phi, box, mean, spread, rng)
        pooled.append(
            UnitPosterior(
                model, np.exp(draws), a.duration_s, label, _discrepancy(f, draws.shape[0], rng)
            )
        )
        ess.append(e)
    diagnostics["ess_min"] = float(min(ess))
    new = _new_unit(model, mean, spread, target, n_new, rng)
    new_disc = None
    # a new unit's discrepancy: a random unit's (zero for adequate units)
    if any(f.widened for f in fits):
        pool = np.concatenate(
            [f.samples[:, p] if f.widened else np.zeros(f.samples.shape[0]) for f in fits]
        )
        new_disc = pool[rng.integers(pool.size, size=new.shape[0])]
    record = float(min(a.duration_s for a in allans))
    new_unit = UnitPosterior(model, np.exp(new), record, "new unit", new_disc)
    return PopulationResult(
        model,
        labels,
        tuple(fits),
        tuple(pooled),
        mean,
        spread,
        new_unit,
        structures,
        evidence,
        chosen,
        diagnostics,
        float(spread_scale),
        seed,
    )


def _discrepancy(fit, n, rng):
    if not fit.widened:
        return None
    d = fit.samples[:, len(fit.model.parameter_names)]
    return d[rng.integers(d.size, size=n)]


def _choose_structure(allans, unit_fits, threshold, rng):
    """Candidate structures with posterior mass in any unit, scored on every unit; summed
    evidence."""
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
    summed = tuple(
        CandidateScore(
            t, float(evidence[i].sum()), float(np.sqrt(np.sum(se[i] ** 2))), np.nan, np.empty(0)
        )
        for i, t in enumerate(seen)
    )
    chosen = select(summed, threshold=threshold) if len(summed) > 1 else 0
    return summed, evidence, chosen


@dataclass(frozen=True)
class _HyperPosterior:
    """Log posterior of ``x = (mu, ln sigma)``, vectorised over rows (module docstring).

    ``smoothing``: each unit's draws stand for a smooth density, a Gaussian kernel density
    estimate with the draws shrunk towards their mean so that its mean and covariance are the
    draws' own (Liu & West 2001, "Combined parameter and state estimation in simulation-based
    filtering", sec 10.3.3; :func:`unit_density`). Without it the importance-sampled
    likelihood at spreads far below a unit's posterior width is a sum of spikes at the draws
    (in 8-10 dimensions no draw lies near another), which trapped the sampler's walkers
    (autocorrelation times near 1000 steps on the ADIS16405 folds, issue 39).
    """

    phis: list
    boxes: list
    spread_scale: float
    smoothing: bool = True

    @property
    def n_par(self):
        return self.phis[0].shape[1]

    @cached_property
    def mean_box(self):
        """Box of ``mu``: the union of the units' prior boxes (computed once; the posterior is
        called every step)."""
        lo = np.min([b[:, 0] for b in self.boxes], axis=0)
        hi = np.max([b[:, 1] for b in self.boxes], axis=0)
        return np.column_stack([lo, hi])

    @cached_property
    def densities(self):
        """``(centre, draws about it, kernel variance)`` of each unit (:func:`unit_density`)."""
        return [unit_density(phi, smoothing=self.smoothing) for phi in self.phis]

    def __call__(self, x):
        x = np.atleast_2d(x)
        p = self.n_par
        mu, log_sigma = x[:, :p], x[:, p:]
        box = self.mean_box
        inside = np.all((mu >= box[:, 0]) & (mu <= box[:, 1]), axis=1) & np.all(
            (log_sigma >= np.log(SPREAD_BOUNDS[0])) & (log_sigma <= np.log(SPREAD_BOUNDS[1])),
            axis=1,
        )
        out = np.full(x.shape[0], -np.inf)
        if not inside.any():
            return out
        mu, log_sigma = mu[inside], log_sigma[inside]
        sigma = np.exp(log_sigma)
        # half-normal prior on sigma, sampled in ln sigma (Jacobian sigma)
        lp = np.sum(-0.5 * (sigma / self.spread_scale) ** 2 + log_sigma, axis=1)
        for density, b in zip(self.densities, self.boxes):
            lp = lp + density_log_likelihood(density, mu, sigma) - log_box_mass(b, mu, sigma)
        out[inside] = lp
        return out

    def value_and_grad(self, x):
        """Log posterior ``(W,)`` of rows ``x`` ``(W, 2p)`` and its gradient ``(W, 2p)`` (-inf and
        zeros outside the support): what the Hamiltonian sampler follows."""
        x = np.atleast_2d(x)
        p = self.n_par
        box = self.mean_box
        mu, log_sigma = x[:, :p], x[:, p:]
        inside = np.all((mu >= box[:, 0]) & (mu <= box[:, 1]), axis=1) & np.all(
            (log_sigma >= np.log(SPREAD_BOUNDS[0])) & (log_sigma <= np.log(SPREAD_BOUNDS[1])),
            axis=1,
        )
        out, grad = np.full(x.shape[0], -np.inf), np.zeros_like(x)
        if not inside.any():
            return out, grad
        mu, log_sigma = mu[inside], log_sigma[inside]
        sigma = np.exp(log_sigma)
        ratio = (sigma / self.spread_scale) ** 2
        lp = np.sum(-0.5 * ratio + log_sigma, axis=1)
        g_mu, g_log_sigma = np.zeros_like(mu), 1.0 - ratio
        for density, b in zip(self.densities, self.boxes):
            value, d_mu, d_log_sigma = density_log_likelihood(density, mu, sigma, gradient=True)
            mass, m_mu, m_log_sigma = log_box_mass(b, mu, sigma, gradient=True)
            lp = lp + value - mass
            g_mu += d_mu - m_mu
            g_log_sigma += d_log_sigma - m_log_sigma
        out[inside] = lp
        grad[inside] = np.concatenate([g_mu, g_log_sigma], axis=1)
        return out, grad


def unit_density(phi, *, smoothing=True):
    """One unit's ln-parameter draws ``phi`` ``(n, p)`` as ``(centre, offsets, kernel)``.

    ``centre`` ``(p,)`` is the draws' mean, ``offsets`` ``(n, p)`` the draws about it and
    ``kernel`` ``(p,)`` the variance of a Gaussian kernel on each (zeros without ``smoothing``:
    the draws themselves). With ``smoothing`` the kernel is ``h^2`` times each parameter's
    variance (Silverman's rule in ``p`` dimensions, ``h = (4 / ((p + 2) n))^(1/(p + 4))``) and
    the offsets are shrunk by ``sqrt(1 - h^2)``: the density's mean and variances are the draws'
    (Liu & West 2001); a Gaussian posterior keeps its covariance up to a factor ``1 - h^2`` on
    its correlations.
    """
    n, p = phi.shape
    centre = phi.mean(axis=0)
    offsets = phi - centre
    if not smoothing or n < 2:
        return centre, offsets, np.zeros(p)
    h2 = (4.0 / ((p + 2) * n)) ** (2.0 / (p + 4))
    return centre, np.sqrt(1.0 - h2) * offsets, h2 * offsets.var(axis=0)


def density_log_likelihood(density, mu, sigma, *, gradient=False):
    """``log mean_n N(c + q_n; mu, sigma^2 + k)`` for each row of ``mu``, ``sigma`` ``(W, p)``.

    ``density``: ``(c, q, k)`` of :func:`unit_density`. The quadratic forms of all draws and rows
    are one matrix product of ``[q^2, q]`` with ``[1 / v, -2 (mu - c) / v]`` (``v = sigma^2 + k``):
    the offsets are small about the centre, so the expansion loses no significant digits where
    the density is not negligible. ``gradient``: also its derivatives ``(W, p)`` by ``mu`` and by
    ``ln sigma``, from the weighted means of ``q - d`` and ``(q - d)^2`` (``d = mu - c``, weights
    each draw's share of the mean).
    """
    centre, q, kernel = density
    v = sigma * sigma + kernel
    d = mu - centre
    coef = np.concatenate([1.0 / v, -2.0 * d / v], axis=1)  # (W, 2p)
    design = np.concatenate([q * q, q], axis=1)
    quad = design @ coef.T  # (n, W), without the rows' own sum(d^2 / v)
    least = quad.min(axis=0)
    quad -= least
    quad *= -0.5
    np.exp(quad, out=quad)  # the log of the mean of the exponentials, about each row's largest term
    total = quad.sum(axis=0)
    value = np.log(total) - 0.5 * (least + np.sum(d * d / v, axis=1))
    value = (
        value - 0.5 * np.sum(np.log(v), axis=1) - 0.5 * q.shape[1] * _LOG_2PI - np.log(q.shape[0])
    )
    if not gradient:
        return value
    moments = (quad.T @ design) / total[:, None]  # (W, 2p): weighted means of q^2 and q
    m2, m1 = moments[:, :q.shape[1]], moments[:, q.shape[1]:]
    first = m1 - d  # weighted mean of q - d
    second = m2 - 2.0 * d * m1 + d * d  # weighted mean of (q - d)^2
    return value, first / v, (second / v - 1.0) * sigma * sigma / v


def log_truncated_normal(phi, box, mu, sigma):
    """``log N_trunc(phi_n; mu_w, sigma_w)``, shape ``(W, n)``: each draw under each population row.

    ``phi`` ``(n, p)``: one unit's ln-parameter draws; ``mu``, ``sigma`` ``(W, p)``; ``box`` ``(p,
    2)``: the truncation (that unit's prior box).
    """
    z = (phi[None, :, :] - mu[:, None, :]) / sigma[:, None, :]
    norm = (
        np.sum(np.log(sigma), axis=1) + 0.5 * phi.shape[1] * _LOG_2PI + log_box_mass(box, mu, sigma)
    )
    return -0.5 * np.einsum("wnp,wnp->wn", z, z) - norm[:, None]


def unit_log_likelihood(phi, box, mu, sigma):
    """``log mean_n N_trunc(phi_n; mu, sigma)`` for each row of ``mu``, ``sigma`` ``(W, p)``.

    ``phi`` ``(n, p)``: one unit's single-fit posterior draws (ln parameters); ``box`` ``(p, 2)``:
    the truncation (that fit's prior box). Up to the constant ``-log pi_u``.
    """
    return special.logsumexp(log_truncated_normal(phi, box, mu, sigma), axis=1) - np.log(
        phi.shape[0]
    )


def log_box_mass(box, mu, sigma, *, gradient=False):
    """``sum_d log P(a_d < N(mu_d, sigma_d) < b_d)`` for rows of ``mu``, ``sigma`` (stable in both
    tails).

    ``gradient``: also its derivatives ``(W, p)`` by ``mu`` and by ``ln sigma``:
    ``(phi(A) - phi(B)) / (sigma P)`` and ``(A phi(A) - B phi(B)) / P`` with ``A``, ``B`` the box's
    ends in standard units and ``phi`` the normal density (each ratio taken in logs).
    """
    a = (box[:, 0] - mu) / sigma
    b = (box[:, 1] - mu) / sigma
    # P(a < Z < b) = Phi(b) - Phi(a) = Phi(-a) - Phi(-b); take the form away from the upper tail
    flip = a > 0
    hi = np.where(flip, -a, b)
    lo = np.where(flip, -b, a)
    log_hi, log_lo = special.log_ndtr(hi), special.log_ndtr(lo)
    log_mass = log_hi + np.log1p(-np.exp(np.minimum(log_lo - log_hi, 0.0)))
    if not gradient:
        return np.sum(log_mass, axis=1)
    dens_a = np.exp(-0.5 * a * a - 0.5 * _LOG_2PI - log_mass)
    dens_b = np.exp(-0.5 * b * b - 0.5 * _LOG_2PI - log_mass)
    with np.errstate(invalid="ignore"):  # an infinite end: its density term is zero
        end_a = np.where(np.isfinite(a), a * dens_a, 0.0)
        end_b = np.where(np.isfinite(b), b * dens_b, 0.0)
    return np.sum(log_mass, axis=1), (dens_a - dens_b) / sigma, end_a - end_b


#: convergence of the population sampler: split R-hat below this, for every hyper-parameter
RHAT_MAX = 1.01
#: convergence of the population sampler: effective draws above this, for every hyper-parameter
ESS_MIN = 400
#: independent chains of the population sampler
N_CHAINS = 16


def _sample_hyper(target, rng, max_steps):
    """Draws of ``(mu, sigma)`` by Hamiltonian Monte Carlo
    (:func:`~bayes_imu.inference.hmc.sample_hmc`) on :data:`N_CHAINS` chains until every
    hyper-parameter has split R-hat below :data:`RHAT_MAX` and more than :data:`ESS_MIN` effective
    draws, or ``max_steps`` iterations.

    The emcee ensemble used before needed 20 000 steps and more on 16-20 hyper-parameters
    (autocorrelation times of 150-1000 steps: issue 39); the posterior being smooth
    (:func:`unit_density`) with a cheap gradient, trajectories cross it in a few steps.
    """
    p = target.n_par
    medians = np.array([np.median(phi, axis=0) for phi in target.phis])
    spread0 = np.clip(np.std(medians, axis=0, ddof=1), 0.01, 1.0)
    start = np.column_stack(
        [
            medians.mean(axis=0) + 0.3 * spread0 * rng.standard_normal((N_CHAINS, p)),
            np.log(spread0) + 0.3 * rng.standard_normal((N_CHAINS, p)),
        ]
    )
    box = target.mean_box
    start[:, :p] = np.clip(start[:, :p], box[:, 0] + 1e-6, box[:, 1] - 1e-6)
    start[:, p:] = np.clip(
        start[:, p:], np.log(SPREAD_BOUNDS[0]) + 1e-6, np.log(SPREAD_BOUNDS[1]) - 1e-6
    )
    scaled = _ScaledMean(target)
    with one_blas_thread():
        run = sample_hmc(scaled.value_and_grad, scaled.to_scaled(start), rng, max_steps=max_steps,
                         rhat_max=RHAT_MAX, ess_min=ESS_MIN, monitor=scaled.to_hyper)
    if not run.converged:
        warnings.warn(
            f"population sampler not converged after {run.chain.shape[0]} iterations of {N_CHAINS} "
            f"chains (R-hat {np.max(run.rhat):.3f}, effective draws {np.min(run.ess):.0f}; needed "
            f"< {RHAT_MAX} and > {ESS_MIN}); raise max_steps",
            ConvergenceWarning,
            stacklevel=3,
        )
    chain = run.chain.reshape(-1, 2 * p)
    diagnostics = {"autocorr_time": float(np.max(run.autocorr_time)), "n_steps": run.chain.shape[0],
                   "n_walkers": N_CHAINS, "n_draws": chain.shape[0], "converged": run.converged,
                   "rhat_max": float(np.max(run.rhat)), "ess_hyper_min": float(np.min(run.ess)),
                   "accept": run.accept}
    return chain[:, :p], np.exp(chain[:, p:]), diagnostics


class _ScaledMean:
    """The hyper-posterior in coordinates ``(z, ln sigma)`` with ``mu = c(sigma) + t(sigma) z``.

    ``c`` and ``t`` are the mean and standard deviation of ``mu`` given ``sigma`` were each unit's
    posterior normal (centre ``m_u``, variance ``w_u^2`` of its smoothed draws):
    ``t^-2 = sum_u 1 / (sigma^2 + w_u^2)``, ``c = t^2 sum_u m_u / (sigma^2 + w_u^2)``, per
    parameter. The map is one to one for each ``sigma``, so the density is the same up to the
    Jacobian ``prod t``; it takes away the funnel of ``mu`` narrowing as the spread falls below the
    units' widths (few units, a poorly measured parameter), which a fixed step size cannot follow
    (partial non-centring: Papaspiliopoulos, Roberts & Skold 2007, Stat. Sci. 22, 59).
    """

    def __init__(self, target):
        self.target = target
        self.m = np.array([d[0] for d in target.densities])  # (U, p)
        self.w2 = np.array([d[1].var(axis=0) + d[2] for d in target.densities])  # (U, p)

    def _moments(self, sigma):
        sigma = np.clip(sigma, 0.5 * SPREAD_BOUNDS[0], 2.0 * SPREAD_BOUNDS[1])  # beyond: rejected
        a = 1.0 / (sigma[:, None, :] ** 2 + self.w2[None])  # (W, U, p)
        precision = a.sum(axis=1)
        return a, precision, np.sum(a * self.m[None], axis=1) / precision, precision ** -0.5

    def to_hyper(self, y):
        p = self.target.n_par
        _, _, c, t = self._moments(np.exp(y[:, p:]))
        return np.concatenate([c + t * y[:, :p], y[:, p:]], axis=1)

    def to_scaled(self, x):
        p = self.target.n_par
        _, _, c, t = self._moments(np.exp(x[:, p:]))
        return np.concatenate([(x[:, :p] - c) / t, x[:, p:]], axis=1)

    def value_and_grad(self, y):
        p = self.target.n_par
        z, log_sigma = y[:, :p], y[:, p:]
        sigma = np.exp(np.clip(log_sigma, np.log(0.5 * SPREAD_BOUNDS[0]),
                               np.log(2.0 * SPREAD_BOUNDS[1])))
        a, precision, c, t = self._moments(sigma)
        with np.errstate(over="ignore", invalid="ignore"):
            mu = c + t * z  # non-finite far outside: the target rejects it
        value, grad = self.target.value_and_grad(np.concatenate([mu, log_sigma], axis=1))
        g_mu, g_log_sigma = grad[:, :p], grad[:, p:]
        da = -2.0 * sigma[:, None, :] ** 2 * a * a  # d a_u / d ln sigma
        d_precision = da.sum(axis=1)
        dc = (np.sum(da * self.m[None], axis=1) - c * d_precision) / precision
        dt = -0.5 * t * d_precision / precision
        value = value + np.sum(np.log(t), axis=1)
        with np.errstate(over="ignore", invalid="ignore"):  # a row far outside: rejected
            g_log_sigma = g_log_sigma + g_mu * (dc + dt * z) - 0.5 * d_precision / precision
            g = np.concatenate([g_mu * t, g_log_sigma], axis=1)
        return value, np.where(np.isfinite(value)[:, None] & np.isfinite(g), g, 0.0)


def _pooled_draws(phi, box, mean, spread, rng, n_hyper=400):
    """One unit's draws reweighted by the population (mean over hyper draws); resampled, and the
    ESS."""
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
        out[bad] = mean[rows[bad]] + spread[rows[bad]] * rng.standard_normal(
            (int(bad.sum()), mean.shape[1])
        )
    return np.clip(out, box[:, 0], box[:, 1])


def _number(value):
    """A float for JSON, ``None`` where it was not computed (NaN)."""
    value = float(value)
    return value if np.isfinite(value) else None


def _unit_fit(label, allan, **options):
    """:func:`fit_allan` of one unit; an error names the unit (one unfittable unit among
    several)."""
    try:
        return fit_allan(allan, **options)
    except BayesIMUError as exc:
        raise type(exc)(f"unit {label!r}: {exc}") from None
