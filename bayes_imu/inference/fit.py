"""Bayesian fit of a noise model to an Allan variance: model selection, then emcee.

Pipeline of :func:`fit_allan`:

1. *Pilot*: posterior mode of the full model (all terms) under the independent-gamma
   likelihood (a weighted least-squares fit in disguise, fast and robust).
2. *Covariance*: the exact covariance of the AVAR estimates under that pilot model
   (:mod:`bayes_imu.noise.avar_covariance`), shared by every candidate so that their evidences
   come from one likelihood function.
3. *Selection*: every candidate (the base terms and a subset of the optional ones, then the
   stepwise extensions: each term's :attr:`~bayes_imu.noise.Term.selection`) gets its mode and
   its evidence (:mod:`bayes_imu.inference.selection`).
4. *Refinement*: the covariance is recomputed at the selected model's mode.
5. *Sampling*: emcee (``vectorize=True``, differential-evolution and stretch moves, and an
   independence move where its estimated acceptance is high enough:
   :mod:`bayes_imu.inference.sampling`; below it the same moves on a tempered ensemble,
   :mod:`bayes_imu.inference.tempering`, stopped on the walkers' mean's autocorrelation time, with
   a jump move between the posterior's regions fitted to a pilot,
   :mod:`bayes_imu.inference.mixture_proposal`) in log-parameters, in chunks of 250 steps (a
   tenth of the chain past 10 000 steps, and none before the chain could stop:
   :func:`~bayes_imu.inference.sampling.steps_to_next_check`) until the chain is longer than 50
   integrated autocorrelation times and that estimate has settled to 5%; then
   rank-normalised R-hat and bulk/tail ESS (:mod:`bayes_imu.inference.diagnostics`) and the ESS of
   the walkers' mean (:func:`ensemble_mean_ess`). Non-convergence
   warns (:class:`ConvergenceWarning`) and sets ``diagnostics["converged"] = False``.
"""

import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._progress import progress_bar
from .._version import __version__
from ..allan.estimator import AllanResult, allan_variance
from ..errors import ConvergenceWarning, InputError
from .likelihood import LIKELIHOODS, LogPosterior, default_bounds
from ..noise.avar_forms import BASE_TERMS, PARAMETER_UNITS, NoiseModel
from .diagnostics import rhat, summary as convergence_summary
from .sampling import (
    AUTOCORR_MULTIPLE,
    INDEPENDENCE_INFLATE,
    INDEPENDENCE_MIN_ACCEPT,
    StudentProposal,
    independence_acceptance,
    autocorr_time,
    burn_and_thin,
    ensemble_mean_autocorr_time,
    ensemble_sampler,
    long_enough,
    one_blas_thread,
    steps_to_next_check,
)
from .stationarity import Stationarity, stationarity_check
from .mixture_proposal import MIXTURE_FIT_DRAWS, fit_student_mixture
from .tempering import TemperedEnsemble
from .selection import (
    Adequacy,
    CandidateScore,
    EvidenceResult,
    adequacy,
    candidate_terms,
    can_skip,
    extensions,
    finite_negative_hessian,
    laplace_log_evidence,
    log_evidence,
    model_probabilities,
    posterior_mode,
    reductions,
    select,
    within_margin,
    to_phi,
)

__all__ = [
    "FitResult",
    "MixtureComponent",
    "SamplerChains",
    "fit",
    "fit_allan",
    "score_models",
    "DISCREPANCY_MODES",
]

DISCREPANCY_MODES = ("auto", "never", "always")
RHAT_MAX = 1.01
ESS_MIN = 400
#: draws of the independence move's acceptance estimate (one vectorised density call)
INDEPENDENCE_PILOT = 1000
#: the sampler is tempered (:class:`~bayes_imu.inference.tempering.TemperedEnsemble`) where the
#: independence move's expected acceptance is below this and the move is not used (0: never;
#: ``scripts/study_tempering.py`` compares the two)
TEMPER_BELOW = INDEPENDENCE_MIN_ACCEPT
#: an untempered ensemble whose walkers' autocorrelation time exceeds this (steps) at a convergence
#: check, a chain that would run more than AUTOCORR_MULTIPLE times it (2 000 steps), goes on
#: tempered from its walkers' last state (0 or less: never). On the real ADIS16405 gyro x logs the
#: posteriors near a t read 5-20 steps at every check and imu4's, whose second region the
#: independence move's estimate missed, 47 at 1 000 steps and 190-280 steps at the end of chains
#: of 11 000-16 500 steps (seeds 0 and 1); tempered from 1 000 steps, those ended 4 000 and 3 250
#: tempered steps later (docs/speed_under_load.md, fourteenth session)
TEMPER_AFTER_TAU = 40.0
#: the least steps left of the budget for a switch to the tempered ensemble (with fewer, the chain
#: goes on untempered: a tempered chain of 40-100 steps' autocorrelation time needs 2 000 or more)
TEMPERED_MIN_STEPS = 2000
#: a tempered chain is given the jump move (:meth:`~bayes_imu.inference.tempering.TemperedEnsemble.
#: add_jump`) after this many steps, its proposal fitted to the cold draws of their second half,
#: which are then discarded (0 or less: never; nor where the budget left is less than this plus
#: :data:`JUMP_MIN_KEPT` and one more check, or the proposal cannot be fitted). On the hard real
#: accelerometer posteriors (imu4 and imu5 accel z, imu3 accel x; the walkers' mean's
#: autocorrelation time up to 1 780 steps under the tempered ensemble alone), 24 of 24 fits at
#: seeds 0-7 converged in 9 250-20 750 steps in all, against 18 of 24 without the move
#: (scripts/study_tempering.py; docs/speed_under_load.md, sixteenth session)
JUMP_PILOT = 1000
#: the least steps a tempered chain runs after the jump move is added before it may stop. The
#: autocorrelation time of a chain that has not yet visited a region of small mass does not see
#: it: without this floor, fits stopped at 1 500-2 250 steps with tail quantiles 0.7-1.4 posterior
#: standard deviations off (ad hoc runs, imu4 accel z). In the study's fixed-length chains with the
#: move from the fits' own starts (seeds 0-7), the largest quantile error was 0.44-0.99 (imu4 accel
#: z) and 0.35-1.83 (imu3 accel x) after 1 500 steps, 0.09-1.16 and 0.09-0.70 (medians 0.28 and
#: 0.22) after 8 000 (scripts/study_tempering.py --lengths; docs/speed_under_load.md)
JUMP_MIN_KEPT = 8000
#: times the jump move's proposal is refitted: at a check at or past JUMP_MIN_KEPT steps with it
#: where the chain is under half of AUTOCORR_MULTIPLE autocorrelation times long, to
#: JUMP_REFIT_DRAWS of every step kept so far, which are then discarded (where the budget left
#: allows JUMP_MIN_KEPT and one more check)
JUMP_REFITS = 1
#: draws the refit's mixture is fitted to (a random subset of the kept chain; the pilot's fit uses
#: MIXTURE_FIT_DRAWS, 4 000). On the real imu5 accelerometer z log at seed 2, whose chain got stuck
#: where the random walk is switched off and a slow second bias replaces it (0.9% of the posterior),
#: a refit on 4 000 draws gave no component there and the chain stopped unconverged at the cap; on
#: 8 000, converged 8 250 steps later (docs/speed_under_load.md, sixteenth session)
JUMP_REFIT_DRAWS = 8000
#: share of the tempered steps that are the jump move, once added
JUMP_SHARE = 0.3


