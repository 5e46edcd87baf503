"""The emcee ensemble shared by the single-sensor fit and the population fit.

Both run emcee with differential-evolution proposals (80%) and stretch moves (20%): on the
white + Gauss-Markov posterior the integrated autocorrelation time is a fraction of the
stretch move's alone, and so are the likelihood calls for the same ESS (timings:
docs/speed_under_load.md#sampler). Both stop once the chain is :data:`AUTOCORR_MULTIPLE`
autocorrelation times long
and the estimate has settled to 5%, then drop 3 autocorrelation times of burn-in and thin by
half of one.

A model with two Gauss-Markov biases of the same prior adds a third move, on
:data:`RELABEL_SHARE` of the steps (:func:`relabel_move`): the weaker bias's time constant drawn
anew from its prior, the biases then sorted by time constant. The two biases are the same term,
ordered only to name them, so where the weaker one is negligible it may sit below or above the
other's time constant: two regions of the ordered parameters that the local moves join only
through a swap of every coordinate of both biases. On the real ADIS16405 imu4 gyro log the
second region holds about 4% of the posterior; without the move a walker that enters it stays
~15 000 steps: of seeds 0-7, four stopped at 40 000 steps unconverged and three of the other four
never visited it; with the move all eight converge, 3-5% of their draws there
(``scripts/study_speed_options.py --seeds``, ``docs/reference.md``).

Where the posterior is close to a Student t about its mode, a fourth move proposes each walker
afresh from that t (:func:`independence_move`, on :data:`INDEPENDENCE_SHARE` of the steps): an
accepted proposal forgets the walker's past in one step, which differential evolution takes tens
of steps to do. It pays only where it is accepted often, so the fit first estimates its expected
acceptance by importance sampling (:func:`independence_acceptance`) and adds it only at
:data:`INDEPENDENCE_MIN_ACCEPT` or more: on the real ADIS16405 logs it halves the chains of the
simple posteriors and is left out of the funnels (a term whose variance reaches the prior floor,
its time constant then free) it cannot help (``docs/speed_under_load.md#sampler``). There the fit
tempers the ensemble instead (:mod:`bayes_imu.inference.tempering`), with emcee's moves at every
temperature.
"""

from dataclasses import dataclass

import numpy as np
from .._lazy import import_without

__all__ = [
    "AUTOCORR_MULTIPLE",
    "RELABEL_SHARE",
    "INDEPENDENCE_SHARE",
    "INDEPENDENCE_MIN_ACCEPT",
    "INDEPENDENCE_DF",
    "INDEPENDENCE_INFLATE",
    "StudentProposal",
    "ensemble_sampler",
    "relabel_move",
    "relabel_proposal",
    "ensemble_mean_autocorr_time",
    "independence_move",
    "independence_acceptance",
    "import_emcee",
    "autocorr_time",
    "long_enough",
    "burn_and_thin",
    "MAX_KEPT_PER_WALKER",
    "one_blas_thread",
    "steps_to_next_check",
    "fft_length",
    "GEOMETRIC_FROM",
    "reserved_backend",
]

#: chain length, in integrated autocorrelation times, before the sampler may stop
AUTOCORR_MULTIPLE = 50
#: the most draws a walker keeps after burn-in and thinning (:func:`burn_and_thin`): a chain that
#: stops at AUTOCORR_MULTIPLE autocorrelation times keeps about 94, thinned by half of one
MAX_KEPT_PER_WALKER = 200
#: chain length (steps) from which convergence is checked at a tenth of the chain instead of every
#: fixed chunk
GEOMETRIC_FROM = 10_000
#: share of the steps that are :func:`relabel_move` where a model has exchangeable Gauss-Markov
#: biases
RELABEL_SHARE = 0.1
#: share of the steps that are :func:`independence_move` where the fit uses it (taken from the
#: differential-evolution and stretch moves; the relabel move keeps its share)
INDEPENDENCE_SHARE = 0.3
#: the least expected acceptance (:func:`independence_acceptance`) for which the fit uses the
#: independence move
INDEPENDENCE_MIN_ACCEPT = 0.3
#: degrees of freedom of the independence proposal (heavier tails than the posterior's)
INDEPENDENCE_DF = 5.0
#: factor on the standard deviations of the Laplace approximation in the independence proposal
INDEPENDENCE_INFLATE = 1.2


