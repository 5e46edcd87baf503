"""The emcee ensemble shared by the fit and the population fit: seeded from the caller's Generator
(same seed, same chain; no global state), the stopping rule and the burn-in / thinning."""

from pathlib import Path

import numpy as np
import pytest

from bayes_imu.inference.sampling import (
    AUTOCORR_MULTIPLE,
    burn_and_thin,
    ensemble_sampler,
    long_enough,
)


def _normal(theta):
    return -0.5 * np.sum(np.atleast_2d(theta) ** 2, axis=1)


def test_same_generator_seed_same_chain_and_no_global_state():
    state = np.random.get_state()
    chains = []
    for _ in range(2):
        rng = np.random.default_rng(5)
        start = rng.standard_normal((16, 3))
        sampler = ensemble_sampler(_normal, start, rng)
        sampler.run_mcmc(start, 200, progress=False)
        chains.append(sampler.get_chain())
    np.testing.assert_array_equal(chains[0], chains[1])
    assert np.all(np.abs(chains[0][100:].reshape(-1, 3).mean(axis=0)) < 0.3)  # it samples N(0, 1)
    np.testing.assert_array_equal(np.random.get_state()[1], state[1])


def _emcee_own(target, start, rng):
    """The same ensemble from emcee's own classes (the reference of the lean ones)."""
    import emcee

    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]
    sampler = emcee.EnsembleSampler(
        start.shape[0], start.shape[1], target, vectorize=True, moves=moves
    )
    sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
    return sampler


def _banana(theta):
    """A curved, bounded target (-inf outside a box): acceptances and rejections of both kinds."""
    theta = np.atleast_2d(theta)
    x, y = theta[:, 0], theta[:, 1]
    out = -0.5 * (x**2 + 10.0 * (y - 0.3 * x**2) ** 2 + np.sum(theta[:, 2:] ** 2, axis=1))
    return np.where(np.all(np.abs(theta) < 4.0, axis=1), out, -np.inf)


def test_lean_sampler_gives_emcees_own_chains_bit_for_bit_across_chunks():
    """ensemble_sampler's classes (no random-state copies, whole-half acceptance, vectorised log
    densities) against emcee's EnsembleSampler, DEMove and StretchMove on the same seed: the same
    chain, log densities and acceptances, bit for bit, also when the run is resumed from its last
    state in chunks (as the fit does: emcee would set its generator back to the state saved in that
    last state)."""
    chains = []
    for make in (ensemble_sampler, _emcee_own):
        rng = np.random.default_rng(11)
        start = 0.1 * rng.standard_normal((16, 4))
        sampler = make(_banana, start, rng)
        state = start
        for chunk in (150, 100, 250):
            state = sampler.run_mcmc(state, chunk, progress=False)
        chains.append(
            (sampler.get_chain(), sampler.get_log_prob(), sampler.backend.accepted.copy())
        )
    lean, own = chains
    for a, b in zip(lean, own):
        np.testing.assert_array_equal(a, b)
    assert 0.1 < np.mean(own[2]) / 500 < 0.9  # proposals both accepted and rejected


def test_lean_moves_in_emcees_own_loop_give_emcees_own_chains_bit_for_bit():
    """Asked for emcee's own loop (a keyword argument: ``thin_by``), the lean sampler runs emcee's
    ``sample``, which calls each move's ``propose`` (the in-place step on the State's arrays): the
    same chain, log densities and acceptances as emcee's own classes, bit for bit."""
    chains = []
    for make in (ensemble_sampler, _emcee_own):
        rng = np.random.default_rng(7)
        start = 0.1 * rng.standard_normal((16, 4))
        sampler = make(_banana, start, rng)
        state = sampler.run_mcmc(start, 150, progress=False, thin_by=1)
        sampler.run_mcmc(state, 100, progress=False, thin_by=1)
        chains.append(
            (sampler.get_chain(), sampler.get_log_prob(), sampler.backend.accepted.copy())
        )
    for a, b in zip(*chains):
        np.testing.assert_array_equal(a, b)
    assert 0.1 < np.mean(chains[1][2]) / 250 < 0.9


