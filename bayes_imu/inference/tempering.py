"""A parallel-tempered ensemble for the posteriors that are not near a t.

Where a term is half resolved by the record, its posterior holds a second, smaller region (the
term near absent, another term taking its place) joined to the main one by a narrow neck. An
ensemble walker that enters it stays there for thousands of steps, and a walker that never
enters it leaves it out: on the real ADIS16405 imu4 accelerometer z log, plain ensembles whose
split R-hat over walkers read 1.006-1.018 had 5% and 95% quantiles of a bias variance up to 1.2
posterior standard deviations from the posterior's (seeds 1, 2 and 4), and the run-to-run
variance of their means said autocorrelation times of 1 000-3 000 steps where the walkers' own
said 150-450 (``docs/speed_under_load.md``, thirteenth session).

Parallel tempering (Geyer 1991; Earl & Deem 2005, Phys. Chem. Chem. Phys. 7, 3910) runs one
ensemble at each of :data:`LADDER`'s inverse temperatures ``beta``, each sampling
``prior x likelihood ** beta``: the hotter ones cross the neck easily, and states pass between
neighbours by swaps. The coldest (``beta = 1``) is the posterior and is the chain kept. Within
each temperature the moves are emcee's (Foreman-Mackey et al. 2013): differential evolution
(ter Braak 2006, emcee's ``DEMove``: ``gamma = 2.38 / sqrt(2 d)``) on 80% of the steps and the
stretch move (Goodman & Weare 2010, ``a = 2``) on 20%, each on two halves of the walkers in
turn, and where two Gauss-Markov biases are one process, the relabel move
(:func:`bayes_imu.inference.sampling.relabel_move`) on
:data:`~bayes_imu.inference.sampling.RELABEL_SHARE` (each of these shares times ``1 - share`` once
the jump move below takes its ``share``), all on every temperature at once (one
vectorised likelihood call for all of them). After each step, the walkers of every other pair
of neighbouring temperatures (:meth:`TemperedEnsemble._swap`) are paired at random and each pair
swaps its states with probability ``min(1, exp((beta_cold - beta_hot) (L_hot - L_cold)))``
(``L`` the log likelihood), a Metropolis move of the joint target whose coldest margin is the
posterior (the prior, uniform on a box, is not tempered: a state outside it has ``L = -inf``).

Within each temperature the walkers still cross between the posterior's regions only as fast as
swaps bring them from hotter temperatures: the walkers' mean kept autocorrelation times of 400 to
1 780 steps on the real imu4 and imu5 accelerometer z logs. :meth:`TemperedEnsemble.add_jump`
adds a jump move, an independence Metropolis-Hastings move whose proposal, a mixture of t's
fitted to a pilot of the ensemble's own draws
(:mod:`bayes_imu.inference.mixture_proposal`), proposes every region at once; the stored steps
are dropped when it is added, so the chain kept is that of a fixed kernel.

Swaps move states between the walkers of the cold ensemble, so one walker's series is no longer
one chain: its autocorrelation time and the spread of the walkers' means understate how slowly
the ensemble as a whole moves. :func:`bayes_imu.inference.sampling.ensemble_mean_autocorr_time`
(the autocorrelation time of the walkers' mean, which no exchange of states between walkers can
shorten) is what the fit's stopping rule then relies on (:mod:`bayes_imu.inference.fit`).
"""

import numpy as np

from .sampling import RELABEL_SHARE, relabel_proposal

__all__ = ["LADDER", "TemperedEnsemble"]

#: inverse temperatures, coldest first, closer together near 1: where a half-resolved term
#: switches on, a posterior changes most between beta = 1 and 0.5 (swap acceptances between
#: neighbours 0.52-0.73, 0.10-0.21, 0.26-0.32 and 0.36-0.38 on four real ADIS16405 accelerometer
#: posteriors, against 0.01-0.05 between 1 and 0.585 on a geometric ladder of four; the ensemble
#: mean's autocorrelation time over 60 000 steps 125-676 steps against 295-3583). 0.2 flattens a
#: likelihood ratio of e^3 between two regions to e^0.6.
LADDER = (1.0, 0.85, 0.6, 0.35, 0.2)
#: emcee's DEMove: relative spread of its scale factor
_DE_SIGMA = 1.0e-5
#: emcee's StretchMove: the stretch scale
_STRETCH_A = 2.0