def ensemble_sampler(target, start, rng, exchangeable=None, capacity=None, independence=None):
    """``emcee.EnsembleSampler`` for the vectorised log density ``target`` from walkers ``start``
    ``(n_walkers, n_par)``; emcee's legacy RandomState is seeded from the Generator ``rng`` (no
    global random state). ``exchangeable``: ``(variance_columns, time_columns, bounds)`` of two or
    more Gauss-Markov biases with one prior (:func:`relabel_move`, on :data:`RELABEL_SHARE` of the
    steps); ``None`` (or fewer than two): differential evolution and stretch moves only, as before.
    ``capacity``: the most steps the caller will run (:func:`reserved_backend`), or ``None``
    (emcee's own storage, copied whole at every ``run_mcmc``). ``independence``: a
    :class:`StudentProposal` for :func:`independence_move` on :data:`INDEPENDENCE_SHARE` of the
    steps (taken from the differential-evolution and stretch moves), or ``None``."""
    emcee = import_emcee()

    n_walkers, n_par = start.shape
    sampler_class, de_move, stretch_move = _lean_classes(emcee)
    local = 1.0
    extra = []
    if exchangeable is not None and len(exchangeable[1]) >= 2:
        local -= RELABEL_SHARE
        extra.append((relabel_move(*exchangeable), RELABEL_SHARE))
    if independence is not None:
        share = INDEPENDENCE_SHARE * local
        local -= share
        extra.append((independence_move(independence), share))
    moves = [(de_move(), 0.8 * local), (stretch_move(), 0.2 * local)] + extra
    backend = None if capacity is None else reserved_backend(emcee, capacity)
    sampler = sampler_class(n_walkers, n_par, target, vectorize=True, moves=moves, backend=backend)
    sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
    return sampler


def reserved_backend(emcee, capacity):
    """An emcee in-memory backend whose chain is reserved once for ``capacity`` steps.

    emcee's backend grows its chain at each ``run_mcmc`` by ``numpy.concatenate``: a fit that
    checks its chain every few hundred steps copies all of it each time, and holds the old and the
    new chain at once (issue 39). This one reserves ``capacity`` steps with ``numpy.empty`` on the
    first run, allocated directly (memory pages are committed only as the steps are written:
    tests/test_sampling.py measures it) and grows only past them, as emcee does. The stored steps
    are the same.
    """
    class Reserved(emcee.backends.Backend):
        def grow(self, ngrow, blobs):
            if blobs is None and self.iteration + ngrow <= len(self.chain):
                return
            if blobs is None and len(self.chain) == 0:
                # allocated directly, not concatenated onto emcee's empty arrays as its own grow
                # does: a concatenation copies the whole reservation, committing every page of it
                # (82 MB for 40 000 steps of 32 walkers x 8 parameters) before a step is written
                self._check_blobs(blobs)
                steps = max(ngrow, int(capacity))
                self.chain = np.empty((steps, self.nwalkers, self.ndim), dtype=self.dtype)
                self.log_prob = np.empty((steps, self.nwalkers), dtype=self.dtype)
                return
            super().grow(ngrow, blobs)

    return Reserved()


def relabel_move(variance_columns, time_columns, bounds):
    """Metropolis move that redraws the time constant of the weakest of exchangeable Gauss-Markov
    biases.

    Each walker takes the bias with the smallest log variance among the columns
    ``variance_columns``, draws its log time constant uniformly within ``bounds`` (the common prior
    interval of the ``time_columns``), and sorts the biases, each keeping its variance, by time
    constant (the ordered parameters). The weakest bias is the same one after the move (no variance
    changes) and its new time constant has the same density whatever the old one, so the proposal is
    symmetric and a walker moves with probability ``min(1, p(new) / p(old))``: a Metropolis-Hastings
    move of the ordered posterior, valid however many biases and whatever the other parameters
    (tested against the exact distribution of order statistics). It joins, in one step, the regions
    of a negligible bias below and above the others' time constants, which otherwise connect only
    through a swap of labels.

    Parameters
    ----------
    variance_columns, time_columns : sequence of int
        Columns of each bias's log variance and log time constant, the biases in one order.
    bounds : (2,) array_like
        Prior interval of every log time constant (the biases' priors must be equal).

    Returns
    -------
    emcee.moves.MHMove
    """
    emcee = import_emcee()
    relabel = relabel_proposal(variance_columns, time_columns, bounds)

    def proposal(coords, random):
        n = coords.shape[0]
        return relabel(coords, random.rand(n)), np.zeros(n)

    return emcee.moves.MHMove(proposal)