def test_lean_sampler_with_a_metropolis_move_gives_emcees_own_chains_bit_for_bit():
    """With the independence move on 30% of the steps (a Metropolis-Hastings move the lean loop
    hands a State, between red-blue steps it runs on the walkers' arrays in place): the same chain,
    log densities and acceptances as emcee's own sampler and moves with the same weights, bit for
    bit, across resumed chunks."""
    import emcee

    from bayes_imu.inference.sampling import INDEPENDENCE_SHARE, StudentProposal, independence_move

    proposal = StudentProposal(np.zeros(4), 0.3 * np.eye(4))
    runs = []
    for lean in (True, False):
        rng = np.random.default_rng(3)
        start = 0.1 * rng.standard_normal((16, 4))
        if lean:
            sampler = ensemble_sampler(_banana, start, rng, independence=proposal)
        else:
            local = 1.0 - INDEPENDENCE_SHARE
            moves = [(emcee.moves.DEMove(), 0.8 * local), (emcee.moves.StretchMove(), 0.2 * local),
                     (independence_move(proposal), INDEPENDENCE_SHARE)]
            sampler = emcee.EnsembleSampler(16, 4, _banana, vectorize=True, moves=moves)
            sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
        state = start
        for chunk in (150, 100, 250):
            state = sampler.run_mcmc(state, chunk, progress=False)
        runs.append((sampler.get_chain(), sampler.get_log_prob(), sampler.backend.accepted.copy()))
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
    assert 0.1 < np.mean(runs[1][2]) / 500 < 0.9


def test_lean_sampler_keeps_a_float32_start_as_emcee_does():
    """A float32 start stays float32 (every update rounded into it, as emcee's State does): the
    same chain as emcee's own classes, bit for bit."""
    chains = []
    for make in (ensemble_sampler, _emcee_own):
        rng = np.random.default_rng(2)
        start = (0.1 * rng.standard_normal((16, 4))).astype(np.float32)
        sampler = make(_banana, start, rng)
        state = sampler.run_mcmc(start, 120, progress=False)
        chains.append((sampler.get_chain(), sampler.get_log_prob(), state.coords.dtype))
    np.testing.assert_array_equal(chains[0][0], chains[1][0])
    np.testing.assert_array_equal(chains[0][1], chains[1][1])
    assert chains[0][2] == chains[1][2] == np.float32


def test_lean_sampler_keeps_emcees_errors():
    import pytest

    rng = np.random.default_rng(0)
    start = rng.standard_normal((8, 2))
    sampler = ensemble_sampler(
        lambda theta: np.full(np.atleast_2d(theta).shape[0], np.nan), start, rng
    )
    with pytest.raises(ValueError, match="NaN"):
        sampler.run_mcmc(start, 2, progress=False)
    start[0, 0] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        ensemble_sampler(_normal, start, rng).compute_log_prob(start)