@dataclass(frozen=True)
class SamplerChains:
    """The kept draws of every walker, in emcee's layout, for ArviZ.

    Attributes
    ----------
    chain : ndarray, shape (n_draws, n_walkers, n_par)
        Log-parameters after burn-in and thinning.
    log_prob : ndarray, shape (n_draws, n_walkers)
    posterior : LogPosterior
        The density sampled; the draws' log likelihoods come from it when ArviZ needs them.
    """

    chain: np.ndarray
    log_prob: np.ndarray
    posterior: LogPosterior = field(repr=False, compare=False)

    @property
    def log_likelihood(self):
        """``(n_draws, n_walkers)`` log likelihood of each kept draw."""
        return self.posterior.log_likelihood(self.chain)

    def to_inference_data(self, names, allan, attrs):
        """``arviz.InferenceData``: walkers as chains; ``log_<name>`` and ``<name>`` for each
        parameter."""
        az = import_arviz()
        posterior = {f"log_{n}": self.chain[:, :, i].T for i, n in enumerate(names)}
        posterior.update({n: np.exp(self.chain[:, :, i].T) for i, n in enumerate(names)})
        with warnings.catch_warnings():  # "more chains than draws" on short runs
            warnings.simplefilter("ignore", UserWarning)
            return az.from_dict(
                posterior=posterior,
                sample_stats={"lp": self.log_prob.T},
                log_likelihood={"allan": self.log_likelihood.T},
                observed_data={"avar": allan.avar},
                coords={"tau": allan.tau},
                dims={"avar": ["tau"]},
                attrs=attrs,
            )


@dataclass(frozen=True)
class MixtureComponent:
    """One candidate's share of the model-averaged posterior.

    Attributes
    ----------
    terms : tuple of str
    probability : float
        Its posterior probability (renormalised over the components kept).
    samples : ndarray, shape (n, n_par)
        Draws of its parameters (physical units, its own ``parameter_names`` order).
    """

    terms: tuple
    probability: float
    samples: np.ndarray


@dataclass(frozen=True)
class FitResult:
    """Posterior of a noise model fitted to an Allan variance.

    Attributes
    ----------
    model : NoiseModel
        Selected model (term names in :data:`bayes_imu.noise.TERMS`): the answer to "which
        terms does this sensor need".
    samples : ndarray, shape (n_draws, n_par)
        Posterior draws of the parameters (physical units, ``parameter_names`` order: the
        model's, then ``model_discrepancy`` when the fit was widened), after burn-in and thinning.
    log_prob : ndarray, shape (n_draws,)
    allan : AllanResult
        The data.
    candidates : tuple of CandidateScore
        Evidence of every candidate model scored.
    selected : int
        Index of the selected candidate.
    diagnostics : dict
        ``rhat_max``, ``ess_bulk_min``, ``ess_tail_min`` (walkers as chains), ``ess_mean_min``
        (:func:`ensemble_mean_ess`), ``rhat_mean_max`` (split R-hat of the walkers' mean, one
        chain), ``autocorr_time`` (steps), ``n_steps``, ``n_walkers``, ``converged``,
        ``tempered`` and, for a tempered fit, ``ladder``, ``swap_acceptance`` and
        ``steps_before_tempering`` (untempered steps discarded where a slow chain went on tempered,
        else 0; ``n_steps`` counts the kept chain's), ``jump_pilot_steps`` (tempered steps
        discarded where the jump move was added, else 0) and, with the jump move,
        ``jump_components`` and ``jump_acceptance`` (its cold ensemble's).
    likelihood : str
    covariance : ndarray, shape (n_tau, n_tau)
        AVAR covariance the likelihood used.
    seed : object
        The ``rng`` argument as given (an int for reproducible runs).
    chains : SamplerChains or None
        The walkers' kept draws (``None`` for a fit read back from ``fit.npz``).
    adequacy : Adequacy
        Goodness of fit of the selected model (without the discrepancy term).
    probabilities : ndarray, shape (n_candidates,)
        Posterior probability of each candidate (equal prior odds over those scored).
    mixture : tuple of MixtureComponent
        The model-averaged posterior that drift numbers use by default.
    widened : bool
        The model-discrepancy term was added (the best candidate was inadequate).
    stationarity : Stationarity or None
        Between-segment check of the log (:mod:`bayes_imu.inference.stationarity`); drift bands of a
        log flagged non-stationary include the spread between its parts.
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
    chains: SamplerChains = field(default=None, repr=False, compare=False)
    adequacy: Adequacy = None
    probabilities: np.ndarray = None
    mixture: tuple = ()
    widened: bool = False
    stationarity: Stationarity = None

    @cached_property
    def inference_data(self):
        """``arviz.InferenceData`` of the chains (walkers as chains; built on first use, which
        imports ArviZ), ``None`` for a fit read back from ``fit.npz``."""
        if self.chains is None:
            return None
        attrs = {
            "terms": " ".join(self.model.terms),
            "likelihood": self.likelihood,
            "bayes_imu_version": __version__,
        }
        return self.chains.to_inference_data(self.parameter_names, self.allan, attrs)

    @property
    def sensor(self):
        """Sensor kind of the fitted samples (``"gyro"``, ``"accel"``), carried from :attr:`allan`;
        ``None`` when not known."""
        return getattr(self.allan, "sensor", None)

    @property
    def parameter_names(self):
        return self.model.parameter_names + (("model_discrepancy",) if self.widened else ())

    @property
    def record_s(self):
        """Duration of the fitted log (s)."""
        return self.allan.duration_s if self.allan is not None else float("nan")

    def draws(self, name):
        """Posterior draws of one parameter, or of a derived one: ``noise_density`` (white plus
        the white-noise equivalents of the filtered-white and high-frequency correlated terms, the
        value to compare with a datasheet ARW / VRW), ``white_noise_density`` (the white term
        alone)."""
        if name == "noise_density":
            return np.sqrt(self.model.short_term_variance(self.samples) * self.model.dt)
        if name == "white_noise_density":
            return np.sqrt(self.draws("noise_variance") * self.model.dt)
        if name not in self.parameter_names:
            raise InputError(
                f"parameter {name!r}: the model {self.model.terms} has "
                f"{', '.join(self.parameter_names)}"
            )
        return self.samples[:, self.parameter_names.index(name)]

    def _derived_names(self):
        names = list(self.parameter_names)
        short = [t.name for t in self.model.components if t.kalibr == "noise_density"]
        if short:
            names.append("noise_density")
        if "white" in short and len(short) > 1:
            names.append("white_noise_density")
        return names

    def term_probabilities(self):
        """Dict term -> posterior probability that the sensor has it: the summed probability of the
        model-averaged components (:attr:`mixture`, what the drift bands average over) whose model
        has the term, for every term of any component, in the canonical term order.

        It can disagree with :attr:`model`, the selection rule's answer (the simplest model within
        the margin of the best evidence): a term the selected model leaves out may carry most of the
        probability when several richer models each come close to the best (a real ADIS16405 gyro:
        rate random walk at 0.84, the selected model, without it, at 0.16).
        """
        from ..noise.avar_forms import TERMS

        present = {t for c in self.mixture for t in c.terms}
        return {
            t: float(sum(c.probability for c in self.mixture if t in c.terms))
            for t in TERMS
            if t in present
        }

    def quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict name -> quantiles of each parameter (and the derived densities)."""
        return {n: np.quantile(self.draws(n), q) for n in self._derived_names()}

    @cached_property
    def part_reads(self):
        """What the parts of the record read of each term's scale
        (:class:`~bayes_imu.inference.repeatability.PartReads`, at the selected model's posterior
        median), ``None`` for a record without parts."""
        from .repeatability import part_reads

        segments = getattr(self.allan, "segments", None)
        if self.stationarity is None or segments is None:
            return None
        n_model = len(self.model.parameter_names)
        params = dict(zip(self.model.parameter_names, np.median(self.samples[:, :n_model], axis=0)))
        return part_reads(self.model, params, self.stationarity, segments.n_samples,
                          self.allan.rate_hz)

    def repeatable_draws(self, name):
        """Draws of ``name`` widened by the repeatability between parts of the record
        (:mod:`bayes_imu.inference.repeatability`): what ``summary.json`` ``parameters`` and
        ``datasheet`` print. Each name has its own deterministic score stream."""
        from .repeatability import repeatability_draws

        names = self._derived_names()
        stream = names.index(name) if name in names else len(names)
        return repeatability_draws(name, self.draws(name), self.stationarity, stream,
                                   reads=self.part_reads, model=self.model)

    def repeatability_quantiles(self, q=(0.05, 0.5, 0.95)):
        """Dict name -> quantiles of each parameter widened by the repeatability between parts
        (:meth:`repeatable_draws`)."""
        return {n: np.quantile(self.repeatable_draws(n), q) for n in self._derived_names()}

    def _repeatability_note(self, parameters, this_record):
        """What ``parameters`` includes beyond ``parameters_this_record`` (summary.json)."""
        reads = self.part_reads
        ends = ("q05", "q95")
        widened = [n for n in parameters
                   if any(parameters[n][e] != this_record[n][e] for e in ends)]
        return {"n_parts": None if reads is None else reads.n_parts, "widened": widened,
                "what": "90% intervals of parameters, datasheet and allan_datasheet include the "
                        "repeatability between the record's parts (Student-t over the parts' "
                        "reads, or the posterior's where wider); parameters_this_record: this "
                        "record alone"}

    def predictive_avar(self, m=None, *, n_draws=400, rng=None, term=None):
        """Posterior draws of the model Allan variance, ``(n_draws, n_tau)`` (one term if given)."""
        m = self.allan.m if m is None else np.asarray(m)
        rng = np.random.default_rng(rng)
        idx = rng.choice(
            self.samples.shape[0], size=min(n_draws, self.samples.shape[0]), replace=False
        )
        params = self.model.unpack(self.samples[idx])
        return self.model.avar(m, params) if term is None else self.model.term_avar(term, m, params)

    def summary(self, *, unit="u"):
        """JSON-ready summary (see the ``bayes-imu fit`` documentation)."""
        parameters, this_record = {}, {}
        for name in self._derived_names():
            pairs = ((parameters, self.repeatable_draws(name)), (this_record, self.draws(name)))
            for block, d in pairs:
                block[name] = {
                    "median": float(np.median(d)),
                    "mean": float(np.mean(d)),
                    "q05": float(np.quantile(d, 0.05)),
                    "q95": float(np.quantile(d, 0.95)),
                    "unit": PARAMETER_UNITS.get(name, "1").format(u=unit),
                }
        probabilities = (
            self.probabilities
            if self.probabilities is not None
            else np.full(len(self.candidates), np.nan)
        )
        adequacy = self.adequacy.to_dict() if self.adequacy is not None else None
        if adequacy is not None:
            adequacy["widened"] = bool(self.widened)
            adequacy["stationarity"] = (
                self.stationarity.to_dict() if self.stationarity is not None else None
            )
        from ..noise.datasheet import datasheet
        from ..noise.quantities import si_sensor
        from .allan_readout import allan_readout

        kind = si_sensor(self.sensor, unit)
        return {
            "model": list(self.model.terms),
            "parameters": parameters,
            "parameters_this_record": this_record,
            "repeatability": self._repeatability_note(parameters, this_record),
            "datasheet": datasheet(_Repeatable(self), kind) if kind is not None else None,
            "allan_datasheet": allan_readout(self, kind, unit=unit),
            "adequacy": adequacy,
            "diagnostics": {
                k: (
                    bool(v)
                    if k in ("converged", "tempered")
                    else int(v)
                    if k in ("n_steps", "n_walkers", "steps_before_tempering", "jump_pilot_steps",
                             "jump_components")
                    else [float(x) for x in v]
                    if k in ("ladder", "swap_acceptance")
                    else float(v)
                )
                for k, v in self.diagnostics.items()
            },
            "candidates": [
                {
                    "model": list(c.terms),
                    "log_evidence": c.log_evidence,
                    "log_evidence_se": c.log_evidence_se,
                    "evidence_method": c.method,
                    "probability": float(p),
                    "selected": i == self.selected,
                }
                for i, (c, p) in enumerate(zip(self.candidates, probabilities))
            ],
            "model_averaging": [
                {"model": list(c.terms), "probability": c.probability} for c in self.mixture
            ],
            "term_probability": self.term_probabilities(),
            "likelihood": self.likelihood,
            "rate_hz": float(self.allan.rate_hz),
            "n_samples": int(self.allan.n_samples),
            "seed": self.seed if isinstance(self.seed, (int, type(None))) else str(self.seed),
            "bayes_imu_version": __version__,
        }


