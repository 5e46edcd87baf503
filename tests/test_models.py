"""Noise models: exact discrete Allan variances against mpmath and against their own structure
functions."""

import mpmath as mp
import numpy as np
import pytest
from test_term_contract import params_of

from bayes_imu.errors import InputError
from bayes_imu.noise import REGISTRY
from bayes_imu.noise.avar_forms import (
    TERMS,
    NoiseModel,
    gauss_markov_avar,
    random_walk_avar,
    structure_function,
)

PARAMS = {
    "white": {"noise_variance": 2.0},
    "quantization": {"quantization": 0.3},
    "bias_instability": {"bias_instability": 0.5},
    "random_walk": {"rate_random_walk": 0.1},
    "gauss_markov": {"bias_variance": 1.5, "time_constant": 30.0},
    "hf_correlated": {"correlated_variance": 3.0, "correlated_time_constant": 0.7},
    "filtered_white": {"filtered_variance": 0.4},
}


def gm_avar_mpmath(m, x):
    """Reference: the AR(1) AVAR from its definition, Var and Cov of adjacent m-averages (100
    digits: x = 1e-15 cancels ~45 digits)."""
    with mp.workdps(100):
        phi = mp.e ** (-mp.mpf(x))
        m = mp.mpf(m)
        var_mean = (m * (1 - phi**2) - 2 * phi * (1 - phi**m)) / (m * m * (1 - phi) ** 2)
        cov_adjacent = phi * (1 - phi**m) ** 2 / (m * m * (1 - phi) ** 2)
        return +(var_mean - cov_adjacent)


@pytest.mark.parametrize("x", [1e-15, 1e-9, 1e-6, 1e-3, 0.049, 0.05, 0.051, 0.3, 1.0, 5.0, 60.0])
def test_gauss_markov_avar_matches_mpmath_across_switch(x):
    """Relative error <= 1e-13 from dt/T = 1e-15 to 60, on both sides of the series switch (m x =
    0.1)."""
    m = np.array([1, 2, 3, 7, 64, 1000, 2**18])
    got = gauss_markov_avar(m, 1.0, 1.0 / x, dt=1.0)
    ref = np.array([float(gm_avar_mpmath(int(mi), x)) for mi in m])
    np.testing.assert_allclose(got, ref, rtol=1e-13)


def test_gauss_markov_avar_of_a_vanishing_time_constant_is_white_without_warnings():
    """T = 1e-308 (dt/T beyond the largest float once times m): the bias is white noise of its
    variance, AVAR = s^2 / m, with no overflow warning (the suite turns warnings into errors)."""
    m = np.array([1, 10, 100, 4096])
    np.testing.assert_allclose(gauss_markov_avar(m, 2.0, 1e-308, dt=0.01), 2.0 / m, rtol=1e-15)


def test_gauss_markov_avar_broadcasts_rows_against_mpmath():
    """Variances ``(2, 1)`` and time constants ``(3,)`` -> ``(2, 3, n_tau)``; each row is its own
    process (rows on both sides of the switch, one with T = inf: zero AVAR, exactly)."""
    m = np.array([1, 3, 64, 5000])
    s2 = np.array([[2.0], [0.5]])
    t = np.array([4.0, 3e5, np.inf])
    got = gauss_markov_avar(m, s2, t, dt=1.0)
    assert got.shape == (2, 3, 4)
    for i in range(2):
        for j in range(2):
            ref = [float(s2[i, 0] * gm_avar_mpmath(int(mi), 1.0 / t[j])) for mi in m]
            np.testing.assert_allclose(got[i, j], ref, rtol=1e-13)
    assert np.all(got[:, 2] == 0.0)


def test_gauss_markov_tends_to_random_walk():
    """T -> infinity with sigma_b^2 dt/T fixed: AVAR -> rate random walk with K^2 dt = 2 sigma_b^2
    dt / T."""
    m = np.array([1, 4, 100])
    x = 1e-12
    gm = gauss_markov_avar(m, 1.0 / x, 1.0 / x, dt=1.0)  # sigma_b^2 x = 1
    np.testing.assert_allclose(gm, random_walk_avar(m, np.sqrt(2.0), dt=1.0), rtol=1e-10)


@pytest.mark.parametrize("term", sorted(REGISTRY))
def test_avar_equals_structure_function_form(term):
    """AVAR(m) = (4 D(m) - D(2m)) / (2 m^2) through :class:`NoiseModel`, every registered term
    alone or with what it requires, at the centre of its prior box; a deterministic term (no
    structure function, the ramp) has D = 0 and a positive AVAR instead."""
    terms = REGISTRY[term].requires + (term,)
    model = NoiseModel(terms, 0.1)
    p = {k: v for t in terms for k, v in params_of(REGISTRY[t]).items()}
    m = np.array([1, 2, 5, 16, 100])
    d = lambda k: model.structure_function(np.asarray(k), p)  # noqa: E731
    if np.all(d(np.arange(300)) == 0):
        assert np.all(model.avar(m, p) > 0)
        return
    np.testing.assert_allclose((4 * d(m) - d(2 * m)) / (2.0 * m * m), model.avar(m, p), rtol=1e-10)


