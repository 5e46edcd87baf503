"""Hamiltonian sampler of the population fit: a correlated Gaussian against its exact moments,
split R-hat against the textbook formula written out, and the population posterior's gradient
and smoothed likelihood against finite differences and a direct sum."""

import numpy as np
import pytest
from scipy import stats

from bayes_imu.inference.hmc import sample_hmc, split_rhat
from bayes_imu.inference.population import (
    _HyperPosterior,
    density_log_likelihood,
    log_box_mass,
    unit_density,
)


def test_hmc_draws_a_correlated_gaussian():
    """6-D Gaussian, scales 0.01-10, correlation 0.9: means within 5 Monte Carlo sd of the exact
    ones
    (sd / sqrt(ESS)), variances within 20% (ESS > 400: the variance's relative sd is < 0.1)."""
    rng = np.random.default_rng(0)
    scale = np.array([0.01, 0.1, 1.0, 10.0, 1.0, 0.3])
    corr = np.eye(6)
    corr[0, 1] = corr[1, 0] = 0.9
    cov = corr * np.outer(scale, scale)
    mean = np.array([1.0, -2.0, 0.0, 5.0, 0.5, -0.1])
    precision = np.linalg.inv(cov)

    def log_prob_grad(x):
        d = x - mean
        g = -d @ precision
        return 0.5 * np.sum(d * g, axis=1), g

    run = sample_hmc(log_prob_grad, mean + scale * rng.standard_normal((16, 6)), rng)
    assert run.converged and np.all(run.rhat < 1.01) and np.all(run.ess > 400)
    draws = run.chain.reshape(-1, 6)
    assert np.all(np.abs(draws.mean(axis=0) - mean) < 5 * scale / np.sqrt(run.ess))
    np.testing.assert_allclose(draws.var(axis=0), scale**2, rtol=0.2)
    assert np.corrcoef(draws[:, 0], draws[:, 1])[0, 1] == pytest.approx(0.9, abs=0.03)


def test_split_rhat_is_the_textbook_formula():
    rng = np.random.default_rng(1)
    chain = rng.standard_normal((40, 3, 2)) + np.array([0.0, 0.3, -0.2])[None, :, None]
    expected = []
    for k in range(2):
        series = [list(chain[:20, c, k]) for c in range(3)] + [
            list(chain[20:, c, k]) for c in range(3)
        ]
        n = 20
        means = [sum(s) / n for s in series]
        grand = sum(means) / len(means)
        b = n / (len(series) - 1) * sum((m - grand) ** 2 for m in means)
        w = sum(sum((x - m) ** 2 for x in s) / (n - 1) for s, m in zip(series, means)) / len(series)
        expected.append(np.sqrt(((n - 1) / n * w + b / n) / w))
    np.testing.assert_allclose(split_rhat(chain), expected, rtol=1e-12)


def _population(rng, p=3, units=4, n=300):
    phis = [
        rng.normal(size=p) + rng.uniform(0.05, 0.5, p) * rng.standard_normal((n, p))
        for _ in range(units)
    ]
    boxes = [np.column_stack([f.mean(axis=0) - 2.0, f.mean(axis=0) + 3.0]) for f in phis]
    return phis, boxes


@pytest.mark.parametrize("smoothing", [True, False])
def test_hyper_posterior_gradient_matches_finite_differences(smoothing):
    """The boxes are tight (the truncation mass matters); central differences of the log
    posterior."""
    rng = np.random.default_rng(2)
    phis, boxes = _population(rng)
    target = _HyperPosterior(phis, boxes, 0.7, smoothing=smoothing)
    x = np.concatenate(
        [
            np.mean([f.mean(axis=0) for f in phis], axis=0)[None]
            + 0.1 * rng.standard_normal((3, 3)),
            np.log(rng.uniform(0.05, 2.0, (3, 3))),
        ],
        axis=1,
    )
    value, grad = target.value_and_grad(x)
    np.testing.assert_allclose(value, target(x), rtol=1e-12)
    h = 1e-6
    for i in range(x.shape[1]):
        e = np.zeros(x.shape[1])
        e[i] = h
        numeric = (target(x + e) - target(x - e)) / (2 * h)
        np.testing.assert_allclose(grad[:, i], numeric, rtol=1e-5, atol=1e-6)
    outside = x.copy()
    outside[0, 3] = np.log(10.0)  # spread beyond SPREAD_BOUNDS
    value, grad = target.value_and_grad(outside)
    assert value[0] == -np.inf and np.all(grad[0] == 0) and np.isfinite(value[1:]).all()