@dataclass(frozen=True)
class _Repeatable:
    """A fit seen through its repeatable draws (what ``summary.json`` ``datasheet`` reads)."""

    fit: FitResult

    @property
    def parameter_names(self):
        return self.fit.parameter_names

    def draws(self, name):
        return self.fit.repeatable_draws(name)


def fit(
    y,
    *,
    rate_hz,
    m="octave",
    terms="auto",
    likelihood="correlated",
    rng=None,
    n_walkers=32,
    max_steps=40000,
    threshold=1.0,
    n_evidence=4000,
    discrepancy="auto",
    progress=False,
    pool=None,
):
    """Fit rate samples ``y`` (1-D, units u) at ``rate_hz`` [Hz]; options as :func:`fit_allan`."""
    return fit_allan(
        allan_variance(y, rate_hz=rate_hz, m=m),
        terms=terms,
        likelihood=likelihood,
        rng=rng,
        n_walkers=n_walkers,
        max_steps=max_steps,
        threshold=threshold,
        n_evidence=n_evidence,
        discrepancy=discrepancy,
        progress=progress,
        pool=pool,
    )


@dataclass(frozen=True)
class _Scored:
    """One candidate's score, its likelihood and its importance draws."""

    score: CandidateScore
    post: LogPosterior
    evidence: EvidenceResult


