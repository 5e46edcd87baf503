"""Exact drift of every noise term, each bias semantics, against brute-force quadratic forms and
Monte Carlo.

References: the covariance matrix of the rate samples ``y_{-N} .. y_{k-1}`` is built for each
term from its definition (independent of the package's structure functions), and the error
of the calibrated outage is the explicit linear form ``e = w' y`` of the paper's Euler
integral of ``y_i - mean(y_{-N..-1})``: ``Var = w' S w``.
"""

import numpy as np
import pytest

from bayes_imu.noise import REGISTRY, NoiseModel
from bayes_imu.noise.bias_instability import flicker_difference_acov
from bayes_imu.noise.simulate import simulate_log

DT = 0.1
PARAMS = {
    "white": {"noise_variance": 2.0},
    "quantization": {"quantization": 0.3},
    "filtered_white": {"filtered_variance": 0.7},
    "hf_correlated": {"correlated_variance": 3.0, "correlated_time_constant": 0.25},
    "gauss_markov": {"bias_variance": 1.5, "time_constant": 4.0},
    "random_walk": {"rate_random_walk": 0.2},
    "bias_instability": {"bias_instability": 0.5},
}


def rate_covariance(term, p, n):
    """Covariance of n consecutive rate samples from the term's definition (index 0 = first
    sample)."""
    i = np.arange(n)
    lag = np.abs(i[:, None] - i[None, :])
    if term == "white":
        return p["noise_variance"] * np.eye(n)
    if term == "quantization":
        return (p["quantization"] / DT) ** 2 * np.where(
            lag == 0, 2.0, np.where(lag == 1, -1.0, 0.0)
        )
    if term == "filtered_white":
        return p["filtered_variance"] * np.where(lag == 0, 2.0, np.where(lag == 1, 1.0, 0.0))
    if term in ("hf_correlated", "gauss_markov"):
        s2, t = (
            (p["correlated_variance"], p["correlated_time_constant"])
            if term == "hf_correlated"
            else (p["bias_variance"], p["time_constant"])
        )
        return s2 * np.exp(-lag * DT / t)
    if term == "random_walk":  # y_j = sum of j+1 increments of variance K^2 dt
        return p["rate_random_walk"] ** 2 * DT * (np.minimum(i[:, None], i[None, :]) + 1)
    z = flicker_difference_acov(n, p["bias_instability"])[lag]
    lower = np.tril(np.ones((n, n)), -1)  # y_k = sum_{t<k} z_t
    return lower @ z @ lower.T


def error_weights(order, k, n_cal, calibrated=True):
    """w with e = w' y over y_{-N..k-1}: v_k = dt sum_{i<k} e_i, p_k = dt sum_{j<k} v_j, e_i = y_i -
    b_hat."""
    outage = DT * np.ones(k) if order == 1 else DT**2 * (k - 1 - np.arange(k, dtype=float))
    weight = outage.sum()
    cal = -weight / n_cal * np.ones(n_cal) if calibrated else np.zeros(n_cal)
    return np.concatenate([cal, outage])


@pytest.mark.parametrize("term", sorted(PARAMS))
@pytest.mark.parametrize("order", [1, 2])
def test_calibrated_drift_equals_brute_force_quadratic_form(term, order):
    """Calibrated start, every stationary and non-stationary term: relative error <= 1e-9
    (extended-precision sums for the contrasts; the Gauss-Markov form cancels a few digits)."""
    p = PARAMS[term]
    for k, n_cal in ((1, 1), (2, 5), (7, 3), (40, 40), (65, 17)):
        w = error_weights(order, k, n_cal)
        ref = w @ rate_covariance(term, p, n_cal + k) @ w
        got = REGISTRY[term].drift_variance(
            order,
            np.array([float(k)]),
            {n: np.array(v) for n, v in p.items()},
            DT,
            bias_start="calibrated",
            n_cal=float(n_cal),
        )
        np.testing.assert_allclose(
            got[0],
            ref,
            rtol=1e-9,
            atol=1e-12 * abs(w) @ np.abs(rate_covariance(term, p, n_cal + k)) @ abs(w),
        )


@pytest.mark.parametrize("term", ["white", "filtered_white", "hf_correlated", "gauss_markov"])
@pytest.mark.parametrize("order", [1, 2])
def test_stationary_start_equals_brute_force(term, order):
    """A stationary process integrated with no bias removed: w' S w with no calibration part."""
    p = PARAMS[term]
    for k in (1, 2, 9, 50):
        w = error_weights(order, k, 1, calibrated=False)[1:]
        ref = w @ rate_covariance(term, p, k) @ w
        got = REGISTRY[term].drift_variance(
            order,
            np.array([float(k)]),
            {n: np.array(v) for n, v in p.items()},
            DT,
            bias_start="stationary",
        )
        np.testing.assert_allclose(got[0], ref, rtol=1e-11, atol=1e-300)