def relabel_proposal(variance_columns, time_columns, bounds):
    """The proposal of :func:`relabel_move` as a function ``(coords, uniform) -> new``: rows
    ``coords`` ``(n, n_par)``, ``uniform`` ``(n,)`` numbers in [0, 1) that place each weakest bias's
    new log time constant in ``bounds`` (also the tempered ensemble's relabel move,
    :mod:`bayes_imu.inference.tempering`)."""
    var_cols, time_cols = np.asarray(variance_columns, int), np.asarray(time_columns, int)
    lo, hi = float(bounds[0]), float(bounds[1])

    def relabel(coords, uniform):
        n = coords.shape[0]
        variances, times = coords[:, var_cols], coords[:, time_cols].copy()
        times[np.arange(n), np.argmin(variances, axis=1)] = lo + (hi - lo) * uniform
        order = np.argsort(times, axis=1, kind="stable")
        new = coords.copy()
        new[:, var_cols] = np.take_along_axis(variances, order, axis=1)
        new[:, time_cols] = np.take_along_axis(times, order, axis=1)
        return new

    return relabel


@dataclass(frozen=True)
class StudentProposal:
    """Multivariate Student t: location ``loc`` ``(n,)``, shape matrix ``shape`` ``(n, n)``
    (positive definite), ``df`` degrees of freedom; the independence move's proposal."""

    loc: np.ndarray
    shape: np.ndarray
    df: float = INDEPENDENCE_DF

    def __post_init__(self):
        s, v = np.linalg.eigh(np.asarray(self.shape, float))
        if not np.all(s > 0):
            raise ValueError("the shape matrix of a Student t proposal must be positive definite")
        object.__setattr__(self, "_factor", v * np.sqrt(s))
        object.__setattr__(self, "_whiten", v / np.sqrt(s))

    def draw(self, n, random):
        """``(n, dim)`` draws from ``random`` (a ``numpy.random.RandomState`` or ``Generator``): a
        normal draw divided by sqrt(chi2_df / df)."""
        z = random.standard_normal((n, self.loc.size)) @ self._factor.T
        return self.loc + z / np.sqrt(random.chisquare(self.df, n) / self.df)[:, None]

    def log_density(self, x):
        """Log density at the rows of ``x``, up to a constant (the same for every point)."""
        maha = np.square((np.asarray(x, float) - self.loc) @ self._whiten).sum(axis=-1)
        return -0.5 * (self.df + self.loc.size) * np.log1p(maha / self.df)


def independence_move(proposal):
    """Independence Metropolis-Hastings move: each walker proposes a draw ``y`` of ``proposal`` (a
    :class:`StudentProposal`), whatever its position ``x``, and moves with probability
    ``min(1, p(y) q(x) / (p(x) q(y)))`` (Tierney 1994, Ann. Statist. 22, 1701, sec 2.3.3): the
    proposal's density ratio is emcee's ``factors``. Valid for any proposal whose support covers the
    target's (a t does); fast where ``q`` is close to ``p`` (:func:`independence_acceptance`).

    Returns
    -------
    emcee.moves.MHMove
    """
    emcee = import_emcee()

    def propose(coords, random):
        new = proposal.draw(coords.shape[0], random)
        return new, proposal.log_density(coords) - proposal.log_density(new)

    return emcee.moves.MHMove(propose)


def independence_acceptance(log_target, proposal, n, rng):
    """Expected acceptance of :func:`independence_move` at stationarity, estimated from ``n`` draws
    of ``proposal``.

    With weights ``w = p / q``, a walker at ``x ~ p`` accepts ``y ~ q`` with probability
    ``min(1, w(y) / w(x))``; the importance draws ``y_j`` (normalised weights ``W_j``) stand for
    both, ``sum_i W_i mean_j min(1, w_j / w_i)``, computed by sorting in ``O(n log n)``. It is
    1 where ``q = p`` and near 0 where ``q`` misses the posterior's mass (an estimate: mass the
    draws never reach is not seen). ``log_target``: vectorised log density (``-inf`` outside its
    support); ``rng``: a ``numpy.random.Generator``.
    """
    y = proposal.draw(int(n), rng)
    log_w = np.asarray(log_target(y), float) - proposal.log_density(y)
    log_w = np.where(np.isfinite(log_w), log_w, -np.inf)
    if not np.isfinite(log_w).any():
        return 0.0
    w = np.sort(np.exp(log_w - log_w.max()))
    below = np.concatenate([[0.0], np.cumsum(w)[:-1]])  # sum of the weights before each one
    # for w_i > 0: (sum_{w_j < w_i} w_j / w_i + #{w_j >= w_i}) / n; ties count as "at or above"
    first = np.searchsorted(w, w, side="left")
    below = below[first]
    inside = w > 0
    mean_accept = np.zeros_like(w)
    mean_accept[inside] = (below[inside] / w[inside] + (w.size - first[inside])) / w.size
    return float(np.sum(w * mean_accept) / np.sum(w))


