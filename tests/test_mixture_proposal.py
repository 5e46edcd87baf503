"""The jump move's proposal (:mod:`bayes_imu.inference.mixture_proposal`): its density against
scipy's multivariate t, its draws against the mixture's exact moments and CDF, and the fit's
recovery of a known Gaussian mixture."""

import numpy as np
import pytest

from bayes_imu.inference.mixture_proposal import (
    MIXTURE_DF,
    MIXTURE_INFLATE,
    StudentMixture,
    fit_student_mixture,
)

WEIGHTS = np.array([0.7, 0.3])
LOCS = np.array([[0.0, 1.0, -2.0], [3.0, -1.0, 0.5]])
SHAPES = np.array([
    [[1.0, 0.3, 0.0], [0.3, 0.5, 0.1], [0.0, 0.1, 2.0]],
    [[0.2, 0.0, 0.05], [0.0, 3.0, -0.4], [0.05, -0.4, 0.7]],
])


def _scipy_log_density(x, weights, locs, shapes, df):
    from scipy.special import logsumexp
    from scipy.stats import multivariate_t

    parts = [np.log(w) + multivariate_t(loc, shape, df=df).logpdf(x)
             for w, loc, shape in zip(weights, locs, shapes)]
    return logsumexp(parts, axis=0)


def test_log_density_is_scipys_mixture_of_multivariate_ts_up_to_one_constant():
    """Against scipy.stats.multivariate_t (an independent implementation): the log density differs
    from the normalised mixture's by the same constant at every point, to 1e-10, over points near
    each component and far in the tails. Components of different determinants and weights check
    their relative normalisation: dropping either would change the difference between points."""
    q = StudentMixture(WEIGHTS, LOCS, SHAPES, df=4.0)
    rng = np.random.default_rng(0)
    x = np.concatenate([LOCS[0] + rng.standard_normal((50, 3)),
                        LOCS[1] + rng.standard_normal((50, 3)),
                        20.0 * rng.standard_normal((20, 3))])
    diff = q.log_density(x) - _scipy_log_density(x, WEIGHTS, LOCS, SHAPES, 4.0)
    assert np.ptp(diff) < 1e-10
    # the components' relative weight matters: another weighting is not a constant away
    other = _scipy_log_density(x, WEIGHTS[::-1], LOCS, SHAPES, 4.0)
    assert np.ptp(q.log_density(x) - other) > 0.1


def test_draws_have_the_mixtures_exact_moments_and_marginal_cdf():
    """200 000 draws: their mean is sum w_k loc_k and their covariance sum w_k (shape_k df /
    (df - 2) + loc_k loc_k') - mean mean' (df = 5), to Monte Carlo tolerance (5 standard errors of
    the mean; 8% on the covariance, whose t-tailed estimate spreads ~2%), and the first
    coordinate passes a Kolmogorov-Smirnov test against the mixture of scipy's univariate t
    CDFs (loc_k0, sqrt(shape_k00)) at the 1e-3 level."""
    from scipy.stats import kstest, t

    df = 5.0
    q = StudentMixture(WEIGHTS, LOCS, SHAPES, df=df)
    x = q.draw(200_000, np.random.default_rng(1))
    mean = WEIGHTS @ LOCS
    cov = sum(w * (s * df / (df - 2) + np.outer(m, m)) for w, m, s in zip(WEIGHTS, LOCS, SHAPES))
    cov -= np.outer(mean, mean)
    se = np.sqrt(np.diag(cov) / x.shape[0])
    assert np.all(np.abs(x.mean(axis=0) - mean) < 5 * se)
    np.testing.assert_allclose(np.cov(x.T), cov, rtol=0.08, atol=0.02)

    def cdf(v):
        return sum(w * t.cdf(v, df, loc=m[0], scale=np.sqrt(s[0, 0]))
                   for w, m, s in zip(WEIGHTS, LOCS, SHAPES))

    assert kstest(x[:20_000, 0], cdf).pvalue > 1e-3


