"""The tempered ensemble (:mod:`bayes_imu.inference.tempering`) and the autocorrelation time of the
walkers' mean that its stopping rule relies on: every temperature's exact tempered distribution, a
two-region posterior's weights that a plain ensemble misses, and the walkers' mean unchanged by
exchanges of states between walkers."""

import numpy as np
import pytest

from bayes_imu.inference.fit import ensemble_mean_ess
from bayes_imu.inference.sampling import autocorr_time, ensemble_mean_autocorr_time
from bayes_imu.inference.tempering import LADDER, TemperedEnsemble


class _BoxTarget:
    """A uniform prior on a box and a vectorised log likelihood: the parts of a LogPosterior the
    tempered ensemble uses."""

    def __init__(self, log_like, low, high):
        self.f, self.low, self.high = log_like, np.asarray(low, float), np.asarray(high, float)
        self.inside = -np.sum(np.log(self.high - self.low))

    def in_prior(self, x):
        return ((x >= self.low) & (x <= self.high)).all(axis=-1)

    def log_prior(self, x):
        return np.where(self.in_prior(x), self.inside, -np.inf)

    def log_likelihood(self, x):
        return self.f(np.asarray(x, float))

    def __call__(self, x):
        x = np.atleast_2d(x)
        return self.log_prior(x) + np.where(self.in_prior(x), self.f(x), 0.0)


def _gaussian(scales):
    scales = np.asarray(scales, float)
    return lambda x: -0.5 * np.sum((x / scales) ** 2, axis=-1)


def test_every_temperature_samples_its_tempered_distribution():
    """A Gaussian likelihood (standard deviations 1, 0.1, 5) in a box 60 wide: at inverse
    temperature beta the walkers' variance is s^2 / beta exactly (the box is 6 standard deviations
    away even at beta = 0.2). Each temperature's variance over 3 000 steps after 500 of burn-in,
    within 12% (the estimate's spread is ~3%: 96 000 draws, autocorrelation times of tens of
    steps). Swaps that moved states the wrong way, or moves tempered at the wrong temperature,
    would put a temperature's variance off by the ratio of two betas (1.7x or more)."""
    scales = np.array([1.0, 0.1, 5.0])
    target = _BoxTarget(_gaussian(scales), -6 * scales / np.sqrt(0.2), 6 * scales / np.sqrt(0.2))
    rng = np.random.default_rng(5)
    start = rng.standard_normal((32, 3)) * scales
    sampler = TemperedEnsemble(target, start, rng, capacity=10)
    seen = []
    sampler.run(500)
    for _ in range(3000):
        sampler.run(1)
        seen.append(sampler.coords.copy())
    seen = np.array(seen)  # (steps, temperatures, walkers, parameters)
    variance = seen.var(axis=(0, 2))
    expected = scales**2 / np.asarray(LADDER)[:, None]
    np.testing.assert_allclose(variance, expected, rtol=0.12)
    # every temperature moved, and states crossed between every pair of neighbours
    assert np.all(sampler.acceptance > 0.05)
    assert np.all(sampler.swap_acceptance > 0.05)
    # the stored chain is the cold ensemble, with its log posterior
    chain, log_prob = sampler.get_chain(), sampler.get_log_prob()
    assert chain.shape == (3500, 32, 3) and sampler.iteration == 3500
    np.testing.assert_array_equal(chain[-1], sampler.coords[0])
    expected = target(chain[-100:].reshape(-1, 3)).reshape(100, 32)
    np.testing.assert_allclose(log_prob[-100:], expected, rtol=1e-12)
    # emcee's slicing: discard, then every thin-th step ending at each thin-th
    np.testing.assert_array_equal(sampler.get_chain(discard=100, thin=7), chain[106::7])
    np.testing.assert_array_equal(sampler.get_log_prob(discard=100, thin=7), log_prob[106::7])


def _two_regions(x):
    """Weights 0.9 and 0.1 at x0 = -2.5 and +2.5 (standard deviation 0.4: 19.5 nats of barrier
    at beta = 1, 3.9 at beta = 0.2), times a standard normal in two more coordinates."""
    a = -0.5 * ((x[..., 0] + 2.5) / 0.4) ** 2 + np.log(0.9)
    b = -0.5 * ((x[..., 0] - 2.5) / 0.4) ** 2 + np.log(0.1)
    return np.logaddexp(a, b) - 0.5 * np.sum(x[..., 1:] ** 2, axis=-1)