def test_gauss_markov_structure_function_mpmath():
    for x in (1e-12, 1e-6, 1e-3, 0.3, 2.0):
        k = np.array([1, 2, 5, 100, 10**4, 10**6])
        got = structure_function(
            k, "gauss_markov", {"bias_variance": 1.0, "time_constant": 1.0 / x}, dt=1.0
        )
        with mp.workdps(60):
            phi = mp.e ** (-mp.mpf(x))
            ref = [
                float((int(kk) * (1 - phi**2) - 2 * phi * (1 - phi ** int(kk))) / (1 - phi) ** 2)
                for kk in k
            ]
        np.testing.assert_allclose(got, ref, rtol=1e-13)


def test_ramp_avar_equals_brute_force_overlapping_estimate():
    """A sampled ramp y_k = R dt k: the overlapping AVAR of the sequence (independent numpy
    second differences) equals R^2 tau^2 / 2 at every cluster size (deterministic, exact)."""
    dt, rate_ramp = 0.01, 3e-4
    y = rate_ramp * dt * np.arange(5000)
    x = np.concatenate([[0.0], np.cumsum(y)])
    m = np.array([1, 2, 7, 100, 1000])
    brute = [np.mean((x[2 * k:] - 2 * x[k:-k] + x[: -2 * k]) ** 2) / (2.0 * k * k) for k in m]
    model = NoiseModel(("ramp",), dt)
    np.testing.assert_allclose(model.avar(m, {"rate_ramp": rate_ramp}), brute, rtol=1e-9)


def test_two_gauss_markov_terms_add_and_are_ordered():
    """gauss_markov_2 adds its own exact AVAR (the same formula at its own parameters), needs
    gauss_markov, and the model lists the time constants fastest first for the ordering prior."""
    dt = 0.01
    model = NoiseModel(("white", "hf_correlated", "gauss_markov", "gauss_markov_2"), dt)
    p = {
        "noise_variance": 1.0,
        "correlated_variance": 0.5,
        "correlated_time_constant": 0.02,
        "bias_variance": 0.1,
        "time_constant": 5.0,
        "bias_variance_2": 0.01,
        "time_constant_2": 300.0,
    }
    m = np.array([1, 10, 1000, 10**5])
    ref = (
        p["noise_variance"] / m
        + gauss_markov_avar(m, 0.5, 0.02, dt=dt)
        + gauss_markov_avar(m, 0.1, 5.0, dt=dt)
        + gauss_markov_avar(m, 0.01, 300.0, dt=dt)
    )
    np.testing.assert_allclose(model.avar(m, p), ref, rtol=1e-14)
    names = model.parameter_names
    assert [names[i] for i in model.ordered] == [
        "correlated_time_constant",
        "time_constant",
        "time_constant_2",
    ]
    with pytest.raises(InputError, match="gauss_markov_2"):
        NoiseModel(("white", "gauss_markov_2"), dt)


def test_broadcasting_equals_loop(rng):
    model = NoiseModel(TERMS, 0.01)
    theta = np.exp(rng.uniform(-3, 3, size=(4, 5, len(model.parameter_names))))
    assert len(model.parameter_names) == sum(len(t.parameters) for t in REGISTRY.values())
    m = np.array([1, 3, 10, 300])
    batch = model.avar(m, theta)
    assert batch.shape == (4, 5, 4)
    for i in range(4):
        for j in range(5):
            # the same bits: a walker's Allan variance does not depend on the batch it is in
            # (every term, and the evaluator's sum of the power terms, works element by element)
            np.testing.assert_array_equal(batch[i, j], model.avar(m, theta[i, j]))
            own = sum(REGISTRY[t].avar(m.astype(float), dict(zip(model.parameter_names,
                                                                  theta[i, j])), 0.01)
                      for t in model.terms)
            np.testing.assert_allclose(batch[i, j], own, rtol=1e-14)


def test_model_validation():
    with pytest.raises(InputError, match="terms"):
        NoiseModel(("white", "pink"), 0.01)
    with pytest.raises(InputError, match="dt"):
        NoiseModel(("white",), 0.0)
    with pytest.raises(InputError, match="cluster sizes"):
        NoiseModel(("white",), 0.01).avar(np.array([0, 1]), {"noise_variance": 1.0})
    assert NoiseModel(("gauss_markov", "white"), 1.0).terms == ("white", "gauss_markov")