def test_the_fit_recovers_a_two_component_mixture_and_prefers_one_for_one_gaussian():
    """4 000 draws (MIXTURE_FIT_DRAWS: no subset) of a 3-D Gaussian mixture, 3 000 and 1 000 of
    its components (means 10 standard deviations apart): BIC picks two components, the weights
    within 0.03 (4 standard errors), each mean within 4 standard errors per coordinate and each
    covariance element within 4 of its standard errors sqrt((s_ii s_jj + s_ij^2) / n), times
    MIXTURE_INFLATE as the shape; MIXTURE_DF degrees of freedom. One Gaussian's draws give one
    component, its mean and covariance the draws' (to the floor, 1e-4 of a variance)."""
    from bayes_imu.inference.mixture_proposal import MIXTURE_FIT_DRAWS

    rng = np.random.default_rng(2)
    cov_a = np.diag([1.0, 0.25, 4.0])
    cov_b = np.array([[0.5, 0.2, 0.0], [0.2, 0.5, 0.0], [0.0, 0.0, 1.0]])
    mean_a, mean_b = np.zeros(3), np.array([10.0, 5.0, -20.0])
    n_a, n_b = 3000, 1000
    assert n_a + n_b == MIXTURE_FIT_DRAWS
    x = np.concatenate([rng.multivariate_normal(mean_a, cov_a, n_a),
                        rng.multivariate_normal(mean_b, cov_b, n_b)])
    rng.shuffle(x)
    q = fit_student_mixture(x, np.random.default_rng(3))
    assert q.n_components == 2 and q.df == MIXTURE_DF
    a = int(np.argmax(q.weights))
    b = 1 - a
    np.testing.assert_allclose(q.weights[[a, b]], [0.75, 0.25], atol=0.03)
    for k, mean, cov, n in ((a, mean_a, cov_a, n_a), (b, mean_b, cov_b, n_b)):
        d = np.diag(cov)
        assert np.all(np.abs(q.locs[k] - mean) < 4 * np.sqrt(d / n))
        se = np.sqrt((np.outer(d, d) + cov**2) / n)
        assert np.all(np.abs(q.shapes[k] / MIXTURE_INFLATE - cov) < 4 * se)

    one = rng.multivariate_normal(mean_a, cov_a, 4000)
    q1 = fit_student_mixture(one, np.random.default_rng(4))
    assert q1.n_components == 1
    np.testing.assert_allclose(q1.locs[0], one.mean(axis=0), atol=1e-9)
    np.testing.assert_allclose(q1.shapes[0], MIXTURE_INFLATE * np.cov(one.T, bias=True),
                               rtol=1e-3)


def test_a_long_pilot_is_subsampled_and_a_stuck_coordinate_keeps_a_shape():
    """A pilot longer than MIXTURE_FIT_DRAWS is fitted on a random subset of that many (one
    Gaussian's mean and covariance still recovered to sampling error). A coordinate the pilot
    never moved (every walker at one value) gets a shape of at least (1e-4 x its scale)^2 x
    MIXTURE_INFLATE, the floor, so the proposal is positive definite and its density finite
    there; weights are normalised to sum to 1 exactly (numpy's choice asks ~1e-8)."""
    from bayes_imu.inference.mixture_proposal import MIXTURE_FIT_DRAWS

    rng = np.random.default_rng(5)
    x = rng.standard_normal((3 * MIXTURE_FIT_DRAWS, 2)) * [1.0, 3.0] + [5.0, -1.0]
    q = fit_student_mixture(x, np.random.default_rng(6), max_components=1)
    np.testing.assert_allclose(q.locs[0], [5.0, -1.0], atol=5 * 3.0 / np.sqrt(MIXTURE_FIT_DRAWS))
    np.testing.assert_allclose(np.sqrt(np.diag(q.shapes[0]) / MIXTURE_INFLATE), [1.0, 3.0],
                               rtol=0.05)
    stuck = np.column_stack([rng.standard_normal(500), np.full(500, 2.0)])
    q = fit_student_mixture(stuck, np.random.default_rng(7), scale=np.array([10.0, 20.0]))
    assert np.all(np.linalg.eigvalsh(q.shapes) > 0)
    assert np.all(q.shapes[:, 1, 1] >= MIXTURE_INFLATE * (1e-4 * 20.0) ** 2)
    assert np.all(np.isfinite(q.log_density(stuck)))
    w = StudentMixture([0.5, 0.5 + 5e-6], LOCS, SHAPES).weights
    assert w.sum() == 1.0
    StudentMixture(w, LOCS, SHAPES).draw(10, np.random.default_rng(0))


def test_bad_mixtures_and_short_pilots_are_refused():
    with pytest.raises(ValueError, match="weights"):
        StudentMixture([0.5, 0.6], LOCS, SHAPES)
    with pytest.raises(ValueError, match="weights"):
        StudentMixture([1.0], LOCS, SHAPES)
    with pytest.raises(np.linalg.LinAlgError):
        StudentMixture([1.0], LOCS[:1], -SHAPES[:1])
    with pytest.raises(ValueError, match="pilot"):
        fit_student_mixture(np.zeros((4, 3)), np.random.default_rng(0))
    bad = np.random.default_rng(1).standard_normal((100, 3))
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_student_mixture(bad, np.random.default_rng(0))