def fit_allan(
    allan,
    *,
    terms="auto",
    likelihood="correlated",
    rng=None,
    n_walkers=32,
    max_steps=40000,
    threshold=1.0,
    n_evidence=4000,
    discrepancy="auto",
    progress=False,
    pool=None,
):
    """Select a noise model for ``allan``, sample its posterior, check its adequacy.

    Parameters
    ----------
    allan : AllanResult
        Overlapping Allan variance (octave grid recommended; at least 4 cluster sizes).
    terms : "auto" or sequence of str
        ``"auto"``: every ``white + subset`` of the IEEE terms, then the stepwise search over
        the extension terms (:mod:`bayes_imu.inference.selection`); a sequence fixes the model.
    likelihood : {"correlated", "copula", "independent"}
    rng : None, int or numpy.random.Generator
        Seeds the evidence draws and the sampler; the same int gives the same numbers.
    n_walkers : int
    max_steps : int
        Cap on sampler steps; reaching it without convergence warns.
    threshold : float
        Selection threshold in nats (:func:`bayes_imu.inference.selection.select`).
    n_evidence : int
        Importance draws per candidate.
    discrepancy : {"auto", "never", "always"}
        The model-discrepancy term (a fitted relative error on the Allan variance): with
        ``"auto"`` it is added, to every candidate, when the best candidate fails the
        adequacy check, so that intervals widen with the misfit instead of shrinking
        (``"correlated"`` likelihood only).
    progress : bool
        Progress bars (candidates, sampler steps) on standard error; same numbers.
    pool : executor or None
        Somewhere to compute ahead, on another core: an object whose ``submit(fn, *args)`` returns a
        future (``done()``, ``exception()``, ``result()``), as a
        :class:`concurrent.futures.Executor` does, or
        :meth:`bayes_imu.report.worker.OutputWriter.pool`. With ``discrepancy="auto"`` and the
        correlated likelihood, each candidate's mode with the discrepancy term (and its Laplace
        estimate) is sought there as soon as the candidate is scored without it, in case the best
        candidate fails the adequacy check and every candidate is scored again with the term; a mode
        not found there by then is sought here. The numbers are the same as without a pool, bit for
        bit (the same function on the same inputs; tested). On ADIS16405 imu1 and imu5 (an ad-hoc
        count, two runs each) the command's output process found 26 of 29 and 20 of 26 widened modes
        this way.

    Returns
    -------
    FitResult
    """
    if not isinstance(allan, AllanResult):
        raise InputError(f"allan: expected an AllanResult, got {type(allan).__name__}")
    if allan.m.size < 4:
        raise InputError(
            f"Allan variance has {allan.m.size} cluster sizes: need at least 4 to fit a model"
        )
    if not np.all(allan.avar > 0):
        i = int(np.argmin(allan.avar))
        raise InputError(
            f"Allan variance is {allan.avar[i]!r} at tau = {allan.tau[i]:g} s: a noise model needs "
            "a positive Allan variance at every cluster size (is the signal constant or periodic?)"
        )
    if likelihood not in LIKELIHOODS:
        raise InputError(f"likelihood={likelihood!r}: expected one of {', '.join(LIKELIHOODS)}")
    if discrepancy not in DISCREPANCY_MODES:
        raise InputError(
            f"discrepancy={discrepancy!r}: expected one of {', '.join(DISCREPANCY_MODES)}"
        )
    if discrepancy == "always" and likelihood != "correlated":
        raise InputError(f"discrepancy='always' needs likelihood='correlated', got {likelihood!r}")
    with one_blas_thread():
        return _fit(
            allan,
            terms,
            likelihood,
            rng,
            n_walkers,
            max_steps,
            threshold,
            n_evidence,
            discrepancy,
            progress,
            pool,
        )


def _fit(
    allan,
    terms,
    likelihood,
    rng,
    n_walkers,
    max_steps,
    threshold,
    n_evidence,
    discrepancy,
    progress,
    pool,
):
    """:func:`fit_allan` after its checks."""
    seed = rng
    rng = np.random.default_rng(rng)
    dt = 1.0 / allan.rate_hz
    stepwise = terms == "auto"
    if stepwise:
        candidates = candidate_terms()
        pilot_model = NoiseModel(BASE_TERMS, dt)
    else:
        candidates = [tuple(terms)]
        pilot_model = NoiseModel(tuple(terms), dt)
    reference, shared = _shared_posterior(pilot_model, allan, likelihood)
    widen = discrepancy == "always"
    make = (lambda model: shared(model).with_discrepancy()) if widen else shared
    ahead = (_WidenedAhead(pool, allan, reference) if pool is not None and discrepancy == "auto"
             and likelihood == "correlated" else None)
    with progress_bar(desc="model selection", unit="model", enabled=progress) as bar:
        scored = _search(
            make,
            allan,
            reference,
            candidates,
            stepwise,
            threshold,
            n_evidence,
            rng,
            bar,
            None if ahead is None else ahead.submit,
        )
        chosen = select([c.score for c in scored], threshold=threshold) if len(scored) > 1 else 0
        if discrepancy == "auto" and likelihood == "correlated":
            best = scored[chosen]
            if not adequacy(best.post, best.score.mode, allan.tau).adequate:
                widen = True
                scored = _rescore_widened(scored, allan, reference, n_evidence, rng, ahead)
                bar.update(len(scored))
                chosen = (
                    select([c.score for c in scored], threshold=threshold) if len(scored) > 1 else 0
                )
    scores = tuple(c.score for c in scored)
    model = NoiseModel(scores[chosen].terms, dt)
    n_model = len(model.parameter_names)
    mode = dict(zip(model.parameter_names, np.exp(scores[chosen].mode[:n_model])))
    if likelihood != "independent":  # covariance refined at the selected model's mode
        cov = _covariance(model, mode, allan)
        post = LogPosterior.from_covariance(
            model,
            allan,
            cov,
            model.avar(allan.m, mode),
            default_bounds(model, allan),
            kind=likelihood,
        )
    else:
        cov = np.diag(2.0 * allan.avar**2 / allan.edf)
        post = LogPosterior.build(model, allan, kind="independent")
    sampled = post.with_discrepancy() if widen else post
    phi_mode = posterior_mode(sampled, [scores[chosen].mode]).phi
    start = _initial_walkers(sampled, scored[chosen].evidence, phi_mode, n_walkers, rng)
    independence = _independence(sampled, phi_mode, rng)
    log_samples, log_prob, diagnostics, chains = _sample(
        sampled, start, rng, max_steps, progress, independence
    )
    best_draw = log_samples[int(np.argmax(log_prob))]
    check = adequacy(post, best_draw, allan.tau, log_samples)
    probabilities = model_probabilities(scores)
    mixture = _mixture(scored, chosen, probabilities, np.exp(log_samples), rng)
    steady = stationarity_check(
        allan, model, dict(zip(model.parameter_names, np.exp(best_draw[:n_model])))
    )
    return FitResult(
        model,
        np.exp(log_samples),
        log_prob,
        allan,
        scores,
        chosen,
        diagnostics,
        likelihood,
        cov,
        seed,
        chains,
        check,
        probabilities,
        mixture,
        widen,
        steady,
    )


def score_models(
    allan, models, *, widened=False, likelihood="correlated", n_evidence=4000, rng=None
):
    """Evidence of each model in ``models`` for ``allan``, as :func:`fit_allan` scores its
    candidates.

    The covariance comes from the same pilot (the full base model), so the evidences are
    comparable with a fit's own ``candidates`` and across calls on one Allan result.

    Parameters
    ----------
    allan : AllanResult
    models : sequence of sequences of str
        Term names of each model.
    widened : bool
        Add the model-discrepancy term to every model (as a widened fit does).
    likelihood : {"correlated", "copula", "independent"}
    n_evidence : int
    rng : None, int or numpy.random.Generator

    Returns
    -------
    tuple of CandidateScore
        In the order of ``models`` (terms in canonical order).
    """
    if likelihood not in LIKELIHOODS:
        raise InputError(f"likelihood={likelihood!r}: expected one of {', '.join(LIKELIHOODS)}")
    rng = np.random.default_rng(rng)
    dt = 1.0 / allan.rate_hz
    reference, shared = _shared_posterior(NoiseModel(BASE_TERMS, dt), allan, likelihood)
    out = []
    for terms in models:
        model = NoiseModel(tuple(terms), dt)
        post = shared(model).with_discrepancy() if widened else shared(model)
        out.append(_score(model, post, allan, reference, n_evidence, rng).score)
    return tuple(out)


