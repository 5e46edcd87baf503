"""Bayesian fit of a noise model to an Allan variance: model selection, then emcee.

Pipeline of :func:`fit_allan`:

1. *Pilot*: posterior mode of the full model (all terms) under the independent-gamma
   likelihood (a weighted least-squares fit in disguise, fast and robust).
2. *Covariance*: the exact covariance of the AVAR estimates under that pilot model
   (:mod:`bayes_imu.avar_covariance`), shared by every candidate so that their evidences
   come from one likelihood function.
3. *Selection*: every candidate ``white + subset of {quantization, bias_instability,
   gauss_markov, random_walk}`` gets its mode and its evidence (:mod:`bayes_imu.selection`).
4. *Refinement*: the covariance is recomputed at the selected model's mode.
5. *Sampling*: emcee (``vectorize=True``, differential-evolution and stretch moves) in
   log-parameters, in chunks of 250 steps until the chain is longer than 50 integrated
   autocorrelation times and that estimate has settled to 5%; then
   R-hat and bulk/tail ESS from ArviZ. Non-convergence warns (:class:`ConvergenceWarning`)
   and sets ``diagnostics["converged"] = False``.
"""

import warnings
from dataclasses import dataclass, field

import numpy as np

from ._progress import progress_bar
from ._version import __version__
from .allan import AllanResult, allan_variance
from .errors import ConvergenceWarning, InputError
from .likelihood import LIKELIHOODS, LogPosterior, default_bounds
from .models import PARAMETER_UNITS, TERMS, NoiseModel
from .selection import CandidateScore, candidate_terms, log_evidence, posterior_mode, select

__all__ = ["FitResult", "fit", "fit_allan"]

AUTOCORR_MULTIPLE = 50
RHAT_MAX = 1.01
ESS_MIN = 400


