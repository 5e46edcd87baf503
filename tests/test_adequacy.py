"""Model adequacy: the goodness-of-fit p-value is uniform when the model is right, tiny when it is
not, and posteriors piled against a prior bound are flagged."""

import dataclasses

import numpy as np
from scipy import stats

from bayes_imu import allan_variance
from bayes_imu.inference.likelihood import LogPosterior
from bayes_imu.noise import NoiseModel
from bayes_imu.inference.selection import adequacy, at_prior_bound, posterior_mode
from bayes_imu.noise.simulate import simulate_log

DT = 0.01
TRUTH = {"noise_variance": 1e-4, "bias_variance": 2e-6, "time_constant": 5.0}


def _likelihood(rng):
    model = NoiseModel(("white", "gauss_markov"), DT)
    allan = allan_variance(simulate_log(model, TRUTH, 2**16, rng=rng), rate_hz=1 / DT)
    post = LogPosterior.build(model, allan, reference=TRUTH)
    chol = np.linalg.inv(post.whiten)  # log-scale covariance = chol chol'
    mean = np.log(model.avar(allan.m, TRUTH)) + post.offset
    return model, allan, post, chol, mean


def test_p_value_uniform_when_model_is_right(rng):
    """200 data vectors drawn from the likelihood at the truth, each refitted (posterior mode):
    the p-values pass a Kolmogorov-Smirnov test of uniformity (p > 0.001) and 5% +- 3.5 sigma of
    them fall below 0.05."""
    model, allan, post, chol, mean = _likelihood(rng)
    truth = np.log([TRUTH[n] for n in model.parameter_names])
    p_values = []
    for _ in range(200):
        data = dataclasses.replace(post, log_avar=mean + chol @ rng.standard_normal(mean.size))
        p_values.append(adequacy(data, posterior_mode(data, [truth]).phi, allan.tau).p_value)
    p_values = np.array(p_values)
    assert stats.kstest(p_values, "uniform").pvalue > 1e-3
    assert abs(np.mean(p_values < 0.05) - 0.05) < 3.5 * np.sqrt(0.05 * 0.95 / 200)


def test_wrong_model_is_inadequate(rng):
    """White noise alone fitted to a white + Gauss-Markov log: p below 1e-6, worst tau near the
    bias."""
    model, allan, post, chol, mean = _likelihood(rng)
    white = NoiseModel(("white",), DT)
    wrong = LogPosterior.build(white, allan, reference=TRUTH | {"_model": model})
    check = adequacy(wrong, posterior_mode(wrong, [[np.log(1e-4)]]).phi, allan.tau)
    assert not check.adequate and check.p_value < 1e-6
    assert 0.5 < check.worst_tau_s < 500


def test_prior_bound_flagged():
    """Draws piled in the outer 2% of a box edge are named; draws in the middle are not."""
    model = NoiseModel(("white", "gauss_markov"), DT)
    bounds = np.array([[-10.0, 0.0], [-20.0, -5.0], [np.log(3 * DT), np.log(100.0)]])
    post = LogPosterior(
        model,
        bounds,
        np.array([1, 2, 4]),
        np.zeros(3),
        "independent",
        np.eye(3),
        np.zeros(3),
        np.ones(3),
        0.0,
    )
    inside = np.column_stack([np.full(100, -5.0), np.full(100, -12.0), np.full(100, 0.0)])
    assert at_prior_bound(post, inside) == ()
    piled = inside.copy()
    piled[:30, 2] = np.log(3 * DT) + 1e-3
    assert at_prior_bound(post, piled) == ("time_constant (lower)",)