def _score(model, post, allan, reference, n_evidence, rng):
    """Mode and importance-sampled evidence of one candidate."""
    mode = posterior_mode(post, _candidate_starts(model, post, allan, reference))
    ev = log_evidence(post, mode.u, n_draws=n_evidence, rng=rng)
    return _Scored(CandidateScore(model.terms, ev.log_z, ev.se, ev.ess, mode.phi), post, ev)


def _candidate_starts(model, post, allan, reference):
    starts = _starts(model, allan, reference)
    if post.discrepancy:
        starts = np.column_stack([starts, np.full(len(starts), np.log(0.1))])
    return starts


def _score_batch(jobs, allan, reference, n_evidence, rng, best, ready=None):
    """Score candidates ``jobs`` = ``[(model, post, starts or None)]`` with the Laplace screen of
    :mod:`bayes_imu.inference.selection`: every mode and Laplace estimate first, then importance
    sampling in decreasing order of the Laplace estimate, except for candidates that
    :func:`~bayes_imu.inference.selection.can_skip` rules out against ``best`` (the largest
    importance-sampled log evidence so far). ``ready(i)``: job ``i``'s ``(mode, Laplace log Z, its
    covariance)`` where computed ahead (:class:`_WidenedAhead`), else ``None``; the jobs not ready
    are done here, the last first (the ones least likely to be ready), asking again before each.
    Returns the ``_Scored`` in the order of ``jobs`` and the new ``best``."""
    found = [None] * len(jobs)
    for i in reversed(range(len(jobs))):
        found[i] = None if ready is None else ready(i)
        if found[i] is None:
            model, post, starts = jobs[i]
            found[i] = _mode_and_laplace(post, _candidate_starts(model, post, allan, reference)
                                         if starts is None else starts)
    found = [(model, post) + f for (model, post, _), f in zip(jobs, found)]
    out = [None] * len(found)
    for i in sorted(range(len(found)), key=lambda i: -found[i][3]):
        model, post, mode, log_z, cov = found[i]
        if can_skip(post, mode.u, log_z, cov, best, rng):
            out[i] = _Scored(
                CandidateScore(model.terms, log_z, 0.0, 0.0, mode.phi, "laplace"), post, None
            )
            continue
        ev = log_evidence(post, mode.u, n_draws=n_evidence, rng=rng, hessian_cov=cov)
        out[i] = _Scored(CandidateScore(model.terms, ev.log_z, ev.se, ev.ess, mode.phi), post, ev)
        best = max(best, ev.log_z)
    return out, best


def _mode_and_laplace(post, starts):
    """``(mode, Laplace log Z, its covariance)`` of ``post`` from ``starts``: a candidate's first
    step in
    :func:`_score_batch`, here or in a pool (:func:`_mode_ahead`)."""
    mode = posterior_mode(post, starts)
    return (mode,) + laplace_log_evidence(post, mode.u)


def _mode_ahead(post, starts):
    """:func:`_mode_and_laplace` on one BLAS thread, as a fit runs: a pool's job."""
    with one_blas_thread():
        return _mode_and_laplace(post, starts)


class _WidenedAhead:
    """Each scored candidate's widened mode and Laplace estimate, sought in ``pool`` while the
    search goes on (:func:`fit_allan`'s ``pool``): one pool job per candidate, sent as its batch is
    scored (:meth:`submit`), taken back by :func:`_rescore_widened` where it is done by then
    (:meth:`take`)."""

    def __init__(self, pool, allan, reference):
        self.pool, self.allan, self.reference, self.jobs = pool, allan, reference, {}

    def submit(self, batch):
        """Send the widened jobs of ``batch`` (``(model, _Scored)`` pairs just scored) to the
        pool."""
        for model, c in batch:
            post, starts = _widened_job(model, c, self.allan, self.reference)
            self.jobs[model.terms] = (post, starts, self.pool.submit(_mode_ahead, post, starts))

    def take(self, terms):
        """``(post, starts, ready)`` of candidate ``terms``: ``ready()`` is its computed tuple where
        its job is done without an error, else ``None``; ``None`` for a candidate never sent."""
        if terms not in self.jobs:
            return None
        post, starts, future = self.jobs[terms]
        return (
            post,
            starts,
            lambda: future.result() if future.done() and future.exception() is None else None,
        )


def _widened_job(model, scored, allan, reference):
    """``(post, starts)`` of a candidate scored without the discrepancy term, scored again with it:
    its own mode (discrepancy 0.1) first, then the usual starts."""
    post = scored.post.with_discrepancy()
    own = np.append(scored.score.mode, np.log(0.1))[None, :]
    return post, np.vstack([own, _candidate_starts(model, post, allan, reference)])


def _search(
    make_post,
    allan,
    reference,
    candidates,
    stepwise,
    threshold,
    n_evidence,
    rng,
    bar,
    on_scored=None,
):
    """Score the base candidates, then (``stepwise``) the extension search of
    :mod:`bayes_imu.inference.selection`; ``on_scored``: called with each batch's ``(model,
    _Scored)`` pairs as they are scored."""
    dt = 1.0 / allan.rate_hz
    scored = {}
    best = -np.inf

    def run(batch):
        nonlocal best
        models = {}
        for terms in batch:
            model = NoiseModel(terms, dt)  # canonical term order: the key of a candidate
            if model.terms not in scored:
                models[model.terms] = model
        results, best = _score_batch(
            [(m, make_post(m), None) for m in models.values()],
            allan,
            reference,
            n_evidence,
            rng,
            best,
        )
        scored.update(zip(models, results))
        if on_scored is not None and results:
            on_scored(list(zip(models.values(), results)))
        bar.update(len(results))
        return [scored[NoiseModel(terms, dt).terms] for terms in batch]

    run(candidates)
    if stepwise:
        current = max(scored.values(), key=lambda c: c.score.log_evidence)
        while True:
            new = run(extensions(current.score.terms))
            if not new:
                break
            best_new = max(new, key=lambda c: c.score.log_evidence)
            # the addition gains no more than the margin
            if within_margin(current.score, best_new.score, threshold):
                break
            current = best_new
        # backward: on to the best removal while it stays within the selection margin of the best
        while True:
            new = run(reductions(current.score.terms))
            top = max(scored.values(), key=lambda c: c.score.log_evidence).score
            near = [c for c in new if within_margin(c.score, top, threshold)]
            if not near:
                break
            current = max(near, key=lambda c: c.score.log_evidence)
    return list(scored.values())


def _rescore_widened(scored, allan, reference, n_evidence, rng, ahead=None):
    """Every candidate again with the model-discrepancy term, with the Laplace screen; its mode is
    sought from the usual starts and from its own mode without the term (discrepancy 0.1). On the
    ADIS16405 logs each of the two alone missed the best mode of some candidates by 4-15 nats (the
    usual starts once by 5.8 nats): the candidates' widened evidences are now those of their best
    mode. ``ahead``: the modes already sought in a pool (:class:`_WidenedAhead`), used where
    done."""
    dt = 1.0 / allan.rate_hz
    jobs, ready = [], []
    for c in scored:
        model = NoiseModel(c.score.terms, dt)
        taken = None if ahead is None else ahead.take(model.terms)
        if taken is None:
            taken = _widened_job(model, c, allan, reference) + (lambda: None,)
        post, starts, ready_one = taken
        jobs.append((model, post, starts))
        ready.append(ready_one)
    return _score_batch(jobs, allan, reference, n_evidence, rng, -np.inf, lambda i: ready[i]())[0]