def test_stopping_rule_and_thinning():
    assert AUTOCORR_MULTIPLE == 50
    # 50 autocorrelation times
    assert long_enough(500, 10.0, 10.4) and not long_enough(499, 10.0, 10.4)
    assert not long_enough(1000, 10.0, 11.0)  # the estimate moved by 10%: not settled
    assert (
        burn_and_thin(10.0) == (30, 5)
        and burn_and_thin(10.2) == (31, 5)
        and burn_and_thin(1.5) == (5, 1)
    )
    # a chain far longer than its autocorrelation times keeps at most MAX_KEPT_PER_WALKER draws a
    # walker (emcee keeps floor((n - burn) / thin) of them), thinned more; a shorter one as above
    from bayes_imu.inference.sampling import MAX_KEPT_PER_WALKER

    assert MAX_KEPT_PER_WALKER == 200
    assert burn_and_thin(10.0, 500) == (30, 5)
    assert burn_and_thin(10.0, 1034) == (30, 5)  # 1 004 // 5: exactly 200 draws
    assert burn_and_thin(10.0, 1035) == (30, 6)  # 201 at a thin of 5: 167 at 6
    for tau, n in ((6.9, 8250), (3.0, 40000), (40.0, 9000), (1.2, 777)):
        burn, thin = burn_and_thin(tau, n)
        kept = (n - burn) // thin
        assert burn == int(np.ceil(3 * tau)) and thin >= max(1, int(tau / 2))
        # at most 200, and the least thinning that keeps at most 200
        assert kept <= 200 and (thin == max(1, int(tau / 2)) or (n - burn) // (thin - 1) > 200)


def test_autocorr_time_is_emcees_and_that_of_an_ar1_chain():
    """Per parameter, emcee's integrated_time (tol=0) to 1e-13 (real instead of complex FFTs), on
    chains of lengths that are and are not powers of two; and for AR(1) walkers, phi = 0.8, the
    exact integrated time (1 + phi) / (1 - phi) = 9 within 10% (32 walkers x 20000 steps: the
    estimate's spread is ~2%)."""
    from emcee.autocorr import integrated_time
    from scipy.signal import lfilter

    from bayes_imu.inference.sampling import autocorr_time

    rng = np.random.default_rng(11)
    phi = 0.8
    for n_t in (250, 256, 1000, 20000):
        noise = rng.standard_normal((n_t, 32, 3)) * np.array([1.0, 1e-3, 50.0])
        chain = lfilter([1.0], [1.0, -phi], noise, axis=0)
        chain[:, :, 2] += 7.0 * np.arange(n_t)[:, None] / n_t  # a drifting parameter too
        ours = autocorr_time(chain)
        np.testing.assert_allclose(ours, integrated_time(chain, tol=0), rtol=1e-13)
    np.testing.assert_allclose(ours[:2], (1 + phi) / (1 - phi), rtol=0.1)


def test_autocorr_time_matches_the_per_walker_transforms(rng):
    """The rewrites of :func:`autocorr_time` (a 5-smooth padded length, spectra summed over walkers
    before one inverse transform) give the per-walker computation written out here (each walker's
    series alone, padded to twice the next power of two as emcee pads, transformed forward and
    back, normalised by its own lag-0 value): equal to 1e-13 relative on chains of several lengths
    (a power of two and not, odd and prime), and the average keeps walkers of very different scale
    apart (each normalised alone)."""
    from emcee.autocorr import auto_window

    from bayes_imu.inference.sampling import autocorr_time

    for n_t in (250, 1000, 3001, 4099):
        chain = np.cumsum(rng.standard_normal((n_t, 16, 3)), axis=0) * 0.05 + rng.standard_normal(
            (n_t, 16, 3)
        )
        chain[:, :8, 1] *= 1e4  # half the walkers of one parameter on another scale
        size = 2
        while size < 2 * n_t:  # emcee's padding (a power of two)
            size <<= 1
        expected = []
        for d in range(3):
            total = np.zeros(n_t)
            for k in range(16):
                x = chain[:, k, d]
                f = np.fft.rfft(x - np.mean(x), n=size)
                acf = np.fft.irfft(f.real * f.real + f.imag * f.imag, n=size)[:n_t]
                total += acf / acf[0]
            taus = 2.0 * np.cumsum(total / 16) - 1.0
            expected.append(taus[auto_window(taus, 5)])
        np.testing.assert_allclose(autocorr_time(chain), expected, rtol=1e-13)


def test_fft_length_is_the_smallest_5_smooth_number_at_least_n():
    """:func:`fft_length` against a scan of the integers from ``n`` up for the first whose only
    prime factors are 2, 3 and 5, for every ``n`` below 3000 and at chain lengths of a fit."""
    from bayes_imu.inference.sampling import fft_length

    def smooth(k):
        for p in (2, 3, 5):
            while k % p == 0:
                k //= p
        return k == 1

    def scan(n):
        k = max(int(n), 1)
        while not smooth(k):
            k += 1
        return k

    for n in list(range(0, 3000)) + [80_000, 80_001, 73_000, 2 * 36_500 + 1, 131_073]:
        assert fft_length(n) == scan(n), n


def test_long_chains_are_checked_at_a_tenth_of_their_length():
    """Every 250 steps below GEOMETRIC_FROM (the schedule of every shorter chain, unchanged), a
    tenth of the chain (a multiple of 250) beyond it: a 40 000-step run is checked 54 times instead
    of 160, and a chain that settles runs at most 10% (plus one chunk) longer."""
    from bayes_imu.inference.sampling import GEOMETRIC_FROM, steps_to_next_check

    assert [steps_to_next_check(n, 250) for n in (0, 250, GEOMETRIC_FROM - 250)] == [250, 250, 250]
    assert (
        steps_to_next_check(GEOMETRIC_FROM, 250) == 1000
        and steps_to_next_check(12_345, 250) == 1250
    )
    iteration, checks = 0, 0
    while iteration < 40_000:
        step = min(steps_to_next_check(iteration, 250), 40_000 - iteration)
        assert step % 250 == 0 and step <= max(250, 0.1 * iteration + 250)
        iteration += step
        checks += 1
    assert iteration == 40_000 and checks == 54


def test_no_check_before_the_chain_could_stop():
    """Given the autocorrelation time ``tau`` of the last check, the next one is not before
    ``0.9 x 50 tau`` steps (a multiple of 250), at most doubling the chain; short chains
    (``tau`` <= 11 steps) and the schedule without ``tau`` are as before. With a constant
    estimate, a chain reaches 50 ``tau`` at most 10% (plus one chunk) later than with the schedule
    before, and with fewer checks."""
    from bayes_imu.inference.sampling import GEOMETRIC_FROM, steps_to_next_check

    for n in range(250, GEOMETRIC_FROM, 250):
        assert steps_to_next_check(n, 250, 11.0) == steps_to_next_check(n, 250) == 250
        assert steps_to_next_check(n, 250, np.inf) == 250  # no estimate yet
    assert steps_to_next_check(2000, 250, 400.0) == 2000  # doubling at most
    assert steps_to_next_check(8000, 250, 400.0) == 8000
    assert steps_to_next_check(16_000, 250, 400.0) == 2000  # to 0.9 x 50 x 400 = 18 000
    assert steps_to_next_check(18_000, 250, 400.0) == 2000  # then a tenth, up to 250s
    for tau in (12.0, 30.0, 100.0, 400.0, 1000.0):
        reached = {}
        for with_tau in (False, True):
            iteration, checks = 0, 0
            while iteration < 50 * tau:
                iteration += steps_to_next_check(iteration, 250, tau if with_tau and iteration
                                                 else None)
                checks += 1
            reached[with_tau] = (iteration, checks)
        assert reached[True][0] <= 1.1 * 50 * tau + 250, (tau, reached)
        assert reached[True][1] <= reached[False][1], (tau, reached)
    assert reached[True][1] < reached[False][1] / 3  # tau = 1000: 50 checks before


def _two_biases(theta):
    """Ordered target of two exchangeable biases: columns (other, v1, t1, v2, t2), each bias with
    density N(v; 0, 1) exp(-t) on 0 <= t <= 3, the time constants increasing (t1 < t2)."""
    theta = np.atleast_2d(theta)
    v, t = theta[:, [1, 3]], theta[:, [2, 4]]
    out = -0.5 * theta[:, 0] ** 2 - 0.5 * np.sum(v * v, axis=1) - np.sum(t, axis=1)
    inside = np.all((t >= 0.0) & (t <= 3.0), axis=1) & (t[:, 0] < t[:, 1])
    return np.where(inside, out, -np.inf)


def test_relabel_move_leaves_the_ordered_posterior_of_exchangeable_biases_invariant():
    """The relabel move alone (no other move: the variances and the stronger bias's time constant
    never change) must give the weaker bias's time constant its exact marginal, the truncated
    exponential on [0, 3] (Kolmogorov-Smirnov against the exact CDF, and the mean within 5 standard
    errors), whichever side of the stronger one it lands; the weaker bias must be the faster one
    (first column) with the exact probability H(t_strong) on average (5 standard errors), and the
    ordering must always hold."""
    from scipy import stats

    from bayes_imu.inference.sampling import import_emcee, relabel_move

    emcee = import_emcee()
    rng = np.random.default_rng(3)
    n = 4000
    start = np.column_stack(
        [
            rng.standard_normal(n),
            rng.standard_normal(n),
            rng.uniform(0.0, 1.0, n),
            rng.standard_normal(n),
            rng.uniform(2.0, 3.0, n),
        ]
    )
    sampler = emcee.EnsembleSampler(n, 5, _two_biases, vectorize=True,
                                    moves=[relabel_move([1, 3], [2, 4], (0.0, 3.0))])
    sampler.random_state = np.random.RandomState(4).get_state()
    sampler.run_mcmc(start, 40, progress=False)
    chain = sampler.get_chain()
    assert np.all(chain[:, :, 2] < chain[:, :, 4])
    end = chain[-1]
    weak_first = end[:, 1] < end[:, 3]
    t_weak = np.where(weak_first, end[:, 2], end[:, 4])
    t_strong = np.where(weak_first, end[:, 4], end[:, 2])
    np.testing.assert_array_equal(
        np.minimum(end[:, 1], end[:, 3]), np.minimum(start[:, 1], start[:, 3])
    )

    def cdf(t):
        return -np.expm1(-np.clip(t, 0.0, 3.0)) / -np.expm1(-3.0)

    mean = 1.0 - 3.0 * np.exp(-3.0) / -np.expm1(-3.0)
    assert stats.kstest(t_weak, cdf).pvalue > 1e-3
    assert abs(t_weak.mean() - mean) < 5 * t_weak.std() / np.sqrt(n)
    assert abs(np.mean(weak_first - cdf(t_strong))) < 5 * 0.5 / np.sqrt(n)


def test_ensemble_sampler_adds_the_relabel_move_only_for_exchangeable_biases():
    """With two exchangeable biases the ensemble runs differential evolution, stretch and relabel
    moves (shares 0.72, 0.18, 0.10) and samples the ordered target (every draw ordered, the weaker
    bias's mean time constant within 0.1 of the exact 0.843); without, the moves and chain are as
    before."""
    from bayes_imu.inference.sampling import RELABEL_SHARE

    rng = np.random.default_rng(6)
    start = np.column_stack(
        [
            rng.standard_normal((32, 2)),
            rng.uniform(0.0, 1.0, 32),
            rng.standard_normal(32),
            rng.uniform(2.0, 3.0, 32),
        ]
    )
    plain = ensemble_sampler(_two_biases, start, np.random.default_rng(1))
    assert len(plain._moves) == 2
    sampler = ensemble_sampler(
        _two_biases, start, np.random.default_rng(1), ([1, 3], [2, 4], (0.0, 3.0))
    )
    np.testing.assert_allclose(
        sampler._weights, [0.8 * (1 - RELABEL_SHARE), 0.2 * (1 - RELABEL_SHARE), RELABEL_SHARE]
    )
    sampler.run_mcmc(start, 3000, progress=False)
    chain = sampler.get_chain(discard=500).reshape(-1, 5)
    assert np.all(chain[:, 2] < chain[:, 4])
    t_weak = np.where(chain[:, 1] < chain[:, 3], chain[:, 2], chain[:, 4])
    assert abs(t_weak.mean() - (1.0 - 3.0 * np.exp(-3.0) / -np.expm1(-3.0))) < 0.1


@pytest.mark.parametrize(
    "coords, density, message",
    [
        ([[0.0, np.inf], [0.0, 1.0]], None, "infinite"),
        ([[0.0, -np.inf], [np.nan, 1.0]], None, "infinite"),
        ([[0.0, np.nan], [0.0, 1.0]], None, "NaN"),
        ([[0.0, 1.0], [0.0, 1.0]], np.nan, "returned NaN"),
    ],
)
def test_lean_sampler_refuses_what_emcee_refuses_with_its_message(coords, density, message):
    """The lean sampler's vectorised log-probability check raises emcee's own ValueError, with its
    message, for infinite and NaN coordinates (infinite first, as emcee checks) and a NaN
    density."""
    from bayes_imu.inference.sampling import _lean_classes, import_emcee

    emcee = import_emcee()
    sampler_class = _lean_classes(emcee)[0]

    def log_prob(x):
        return np.full(len(x), 0.0 if density is None else density)

    coords = np.array(coords)
    with pytest.raises(ValueError) as ours:
        sampler_class(4, 2, log_prob, vectorize=True).compute_log_prob(coords)
    with pytest.raises(ValueError) as theirs:
        emcee.EnsembleSampler(4, 2, log_prob, vectorize=True).compute_log_prob(coords)
    assert message in str(theirs.value) and str(ours.value) == str(theirs.value)


def test_reserved_chain_storage_keeps_the_chain_and_grows_past_its_capacity():
    """A backend reserved for ``capacity`` steps (no copy of the chain at each run) stores the same
    chain, log densities and acceptances, bit for bit, as emcee's growing one: with room to spare,
    and with a capacity the run outgrows (emcee's growth from there)."""
    runs = []
    for capacity in (None, 1000, 200):
        rng = np.random.default_rng(5)
        start = 0.1 * rng.standard_normal((16, 4))
        sampler = ensemble_sampler(_banana, start, rng, capacity=capacity)
        state = start
        for chunk in (150, 100, 250):
            state = sampler.run_mcmc(state, chunk, progress=False)
        runs.append((sampler.get_chain(), sampler.get_log_prob(), sampler.backend.accepted.copy()))
        assert sampler.iteration == 500 and len(sampler.backend.chain) == max(500, capacity or 0)
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            np.testing.assert_array_equal(a, b)


def _resident_bytes():
    """Resident memory of this process (bytes), from /proc (Linux)."""
    import os

    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs Linux's /proc")
def test_reserved_chain_storage_commits_only_the_steps_written():
    """The reservation is allocated, not copied: emcee's own growth concatenates the new storage
    onto the old, which writes (commits) every page of it before a step is taken. A capacity of
    100 000 steps of 32 walkers x 16 parameters reserves 410 MB; after 20 steps the process may
    have grown by far less (the bound, 100 MB, leaves room for what the run itself allocates; the
    concatenating growth adds all 410 MB and fails it)."""
    rng = np.random.default_rng(3)
    start = 0.1 * rng.standard_normal((32, 16))
    sampler = ensemble_sampler(lambda x: -0.5 * np.sum(x * x, axis=-1), start, rng,
                               capacity=100_000)
    before = _resident_bytes()
    sampler.run_mcmc(start, 20, progress=False)
    grown = _resident_bytes() - before
    assert len(sampler.backend.chain) == 100_000
    assert grown < 100e6, f"resident memory grew by {grown / 1e6:.0f} MB"


def _log_gamma_pair(x):
    """Log density of ``(log G, 0.5 log G + Z)``, ``G ~ Gamma(2)``, ``Z ~ N(0, 1)`` (a skewed,
    correlated target with exact marginals)."""
    x = np.atleast_2d(x)
    return 2.0 * x[:, 0] - np.exp(x[:, 0]) - 0.5 * (x[:, 1] - 0.5 * x[:, 0]) ** 2


def _log_gamma_pair_draws(rng, n):
    g = np.log(rng.gamma(2.0, size=n))
    return np.column_stack([g, 0.5 * g + rng.standard_normal(n)])


def test_student_proposal_density_is_scipys_up_to_a_constant_and_draws_follow_it():
    """:class:`StudentProposal`: its log density differs from scipy's multivariate t by one
    constant (to 1e-12) over points near and far; its draws (from a legacy RandomState, as emcee
    passes) have the t's covariance ``shape df / (df - 2)`` within 5% (40 000 draws), and a
    non-positive-definite shape is refused."""
    from scipy import stats

    from bayes_imu.inference.sampling import StudentProposal

    shape = np.array([[2.0, 0.6], [0.6, 0.5]])
    loc = np.array([0.3, -1.0])
    q = StudentProposal(loc, shape, 5.0)
    x = np.random.default_rng(0).standard_normal((50, 2)) * [1.0, 20.0]
    diff = q.log_density(x) - stats.multivariate_t(loc, shape, df=5.0).logpdf(x)
    np.testing.assert_allclose(diff, diff[0], rtol=0, atol=1e-12)
    draws = q.draw(40_000, np.random.RandomState(1))
    np.testing.assert_allclose(np.cov(draws.T), shape * 5.0 / 3.0, rtol=0.05, atol=0.02)
    with pytest.raises(ValueError, match="positive definite"):
        StudentProposal(loc, np.array([[1.0, 2.0], [2.0, 1.0]]))


def test_independence_acceptance_is_the_double_sum_and_one_for_the_exact_proposal():
    """The sorted O(n log n) estimate equals the direct double sum ``sum_i W_i mean_j min(1,
    w_j / w_i)`` (to 1e-12, ties included); a proposal equal to the target is always accepted
    (1); a target outside the proposal's reach gives 0."""
    from bayes_imu.inference.sampling import StudentProposal, independence_acceptance

    q = StudentProposal(np.zeros(2), np.eye(2), 4.0)
    y = q.draw(300, np.random.default_rng(5))  # the draws the estimate takes with seed 5
    w = np.exp(_log_gamma_pair(y) - q.log_density(y))
    w = np.maximum(np.round(w / w.max(), 2), 0.01)  # ties on purpose
    assert len(np.unique(w)) < w.size
    expected = float(np.sum(w * np.minimum(1.0, w[None, :] / w[:, None]).mean(axis=1)) / w.sum())
    got = independence_acceptance(lambda x: np.log(w) + q.log_density(x), q, 300,
                                  np.random.default_rng(5))
    assert got == pytest.approx(expected, rel=0, abs=1e-12)
    assert independence_acceptance(q.log_density, q, 500, np.random.default_rng(1)) == 1.0
    assert independence_acceptance(lambda y: np.full(len(y), -np.inf), q, 50,
                                   np.random.default_rng(1)) == 0.0


def test_independence_move_leaves_a_skewed_correlated_target_invariant():
    """The independence move alone, with a mis-centred and mis-scaled t proposal, started from
    4000 exact draws of the target: after 40 steps (about 25 accepted per walker) the first
    coordinate still has the exact log-gamma(2) law and ``x2 - x1 / 2`` the standard normal
    (Kolmogorov-Smirnov p > 1e-3, means within 5 standard errors). Leaving out the proposal's
    density ratio (a symmetric-proposal Metropolis rule) fails this test: its stationary law is
    ``p q`` normalised, not ``p``. The walkers' acceptance agrees with
    :func:`independence_acceptance` within 0.02."""
    from scipy import special, stats

    from bayes_imu.inference.sampling import (
        StudentProposal,
        import_emcee,
        independence_acceptance,
        independence_move,
    )

    emcee = import_emcee()
    rng = np.random.default_rng(7)
    n = 4000
    q = StudentProposal(np.array([1.0, 0.0]), np.array([[1.5, 0.3], [0.3, 2.0]]), 5.0)
    sampler = emcee.EnsembleSampler(n, 2, _log_gamma_pair, vectorize=True,
                                    moves=[independence_move(q)])
    sampler.random_state = np.random.RandomState(8).get_state()
    sampler.run_mcmc(_log_gamma_pair_draws(rng, n), 40, progress=False)
    end = sampler.get_chain()[-1]
    log_g, z = end[:, 0], end[:, 1] - 0.5 * end[:, 0]
    assert stats.kstest(log_g, lambda x: special.gammainc(2.0, np.exp(x))).pvalue > 1e-3
    assert stats.kstest(z, "norm").pvalue > 1e-3
    mean_log_g = special.digamma(2.0)
    assert abs(log_g.mean() - mean_log_g) < 5 * np.sqrt(special.polygamma(1, 2.0) / n)
    assert abs(z.mean()) < 5 / np.sqrt(n)
    accept = float(np.mean(sampler.acceptance_fraction))
    expected = independence_acceptance(_log_gamma_pair, q, 40_000, np.random.default_rng(9))
    assert 0.1 < expected < 0.9 and abs(accept - expected) < 0.02


def test_ensemble_sampler_shares_with_the_independence_move():
    """With a proposal the independence move takes :data:`INDEPENDENCE_SHARE` of the steps from
    the differential-evolution and stretch moves (the relabel move keeps its share), last in the
    list: the other moves keep their order, so a sampler without the proposal draws as before."""
    from bayes_imu.inference.sampling import (
        INDEPENDENCE_SHARE as S,
        RELABEL_SHARE as R,
        StudentProposal,
    )

    rng = np.random.default_rng(6)
    start = np.column_stack([rng.standard_normal((32, 2)), rng.uniform(0.0, 1.0, 32),
                             rng.standard_normal(32), rng.uniform(2.0, 3.0, 32)])
    q = StudentProposal(np.zeros(5), np.eye(5))
    alone = ensemble_sampler(_two_biases, start, np.random.default_rng(1), independence=q)
    np.testing.assert_allclose(alone._weights, [0.8 * (1 - S), 0.2 * (1 - S), S])
    both = ensemble_sampler(_two_biases, start, np.random.default_rng(1),
                            ([1, 3], [2, 4], (0.0, 3.0)), independence=q)
    np.testing.assert_allclose(
        both._weights,
        [0.8 * (1 - R) * (1 - S), 0.2 * (1 - R) * (1 - S), R, S * (1 - R)],
    )
