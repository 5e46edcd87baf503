"""Model selection: the candidate set, the selection rule, probabilities, stepwise moves;
max_outage."""

import numpy as np
import pytest

from bayes_imu import NoiseModel
from bayes_imu.inference.population import UnitPosterior
from bayes_imu.report.scene import max_outage
from bayes_imu.inference.selection import (
    CandidateScore,
    candidate_terms,
    extensions,
    model_probabilities,
    reductions,
    select,
)


def _score(terms, log_z, se=0.0):
    return CandidateScore(tuple(terms), float(log_z), float(se), 1000.0, np.zeros(len(terms)))


def test_candidate_terms_are_white_plus_every_subset():
    cands = candidate_terms()
    assert len(cands) == 16 and len(set(cands)) == 16
    assert all(c[0] == "white" for c in cands)
    assert [len(c) for c in cands] == sorted(len(c) for c in cands)  # simplest first
    assert set(candidate_terms(("gauss_markov",))) == {("white",), ("white", "gauss_markov")}


def test_select_takes_the_simplest_within_threshold():
    scores = [_score(["white"], 8.0), _score(["white", "gauss_markov"], 9.5),
              _score(["white", "gauss_markov", "random_walk"], 10.0)]
    # 0.5 nat below the best, fewer terms; the one-term model is 2 nats below
    assert select(scores) == 1
    assert select(scores, threshold=0.1) == 2
    assert select(scores, threshold=2.5) == 0
    # the Monte Carlo error widens the margin: 1 + 2 * hypot(0.6, 0) = 2.2 nats
    noisy = [_score(["white"], 8.0, 0.6)] + scores[1:]
    assert select(noisy) == 0


def test_select_breaks_ties_in_size_by_evidence():
    scores = [_score(["white", "quantization"], 9.2), _score(["white", "gauss_markov"], 9.9),
              _score(["white", "gauss_markov", "random_walk"], 10.0)]
    assert select(scores) == 1


def test_model_probabilities_are_normalised_evidences():
    log_z = np.array([-1000.0, -1001.0, -1003.5])
    p = model_probabilities([_score(["white"] * 1, z) for z in log_z])
    w = np.exp(log_z - log_z.max())
    np.testing.assert_allclose(p, w / w.sum(), rtol=1e-12)
    assert p.sum() == pytest.approx(1.0)


def test_stepwise_moves():
    ext = extensions(("white",))
    assert ("white", "gauss_markov_2") not in ext and ("white", "gauss_markov") in ext
    assert ("white", "gauss_markov", "gauss_markov_2") in extensions(("white", "gauss_markov"))
    red = reductions(("white", "gauss_markov", "gauss_markov_2", "ramp"))
    assert ("gauss_markov", "gauss_markov_2", "ramp") not in red  # white stays
    assert ("white", "gauss_markov_2", "ramp") not in red  # gauss_markov goes only with its second
    assert ("white", "gauss_markov", "ramp") in red and (
        "white",
        "gauss_markov",
        "gauss_markov_2",
    ) in red


@pytest.mark.parametrize("bias_start", ["zero", "calibrated"])
def test_max_outage_white_noise(bias_start):
    """White noise q per sample, zero bias start: sigma(t)^2 = q dt t exactly, so the longest outage
    within E is E^2 / (q dt) (to one sample); a calibrated start only adds error, so it is
    shorter."""
    dt, q, limit = 0.01, 4e-4, 0.01
    post = UnitPosterior(NoiseModel(("white",), dt), np.array([[q]]), 1e4)
    t = max_outage(post, "attitude", limit, 0.95, bias_start=bias_start, calibration_s=10.0)
    exact = limit**2 / (q * dt)
    if bias_start == "zero":
        assert abs(t - exact) <= dt
    else:  # the mean of 10 s removed adds q dt t^2 / 10 s: solve q dt t (1 + t / 10) = E^2
        assert t == pytest.approx((-1 + np.sqrt(1 + 4 * exact / 10.0)) / (2 / 10.0), abs=2 * dt)