def test_tempering_finds_the_small_region_a_plain_ensemble_misses():
    """Every walker starts in the large region; the posterior puts exactly 0.1 in the small one
    (the regions' overlap beyond x0 = 0 is 2e-10). The tempered ensemble's share of draws there
    over 6 000 steps (1 000 dropped), within 0.03 (0.097-0.103 over seeds 0-3 of an ad-hoc run).
    emcee's own ensemble with the fit's moves (differential evolution and stretch) from the same
    start does not cross the barrier in as many steps (none crossed in those four seeds): its
    share stays below 0.02, the failure the tempering is for."""
    from bayes_imu.inference.sampling import ensemble_sampler

    target = _BoxTarget(_two_regions, [-10, -10, -10], [10, 10, 10])
    rng = np.random.default_rng(8)
    start = np.column_stack([-2.5 + 0.4 * rng.standard_normal(32),
                             rng.standard_normal((32, 2))])
    tempered = TemperedEnsemble(target, start, np.random.default_rng(9), capacity=6000)
    tempered.run(6000)
    share = np.mean(tempered.get_chain(discard=1000)[..., 0] > 0)
    assert abs(share - 0.1) < 0.03
    plain = ensemble_sampler(target, start, np.random.default_rng(9))
    plain.run_mcmc(start, 6000, progress=False)
    assert np.mean(plain.get_chain(discard=1000)[..., 0] > 0) < 0.02


def _weak_and_strong(x):
    """Two exchangeable 'biases': log variances x0, x1, log time constants x2 < x3 in [0, 3]. The
    stronger bias (the larger variance) has log variance 2 +- 0.1 and time constant 2.5 +- 0.02,
    the weaker one log variance -2 +- 0.1 and its time constant free. Ordered by time constant,
    the weaker bias is the first (faster) one with probability P(t_weak < t_strong) = 2.5 / 3
    (to 1e-6); the two labellings are regions joined only through a swap of all four
    coordinates (the variances cannot cross: 400 nats between them)."""
    first_strong = x[..., 0] > x[..., 1]
    strong_v = np.where(first_strong, x[..., 0], x[..., 1])
    weak_v = np.where(first_strong, x[..., 1], x[..., 0])
    strong_t = np.where(first_strong, x[..., 2], x[..., 3])
    like = -0.5 * (((strong_v - 2) / 0.1) ** 2 + ((weak_v + 2) / 0.1) ** 2
                   + ((strong_t - 2.5) / 0.02) ** 2)
    return np.where(x[..., 2] < x[..., 3], like, -np.inf)


def test_tempered_relabel_move_joins_the_two_labellings_with_their_exact_weights():
    """With the relabel move among the tempered ensemble's moves, the weaker bias is the faster
    one in 2.5 / 3 of the draws (within 0.04; 4 000 steps) from a start where it is the slower
    one in every walker, the order holding at every step; the same on the coldest ensemble alone
    (a ladder of one temperature). There, without the relabel move (the same start, the same
    steps), the share stays far from it (below 0.5): the relabel move, not only the hotter
    ensembles, joins the labellings, and with the right weights."""
    target = _BoxTarget(_weak_and_strong, [-8, -8, 0, 0], [8, 8, 3, 3])
    rng = np.random.default_rng(2)
    variances = np.column_stack([2 + 0.1 * rng.standard_normal(32),  # the first is stronger
                                 -2 + 0.1 * rng.standard_normal(32)])
    start = np.column_stack([variances, 2.5 + 0.02 * rng.standard_normal(32),
                             rng.uniform(2.6, 3.0, 32)])
    relabel = ([0, 1], [2, 3], (0.0, 3.0))
    shares = {}
    for name, exchangeable, ladder in (("tempered", relabel, LADDER), ("cold", relabel, (1.0,)),
                                       ("cold, no relabel", None, (1.0,))):
        sampler = TemperedEnsemble(target, start, np.random.default_rng(3), exchangeable,
                                   ladder=ladder, capacity=4000)
        sampler.run(4000)
        chain = sampler.get_chain(discard=1000)
        assert np.all(chain[..., 2] < chain[..., 3])
        shares[name] = np.mean(chain[..., 0] < chain[..., 1])
    assert abs(shares["tempered"] - 2.5 / 3.0) < 0.04
    assert abs(shares["cold"] - 2.5 / 3.0) < 0.04
    assert shares["cold, no relabel"] < 0.5


def test_a_ladder_must_start_at_one_and_fall():
    target = _BoxTarget(_gaussian([1.0]), [-5], [5])
    start = np.linspace(-1, 1, 8)[:, None]
    rng = np.random.default_rng(0)
    for ladder in [(0.9, 0.5), (1.0, 1.0), (1.0, 0.5, 0.0), (1.0, 0.3, 0.5)]:
        with pytest.raises(ValueError, match="ladder"):
            TemperedEnsemble(target, start, rng, ladder=ladder)
    with pytest.raises(ValueError, match="walkers"):
        TemperedEnsemble(target, start[:5], rng)
    with pytest.raises(ValueError, match="inside"):
        TemperedEnsemble(target, start + 10, rng)