def _avar_brute(cov, m):
    """AVAR(m) from its definition: half the variance of the difference of adjacent m-sample means,
    a' S a / 2."""
    a = np.concatenate([-np.ones(m), np.ones(m)]) / m
    return 0.5 * a @ cov @ a


@pytest.mark.parametrize("m", [1, 3, 10])
def test_per_term_avar_functions_against_definitions(m):
    """white, quantization, rate random walk and ramp against covariance matrices built from each
    process's definition (dt = 0.25)."""
    from bayes_imu.noise.avar_forms import quantization_avar, ramp_avar, white_avar

    dt, n = 0.25, 2 * m
    # white: y_k iid, variance q
    assert white_avar(np.array([m]), 2.0)[0] == pytest.approx(
        _avar_brute(2.0 * np.eye(n), m), rel=1e-12
    )
    # quantization: phase noise e_k iid (variance Q^2), y_k = (e_{k+1} - e_k) / dt
    d = (np.eye(n + 1)[1:] - np.eye(n + 1)[:-1]) / dt
    cov = 0.3**2 * d @ d.T
    assert quantization_avar(np.array([m]), 0.3, dt=dt)[0] == pytest.approx(
        _avar_brute(cov, m), rel=1e-12
    )
    # rate random walk: y_k = sum_{i<=k} w_i, var(w) = K^2 dt (constant offsets cancel in the
    # contrast)
    i = np.arange(1, n + 1)
    cov = 0.1**2 * dt * np.minimum.outer(i, i)
    assert random_walk_avar(np.array([m]), 0.1, dt=dt)[0] == pytest.approx(
        _avar_brute(cov, m), rel=1e-12
    )
    # ramp: y_k = R k dt, deterministic: AVAR = (difference of the means)^2 / 2
    y = 0.7 * np.arange(n) * dt
    assert ramp_avar(np.array([m]), 0.7, dt=dt)[0] == pytest.approx(
        0.5 * (y[m:].mean() - y[:m].mean()) ** 2, rel=1e-12
    )


def test_bias_instability_avar_is_flat_at_its_definition():
    """Flicker: AVAR = 2 ln2 B^2 / pi at every m (IEEE Std 952's definition of B)."""
    from bayes_imu.noise.avar_forms import bias_instability_avar

    m = np.array([1, 2, 10, 1000])
    np.testing.assert_allclose(
        bias_instability_avar(m, 0.5), 2 * np.log(2) * 0.25 / np.pi, rtol=1e-12
    )


def test_quantities_are_one_table_and_unsupported_orders_raise():
    """Sensor kinds and drift quantities from one module: attitude from a gyro (order 1), velocity
    (1) and position (2) from an accelerometer; the drift tables are built from it; an order
    other than 1 or 2 raises."""
    from bayes_imu.drift.bands import SENSOR_QUANTITIES
    from bayes_imu.drift.closed_forms import QUANTITY_ORDER
    from bayes_imu.errors import ModelError
    from bayes_imu.noise import check_order
    from bayes_imu.noise.quantities import QUANTITIES, SENSORS, order_of, quantity, si_sensor

    assert {n: (q.sensor, q.order) for n, q in QUANTITIES.items()} == {
        "attitude": ("gyro", 1), "velocity": ("accel", 1), "position": ("accel", 2)}
    assert QUANTITY_ORDER == {"attitude": 1, "velocity": 1, "position": 2}
    assert SENSOR_QUANTITIES == {"gyro": ("attitude",), "accel": ("velocity", "position")}
    assert all(QUANTITIES[q].sensor == s for s, qs in SENSOR_QUANTITIES.items() for q in qs)
    assert SENSORS["gyro"].si_unit == "rad/s" and order_of("position") == 2
    with pytest.raises(InputError, match="quantity"):
        quantity("jerk")
    for bad in (0, 3, 2.5, True):
        with pytest.raises(ModelError, match="integration order"):
            check_order(bad)
    assert si_sensor(None, "m/s^2") == "accel" and si_sensor("gyro", "deg/s") is None
    with pytest.raises(InputError, match="accelerometer"):
        si_sensor("gyro", "m/s^2")


def test_allan_result_carries_its_sensor_kind(rng):
    """The sensor kind travels on the Allan result (and so on a fit) instead of a unit string."""
    from bayes_imu.allan.estimator import allan_variance

    y = rng.standard_normal(2000)
    a = allan_variance(y, rate_hz=100.0, sensor="gyro", segments=0)
    assert a.sensor == "gyro" and a.scaled(2.0).sensor == "gyro"
    assert a.with_sensor("accel").sensor == "accel"
    assert allan_variance(y, rate_hz=100.0, segments=0).sensor is None
    with pytest.raises(InputError, match="sensor"):
        allan_variance(y, rate_hz=100.0, sensor="magnetometer")
