"""The emcee ensemble shared by the fit and the population fit: seeded from the caller's Generator
(same seed, same chain; no global state), the stopping rule and the burn-in / thinning."""

import numpy as np

from bayes_imu.inference.sampling import AUTOCORR_MULTIPLE, burn_and_thin, ensemble_sampler, long_enough


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


def test_stopping_rule_and_thinning():
    assert AUTOCORR_MULTIPLE == 50
    assert long_enough(500, 10.0, 10.4) and not long_enough(499, 10.0, 10.4)  # 50 autocorrelation times
    assert not long_enough(1000, 10.0, 11.0)  # the estimate moved by 10%: not settled
    assert burn_and_thin(10.0) == (30, 5) and burn_and_thin(10.2) == (31, 5) and burn_and_thin(1.5) == (5, 1)


def test_autocorr_time_is_emcees_and_that_of_an_ar1_chain():
    """Per parameter, emcee's integrated_time (tol=0) to 1e-13 (real instead of complex FFTs), on chains
    of lengths that are and are not powers of two; and for AR(1) walkers, phi = 0.8, the exact integrated
    time (1 + phi) / (1 - phi) = 9 within 10% (32 walkers x 20000 steps: the estimate's spread is ~2%)."""
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


def test_autocorr_time_transforms_walkers_together_with_the_same_bits(rng):
    """The walkers of a parameter are transformed together as contiguous rows: the same numbers, bit for bit,
    as transforming each walker's series alone (emcee's layout, written out here with real transforms), on
    chains of several lengths (a power of two and not)."""
    from emcee.autocorr import auto_window

    from bayes_imu.inference.sampling import autocorr_time

    for n_t in (250, 1000, 3001):
        chain = np.cumsum(rng.standard_normal((n_t, 16, 3)), axis=0) * 0.05 + rng.standard_normal((n_t, 16, 3))
        size = 2
        while size < 2 * n_t:
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
        np.testing.assert_array_equal(autocorr_time(chain), expected)


def test_long_chains_are_checked_at_a_tenth_of_their_length():
    """Every 250 steps below GEOMETRIC_FROM (the schedule of every shorter chain, unchanged), a tenth of the
    chain (a multiple of 250) beyond it: a 40 000-step run is checked 54 times instead of 160, and a chain that
    settles runs at most 10% (plus one chunk) longer."""
    from bayes_imu.inference.sampling import GEOMETRIC_FROM, steps_to_next_check

    assert [steps_to_next_check(n, 250) for n in (0, 250, GEOMETRIC_FROM - 250)] == [250, 250, 250]
    assert steps_to_next_check(GEOMETRIC_FROM, 250) == 1000 and steps_to_next_check(12_345, 250) == 1250
    iteration, checks = 0, 0
    while iteration < 40_000:
        step = min(steps_to_next_check(iteration, 250), 40_000 - iteration)
        assert step % 250 == 0 and step <= max(250, 0.1 * iteration + 250)
        iteration += step
        checks += 1
    assert iteration == 40_000 and checks == 54