@dataclass(frozen=True)
class FitResult:
    """Posterior of a noise model fitted to an Allan variance.

    Attributes
    ----------
    model : NoiseModel
        Selected model (term names in :data:`bayes_imu.models.TERMS`).
    samples : ndarray, shape (n_draws, n_par)
        Posterior draws of the parameters (physical units, ``model.parameter_names`` order),
        after burn-in and thinning.
    log_prob : ndarray, shape (n_draws,)
    allan : AllanResult
        The data.
    candidates : tuple of CandidateScore
        Evidence of every candidate model.
    selected : int
        Index of the selected candidate.
    diagnostics : dict
        ``rhat_max``, ``ess_bulk_min``, ``ess_tail_min``, ``autocorr_time`` (steps),
        ``n_steps``, ``n_walkers``, ``converged``.
    likelihood : str
    covariance : ndarray, shape (n_tau, n_tau)
        AVAR covariance the likelihood used.
    seed : object
        The ``rng`` argument as given (an int for reproducible runs).
    inference_data : arviz.InferenceData
    """

    model: NoiseModel
    samples: np.ndarray
    log_prob: np.ndarray
    allan: AllanResult
    candidates: tuple
    selected: int
    diagnostics: dict
    likelihood: str
    covariance: np.ndarray
    seed: object = None
    inference_data: object = field(default=None, repr=False, compare=False)

    @property
    def parameter_names(self):
        return self.model.parameter_names

    def draws(self, name):
        """Posterior draws of one parameter (or the derived ``noise_density``)."""
        if name == "noise_density":
            return np.sqrt(self.draws("noise_variance") * self.model.dt)
        if name not in self.parameter_names:
            raise InputError(f"parameter {name!r}: the model {self.model.terms} has {', '.join(self.parameter_names)}")
        return self.samples[:, self.parameter_names.index(name)]

    def quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict name -> quantiles of each parameter (and ``noise_density`` when white)."""
        names = list(self.parameter_names) + (["noise_density"] if "white" in self.model.terms else [])
        return {n: np.quantile(self.draws(n), q) for n in names}

    def predictive_avar(self, m=None, *, n_draws=400, rng=None, term=None):
        """Posterior draws of the model Allan variance, ``(n_draws, n_tau)`` (one term if given)."""
        m = self.allan.m if m is None else np.asarray(m)
        rng = np.random.default_rng(rng)
        idx = rng.choice(self.samples.shape[0], size=min(n_draws, self.samples.shape[0]), replace=False)
        params = self.model.unpack(self.samples[idx])
        return self.model.avar(m, params) if term is None else self.model.term_avar(term, m, params)

    def summary(self, *, unit="u"):
        """JSON-ready summary (see the ``bayes-imu fit`` documentation)."""
        parameters = {}
        names = list(self.parameter_names) + (["noise_density"] if "white" in self.model.terms else [])
        for name in names:
            d = self.draws(name)
            parameters[name] = {
                "median": float(np.median(d)),
                "mean": float(np.mean(d)),
                "q05": float(np.quantile(d, 0.05)),
                "q95": float(np.quantile(d, 0.95)),
                "unit": PARAMETER_UNITS[name].format(u=unit),
            }
        return {
            "model": list(self.model.terms),
            "parameters": parameters,
            "diagnostics": {k: (bool(v) if k == "converged" else float(v)) for k, v in self.diagnostics.items()},
            "candidates": [
                {"model": list(c.terms), "log_evidence": c.log_evidence, "log_evidence_se": c.log_evidence_se,
                 "selected": i == self.selected}
                for i, c in enumerate(self.candidates)
            ],
            "likelihood": self.likelihood,
            "rate_hz": float(self.allan.rate_hz),
            "n_samples": int(self.allan.n_samples),
            "seed": self.seed if isinstance(self.seed, (int, type(None))) else str(self.seed),
            "bayes_imu_version": __version__,
        }


def fit(y, *, rate_hz, m="octave", **kwargs):
    """Fit rate samples ``y`` (1-D, units u) at ``rate_hz``; see :func:`fit_allan` for options."""
    return fit_allan(allan_variance(y, rate_hz=rate_hz, m=m), **kwargs)


def fit_allan(allan, *, terms="auto", likelihood="correlated", rng=None, n_walkers=32, max_steps=40000,
              threshold=1.0, n_evidence=4000, progress=False):
    """Select a noise model for ``allan`` and sample its posterior.

    Parameters
    ----------
    allan : AllanResult
        Overlapping Allan variance (octave grid recommended; at least 4 cluster sizes).
    terms : "auto" or sequence of str
        ``"auto"`` selects among all candidates by evidence; a sequence fixes the model.
    likelihood : {"correlated", "independent"}
    rng : None, int or numpy.random.Generator
        Seeds the evidence draws and the sampler; the same int gives the same numbers.
    n_walkers : int
    max_steps : int
        Cap on sampler steps; reaching it without convergence warns.
    threshold : float
        Selection threshold in nats (:func:`bayes_imu.selection.select`).
    n_evidence : int
        Importance draws per candidate.
    progress : bool
        Progress bars (candidates, sampler steps) on standard error; same numbers.

    Returns
    -------
    FitResult
    """
    if not isinstance(allan, AllanResult):
        raise InputError(f"allan: expected an AllanResult, got {type(allan).__name__}")
    if allan.m.size < 4:
        raise InputError(f"Allan variance has {allan.m.size} cluster sizes: need at least 4 to fit a model")
    if not np.all(allan.avar > 0):
        i = int(np.argmin(allan.avar))
        raise InputError(f"Allan variance is {allan.avar[i]!r} at tau = {allan.tau[i]:g} s: a noise model needs a "
                         "positive Allan variance at every cluster size (is the signal constant or periodic?)")
    seed = rng
    rng = np.random.default_rng(rng)
    dt = 1.0 / allan.rate_hz
    if terms == "auto":
        candidates = candidate_terms()
        pilot_model = NoiseModel(TERMS, dt)
    else:
        candidates = [tuple(terms)]
        pilot_model = NoiseModel(tuple(terms), dt)
    if likelihood not in LIKELIHOODS:
        raise InputError(f"likelihood={likelihood!r}: expected one of {', '.join(LIKELIHOODS)}")
    reference = _pilot(pilot_model, allan)
    shared = _posterior_factory(pilot_model, reference, allan, likelihood)
    scores, draws = [], []
    with progress_bar(total=len(candidates), desc="model selection", unit="model", enabled=progress) as bar:
        for cand in candidates:
            model = NoiseModel(cand, dt)
            post = shared(model)
            u_mode, phi_mode, _ = posterior_mode(post, _starts(model, allan, reference))
            log_z, se, ess, u, log_w = log_evidence(post, u_mode, n_draws=n_evidence, rng=rng)
            scores.append(CandidateScore(model.terms, log_z, se, ess, phi_mode))
            draws.append((u, log_w))
            bar.update()
    chosen = select(scores, threshold=threshold) if len(scores) > 1 else 0
    model = NoiseModel(scores[chosen].terms, dt)
    mode = dict(zip(model.parameter_names, np.exp(scores[chosen].mode)))
    if likelihood != "independent":  # covariance refined at the selected model's mode
        cov = _covariance(model, mode, allan)
        post = LogPosterior.from_covariance(model, allan, cov, model.avar(allan.m, mode), default_bounds(model, allan),
                                            kind=likelihood)
    else:
        cov = np.diag(2.0 * allan.avar**2 / allan.edf)
        post = LogPosterior.build(model, allan, kind="independent")
    u_mode, phi_mode, _ = posterior_mode(post, [scores[chosen].mode])
    start = _initial_walkers(post, draws[chosen], phi_mode, n_walkers, rng)
    samples, log_prob, diagnostics, idata = _sample(post, start, rng, max_steps, allan, progress)
    return FitResult(model, samples, log_prob, allan, tuple(scores), chosen, diagnostics, likelihood, cov, seed, idata)


def _posterior_factory(ref_model, reference, allan, likelihood):
    """``model -> LogPosterior`` sharing one AVAR covariance computed under ``ref_model`` at ``reference``."""
    if likelihood == "independent":
        return lambda model: LogPosterior.build(model, allan, kind="independent")
    cov = _covariance(ref_model, reference, allan)
    ref_avar = ref_model.avar(allan.m, reference)
    return lambda model: LogPosterior.from_covariance(model, allan, cov, ref_avar, default_bounds(model, allan),
                                                      kind=likelihood)


def _covariance(model, params, allan):
    from .avar_covariance import avar_covariance

    return avar_covariance(model, params, allan.m, allan.n_samples)


def _pilot(model, allan):
    """Mode under the independent-gamma likelihood: dict of physical parameters."""
    post = LogPosterior.build(model, allan, kind="independent")
    _, phi, _ = posterior_mode(post, _starts(model, allan, None))
    return dict(zip(model.parameter_names, np.exp(phi)))


def _starts(model, allan, reference):
    """Starting log-parameter vectors: heuristics from the curve, one per GM time constant guess."""
    tau, avar = allan.tau, allan.avar
    guess = {
        "noise_variance": avar[0] * allan.m[0],
        "quantization": np.sqrt(0.1 * avar[0] * tau[0] ** 2 / 3.0),
        "bias_instability": np.sqrt(0.5 * avar.min() * np.pi / (2.0 * np.log(2.0))),
        "bias_variance": avar.min(),
        "time_constant": tau[np.argmin(avar)],
        "rate_random_walk": np.sqrt(1.5 * avar[-1] / tau[-1]),
    }
    bounds = default_bounds(model, allan)
    out = []
    if "gauss_markov" not in model.terms:
        gm_taus = [None]
    elif reference is None:  # pilot: three time-constant guesses
        gm_taus = list(tau[[len(tau) // 4, len(tau) // 2, 3 * len(tau) // 4]])
    else:  # candidates: the full-model pilot plus one guess
        gm_taus = [tau[len(tau) // 2]]
    sources = [guess] + ([reference] if reference is not None else [])
    for src in sources:
        for t in gm_taus:
            values = {k: src.get(k, guess[k]) for k in model.parameter_names}
            if t is not None and src is guess:
                values["time_constant"] = t
                values["bias_variance"] = 2.0 * np.interp(1.9 * t, tau, avar)
            phi = np.log([max(values[k], 1e-300) for k in model.parameter_names])
            width = bounds[:, 1] - bounds[:, 0]
            out.append(np.clip(phi, bounds[:, 0] + 0.01 * width, bounds[:, 1] - 0.01 * width))
    return np.array(out)


def _initial_walkers(post, draws, phi_mode, n_walkers, rng):
    """Walkers from the importance draws, resampled by weight (distinct), else around the mode."""
    from .selection import _to_phi

    u, log_w = draws
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    k = min(n_walkers, int(np.count_nonzero(w)))
    idx = rng.choice(w.size, size=k, replace=False, p=w) if k == n_walkers else np.array([], int)
    start = _to_phi(u[idx], post.bounds) if idx.size else np.empty((0, phi_mode.size))
    if start.shape[0] < n_walkers or start.shape[1] != phi_mode.size:
        start = phi_mode + 1e-3 * rng.standard_normal((n_walkers, phi_mode.size))
    return np.clip(start, post.bounds[:, 0] + 1e-9, post.bounds[:, 1] - 1e-9)


def _sample(post, start, rng, max_steps, allan, progress=False):
    import emcee

    n_walkers, n_par = start.shape
    # differential-evolution proposals with some stretch moves: integrated autocorrelation
    # times ~11 steps instead of ~36 for the stretch move alone on the white + GM posterior
    # (scripts/bench_fit.py; 3x fewer likelihood calls for the same ESS)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]
    sampler = emcee.EnsembleSampler(n_walkers, n_par, post, vectorize=True, moves=moves)
    # emcee keeps a legacy RandomState: seed it from our Generator (no global state)
    sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
    chunk, state, tau_old = min(250, max_steps), start, np.inf
    converged = False
    with progress_bar(desc="sampling", unit="step", enabled=progress) as bar:
        while sampler.iteration < max_steps:
            state = sampler.run_mcmc(state, chunk, progress=False)
            tau_max = float(np.max(sampler.get_autocorr_time(tol=0)))
            bar.update(chunk)
            bar.set_postfix_str(f"autocorrelation {tau_max:.0f} steps")
            long_enough = sampler.iteration >= AUTOCORR_MULTIPLE * tau_max and abs(tau_max - tau_old) < 0.05 * tau_max
            tau_old = tau_max
            if long_enough:
                chain, lp, idata, diagnostics = _thinned(sampler, post, allan, tau_max, n_walkers, True)
                if diagnostics["converged"]:
                    converged = True
                    break
    if not converged:
        chain, lp, idata, diagnostics = _thinned(sampler, post, allan, tau_max, n_walkers, False)
        warnings.warn(
            f"sampler not converged after {sampler.iteration} steps (autocorrelation time {tau_max:.0f} steps, "
            f"R-hat {diagnostics['rhat_max']:.3f}, bulk ESS {diagnostics['ess_bulk_min']:.0f}); "
            "raise max_steps or inspect the chain",
            ConvergenceWarning,
            stacklevel=3,
        )
    samples = np.exp(chain.reshape(-1, n_par))
    return samples, lp.reshape(-1), diagnostics, idata


def _arviz():
    import contextlib
    import io

    # ArviZ 0.2x announces its refactor on import (a FutureWarning and lines on stdout)
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore", FutureWarning)
        import arviz

    return arviz


def _thinned(sampler, post, allan, tau_max, n_walkers, long_enough):
    """Drop 3 autocorrelation times of burn-in, thin by half of one; diagnostics on the rest."""
    burn = int(np.ceil(3 * tau_max))
    thin = max(1, int(tau_max / 2))
    chain = sampler.get_chain(discard=burn, thin=thin)  # (draws, walkers, par)
    lp = sampler.get_log_prob(discard=burn, thin=thin)
    with warnings.catch_warnings():  # "more chains than draws" on short runs: reported as ConvergenceWarning
        warnings.simplefilter("ignore", UserWarning)
        idata = _inference_data(post, chain, lp, allan)
        diagnostics = _diagnostics(idata, tau_max, sampler.iteration, n_walkers, long_enough)
    return chain, lp, idata, diagnostics


def _inference_data(post, chain, lp, allan):
    az = _arviz()

    names = post.model.parameter_names
    posterior = {f"log_{n}": chain[:, :, i].T for i, n in enumerate(names)}
    posterior.update({n: np.exp(chain[:, :, i].T) for i, n in enumerate(names)})
    loglik = post.log_likelihood(chain).T
    return az.from_dict(
        posterior=posterior,
        sample_stats={"lp": lp.T},
        log_likelihood={"allan": loglik},
        observed_data={"avar": allan.avar},
        coords={"tau": allan.tau},
        dims={"avar": ["tau"]},
        attrs={"terms": " ".join(post.model.terms), "likelihood": post.kind, "bayes_imu_version": __version__},
    )


def _diagnostics(idata, tau_max, n_steps, n_walkers, converged):
    az = _arviz()

    names = [v for v in idata.posterior.data_vars if v.startswith("log_")]
    rhat = az.rhat(idata, var_names=names)
    bulk = az.ess(idata, var_names=names, method="bulk")
    tail = az.ess(idata, var_names=names, method="tail")
    out = {
        "rhat_max": float(max(rhat[v].values for v in names)),
        "ess_bulk_min": float(min(bulk[v].values for v in names)),
        "ess_tail_min": float(min(tail[v].values for v in names)),
        "autocorr_time": float(tau_max),
        "n_steps": int(n_steps),
        "n_walkers": int(n_walkers),
    }
    out["converged"] = bool(converged and out["rhat_max"] < RHAT_MAX and out["ess_bulk_min"] >= ESS_MIN)
    return out



