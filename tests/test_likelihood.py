"""Likelihoods of Allan variance data: the Gaussian copula against its references.

References: scipy's gamma and normal distributions (exact marginals), the independent
gamma likelihood (the copula with an identity correlation), and Monte Carlo over
simulated logs (the copula's normal scores at the truth are N(0, R)).
"""

import numpy as np
import pytest
from scipy import stats

from bayes_imu.allan.estimator import allan_variance, cluster_sizes
from bayes_imu.noise.avar_covariance import avar_covariance
from bayes_imu.inference.likelihood import LIKELIHOODS, LogPosterior, _normal_scores, default_bounds
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import simulate_log

TRUTH = {"noise_variance": 1e-2, "bias_variance": 1e-5, "time_constant": 10.0}
MODEL = NoiseModel(("white", "gauss_markov"), 0.01)


@pytest.fixture
def allan(rng):
    return allan_variance(simulate_log(MODEL, TRUTH, 2**15, rng=rng), rate_hz=100.0)


def test_normal_scores_exact_and_finite():
    """Phi^-1 of the gamma CDF to 1e-13 wherever the tail probability is representable; finite
    beyond."""
    p = np.array([1e-280, 1e-15, 1e-3, 0.5, 0.999, 1 - 1e-12])
    for shape in (1.0, 2.5, 10.0, 200.0):
        y = stats.gamma.ppf(p, shape)
        np.testing.assert_allclose(
            _normal_scores(shape, y), stats.norm.ppf(p), rtol=1e-12, atol=1e-13
        )
        far = _normal_scores(shape, np.array([0.0, 1e-320, 1e6, np.inf]))
        assert np.all(np.isfinite(far)) and far[0] == far[1] < -37 and far[2] == far[3] > 37


def test_copula_with_identity_correlation_is_independent_gamma(allan):
    """R = I: the copula term vanishes and the likelihood is the product of the gamma marginals."""
    reference = MODEL.avar(allan.m, TRUTH)
    # shapes = edf / 2, as the independent likelihood
    diagonal = np.diag(2.0 * reference**2 / allan.edf)
    copula = LogPosterior.from_covariance(
        MODEL, allan, diagonal, reference, default_bounds(MODEL, allan), kind="copula"
    )
    independent = LogPosterior.build(MODEL, allan, kind="independent")
    theta = np.log([[1e-2, 1e-5, 10.0], [1.3e-2, 3e-5, 4.0], [0.8e-2, 1e-6, 30.0]])
    np.testing.assert_allclose(
        copula.log_likelihood(theta), independent.log_likelihood(theta), rtol=1e-12
    )


@pytest.mark.parametrize("kind", LIKELIHOODS)
def test_likelihoods_vectorised_and_finite_far_away(allan, kind):
    """Batch equals a loop (emcee vectorize=True); a parameter far from the data is finite, never
    NaN."""
    post = LogPosterior.build(MODEL, allan, kind=kind, reference=TRUTH)
    theta = np.log([[1e-2, 1e-5, 10.0], [1e-6, 1e-12, 0.05], [10.0, 1.0, 80.0]])
    batch = post.log_likelihood(theta)
    np.testing.assert_allclose(batch, [post.log_likelihood(t) for t in theta], rtol=1e-13)
    assert np.all(np.isfinite(batch)) and batch[0] > batch[1] and batch[0] > batch[2]


def test_copula_scores_at_truth_are_standard_normal_with_model_correlation(rng):
    """Monte Carlo, 400 white + GM logs of 2**12 samples: the scores of the observed AVARs at the
    true parameters have mean 0 and variance 1 (5 standard errors), and adjacent octaves
    correlate as the exact AVAR covariance says (within 0.1: sampling error ~0.05, 2 sigma)."""
    n_logs, n = 400, 2**12
    m = cluster_sizes("octave", n)
    reference = MODEL.avar(m, TRUTH)
    cov = avar_covariance(MODEL, TRUTH, m, n)
    sd = np.sqrt(np.diag(cov))
    rho = cov / np.outer(sd, sd)
    shape = reference**2 / np.diag(cov)
    scores = np.array(
        [
            _normal_scores(
                shape,
                shape
                * allan_variance(simulate_log(MODEL, TRUTH, n, rng=rng), rate_hz=100.0, m=m).avar
                / reference,
            )
            for _ in range(n_logs)
        ]
    )
    se = 1.0 / np.sqrt(n_logs)
    assert np.all(np.abs(scores.mean(axis=0)) < 5 * se), scores.mean(axis=0)
    assert np.all(np.abs(scores.var(axis=0) - 1.0) < 5 * np.sqrt(2.0) * se), scores.var(axis=0)
    empirical = np.corrcoef(scores.T)
    k = np.arange(m.size - 1)
    np.testing.assert_allclose(empirical[k, k + 1], rho[k, k + 1], atol=0.1)


def test_max_score_is_the_normal_score_of_the_smallest_probability():
    from scipy import special

    from bayes_imu.inference import likelihood

    assert likelihood._MAX_SCORE == float(-special.ndtri(np.finfo(float).tiny))