def test_a_start_outside_the_posterior_moves_in_and_the_stored_log_posterior_is_right():
    """A first walker outside the prior box (as emcee allows): it moves in, and every stored log
    posterior is the target's (the prior's constant taken from a walker inside, not -inf)."""
    target = _BoxTarget(_gaussian([1.0, 1.0]), [-5, -5], [5, 5])
    rng = np.random.default_rng(6)
    start = rng.standard_normal((8, 2))
    start[0] = [9.0, 0.0]
    sampler = TemperedEnsemble(target, start, rng, capacity=500)
    sampler.run(500)
    chain, log_prob = sampler.get_chain(discard=250), sampler.get_log_prob(discard=250)
    assert np.all(np.isfinite(log_prob))
    np.testing.assert_allclose(log_prob, target(chain.reshape(-1, 2)).reshape(log_prob.shape),
                               rtol=1e-12)


def _ar1_walkers(rng, steps, walkers, phi):
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -phi], rng.standard_normal((steps, walkers, 2)), axis=0)


def test_the_walkers_mean_keeps_its_autocorrelation_when_states_move_between_walkers():
    """AR(1) walkers (phi = 0.8: integrated time (1 + phi) / (1 - phi) = 9 exactly), 20 000 steps of
    32. Independent walkers: the walkers' own time is 9 (10%: 32 series averaged) and their mean's
    too (30%: one series, its estimate's spread ~8%), and the ESS of the mean is steps x walkers / 9
    (30%). The same draws with the walkers' states shuffled between walkers at every step (what
    swaps do): each walker's series looks independent (its own time below 2, an ESS from it 4.5
    times too large) while the mean's ESS is still steps x walkers / 9. Walkers that are one chain
    copied: the mean's ESS is steps / 9, not 32 times that."""
    rng = np.random.default_rng(4)
    phi, steps, walkers = 0.8, 20000, 32
    chain = _ar1_walkers(rng, steps, walkers, phi)
    exact = (1 + phi) / (1 - phi)
    np.testing.assert_allclose(autocorr_time(chain), exact, rtol=0.1)
    np.testing.assert_allclose(ensemble_mean_autocorr_time(chain), exact, rtol=0.3)
    np.testing.assert_allclose(ensemble_mean_ess(chain), steps * walkers / exact, rtol=0.3)
    shuffled = np.take_along_axis(chain, np.argsort(rng.random((steps, walkers, 1)), axis=1), 1)
    assert np.all(autocorr_time(shuffled) < 2.0)
    np.testing.assert_allclose(ensemble_mean_ess(shuffled), steps * walkers / exact, rtol=0.3)
    copies = np.repeat(chain[:, :1], walkers, axis=1)
    np.testing.assert_allclose(ensemble_mean_ess(copies), steps / exact, rtol=0.3)


def _jump_proposal():
    """A deliberately poor proposal for :func:`_two_regions`: weights 0.3 and 0.7 where the
    posterior's are 0.9 and 0.1, locations 0.3 off and spreads 1.5x, so that only the Hastings
    factor makes the draws right."""
    from bayes_imu.inference.mixture_proposal import StudentMixture

    locs = np.array([[-2.2, 0.3, 0.0], [2.8, 0.0, -0.3]])
    shapes = np.array([np.diag([0.36, 2.25, 2.25])] * 2)
    return StudentMixture([0.3, 0.7], locs, shapes)


def test_the_jump_move_crosses_a_barrier_with_the_posteriors_exact_weights():
    """One temperature (no swaps) and every walker in the large region: the local moves cannot
    cross the 19.5-nat barrier (test above), so every crossing is the jump move's (on half the
    steps). With a proposal whose weights, locations and spreads are all wrong, the draws still
    put 0.1 in the small region (within 0.025 over 4 000 steps, 500 dropped; 0.098-0.099 at two
    seeds) and keep each region's standard deviation 0.4 in x0 and 1 in x1 (within 5%; 1% off at
    most): the Metropolis-Hastings factor q(x) / q(y) at work. Without it (a mutation tried by
    hand) the share is 0.19-0.20 and the standard deviations 10-15% low."""
    target = _BoxTarget(_two_regions, [-10, -10, -10], [10, 10, 10])
    rng = np.random.default_rng(11)
    start = np.column_stack([-2.5 + 0.4 * rng.standard_normal(32),
                             rng.standard_normal((32, 2))])
    sampler = TemperedEnsemble(target, start, np.random.default_rng(12), ladder=(1.0,),
                               capacity=10)
    sampler.add_jump(_jump_proposal(), 0.5)
    sampler.run(4000)
    x = sampler.get_chain(discard=500).reshape(-1, 3)
    small = x[:, 0] > 0
    assert abs(small.mean() - 0.1) < 0.025
    for region in (small, ~small):
        np.testing.assert_allclose(x[region, 0].std(), 0.4, rtol=0.05)
        np.testing.assert_allclose(x[region, 1].std(), 1.0, rtol=0.05)
    assert 0.05 < sampler.jump_acceptance < 1.0