_LEAN = {}


def _lean_classes(emcee):
    """emcee's sampler and its two moves, with the same draws from the same random numbers, less
    Python per step.

    At 32 walkers emcee's own classes cost more than a step's two vectorised likelihood calls,
    and these less a step (timings: docs/speed_under_load.md#sampler). emcee's time goes where
    it handles one walker at a time or copies its random state:

    * the sampler's ``random_state`` reads as ``None``: emcee copies the generator's state (624
      words) into every ``State`` it makes, twice a step, and on the next ``run_mcmc`` sets the
      generator back to the state of the last step, which it is in already (its setter ignores
      ``None``, as it does a state it cannot set). Setting it (the seed) works as in emcee.
    * ``compute_log_prob`` converts the vectorised log densities in one call, not one walker at a
      time (no blobs; the same errors for non-finite coordinates and NaN densities).
    * the moves accept or reject a half-ensemble's proposals in one comparison, with its uniform
      numbers drawn in one call: the legacy generator draws the same numbers in one call as one at a
      time (tested).
    * ``run_mcmc`` is emcee's loop written out (no generator, progress bar or per-step checks; the
      move drawn as ``RandomState.choice`` draws it).

    The chains are the same, bit for bit, as emcee's own classes give (tested).
    """
    if _LEAN:
        return _LEAN["classes"]
    State = emcee.State
    from emcee.ensemble import walkers_independent
    from emcee.model import Model

    class Sampler(emcee.EnsembleSampler):
        @property
        def random_state(self):
            return None

        @random_state.setter
        def random_state(self, state):
            emcee.EnsembleSampler.random_state.fset(self, state)

        def run_mcmc(self, initial_state, nsteps, progress=False, **kwargs):
            """emcee's ``run_mcmc`` (``sample`` with every step stored, no thinning, no tuning),
            its loop written out: a step is the move drawn as ``RandomState.choice`` with
            weights draws it (one uniform number against the weights' cumulative sum), the
            move's proposal, and the state written into the backend's arrays, without emcee's
            generator, progress-bar and per-step checks. The same draws in the same order: the
            chain, log densities and acceptances are emcee's, bit for bit (tested). Other
            arguments (a progress bar, thinning, tuning) go to emcee's own loop."""
            if progress or kwargs:
                return super().run_mcmc(initial_state, nsteps, progress=progress, **kwargs)
            if initial_state is None:
                if self._previous_state is None:
                    raise ValueError(
                        "Cannot have `initial_state=None` if run_mcmc has never been called."
                    )
                initial_state = self._previous_state
            state = State(initial_state, copy=True)
            shape = np.shape(state.coords)
            if shape != (self.nwalkers, self.ndim):
                raise ValueError(f"incompatible input dimensions {shape}")
            if not walkers_independent(state.coords):
                raise ValueError(
                    "Initial state has a large condition number. Make sure that your walkers are "
                    "linearly independent for the best performance"
                )
            if state.log_prob is None:
                state.log_prob, state.blobs = self.compute_log_prob(state.coords)
            if np.shape(state.log_prob) != (self.nwalkers,):
                raise ValueError("incompatible input dimensions")
            if np.any(np.isnan(state.log_prob)):
                raise ValueError("The initial log_prob was NaN")
            nsteps = int(nsteps)
            backend = self.backend
            backend.grow(nsteps, state.blobs)
            model = Model(self.log_prob_fn, self.compute_log_prob, map, self._random)
            cdf = np.cumsum(self._weights)
            cdf /= cdf[-1]
            random = self._random
            uniform, moves = random.random_sample, self._moves
            # the walkers as two arrays, updated in place by the red-blue moves (:meth:`WholeHalves.
            # step`); a State only for another move (emcee's ``propose``)
            # copies in the start's own dtype, as emcee's State keeps it (a float32 start rounds
            # every update into float32 there too)
            coords = np.array(state.coords)
            log_prob = np.array(state.log_prob)
            chain, log_probs, accepted_total = backend.chain, backend.log_prob, backend.accepted
            step = backend.iteration
            for _ in range(nsteps):
                move = moves[int(cdf.searchsorted(uniform(), side="right"))]
                if isinstance(move, WholeHalves):
                    accepted = move.step(coords, log_prob, self.compute_log_prob, random)
                else:
                    new, accepted = move.propose(model, State(coords, log_prob=log_prob))
                    coords, log_prob = new.coords, new.log_prob
                chain[step] = coords
                log_probs[step] = log_prob
                accepted_total += accepted
                step += 1
                backend.iteration = step
            state = State(coords, log_prob=log_prob, blobs=state.blobs)
            self._previous_state = state
            return state

        def compute_log_prob(self, coords):
            if not np.isfinite(coords).all():
                if np.isinf(coords).any():
                    raise ValueError("At least one parameter value was infinite")
                raise ValueError("At least one parameter value was NaN")
            log_prob = np.asarray(self.log_prob_fn(coords), dtype=np.float64).reshape(-1)
            if np.isnan(log_prob).any():
                raise ValueError("Probability function returned NaN")
            return log_prob, None

    class WholeHalves:
        """``RedBlueMove.propose`` with each half-ensemble accepted at once (:meth:`step`, on the
        walkers' arrays in place)."""

        def propose(self, model, state):
            """emcee's ``propose``: :meth:`step` on the State's own arrays, which emcee's
            ``update`` also changes in place (the lean sampler's log densities carry no blobs)."""
            accepted = self.step(state.coords, state.log_prob, model.compute_log_prob_fn,
                                 model.random)
            return state, accepted

        def step(self, coords, log_prob, compute_log_prob, random):
            """:meth:`propose` on ``coords`` ``(n_walkers, n_dim)`` and ``log_prob`` in place
            (no State objects, no blobs): the same draws in the same order, the same proposals,
            acceptances and updates (tested against emcee's own classes); returns the accepted
            walkers."""
            n_walkers, n_dim = coords.shape
            if n_walkers < 2 * n_dim and not self.live_dangerously:
                raise RuntimeError(
                    "It is unadvisable to use a red-blue move with fewer walkers than twice the "
                    "number of dimensions."
                )
            self.setup(coords)
            accepted = np.zeros(n_walkers, dtype=bool)
            halves = np.arange(n_walkers) % self.nsplits
            if self.randomize_split:
                random.shuffle(halves)
            for split in range(self.nsplits):
                chosen = halves == split
                others = [coords[halves == j] for j in range(self.nsplits) if j != split]
                proposal, factors = self.get_proposal(coords[chosen], others, random)
                new_log_probs = compute_log_prob(proposal)[0]
                difference = factors + new_log_probs - log_prob[chosen]
                ok = difference > np.log(random.rand(difference.size))
                rows = np.flatnonzero(chosen)[ok]
                coords[rows] = proposal[ok]
                log_prob[rows] = new_log_probs[ok]
                accepted[rows] = True
            return accepted

    class DEMove(WholeHalves, emcee.moves.DEMove):
        def get_proposal(self, s, c, random):
            """emcee's differential-evolution proposal with the same draws: ``choice`` of a pair
            index with replacement is ``randint`` on the legacy generator (the same numbers,
            tested), without ``choice``'s checks; the pairs' differences taken directly instead of
            through ``numpy.diff`` of the pairs' rows (the same subtraction)."""
            c = np.concatenate(c, axis=0)
            ns = s.shape[0]
            pairs = _nondiagonal_pairs(c.shape[0])
            chosen = pairs[random.randint(0, pairs.shape[0], size=ns)]
            diffs = c[chosen[:, 1]] - c[chosen[:, 0]]
            gamma = self.g0 * (1 + self.sigma * random.randn(ns, 1))
            return s + gamma * diffs, np.zeros(ns, dtype=np.float64)

    class StretchMove(WholeHalves, emcee.moves.StretchMove):
        pass

    _LEAN["classes"] = Sampler, DEMove, StretchMove
    return _LEAN["classes"]