def test_flicker_without_calibration_is_sqrt2_allan_deviation():
    """Zero / stationary start for flicker: the window equals the outage, so the residual rate is
    the difference of two adjacent means, whose variance is twice the Allan variance (definition
    of the AVAR), the flat 2 ln2 B^2 / pi: sigma = sqrt(2) ADEV t exactly."""
    b = 0.01
    t = np.array([1.0, 10.0, 100.0])
    k = t / DT
    adev = b * np.sqrt(2 * np.log(2) / np.pi)
    got = np.sqrt(
        REGISTRY["bias_instability"].drift_variance(
            1, k, {"bias_instability": np.array(b)}, DT, bias_start="zero"
        )
    )
    np.testing.assert_allclose(got, np.sqrt(2) * adev * t, rtol=1e-9)


def test_quantization_position_is_k_minus_one_k():
    """Double integral of white angle noise: dt (sum_{j=1}^{k-1} e_j - (k-1) e_0), variance
    Q^2 dt^2 ((k-1) + (k-1)^2) = Q^2 dt^2 (k-1) k (the old code had k (k+1))."""
    q = 0.3
    k = np.array([1.0, 2.0, 10.0, 1000.0])
    got = REGISTRY["quantization"].drift_variance(
        2, k, {"quantization": np.array(q)}, DT, bias_start="zero"
    )
    np.testing.assert_allclose(got, q * q * DT**2 * (k - 1) * k, rtol=1e-14)


def test_ramp_drift_is_the_deterministic_error():
    """A ramp y_i = R dt i: the Euler sums computed directly (numpy cumsum), both semantics."""
    r, k, n_cal = 0.02, 37, 11
    y = r * DT * np.arange(-n_cal, k)
    for start in ("zero", "calibrated"):
        e = y[n_cal:] - (y[:n_cal].mean() if start == "calibrated" else 0.0)
        v = DT * np.cumsum(np.concatenate([[0.0], e]))  # v_0 = 0, v_k = dt sum_{i<k} e_i
        pos = DT * np.sum(v[:k])
        for order, ref in ((1, v[k]), (2, pos)):
            got = REGISTRY["ramp"].drift_variance(
                order,
                np.array([float(k)]),
                {"rate_ramp": np.array(r)},
                DT,
                bias_start=start,
                n_cal=float(n_cal),
            )
            np.testing.assert_allclose(got[0], ref**2, rtol=1e-12)


def test_calibrated_drift_monte_carlo(rng):
    """4000 simulated logs of white + Gauss-Markov + random walk + flicker: the sample variance of
    the calibrated-outage attitude and position errors is within 5 sigma of the sum of the terms."""
    terms = ("white", "bias_instability", "gauss_markov", "random_walk")
    model = NoiseModel(terms, DT)
    p = {k: v for t in terms for k, v in PARAMS[t].items()}
    k, n_cal, n_paths = 30, 20, 4000
    logs = np.array([simulate_log(model, p, n_cal + k, rng=rng) for _ in range(n_paths)])
    for order in (1, 2):
        errors = logs @ error_weights(order, k, n_cal)
        expected = sum(
            t.drift_variance(
                order,
                np.array([float(k)]),
                {n: np.array(v) for n, v in p.items()},
                DT,
                bias_start="calibrated",
                n_cal=float(n_cal),
            )[0]
            for t in model.components
        )
        assert abs(errors.var() / expected - 1) < 5 * np.sqrt(2 / n_paths)


def test_calibrated_gauss_markov_slow_bias_is_removed():
    """A bias much slower than the windows is almost fully removed by the calibration: the
    calibrated variance is far below the stationary one and tends to the random-walk limit
    of the same increments (T -> inf with s^2 / T fixed), to the cancellation the prior allows."""
    k, n = np.array([100.0]), 100.0
    big_t = 1e4
    gm = REGISTRY["gauss_markov"].drift_variance(
        1,
        k,
        {"bias_variance": np.array(big_t), "time_constant": np.array(big_t)},
        DT,
        bias_start="calibrated",
        n_cal=n,
    )
    rw = REGISTRY["random_walk"].drift_variance(
        1, k, {"rate_random_walk": np.array(np.sqrt(2.0))}, DT, bias_start="calibrated", n_cal=n
    )
    np.testing.assert_allclose(gm, rw, rtol=1e-3)