def _mixture(scored, chosen, probabilities, samples, rng, floor=1e-3):
    """Model-averaged draws: each candidate with probability >= ``floor`` contributes that share.

    The selected model contributes its MCMC draws; the others their importance draws,
    resampled by weight. Returns a tuple of :class:`MixtureComponent`.
    """
    keep = np.flatnonzero(probabilities >= floor)
    weights = probabilities[keep] / probabilities[keep].sum()
    n_total = samples.shape[0]
    out = []
    for i, w in zip(keep, weights):
        count = int(round(w * n_total))
        if count == 0:
            continue
        if i == chosen:
            draws = samples[rng.choice(n_total, size=min(count, n_total), replace=False)]
        else:
            # never None here: a screened candidate's probability is below e^-10
            ev = scored[i].evidence
            lw = np.where(np.isfinite(ev.log_w), ev.log_w, -np.inf)
            p = np.exp(lw - lw.max())
            idx = rng.choice(p.size, size=count, replace=True, p=p / p.sum())
            draws = np.exp(to_phi(ev.u[idx], scored[i].post.bounds))
        out.append(MixtureComponent(scored[i].score.terms, float(w), draws))
    return tuple(out)


def _shared_posterior(pilot_model, allan, likelihood):
    """The pilot fit of ``pilot_model`` and the factory of every candidate's posterior (one
    covariance for all)."""
    reference = _pilot(pilot_model, allan)
    return reference, _posterior_factory(pilot_model, reference, allan, likelihood)


def _posterior_factory(ref_model, reference, allan, likelihood):
    """``model -> LogPosterior`` sharing one AVAR covariance computed under ``ref_model`` at
    ``reference``."""
    if likelihood == "independent":
        return lambda model: LogPosterior.build(model, allan, kind="independent")
    cov = _covariance(ref_model, reference, allan)
    ref_avar = ref_model.avar(allan.m, reference)
    return lambda model: LogPosterior.from_covariance(
        model, allan, cov, ref_avar, default_bounds(model, allan), kind=likelihood
    )


def _covariance(model, params, allan):
    from ..noise.avar_covariance import avar_covariance

    return avar_covariance(model, params, allan.m, allan.n_samples)


def _pilot(model, allan):
    """Mode under the independent-gamma likelihood: dict of physical parameters."""
    post = LogPosterior.build(model, allan, kind="independent")
    phi = posterior_mode(post, _starts(model, allan, None)).phi
    return dict(zip(model.parameter_names, np.exp(phi)))


def _starts(model, allan, reference):
    """Starting log-parameter vectors: each term's guess from the curve, once per combination of
    the terms' start variants (:meth:`bayes_imu.noise.Term.start_variants`: a Gauss-Markov bias's
    time constants), and the reference point (a candidate's: the full-model pilot) where given.

    Time constants of ordered Gauss-Markov terms are sorted into their order.
    """
    tau, avar = allan.tau, allan.avar
    dt = 1.0 / allan.rate_hz
    guess = {}
    variants = [{}]
    for term in model.components:  # each term's own (:meth:`bayes_imu.noise.Term.starting_guess`)
        guess.update(term.starting_guess(tau, avar, allan.m, dt))
        variants = [dict(v, **w) for v in variants
                    for w in term.start_variants(tau, avar, pilot=reference is None)]
    bounds = default_bounds(model, allan)
    out = []
    sources = [guess] + ([reference] if reference is not None else [])
    order = model.ordered
    for src in sources:
        for variant in variants:
            values = {k: src.get(k, guess[k]) for k in model.parameter_names}
            if src is guess:
                values.update(variant)
            phi = np.log([max(values[k], 1e-300) for k in model.parameter_names])
            width = bounds[:, 1] - bounds[:, 0]
            phi = np.clip(phi, bounds[:, 0] + 0.01 * width, bounds[:, 1] - 0.01 * width)
            if len(order) > 1:
                phi[list(order)] = _ordered_inside(phi[list(order)], bounds[list(order)])
            out.append(phi)
    return np.array(out)


def _ordered_inside(values, bounds):
    """Strictly increasing values, each inside its own box row (boxes of ordered terms overlap)."""
    values = np.sort(values)
    lo = bounds[:, 0] + 0.01 * (bounds[:, 1] - bounds[:, 0])
    hi = bounds[:, 1] - 0.01 * (bounds[:, 1] - bounds[:, 0])
    out = np.clip(values, lo, hi)
    for i in range(1, out.size):
        if out[i] <= out[i - 1]:
            out[i] = min(hi[i], out[i - 1] + 0.05 * (hi[i] - lo[i]))
    for i in range(out.size - 2, -1, -1):
        if out[i] >= out[i + 1]:
            out[i] = max(lo[i], out[i + 1] - 0.05 * (hi[i] - lo[i]))
    return out


def _initial_walkers(post, evidence, phi_mode, n_walkers, rng):
    """Walkers from the importance draws, resampled by weight (distinct), else around the mode."""
    u, log_w = evidence.u, evidence.log_w
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    k = min(n_walkers, int(np.count_nonzero(w)))
    idx = rng.choice(w.size, size=k, replace=False, p=w) if k == n_walkers else np.array([], int)
    start = (
        to_phi(u[idx], post.bounds)
        if idx.size and u.shape[1] == phi_mode.size
        else np.empty((0, phi_mode.size))
    )
    if start.shape[0] < n_walkers:
        start = phi_mode + 1e-3 * rng.standard_normal((n_walkers, phi_mode.size))
        if len(post.order) > 1:
            start[:, list(post.order)] = np.sort(start[:, list(post.order)], axis=1)
    return np.clip(start, post.bounds[:, 0] + 1e-9, post.bounds[:, 1] - 1e-9)


def exchangeable_biases(post):
    """``(variance_columns, time_columns, time_bounds)`` of the terms of ``post`` that are one
    process with one prior box (two or more terms of one :attr:`bayes_imu.noise.Term.exchangeable`
    group whose boxes agree: the relabel move of
    :func:`~bayes_imu.inference.sampling.relabel_move`), else ``None``."""
    names = post.model.parameter_names
    groups = {}
    for t in post.model.components:
        if t.exchangeable:
            groups.setdefault(t.exchangeable, []).append(t)
    group = next((g for g in groups.values() if len(g) >= 2), [])
    columns = [(names.index(t.parameters[0]), names.index(t.parameters[1])) for t in group]
    if len(columns) < 2:
        return None
    var_cols, time_cols = (list(c) for c in zip(*columns))
    rows = post.bounds
    if not (
        np.all(rows[var_cols] == rows[var_cols[0]])
        and np.all(rows[time_cols] == rows[time_cols[0]])
    ):
        return None
    return var_cols, time_cols, rows[time_cols[0]]