def _nondiagonal_pairs(n):
    """emcee's ``_get_nondiagonal_pairs(n)`` (its DE move's pairs of distinct walkers, in its
    order), kept per ``n``."""
    pairs = _PAIRS.get(n)
    if pairs is None:
        from emcee.moves.de import _get_nondiagonal_pairs

        pairs = _PAIRS[n] = _get_nondiagonal_pairs(n)
    return pairs


_PAIRS = {}


def import_emcee():
    """``emcee``, without loading scipy.stats for it where nothing else has.

    emcee's KDE move (not used here) imports ``scipy.stats.gaussian_kde`` as emcee is imported,
    and scipy.stats is slow to import (docs/speed_under_load.md#imports); nothing else in a fit
    needs it. So emcee is imported with scipy.stats marked absent, which emcee handles (its KDE
    move is then without ``gaussian_kde``), and the move is given back a ``gaussian_kde`` that
    imports scipy.stats when called: :class:`emcee.moves.KDEMove` works as before (tested). The
    mechanism and its version pin: :func:`bayes_imu._lazy.import_without`.
    """
    return import_without("emcee", "scipy.stats", owner="emcee.moves.kde", attribute="gaussian_kde",
                          stand_in=_gaussian_kde)


def _gaussian_kde(*args, **kwargs):
    """``scipy.stats.gaussian_kde``, imported when first called (emcee's KDE move, see
    :func:`import_emcee`)."""
    from scipy.stats import gaussian_kde

    return gaussian_kde(*args, **kwargs)