def test_smoothed_unit_likelihood_is_a_sum_of_gaussians():
    """Direct sum of scipy normal densities over draws and dimensions; the kernel keeps each
    parameter's mean and variance (Liu & West shrinkage)."""
    rng = np.random.default_rng(3)
    phi = rng.normal(size=3) + np.array([0.02, 0.3, 1.0]) * rng.standard_normal((200, 3))
    centre, q, kernel = unit_density(phi)
    np.testing.assert_allclose(centre + q.mean(axis=0), phi.mean(axis=0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(q.var(axis=0) + kernel, phi.var(axis=0), rtol=1e-12)
    mu = phi.mean(axis=0) + rng.normal(size=(4, 3)) * 0.2
    sigma = rng.uniform(0.01, 0.5, (4, 3))
    got = density_log_likelihood((centre, q, kernel), mu, sigma)
    for w in range(4):
        logs = stats.norm.logpdf(centre + q, mu[w], np.sqrt(sigma[w] ** 2 + kernel)).sum(axis=1)
        assert got[w] == pytest.approx(
            np.log(np.mean(np.exp(logs - logs.max()))) + logs.max(), rel=1e-11
        )


def test_box_mass_gradient_in_the_tails():
    box = np.array([[-1.0, 2.0], [3.0, 3.5], [-40.0, -39.0]])
    mu = np.array([[0.0, 0.0, 0.0], [30.0, -30.0, 0.5], [0.5, 3.2, -39.5]])
    sigma = np.array([[1.0, 0.1, 1.0], [1.0, 1.0, 0.05], [0.3, 0.2, 0.5]])
    _, g_mu, g_log_sigma = log_box_mass(box, mu, sigma, gradient=True)
    h = 1e-6
    for d in range(3):
        e = np.zeros(3)
        e[d] = h
        num_mu = (log_box_mass(box, mu + e, sigma) - log_box_mass(box, mu - e, sigma)) / (2 * h)
        num_ls = (
            log_box_mass(box, mu, sigma * np.exp(e)) - log_box_mass(box, mu, sigma * np.exp(-e))
        ) / (2 * h)
        np.testing.assert_allclose(g_mu[:, d], num_mu, rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(g_log_sigma[:, d], num_ls, rtol=1e-5, atol=1e-7)


def test_scaled_mean_coordinates_keep_the_density():
    """``(z, ln sigma)`` -> ``(mu, ln sigma)`` and back; the density there is the target's times the
    Jacobian prod t (a numerical derivative of the map), and its gradient matches finite
    differences."""
    from bayes_imu.inference.population import _ScaledMean

    rng = np.random.default_rng(4)
    phis, boxes = _population(rng)
    target = _HyperPosterior(phis, boxes, 0.7)
    scaled = _ScaledMean(target)
    x = np.concatenate(
        [
            np.mean([f.mean(axis=0) for f in phis], axis=0)[None]
            + 0.1 * rng.standard_normal((3, 3)),
            np.log(rng.uniform(0.05, 2.0, (3, 3))),
        ],
        axis=1,
    )
    y = scaled.to_scaled(x)
    np.testing.assert_allclose(scaled.to_hyper(y), x, rtol=1e-12, atol=1e-12)
    value, grad = scaled.value_and_grad(y)
    h = 1e-6
    for row in range(3):
        jac = np.empty((6, 6))
        for i in range(6):
            e = np.zeros((1, 6))
            e[0, i] = h
            jac[:, i] = (
                scaled.to_hyper(y[row : row + 1] + e) - scaled.to_hyper(y[row : row + 1] - e)
            )[0] / (2 * h)
        assert value[row] == pytest.approx(
            target(x[row : row + 1])[0] + np.log(abs(np.linalg.det(jac))), rel=1e-8
        )
    for i in range(6):
        e = np.zeros(6)
        e[i] = h
        numeric = (scaled.value_and_grad(y + e)[0] - scaled.value_and_grad(y - e)[0]) / (2 * h)
        np.testing.assert_allclose(grad[:, i], numeric, rtol=1e-5, atol=1e-6)


def test_two_units_converge():
    """Two units, one well-measured parameter: the spread's posterior spans decades (the funnel the
    scaled coordinates remove); the sampler converges well within its budget."""
    from bayes_imu.inference.population import _sample_hyper

    rng = np.random.default_rng(5)
    phis = [m + 0.02 * rng.standard_normal((800, 1)) for m in (-9.2, -9.25)]
    target = _HyperPosterior(phis, [np.array([[-20.0, 0.0]])] * 2, 1.0)
    _, spread, diagnostics = _sample_hyper(target, rng, max_steps=1000)
    assert (
        diagnostics["converged"]
        and diagnostics["rhat_max"] < 1.01
        and diagnostics["ess_hyper_min"] > 400
    )
    assert np.quantile(spread[:, 0], 0.05) < 0.02 < 0.3 < np.quantile(spread[:, 0], 0.95)
