"""Repeatability between the parts of a record (inference.repeatability): the parts' reads of each
term's scale, the Student-t batch-means interval combined with the posterior's, and what
summary.json, the datasheet and the Kalibr export print.

References: exact algebra (a white log's parts read a planted scale exactly: the share is 1 at
every size), an independent whitened least-squares solve (numpy lstsq on the Cholesky-whitened
system), the read's sampling standard deviation against Monte Carlo over simulated logs, and the
coverage of the combined interval against a numerical integral over the Student-t scatter (scipy
quad)."""

import numpy as np
import pytest

from bayes_imu import allan_variance, fit_allan
from bayes_imu.inference.repeatability import (
    INTERVAL_MASS, MAX_READ_SD, between_parts_sd, group_of, part_reads, widen)
from bayes_imu.inference.stationarity import Stationarity
from bayes_imu.noise.avar_covariance import avar_covariance
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import simulate_log

RATE = 100.0
TAU = np.array([0.01, 0.02, 0.04, 0.08, 0.16, 0.32, 0.64, 1.28])


def _parts(avar):
    """A stationarity result carrying the parts' Allan variances ``(K, n_tau)`` at :data:`TAU`."""
    avar = np.asarray(avar, float)
    return Stationarity(True, 0.5, 0.01, TAU, np.sqrt(avar), np.zeros(TAU.size))


def test_white_parts_read_a_planted_scale_exactly():
    """White noise alone: the share is 1 at every size, so whatever the covariance the read of
    part k is the planted ln-scale c_k minus the mean of the c's (exact algebra, 1e-12)."""
    model = NoiseModel(("white",), 1.0 / RATE)
    params = {"noise_variance": 4e-4}
    c = np.array([-0.03, 0.01, 0.015, 0.04])
    avar = model.avar(np.round(TAU * RATE).astype(int), params) * np.exp(c)[:, None]
    reads = part_reads(model, params, _parts(avar), 25_000, RATE)
    d, sd = reads.read(("white",))
    np.testing.assert_allclose(d, c - c.mean(), rtol=0, atol=1e-12)
    assert reads.n_parts == 4 and 0 < sd < MAX_READ_SD
    assert reads.read(("random_walk",)) is None  # a term the model lacks reads nothing


def test_read_is_the_whitened_least_squares_scale(rng):
    """White + Gauss-Markov + random walk, parts with arbitrary deviations: the read equals the
    one-parameter least-squares slope of the Cholesky-whitened deviations on the whitened share
    (numpy lstsq, an independent route), and its standard deviation the whitened residual scale
    1."""
    model = NoiseModel(("white", "gauss_markov", "random_walk"), 1.0 / RATE)
    params = {"noise_variance": 4e-4, "bias_variance": 1e-6, "time_constant": 5.0,
              "rate_random_walk": 1e-4}
    m = np.round(TAU * RATE).astype(int)
    avar = model.avar(m, params) * np.exp(rng.normal(0, 0.02, (4, TAU.size)))
    reads = part_reads(model, params, _parts(avar), 25_000, RATE)
    total = model.avar(m, params)
    cov = avar_covariance(model, params, m, 25_000) / np.outer(total, total)
    chol = np.linalg.cholesky(cov)
    r = np.log(avar) - np.log(avar).mean(axis=0)
    for group in (("white",), ("gauss_markov", "random_walk")):
        w = sum(model.term_avar(t, m, params) for t in group) / total
        a = np.linalg.solve(chol, w)[:, None]
        want = [np.linalg.lstsq(a, np.linalg.solve(chol, rk), rcond=None)[0][0] for rk in r]
        d, sd = reads.read(group)
        np.testing.assert_allclose(d, want, rtol=1e-8, atol=1e-12)
        assert sd == pytest.approx(1.0 / np.linalg.norm(a), rel=1e-8)


@pytest.mark.slow
def test_read_standard_deviation_matches_monte_carlo():
    """The per-part sampling standard deviation of the white read, ``1 / sqrt(w' C^-1 w)``,
    against the scatter of the reads over 150 simulated white + Gauss-Markov logs of 4 x 2^14
    samples (each part's own Allan variance): the sample sd of 600 reads is within 4 standard
    errors (sd / sqrt(2 * 599))."""
    model = NoiseModel(("white", "gauss_markov"), 1.0 / RATE)
    params = {"noise_variance": 4e-4, "bias_variance": 4e-6, "time_constant": 2.0}
    n_part = 2**14
    m = np.round(TAU * RATE).astype(int)
    rng = np.random.default_rng(7)
    reads, sd = [], None
    for _ in range(150):
        y = simulate_log(model, params, 4 * n_part, rng=rng)
        avar = [allan_variance(y[k * n_part:(k + 1) * n_part], rate_hz=RATE, m=m, segments=0).avar
                for k in range(4)]
        d, sd = part_reads(model, params, _parts(avar), n_part, RATE).read(("white",))
        reads.extend(d * np.sqrt(4 / 3))  # deviations from the parts' mean: variance (K - 1) / K
    got = np.std(reads, ddof=1)
    assert abs(got - sd) < 4 * sd / np.sqrt(2 * (len(reads) - 1))