def test_laplace_evidence_against_quadrature_for_one_parameter(rng):
    """The Laplace estimate of log Z in u (one parameter: white noise) against the same integral by
    adaptive quadrature of the exact density; one parameter and 2^16 samples: within 0.05 nat."""
    from scipy import integrate

    from bayes_imu import allan_variance
    from bayes_imu.inference.likelihood import LogPosterior
    from bayes_imu.inference.selection import _log_density_u, laplace_log_evidence, posterior_mode

    a = allan_variance(0.3 * rng.standard_normal(2**16), rate_hz=100.0)
    model = NoiseModel(("white",), 0.01)
    post = LogPosterior.build(model, a, kind="correlated", reference={"noise_variance": 0.09})
    mode = posterior_mode(post, [[np.log(0.09)]])
    log_z, cov = laplace_log_evidence(post, mode.u)
    peak = float(_log_density_u(post, mode.u)[0])
    width = 12.0 * np.sqrt(cov[0, 0])
    mass, _ = integrate.quad(
        lambda u: np.exp(_log_density_u(post, np.array([u]))[0] - peak),
        mode.u[0] - width,
        mode.u[0] + width,
        epsabs=0,
        epsrel=1e-10,
        limit=200,
    )
    assert log_z == pytest.approx(peak + np.log(mass), abs=0.05)


def test_screened_candidates_are_those_importance_sampling_puts_far_below(rng):
    """A fit's candidates left with their Laplace estimate (method 'laplace') are more than
    LAPLACE_SCREEN nats below the best importance-sampled evidence, and their own importance-sampled
    evidence (score_models, which screens nothing) is more than 8 nats below it: they could not
    matter."""
    from bayes_imu import allan_variance
    from bayes_imu.inference.fit import fit_allan, score_models
    from bayes_imu.inference.selection import LAPLACE_SCREEN
    from bayes_imu.noise.simulate import simulate_log

    truth = {"noise_variance": 0.25, "bias_variance": 1e-3, "time_constant": 20.0}
    y = simulate_log(NoiseModel(("white", "gauss_markov"), 0.01), truth, 2**18, rng=rng)
    a = allan_variance(y, rate_hz=100.0)
    fit = fit_allan(a, rng=1)
    screened = [c for c in fit.candidates if c.method == "laplace"]
    sampled = [c for c in fit.candidates if c.method == "importance"]
    assert screened and sampled  # white alone and white + random walk are far below on this log
    best = max(c.log_evidence for c in sampled)
    assert all(
        c.log_evidence < best - LAPLACE_SCREEN and c.log_evidence_se == 0 and c.ess == 0
        for c in screened
    )
    assert all(p < 1e-3 for c, p in zip(fit.candidates, fit.probabilities) if c.method == "laplace")
    again = score_models(a, [c.terms for c in screened], rng=2)
    assert all(c.method == "importance" for c in again)
    assert max(c.log_evidence for c in again) < best - 8.0


def test_can_skip_refuses_a_mode_the_optimiser_stopped_short_of(rng):
    """A Laplace estimate taken at a point that is not the mode can be far too low: the screen's
    pilot draws find a denser point and the candidate is importance-sampled after all; at the true
    mode, with the same (low) best, it is skipped, and never when the Laplace estimate is within the
    screen."""
    from bayes_imu import allan_variance
    from bayes_imu.inference.likelihood import LogPosterior
    from bayes_imu.inference.selection import (
        LAPLACE_SCREEN,
        can_skip,
        laplace_log_evidence,
        posterior_mode,
    )

    a = allan_variance(0.3 * rng.standard_normal(2**16), rate_hz=100.0)
    post = LogPosterior.build(
        NoiseModel(("white",), 0.01), a, kind="correlated", reference={"noise_variance": 0.09}
    )
    mode = posterior_mode(post, [[np.log(0.09)]])
    log_z, cov = laplace_log_evidence(post, mode.u)
    far_above = log_z + LAPLACE_SCREEN + 50.0  # a best evidence this candidate cannot approach
    assert can_skip(post, mode.u, log_z, cov, far_above, np.random.default_rng(1))
    assert not can_skip(
        post, mode.u, log_z, cov, log_z + 0.5 * LAPLACE_SCREEN, np.random.default_rng(1)
    )
    short = mode.u + 6.0 * np.sqrt(np.diag(cov))  # six standard deviations off: "stopped short"
    low_z, low_cov = laplace_log_evidence(post, short)
    assert low_z < log_z - 10.0  # the Laplace estimate there is far too low
    assert not can_skip(
        post, short, low_z, low_cov, low_z + LAPLACE_SCREEN + 1.0, np.random.default_rng(1)
    )