#: walkers transformed together by :func:`autocorr_time` (8 rows of a 40 000-step chain: 5 MB of
#: transforms instead of 41 MB for 64 walkers)
_ACF_ROWS = 8


def autocorr_time(chain, c=5):
    """Integrated autocorrelation time of each parameter of ``chain`` ``(steps, walkers,
    parameters)``: emcee's estimator (:func:`emcee.autocorr.integrated_time` with ``tol=0``: the
    walkers' normalised autocorrelation functions averaged, Sokal's window with ``c = 5``).

    emcee transforms each walker's series forward and back as complex numbers, zero-padded to twice
    the next power of two. Here, the same average by three exact rewrites: real transforms; a
    padded length that is the smallest 5-smooth number of at least twice the chain
    (:func:`fft_length`: still no circular wrap, and up to 1.6x shorter than a power of two); and,
    as the transform is linear, each walker's power spectrum divided by its series' sum of squares
    (its autocovariance at lag 0, by Parseval) and summed over walkers before one inverse
    transform per parameter, instead of one per walker. The times agree with emcee's to about
    1e-15 relative (tested against emcee and against an AR(1) chain's exact time); a convergence
    check of a 40 000-step chain takes a fraction of emcee's time
    (``scripts/study_speed_options.py --sampler``).
    """
    from emcee.autocorr import auto_window

    n_t, n_w, n_d = chain.shape
    size = fft_length(2 * n_t)
    out = np.empty(n_d)
    rows = _ACF_ROWS
    for d in range(n_d):
        power = np.zeros(size // 2 + 1)
        for lo in range(0, n_w, rows):  # a few walkers at a time: bounded memory on long chains
            x = np.ascontiguousarray(chain[:, lo:lo + rows, d].T)  # (walkers, steps)
            x = x - np.mean(x, axis=1, keepdims=True)
            f = np.fft.rfft(x, n=size, axis=-1)
            spectra = f.real * f.real + f.imag * f.imag
            power += np.sum(spectra / np.einsum("ij,ij->i", x, x)[:, None], axis=0)
        total = np.fft.irfft(power, n=size)[:n_t] / n_w
        taus = 2.0 * np.cumsum(total) - 1.0
        out[d] = taus[auto_window(taus, c)]
    return out


def ensemble_mean_autocorr_time(chain, c=5):
    """Integrated autocorrelation time of each parameter's mean over the walkers of ``chain``
    ``(steps, walkers, parameters)``: :func:`autocorr_time` of the one series
    ``chain.mean(axis=1)``.

    The walkers of an ensemble are not independent chains: every move builds a walker's proposal
    from the others, and the tempered ensemble (:mod:`bayes_imu.inference.tempering`) exchanges
    states between them. The variance of a posterior mean estimated from ``n`` steps is
    ``var(mean over walkers) x tau_mean / n`` exactly, whatever the walkers' dependence, with
    ``tau_mean`` this time; the walkers' own times (:func:`autocorr_time`) give it only where
    the walkers are independent. On the real ADIS16405 logs they agree on the posteriors near a
    t (7-23 steps) and the mean's is 2-10 times longer on the others (measured:
    docs/speed_under_load.md, thirteenth session); no exchange of states between walkers can
    shorten it.
    """
    chain = np.asarray(chain, float)
    return autocorr_time(chain.mean(axis=1, keepdims=True), c=c)


def fft_length(n):
    """The smallest ``2**a * 3**b * 5**c`` of at least ``n`` (a length numpy's FFT transforms fast;
    ``scipy.fft.next_fast_len`` for real transforms, without importing scipy.fft)."""
    n = int(n)
    if n <= 1:
        return 1
    best = 1 << (n - 1).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            # the smallest power of two taking p35 to n or beyond
            q = -(-n // p35)
            candidate = p35 * (1 << (q - 1).bit_length())
            best = min(best, candidate)
            p35 *= 3
        p5 *= 5
    return best


def steps_to_next_check(iteration, every, tau=None):
    """Steps to run before the next convergence check of a chain ``iteration`` steps long: ``every``
    while it is shorter than :data:`GEOMETRIC_FROM`, then a tenth of its length (a multiple of
    ``every``); and, given ``tau`` (the autocorrelation time estimated at this check, steps), no
    check before the chain could stop, up to doubling its length.

    Each check estimates the autocorrelation time over the whole chain (an FFT of every walker's
    series), so checking every ``every`` steps costs quadratically in the chain length: on a real
    40 000-step ADIS16405 fit the checks were most of its time (timings:
    docs/speed_under_load.md#sampler). Geometric spacing makes their total cost linear in the
    length, and a chain that settles
    runs at most 10% longer than with fixed chunks; shorter chains are checked exactly as before.

    A chain stops only once it is :data:`AUTOCORR_MULTIPLE` autocorrelation times long
    (:func:`long_enough`), so a check before ``0.9 AUTOCORR_MULTIPLE tau`` steps can only estimate
    ``tau`` again: with ``tau`` given, the next check is there (a multiple of ``every``), at most
    as many steps on as the chain already has. A chain's estimate grows as it lengthens (a short
    chain has not seen its slow excursions), so this does not pass over a check at which the
    chain could stop unless the estimate falls by more than 10% by then. With ``tau`` 400 steps
    throughout, a chain reaches 50 ``tau`` in 9 checks instead of 47 (tested). Short chains
    (``tau`` of 11 steps or less at ``every = 250``) are checked as without it.
    """
    step = every if iteration < GEOMETRIC_FROM else every * int(np.ceil(0.1 * iteration / every))
    if tau is not None and np.isfinite(tau):
        ahead = every * int(np.ceil((0.9 * AUTOCORR_MULTIPLE * tau - iteration) / every))
        step = max(step, min(ahead, every * int(np.ceil(iteration / every))))
    return step


def long_enough(iteration, tau_max, tau_previous):
    """The chain is ``AUTOCORR_MULTIPLE`` autocorrelation times long and ``tau`` moved < 5% since
    the last check."""
    return iteration >= AUTOCORR_MULTIPLE * tau_max and abs(tau_max - tau_previous) < 0.05 * tau_max


def burn_and_thin(tau_max, n_steps=None):
    """``(burn, thin)``: 3 autocorrelation times of burn-in, thinning by half of one, or by more
    where a chain of ``n_steps`` would keep more than :data:`MAX_KEPT_PER_WALKER` draws a walker
    (a chain far longer than its autocorrelation times: the tempered ensemble's with the jump
    move runs 8 000 steps at least, 2 700 draws a walker at a time of 7 steps, whose drift bands
    and reports cost in proportion)."""
    burn, thin = int(np.ceil(3 * tau_max)), max(1, int(tau_max / 2))
    if n_steps is not None and (n_steps - burn) // thin > MAX_KEPT_PER_WALKER:
        # the least thinning that keeps at most that many: emcee keeps floor((n - burn) / thin)
        thin = (n_steps - burn) // (MAX_KEPT_PER_WALKER + 1) + 1
    return burn, thin


def one_blas_thread():
    """Context manager: BLAS on one thread (threadpoolctl).

    The fits multiply small matrices (an ensemble of walkers or importance draws by an
    ``n_tau x n_tau`` Cholesky factor): a multi-threaded BLAS gains nothing on them, and its
    idle threads spin on the other cores, where the output process (and, in a fleet, the
    other fits) would run (more CPU time for the same wall time: docs/speed_under_load.md#sampler).
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")