def test_between_parts_sd_is_the_student_t_excess():
    """``e = sqrt(max(0, h_B^2 - h_P^2)) / z_0.95`` with ``h_B = t_3(0.95) sd / 2`` (scipy.stats.t,
    independent of the module's special functions); zero when the posterior is already wider."""
    from scipy import stats

    readings = np.array([-0.02, 0.0, 0.005, 0.015])
    h_b = stats.t.ppf(0.95, 3) * np.std(readings, ddof=1) / 2
    draws = np.linspace(-1, 1, 20_001) * 1e-3  # uniform: h_P = 0.9e-3
    want = np.sqrt(h_b**2 - 0.9e-3**2) / stats.norm.ppf(0.95)
    assert between_parts_sd(readings, draws) == pytest.approx(want, rel=1e-6)
    assert between_parts_sd(readings, draws * 100) == 0.0


def test_combined_interval_coverage_against_an_integral():
    """Stationary parts: K = 4 readings ~ N(0, s^2), the posterior N(mean, s^2 / 4) (the same
    information). The widened 90% interval covers the truth with probability ``E[P(|Z| <=
    max(z_0.95, t_3 S / s))]`` over the scatter S (an integral over the chi-square, scipy quad):
    between 90% and 96%, and 4000 Monte Carlo trials of :func:`widen` agree within 4 sigma."""
    from scipy import integrate, stats

    k, z95, t95 = 4, stats.norm.ppf(0.95), stats.t.ppf(0.95, 3)

    def covered(x):  # x = (K - 1) S^2 / s^2 ~ chi2_3
        half = max(z95, t95 * np.sqrt(x / (k - 1)))
        return (2 * stats.norm.cdf(half) - 1) * stats.chi2.pdf(x, k - 1)

    want = integrate.quad(covered, 0, np.inf)[0]
    assert 0.90 < want < 0.96
    rng = np.random.default_rng(11)
    z = stats.norm.ppf((np.arange(4000) + 0.5) / 4000)  # a smooth posterior of sd 1/2

    class Reads:
        def read(self, terms):
            return self.d, 0.1

    hits, n = 0, 400
    reads = Reads()
    for _ in range(n):
        parts = rng.normal(0.0, 1.0, k)
        reads.d = 2 * (parts - parts.mean())  # ln-AVAR scales; power 1/2 makes them the readings
        draws = np.exp(parts.mean() + 0.5 * z)
        lo, hi = np.quantile(np.log(widen(draws, ("white",), 0.5, reads, None)), [0.05, 0.95])
        hits += lo <= 0.0 <= hi
    assert abs(hits / n - want) < 4 * np.sqrt(want * (1 - want) / n)


def test_group_of_names_the_terms_that_read_a_parameter():
    model = NoiseModel(("white", "filtered_white", "gauss_markov"), 0.01)
    assert group_of("noise_density", model) == (("white", "filtered_white"), 0.5)
    assert group_of("white_noise_density", model) == (("white",), 0.5)
    assert group_of("noise_variance", model) == (("white",), 1.0)
    assert group_of("time_constant", model) == (("gauss_markov",), 0.0)
    assert group_of("model_discrepancy", model) == ((), 0.0)
    assert INTERVAL_MASS == 0.9


def test_a_changing_log_prints_the_spread_between_its_parts(rng):
    """A white log whose first quarter is 8% noisier in variance: ``parameters`` (what a user
    copies) includes the parts' scatter, ``parameters_this_record`` keeps the posterior alone;
    the datasheet's ARW and the Kalibr density are the same draws (unit factors 180/pi 60 and 1,
    to 1e-9)."""
    from bayes_imu.report.kalibr import KalibrAxis, kalibr_values

    n = 2**17
    y = rng.normal(0, 0.02, n)
    y[: n // 4] *= np.sqrt(1.08)
    fit = fit_allan(allan_variance(y, rate_hz=RATE, sensor="gyro"), terms=("white",), rng=1)
    s = fit.summary(unit="rad/s")
    printed, alone = s["parameters"]["noise_density"], s["parameters_this_record"]["noise_density"]
    assert printed["q95"] - printed["q05"] > 1.5 * (alone["q95"] - alone["q05"])
    assert alone["q05"] == pytest.approx(np.quantile(fit.draws("noise_density"), 0.05), rel=1e-12)
    assert s["repeatability"]["n_parts"] == 4 and "noise_density" in s["repeatability"]["widened"]
    d, _ = fit.part_reads.read(("white",))
    assert d[0] == pytest.approx(np.log(1.08) * 3 / 4, abs=0.02)  # the planted step, part 1
    arw = s["datasheet"]["angle_random_walk"]
    for key in ("median", "q05", "q95"):
        assert arw[key] == pytest.approx(printed[key] * 180 / np.pi * 60, rel=1e-9)
    kalibr = kalibr_values([KalibrAxis("x", fit)], credibility=0.95)
    assert kalibr.values["gyroscope_noise_density"] == pytest.approx(printed["q95"], rel=1e-9)