def test_importance_proposal_is_scipy_multivariate_t_and_logistic():
    """The proposal of the importance sampler (written without scipy.stats) draws and weighs as
    scipy.stats.multivariate_t and scipy.stats.logistic do from the same Generator state."""
    from scipy import stats

    from bayes_imu.inference.selection import _StudentT, _logistic_logpdf

    b = np.array([[1.4, 0.0, 0.0], [0.2, 0.7, 0.0], [-0.1, 0.05, 1e-2]])
    a = b @ b.T  # a covariance with one small eigenvalue
    loc = np.array([0.5, -1.0, 3.0])
    ours = _StudentT(loc, a, 4.0)
    draws = ours.rvs(500, np.random.default_rng(7))
    ref = stats.multivariate_t(loc=loc, shape=a, df=4.0, seed=np.random.default_rng(7)).rvs(
        size=500
    )
    np.testing.assert_allclose(draws, ref, rtol=1e-13, atol=0)
    u = np.vstack([draws, loc + 50.0])
    np.testing.assert_allclose(
        ours.logpdf(u), stats.multivariate_t(loc=loc, shape=a, df=4.0).logpdf(u), rtol=1e-13
    )
    x = np.concatenate([np.linspace(-800.0, 800.0, 4001), [0.0]])
    np.testing.assert_allclose(_logistic_logpdf(x), stats.logistic.logpdf(x), rtol=1e-14)
    assert np.isfinite(_logistic_logpdf(x)).all()
    np.testing.assert_array_equal(
        np.random.default_rng(3).logistic(size=(5, 2)),
        stats.logistic.rvs(size=(5, 2), random_state=np.random.default_rng(3)),
    )


def test_mode_search_stencil_gives_the_analytic_gradient_and_hessian(rng):
    """The mode search's central differences against the analytic derivatives of a smooth
    non-quadratic function in five dimensions (a quadratic form plus an exponential): gradient and
    Hessian to 1e-6."""
    from bayes_imu.inference.selection import _stencil

    n = 5
    a = rng.standard_normal((n, n))
    a = a @ a.T + n * np.eye(n)
    b, c, x = rng.standard_normal(n), 0.3 * rng.standard_normal(n), 0.5 * rng.standard_normal(n)

    def f(u):
        return 0.5 * np.einsum("...i,ij,...j->...", u, a, u) + u @ b + np.exp(u @ c)

    offsets, derivatives = _stencil(n)
    value, grad, hess = derivatives(f(x + offsets))
    e = np.exp(x @ c)
    assert value == f(x)
    np.testing.assert_allclose(grad, a @ x + b + e * c, rtol=0, atol=1e-6 * np.abs(a @ x + b).max())
    np.testing.assert_allclose(hess, a + e * np.outer(c, c), rtol=0, atol=1e-6 * np.abs(a).max())


def test_newton_mode_finds_the_mode_bfgs_finds_at_high_precision(rng):
    """From the usual starts and from far ones (indefinite Hessian there), the Newton search ends at
    the mode that scipy's BFGS reaches with a gradient tolerance 1000x tighter: the same point to
    1e-4 in u and the same density to 1e-6 nat, with every gradient component below MODE_GTOL; the
    density it reports is the one at its end point, to 4 ulp (it comes from the stencil's batched
    likelihood call, and the BLAS product rounds a row of a batch differently from a lone row: 2 ulp
    on this log since the Allan sums' last bits moved; bit for bit before, by chance)."""
    from scipy import optimize

    from bayes_imu import allan_variance
    from bayes_imu.inference.likelihood import LogPosterior
    from bayes_imu.inference.selection import (
        MODE_GTOL,
        _log_density_u,
        _neg_gradient,
        _neg_log_density,
        _to_u,
        newton_mode,
        posterior_mode,
    )
    from bayes_imu.noise.simulate import simulate_log

    model = NoiseModel(("white", "gauss_markov", "random_walk"), 0.01)
    truth = {
        "noise_variance": 0.01,
        "bias_variance": 1e-4,
        "time_constant": 50.0,
        "rate_random_walk": 1e-5,
    }
    a = allan_variance(simulate_log(model, truth, 2**17, rng=rng), rate_hz=100.0)
    post = LogPosterior.build(model, a, reference=truth)
    phi_true = np.log([truth[k] for k in model.parameter_names])
    u_true = _to_u(phi_true, post.bounds)
    ref = optimize.minimize(
        _neg_log_density,
        u_true,
        args=(post,),
        jac=_neg_gradient,
        method="BFGS",
        options={"gtol": 1e-8, "maxiter": 5000},
    )
    width = post.bounds[:, 1] - post.bounds[:, 0]
    starts = [phi_true, post.bounds[:, 0] + 0.1 * width, post.bounds[:, 0] + 0.9 * width]
    for phi0 in starts:
        u, fun, grad = newton_mode(post, _to_u(phi0, post.bounds))
        assert np.max(np.abs(grad)) < MODE_GTOL
        np.testing.assert_allclose(u, ref.x, atol=1e-4)
        assert fun == pytest.approx(ref.fun, abs=1e-6)
        assert abs(fun - -_log_density_u(post, u)[0]) <= 4 * np.spacing(abs(fun))
    mode = posterior_mode(post, starts)
    assert mode.neg_log_density == pytest.approx(ref.fun, abs=1e-6)