class TemperedEnsemble:
    """Ensembles of ``start.shape[0]`` walkers at each inverse temperature of ``ladder``, the
    coldest kept (:mod:`bayes_imu.inference.tempering`).

    Parameters
    ----------
    post : bayes_imu.inference.likelihood.LogPosterior
        The posterior: its ``log_prior`` (uniform on a box) and ``log_likelihood`` are used,
        vectorised over rows.
    start : ndarray, shape (n_walkers, n_par)
        The coldest ensemble's walkers (an even number of at least four, at least one inside the
        posterior); each hotter one's start spread about their mean by ``1 / sqrt(beta)``, a
        walker that this takes out of the posterior starting where the cold one does.
    rng : numpy.random.Generator
        The draws of every move and swap.
    exchangeable : tuple or None
        ``(variance_columns, time_columns, bounds)`` of Gauss-Markov biases that are one process
        (:func:`bayes_imu.inference.fit.exchangeable_biases`): the relabel move on
        :data:`~bayes_imu.inference.sampling.RELABEL_SHARE` of the steps.
    ladder : sequence of float
        Inverse temperatures, the first 1 (the posterior), decreasing.
    capacity : int
        Steps reserved for the cold chain (it grows past them).
    """

    def __init__(self, post, start, rng, exchangeable=None, ladder=LADDER, capacity=1000):
        start = np.asarray(start, float)
        n_walkers, n_par = start.shape
        betas = np.asarray(ladder, float)
        if betas[0] != 1.0 or np.any(np.diff(betas) >= 0) or betas[-1] <= 0:
            raise ValueError("a ladder of inverse temperatures starts at 1 and decreases above 0")
        if n_walkers < 4 or n_walkers % 2:
            raise ValueError("a tempered ensemble needs an even number of at least four walkers")
        self.post, self.rng, self.betas = post, rng, betas
        # each temperature's walkers spread about the start's mean by 1 / sqrt(beta), the spread of
        # the tempered Laplace approximation: a hot ensemble starts near its own breadth instead of
        # taking thousands of steps to widen; a spread walker outside the posterior starts where
        # the cold one does
        centre = start.mean(axis=0)
        spread = centre + (start - centre) / np.sqrt(betas)[:, None, None]
        spread[0] = start
        spread_like = self._log_like(spread)
        cold_like = spread_like[0]
        if np.any(np.isnan(cold_like)) or not np.any(np.isfinite(cold_like)):
            raise ValueError("a tempered ensemble needs a start inside the posterior")
        keep = np.isfinite(spread_like)
        self.coords = np.where(keep[..., None], spread, start)
        self.log_like = np.where(keep, spread_like, cold_like)
        # the prior's constant, from a start inside the posterior (the first may be outside)
        self._prior = float(post.log_prior(start[np.isfinite(cold_like)][:1])[0])
        self._relabel = None
        shares = [0.8, 0.2]
        if exchangeable is not None and len(exchangeable[1]) >= 2:
            self._relabel = relabel_proposal(*exchangeable)
            shares = [0.8 * (1 - RELABEL_SHARE), 0.2 * (1 - RELABEL_SHARE), RELABEL_SHARE]
        self._cdf = np.cumsum(shares) / np.sum(shares)
        self._local = np.array(shares + [0.0] * (3 - len(shares))) / np.sum(shares)  # before jumps
        self.jump = None  # the jump move's proposal (:meth:`add_jump`)
        self.jumped = 0.0  # the cold ensemble's accepted jumps
        self.jumps = 0  # and tried
        self._g0 = 2.38 / np.sqrt(2.0 * n_par)
        self._temps = np.arange(betas.size)[:, None]  # a temperature index per row
        self.chain = np.empty((int(capacity), n_walkers, n_par))
        self.log_prob = np.empty((int(capacity), n_walkers))
        self.iteration = 0
        self.accepted = np.zeros(betas.size)
        self.swapped = np.zeros(betas.size - 1)
        self.tried = np.zeros(betas.size - 1)

    def _log_like(self, x):
        """Log likelihood of rows ``x`` ``(..., n_par)``, ``-inf`` outside the prior box."""
        flat = x.reshape(-1, x.shape[-1])
        inside = self.post.in_prior(flat)
        if inside.all():
            return self.post.log_likelihood(flat).reshape(x.shape[:-1])
        out = np.full(flat.shape[0], -np.inf)
        if inside.any():
            out[inside] = self.post.log_likelihood(flat[inside])
        return out.reshape(x.shape[:-1])

    def run(self, n_steps):
        """Run ``n_steps`` steps (moves on every temperature, then swaps); the cold ensemble of
        each is stored."""
        n_steps = int(n_steps)
        if self.iteration + n_steps > self.chain.shape[0]:
            grow = self.iteration + n_steps - self.chain.shape[0]
            self.chain = np.concatenate([self.chain, np.empty((grow,) + self.chain.shape[1:])])
            self.log_prob = np.concatenate(
                [self.log_prob, np.empty((grow,) + self.log_prob.shape[1:])]
            )
        for _ in range(n_steps):
            move = int(self._cdf.searchsorted(self.rng.random(), side="right"))
            if move == 3:
                self._jump_step()
            elif move == 2:
                self._relabel_step()
            else:
                self._red_blue_step(stretch=move == 1)
            self._swap()
            self.chain[self.iteration] = self.coords[0]
            self.log_prob[self.iteration] = self._prior + self.log_like[0]
            self.iteration += 1

    def add_jump(self, proposal, share):
        """From now on, the jump move on ``share`` of the steps (taken from every other move in
        proportion), its proposal ``proposal`` (a
        :class:`~bayes_imu.inference.mixture_proposal.StudentMixture`; a second call replaces the
        proposal and the share); the steps stored so far are dropped, the states of every
        temperature kept: the chain kept from here is a fixed Metropolis-Hastings kernel's
        (:mod:`bayes_imu.inference.mixture_proposal`)."""
        if not 0.0 < share < 1.0:
            raise ValueError("the jump move's share is between 0 and 1")
        self._cdf = np.cumsum(np.append((1.0 - share) * self._local, share))
        self._cdf[-1] = 1.0
        self.jump = proposal
        self.iteration = 0
        self.accepted[:] = 0.0
        self.swapped[:] = 0.0
        self.tried[:] = 0.0
        self.jumped, self.jumps = 0.0, 0

    @property
    def jump_acceptance(self):
        """The jump move's acceptance in the cold ensemble (NaN before it was tried)."""
        return self.jumped / self.jumps if self.jumps else float("nan")

    def _jump_step(self):
        """The jump move (an independence Metropolis-Hastings move, :meth:`add_jump`) on every
        walker of every temperature: the proposal's density ratio ``q(x) / q(y)`` is the
        Hastings factor."""
        n_temps, n_walkers, n_par = self.coords.shape
        new = self.jump.draw(n_temps * n_walkers, self.rng)
        factor = self.jump.log_density(self.coords.reshape(-1, n_par)) - self.jump.log_density(new)
        cold_before = self.accepted[0]
        self._accept(np.arange(n_walkers), new.reshape(self.coords.shape),
                     factor.reshape(n_temps, n_walkers))
        self.jumped += self.accepted[0] - cold_before
        self.jumps += n_walkers

    def _accept(self, rows, proposal, log_factor):
        """Metropolis-Hastings at each temperature: walkers ``rows`` of every temperature to
        ``proposal`` ``(K, len(rows), n_par)`` with the proposal's log density ratio
        ``log_factor``."""
        new = self._log_like(proposal)
        with np.errstate(invalid="ignore"):  # -inf - finite is -inf; no current state is -inf
            log_ratio = log_factor + self.betas[:, None] * (new - self.log_like[:, rows])
        ok = log_ratio > np.log(self.rng.random(log_ratio.shape))
        k, i = np.nonzero(ok)
        self.coords[k, rows[i]] = proposal[k, i]
        self.log_like[k, rows[i]] = new[k, i]
        self.accepted += ok.sum(axis=1)

    def _red_blue_step(self, stretch):
        """emcee's differential-evolution or stretch move on each half of the walkers in turn,
        the other half the complementary ensemble, at every temperature."""
        n_temps, n_walkers, n_par = self.coords.shape
        halves = self.rng.permutation(np.arange(n_walkers) % 2)
        for split in (0, 1):
            rows, others = np.flatnonzero(halves == split), np.flatnonzero(halves != split)
            s, c = self.coords[:, rows], self.coords[:, others]
            n, m = rows.size, others.size
            t = self._temps
            if stretch:
                z = ((_STRETCH_A - 1.0) * self.rng.random((n_temps, n)) + 1.0) ** 2 / _STRETCH_A
                partner = c[t, self.rng.integers(0, m, (n_temps, n))]
                proposal = partner - (partner - s) * z[..., None]
                factor = (n_par - 1.0) * np.log(z)
            else:
                first = self.rng.integers(0, m, (n_temps, n))
                second = (first + self.rng.integers(1, m, (n_temps, n))) % m  # distinct from first
                gamma = self._g0 * (1.0 + _DE_SIGMA * self.rng.standard_normal((n_temps, n, 1)))
                proposal, factor = s + gamma * (c[t, second] - c[t, first]), 0.0
            self._accept(rows, proposal, factor)

    def _relabel_step(self):
        """The relabel move (a symmetric proposal) on every walker of every temperature."""
        n_temps, n_walkers, n_par = self.coords.shape
        flat = self.coords.reshape(-1, n_par)
        proposal = self._relabel(flat, self.rng.random(flat.shape[0]))
        self._accept(np.arange(n_walkers), proposal.reshape(self.coords.shape), 0.0)

    def _swap(self):
        """Swaps between neighbouring temperatures: the pairs ``(k - 1, k)`` with ``k`` odd at even
        steps, ``k`` even at odd steps (the deterministic even-odd scheme of Okabe et al. 2001,
        non-reversible parallel tempering: Syed et al. 2022, JRSS B 84, 321), each walker of the
        colder of a pair paired with a walker of the hotter one at random. The pairs of one step
        share no temperature, so they swap at once."""
        n_temps, n_walkers = self.log_like.shape
        hot = np.arange(1 + self.iteration % 2, n_temps, 2)
        if hot.size == 0:
            return
        cold = hot - 1
        partner = self.rng.permuted(np.broadcast_to(np.arange(n_walkers), (hot.size, n_walkers)),
                                    axis=1)
        hot_like = self.log_like[hot[:, None], partner]
        cold_like = self.log_like[cold]
        with np.errstate(invalid="ignore"):
            log_ratio = (self.betas[cold] - self.betas[hot])[:, None] * (hot_like - cold_like)
        ok = log_ratio > np.log(self.rng.random(log_ratio.shape))
        pair, row = np.nonzero(ok)
        c, h, hot_row = cold[pair], hot[pair], partner[pair, row]
        cold_coords, hot_coords = self.coords[c, row], self.coords[h, hot_row]
        self.coords[c, row], self.coords[h, hot_row] = hot_coords, cold_coords
        self.log_like[c, row], self.log_like[h, hot_row] = hot_like[pair, row], cold_like[pair, row]
        self.swapped[cold] += ok.mean(axis=1)
        self.tried[cold] += 1

    def get_chain(self, discard=0, thin=1):
        """The cold ensemble's steps ``(steps, n_walkers, n_par)`` (a view), as emcee's
        ``get_chain``."""
        return self.chain[discard + thin - 1:self.iteration:thin]

    def get_log_prob(self, discard=0, thin=1):
        """The cold ensemble's log posterior ``(steps, n_walkers)`` (a view)."""
        return self.log_prob[discard + thin - 1:self.iteration:thin]

    @property
    def acceptance(self):
        """Mean acceptance of the moves at each temperature, coldest first."""
        return self.accepted / max(1, self.iteration * self.coords.shape[1])

    @property
    def swap_acceptance(self):
        """Mean acceptance of the swaps between each pair of neighbouring temperatures, coldest
        pair first."""
        return self.swapped / np.maximum(1, self.tried)