def _independence(post, phi_mode, rng):
    """``(proposal, acceptance)``: the independence move's Student t at ``phi_mode`` (the Laplace
    approximation of ``post`` in log-parameters, its standard deviations inflated by
    :data:`~bayes_imu.inference.sampling.INDEPENDENCE_INFLATE`) and the move's expected acceptance
    (:func:`~bayes_imu.inference.sampling.independence_acceptance`, :data:`INDEPENDENCE_PILOT`
    draws from a generator spawned from ``rng``: ``rng``'s own draws are as without it; a fit
    below the threshold is tempered, :func:`_sample`)."""
    try:
        pilot_rng = rng.spawn(1)[0]
    except (TypeError, ValueError):  # a bit generator without a seed sequence to spawn from
        pilot_rng = np.random.default_rng(rng.integers(2**63))
    width = post.bounds[:, 1] - post.bounds[:, 0]
    h = finite_negative_hessian(lambda x: post(np.atleast_2d(x)), np.asarray(phi_mode, float))
    w, v = np.linalg.eigh(h)
    # a flat direction is bounded by the prior box: at most its widest side as standard deviation
    w = np.clip(w, 1.0 / np.max(width) ** 2, None)
    proposal = StudentProposal(phi_mode, INDEPENDENCE_INFLATE**2 * (v / w) @ v.T)
    return proposal, independence_acceptance(post, proposal, INDEPENDENCE_PILOT, pilot_rng)


def _sample(post, start, rng, max_steps, progress=False, independence=None):
    """emcee until converged or ``max_steps``. ``independence``: ``(proposal, acceptance)`` of
    :func:`_independence`; the move is used where the acceptance is at least
    :data:`~bayes_imu.inference.sampling.INDEPENDENCE_MIN_ACCEPT`, and below it (a posterior far
    from a t) the ensemble is tempered (:class:`~bayes_imu.inference.tempering.TemperedEnsemble`).
    An untempered ensemble whose walkers' autocorrelation time exceeds :data:`TEMPER_AFTER_TAU` at
    a check (a posterior the acceptance estimate took for a t), while the chain is shorter than
    ``AUTOCORR_MULTIPLE`` of those times and at least :data:`TEMPERED_MIN_STEPS` of ``max_steps``
    are left, goes on tempered from its walkers' last state, the steps before discarded
    (``steps_before_tempering`` in the diagnostics; ``max_steps`` counts them).

    A tempered chain, where the budget left allows :data:`JUMP_PILOT` plus :data:`JUMP_MIN_KEPT`
    steps, runs a pilot of :data:`JUMP_PILOT` steps; a mixture of t's fitted to the second half
    of them (:func:`~bayes_imu.inference.mixture_proposal.fit_student_mixture`) is then the
    proposal of the jump move (:meth:`~bayes_imu.inference.tempering.TemperedEnsemble.add_jump`),
    the pilot discarded, and the chain may stop only after :data:`JUMP_MIN_KEPT` steps with it.
    Where it is then still far from stopping, the proposal is refitted to every step kept
    (:data:`JUMP_REFITS` times) and those steps discarded too (``jump_pilot_steps`` in the
    diagnostics counts every discarded tempered step; ``max_steps`` counts them).

    The chain stops once it is :data:`~bayes_imu.inference.sampling.AUTOCORR_MULTIPLE`
    autocorrelation times long: the walkers' own
    (:func:`~bayes_imu.inference.sampling.autocorr_time`) for emcee's ensemble, and for the
    tempered one, whose swaps move states between walkers, the larger of those and the time of
    the walkers' mean (:func:`~bayes_imu.inference.sampling.ensemble_mean_autocorr_time`), which
    no exchange of states can shorten. Either way it is converged only where the ESS of the
    walkers' mean (:func:`ensemble_mean_ess`) is also :data:`ESS_MIN` or more: a guard, on
    the ensemble as a whole, that the walkers' own ESS gives only where they are independent."""
    n_walkers, n_par = start.shape
    use = independence is not None and independence[1] >= INDEPENDENCE_MIN_ACCEPT
    # (the tempered ensemble's red-blue halves need an even number of walkers; emcee's takes any)
    can_temper = n_walkers % 2 == 0 and n_walkers >= 4
    tempered = (independence is not None and not use and independence[1] < TEMPER_BELOW
                and can_temper)
    exchangeable = exchangeable_biases(post)
    if tempered:
        sampler = TemperedEnsemble(post, start, rng, exchangeable, capacity=max_steps)
    else:
        sampler = ensemble_sampler(post, start, rng, exchangeable, capacity=max_steps,
                                   independence=independence[0] if use else None)
    chunk, state, tau_old = min(250, max_steps), start, np.inf
    before = 0  # steps of an untempered start, discarded where the ensemble went on tempered
    pilot = 0  # tempered steps discarded when the jump move was added or refitted
    refits = 0
    jump_ok = JUMP_PILOT > 0  # False where the proposal could not be fitted
    room = JUMP_MIN_KEPT + 250  # steps after a (re)fit: the least to stop, and one more check
    widths = np.diff(post.bounds, axis=1).ravel()
    converged = False
    with progress_bar(desc="sampling", unit="step", enabled=progress) as bar:
        while before + pilot + sampler.iteration < max_steps:
            if tempered:
                sampler.run(chunk)
            else:
                state = sampler.run_mcmc(state, chunk, progress=False)
            tau_max = _tau_max(sampler.get_chain(), tempered)
            if (not tempered and can_temper and 0.0 < TEMPER_AFTER_TAU < tau_max
                    and sampler.iteration < AUTOCORR_MULTIPLE * tau_max
                    and max_steps - before - sampler.iteration >= TEMPERED_MIN_STEPS):
                # a slow chain, not yet long enough to stop, with budget left: tempered from here,
                # its steps so far discarded as burn-in
                bar.update(chunk)
                before += sampler.iteration
                sampler = TemperedEnsemble(post, state.coords, rng, exchangeable,
                                           capacity=max_steps - before)
                tempered = True
                chunk, tau_old = min(250, max_steps - before), np.inf
                continue
            jump_due = (tempered and sampler.jump is None and jump_ok
                        and max_steps - before - pilot >= JUMP_PILOT + room)
            refit_due = (tempered and sampler.jump is not None and refits < JUMP_REFITS
                         and sampler.iteration >= JUMP_MIN_KEPT
                         and AUTOCORR_MULTIPLE * tau_max > 2 * sampler.iteration
                         and max_steps - before - pilot - sampler.iteration >= room)
            if (jump_due and sampler.iteration >= JUMP_PILOT) or refit_due:
                # the jump move, fitted to the second half of the pilot (or, refitted, to every
                # step kept: they reach regions the pilot did not); those steps discarded
                bar.update(chunk)
                steps = sampler.iteration
                try:
                    proposal = fit_student_mixture(
                        sampler.get_chain(discard=0 if refit_due else steps // 2).reshape(
                            -1, n_par), rng, scale=widths,
                        n_draws=JUMP_REFIT_DRAWS if refit_due else MIXTURE_FIT_DRAWS)
                except (ValueError, np.linalg.LinAlgError):
                    proposal = None  # not fitted: the chain goes on as it is
                if proposal is not None:
                    sampler.add_jump(proposal, JUMP_SHARE)
                    pilot += steps
                    refits += refit_due
                    # the first check where it may stop (none before)
                    chunk, tau_old = min(JUMP_MIN_KEPT, max_steps - before - pilot), np.inf
                    continue
                jump_ok, jump_due = False, False
                refits = JUMP_REFITS
            if tempered:
                # the largest estimate so far: the mean's time comes from one series, whose
                # estimate moves by more than 5% from check to check (with it a chain of imu2
                # accelerometer x, 500 000 samples, never settled in 40 000 steps at 200 steps);
                # a running maximum settles once the estimate stops growing, and never stops a
                # chain on a low swing
                tau_max = max(tau_max, tau_old if np.isfinite(tau_old) else 0.0)
            bar.update(chunk)
            # a long chain: checked at a tenth of its length, and not before it could stop; a
            # pilot ends at JUMP_PILOT steps exactly
            chunk = min(
                steps_to_next_check(sampler.iteration, 250, tau_max),
                max_steps - before - pilot - sampler.iteration,
            )
            if jump_due:
                chunk = min(chunk, max(JUMP_PILOT - sampler.iteration, 1))
            bar.set_postfix_str(f"autocorrelation {tau_max:.0f} steps")
            # a tempered chain stops only once it has had the jump move and JUMP_MIN_KEPT steps
            # with it (where the budget allows the move)
            settled = not jump_due and not (
                tempered and sampler.jump is not None and sampler.iteration < JUMP_MIN_KEPT
            ) and long_enough(sampler.iteration, tau_max, tau_old)
            tau_old = tau_max
            if settled:
                chain, lp, diagnostics = _thinned(sampler, tau_max, n_walkers, True)
                if diagnostics["converged"]:
                    converged = True
                    break
    if not converged:
        chain, lp, diagnostics = _thinned(sampler, tau_max, n_walkers, False)
        warnings.warn(
            f"sampler not converged after {before + pilot + sampler.iteration} steps"
            + _discarded_note(before, pilot)
            + " (autocorrelation time "
            f"{tau_max:.0f} steps, R-hat {diagnostics['rhat_max']:.3f}, bulk ESS "
            f"{diagnostics['ess_bulk_min']:.0f}, ESS of the walkers' mean "
            f"{diagnostics['ess_mean_min']:.0f}); "
            "raise max_steps or inspect the chain",
            ConvergenceWarning,
            stacklevel=4,
        )
    if independence is not None:
        diagnostics["independence_acceptance"] = float(independence[1])
        diagnostics["independence_share"] = (
            float(sampler._weights[-1]) if use and not tempered else 0.0
        )
    diagnostics["tempered"] = bool(tempered)
    if tempered:
        # untempered steps run before the switch (discarded; 0 where tempered from the start)
        diagnostics["steps_before_tempering"] = int(before)
        # tempered steps discarded where the jump move was added (0 where it was not), its
        # proposal's components and its acceptance in the cold ensemble
        diagnostics["jump_pilot_steps"] = int(pilot)
        if sampler.jump is not None:
            diagnostics["jump_components"] = int(sampler.jump.n_components)
            diagnostics["jump_acceptance"] = float(sampler.jump_acceptance)
        diagnostics["ladder"] = [float(b) for b in sampler.betas]
        diagnostics["swap_acceptance"] = [float(a) for a in sampler.swap_acceptance]
    return chain.reshape(-1, n_par), lp.reshape(-1), diagnostics, SamplerChains(chain, lp, post)