def test_adding_the_jump_move_drops_the_stored_steps_and_keeps_the_states():
    """add_jump: the steps stored so far are dropped (iteration 0, counters reset), every
    temperature's walkers and log likelihoods kept; a second call replaces the proposal and keeps
    the move's share; a share outside (0, 1) is refused. Before the move is tried its acceptance
    is NaN."""
    target = _BoxTarget(_two_regions, [-10, -10, -10], [10, 10, 10])
    rng = np.random.default_rng(13)
    start = np.column_stack([-2.5 + 0.4 * rng.standard_normal(8), rng.standard_normal((8, 2))])
    sampler = TemperedEnsemble(target, start, np.random.default_rng(14), capacity=10)
    sampler.run(50)
    coords, like = sampler.coords.copy(), sampler.log_like.copy()
    with pytest.raises(ValueError, match="share"):
        sampler.add_jump(_jump_proposal(), 1.0)
    sampler.add_jump(_jump_proposal(), 0.3)
    assert sampler.iteration == 0 and sampler.get_chain().shape[0] == 0
    assert np.isnan(sampler.jump_acceptance)
    assert not sampler.accepted.any() and not sampler.tried.any()
    np.testing.assert_array_equal(sampler.coords, coords)
    np.testing.assert_array_equal(sampler.log_like, like)
    cdf = sampler._cdf.copy()
    assert cdf[-1] == 1.0 and cdf[-1] - cdf[-2] == pytest.approx(0.3)
    sampler.run(20)
    other = _jump_proposal()
    sampler.add_jump(other, 0.5)
    assert sampler.jump is other and sampler.iteration == 0
    # the new share, the local moves' shares 0.8 : 0.2 as before it
    np.testing.assert_allclose(np.diff(sampler._cdf, prepend=0.0), [0.4, 0.1, 0.0, 0.5])
    np.testing.assert_allclose(np.diff(cdf, prepend=0.0), [0.56, 0.14, 0.0, 0.3])


def test_the_jump_move_takes_its_share_from_the_relabel_move_too():
    """With exchangeable biases the moves' shares are 0.8 x 0.9, 0.2 x 0.9 and RELABEL_SHARE 0.1;
    the jump move's 0.3 takes 30% of each (0.504, 0.126, 0.07, 0.3), and over 2 000 steps each
    move runs on its share of the steps (within 0.03)."""
    from bayes_imu.inference.sampling import RELABEL_SHARE

    assert RELABEL_SHARE == 0.1
    rng = np.random.default_rng(15)
    start = np.column_stack([rng.normal(-2, 0.1, 8), rng.normal(2, 0.1, 8),
                             rng.uniform(0, 2.4, 8), rng.normal(2.5, 0.02, 8)])
    target = _BoxTarget(_weak_and_strong, [-5, -5, 0, 0], [5, 5, 3, 3])
    sampler = TemperedEnsemble(target, start, np.random.default_rng(16),
                               exchangeable=([0, 1], [2, 3], (0.0, 3.0)), capacity=10)
    q = _start_proposal(start)
    sampler.add_jump(q, 0.3)
    np.testing.assert_allclose(np.diff(sampler._cdf, prepend=0.0), [0.504, 0.126, 0.07, 0.3])
    counts = np.zeros(4)
    for name, k in (("_red_blue_step", None), ("_relabel_step", 2), ("_jump_step", 3)):
        original = getattr(sampler, name)

        def counted(*args, _k=k, _original=original, **kwargs):
            counts[_k if _k is not None else (1 if kwargs.get("stretch") else 0)] += 1
            return _original(*args, **kwargs)

        setattr(sampler, name, counted)
    sampler.run(2000)
    np.testing.assert_allclose(counts / 2000, [0.504, 0.126, 0.07, 0.3], atol=0.03)


def _start_proposal(start):
    """A one-component proposal about ``start``'s mean, its covariance (plus 0.01) its shape."""
    from bayes_imu.inference.mixture_proposal import StudentMixture

    shape = np.cov(start.T) + 0.01 * np.eye(start.shape[1])
    return StudentMixture([1.0], start.mean(axis=0)[None], shape[None])