def test_stepwise_search_goes_backward_while_removals_stay_within_the_margin(monkeypatch):
    """A scripted evidence landscape (standard errors 0.1: margin 1.28 nats): the best base
    candidate is white + GM + RW; the forward steps add filtered_white, then gauss_markov_2, each
    gaining 1.5 nats. Removing the random walk, then the second bias, stays within the margin of the
    best: the backward steps reach white + filtered_white + GM, which the selection rule then picks
    (one removal alone, as before, stopped at four terms). A removal beyond the margin (to white +
    GM) is not moved to."""
    import importlib
    from types import SimpleNamespace

    fit_module = importlib.import_module("bayes_imu.inference.fit")
    w, fw, gm, gm2, rw = "white", "filtered_white", "gauss_markov", "gauss_markov_2", "random_walk"
    evidence = {(w, gm): 10.0, (w, gm, rw): 12.0, (w, fw, gm, rw): 13.5, (w, fw, gm, gm2, rw): 15.0,
                (w, fw, gm, gm2): 14.5, (w, fw, gm): 14.2}

    def scripted(jobs, allan, reference, n_evidence, rng, best):
        out = [
            fit_module._Scored(
                CandidateScore(m.terms, evidence.get(m.terms, -100.0), 0.1, 1000.0, np.zeros(1)),
                None,
                None,
            )
            for m, _, _ in jobs
        ]
        return out, max([best] + [s.score.log_evidence for s in out])

    monkeypatch.setattr(fit_module, "_score_batch", scripted)

    class Bar:
        def update(self, n):
            pass

    scored = fit_module._search(
        lambda model: None,
        SimpleNamespace(rate_hz=100.0),
        None,
        candidate_terms(),
        True,
        1.0,
        100,
        None,
        Bar(),
    )
    terms = [c.score.terms for c in scored]
    assert (w, fw, gm, gm2, rw) in terms and (w, fw, gm) in terms
    chosen = scored[select([c.score for c in scored], threshold=1.0)].score.terms
    assert chosen == (w, fw, gm)


def test_density_in_u_adds_the_exact_log_jacobian_of_the_logistic_map():
    """``_log_density_u`` = the log likelihood at ``to_phi(u)`` + ``log sigma(u) (1 - sigma(u))``
    summed over the coordinates; that Jacobian against mpmath (50 digits) from 0 to |u| = 700 (where
    sigma(-u) underflows to 1e-304), to 4e-16 relative, through a stand-in likelihood that returns
    0."""
    import mpmath

    from bayes_imu.inference.selection import _log_density_u

    class Flat:
        bounds = np.array([[-3.0, 2.0], [0.0, 1.0]])

        @staticmethod
        def log_likelihood(phi):
            assert np.all((phi >= -3.0) & (phi <= 2.0))
            return np.zeros(phi.shape[:-1])

    values = np.array([0.0, 1e-9, 0.3, -0.3, 1.0, -2.5, 7.0, -19.0, 37.0, -40.0, 120.0, -700.0])
    u = np.column_stack([values, values[::-1]])
    got = _log_density_u(Flat, u)
    mpmath.mp.dps = 50

    def log_jacobian(x):
        x = mpmath.mpf(float(x))  # log sigma(x) + log sigma(-x), each -log(1 + e^-+x)
        return -mpmath.log(1 + mpmath.exp(-x)) - mpmath.log(1 + mpmath.exp(x))

    want = np.array([float(log_jacobian(a) + log_jacobian(b)) for a, b in u])
    np.testing.assert_allclose(got, want, rtol=4e-16, atol=0)