def _discarded_note(untempered, pilot):
    """The convergence warning's count of discarded steps: ``untempered`` before the switch to
    the tempered ensemble, ``pilot`` tempered before the jump move's last fit ("" for none)."""
    parts = [f"{n} of them {what}" for n, what in (
        (untempered, "untempered"), (pilot, "tempered before the jump move's last fit")) if n]
    return f" ({'; '.join(parts)}, discarded)" if parts else ""


def _tau_max(chain, tempered):
    """The stopping rule's autocorrelation time (steps): the longest of every parameter's walkers'
    own, and with ``tempered``, of their mean's too (:func:`_sample`).

    The mean's time comes from one series, the walkers' from 32 averaged: its estimate is several
    times noisier (relative spread about ``sqrt(20 tau / steps)``, 60% at 50 times), so a rule on
    it alone lengthens chains for nothing where the two agree, as they do for emcee's ensemble
    on the posteriors near a t that it samples here (7-23 steps both on the real ADIS16405 gyro
    x logs); that ensemble's chains stop as before, checked by the ESS of the mean."""
    tau = np.max(autocorr_time(chain))
    if tempered:
        tau = max(tau, np.max(ensemble_mean_autocorr_time(chain)))
    return float(tau)


def warm_up():
    """Import what a fit's pool jobs need (:func:`_mode_ahead`; scipy.optimize for a mode search's
    last steps): the warm-up of the command's output process, which then seeks modes ahead."""
    import scipy.optimize  # noqa: F401
    import scipy.special  # noqa: F401


def import_arviz():
    """``arviz``, imported without its import-time announcement (a FutureWarning and lines on
    stdout)."""
    import contextlib
    import io

    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore", FutureWarning)
        import arviz

    return arviz


def _thinned(sampler, tau_max, n_walkers, settled):
    """Drop the burn-in, thin (:func:`~bayes_imu.inference.sampling.burn_and_thin`); diagnostics on
    the rest."""
    burn, thin = burn_and_thin(tau_max, sampler.iteration)
    # copies: emcee returns views of its storage, which would keep every step of the chain (the
    # reserved backend: up to max_steps, ~90 MB for 40 000 steps of 9 parameters) alive with the
    # result; a report of two refitted logs held both (issue 39's memory bound)
    chain = np.array(sampler.get_chain(discard=burn, thin=thin))  # (draws, walkers, par)
    lp = np.array(sampler.get_log_prob(discard=burn, thin=thin))
    kept = sampler.get_chain(discard=burn)
    mean = kept.mean(axis=1)  # the walkers' mean at each step, (steps, par)
    out = _diagnostics(chain, tau_max, sampler.iteration, n_walkers, settled,
                       _mean_ess(kept, mean))
    # the walkers' mean as one chain, split in two (reported: for a tempered ensemble the walkers
    # are not chains, and R-hat over them reads low; this one asks ~100 of the mean's
    # autocorrelation times of a single chain, where the convergence rule asks 50)
    out["rhat_mean_max"] = float(np.max([rhat(mean[:, j]) for j in range(mean.shape[-1])]))
    return chain, lp, out


def ensemble_mean_ess(chain):
    """Effective sample size of each parameter's posterior mean from an ensemble's steps
    ``chain`` ``(steps, walkers, parameters)``: ``steps var(draws) / (var(mean over walkers)
    tau_mean)``, ``tau_mean`` the autocorrelation time of the walkers' mean
    (:func:`~bayes_imu.inference.sampling.ensemble_mean_autocorr_time`). The variance of the
    chain's average is ``var(mean over walkers) tau_mean / steps`` whatever the walkers'
    dependence, so this is the number of independent draws with the same variance; it equals
    ``steps walkers / tau`` for independent walkers."""
    chain = np.asarray(chain, float)
    return _mean_ess(chain, chain.mean(axis=1))


def _mean_ess(chain, mean):
    """:func:`ensemble_mean_ess` of ``chain`` given its walkers' mean ``mean`` ``(steps, par)``
    (computed once by the caller)."""
    # one parameter at a time: no copy of the whole chain (40 000 steps x 32 walkers x 9: 90 MB)
    spread = np.array([chain[:, :, j].var() for j in range(chain.shape[-1])])
    with np.errstate(divide="ignore", invalid="ignore"):
        ess = chain.shape[0] * spread / (mean.var(axis=0) * autocorr_time(mean[:, None, :]))
    return np.where(np.isfinite(ess), ess, 0.0)


def _diagnostics(chain, tau_max, n_steps, n_walkers, converged, ess_mean):
    out = {**convergence_summary(chain), "autocorr_time": float(tau_max), "n_steps": int(n_steps),
           "n_walkers": int(n_walkers), "ess_mean_min": float(np.min(ess_mean))}
    out["converged"] = bool(
        converged
        and out["rhat_max"] < RHAT_MAX
        and out["ess_bulk_min"] >= ESS_MIN
        and out["ess_mean_min"] >= ESS_MIN
    )
    return out



