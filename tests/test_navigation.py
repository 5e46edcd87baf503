"""The navigation channel's exact variances (:mod:`bayes_imu.drift.navigation`, ``nav_variance``).

References, each independent of the code under test:

* brute force: the loop's sample weights from ``scipy.linalg.expm`` of the continuous
  (loop + held input) system, stepped one sample at a time, and the quadratic form with the
  samples' covariance written from each term's definition (or, calibrated, ``-1/2 a' D a`` with
  the phase weights ``a`` and the term's own structure function ``D``, which the AVAR tests
  check separately);
* mpmath at 40 digits for the loop functions and for the white / random-walk sums at 0.01 s - 6 h;
* a Monte Carlo of an independent simulation (the term's simulator, the loop stepped by expm);
* the textbook uncoupled forms (``g b t^3/6``, ``g N sqrt(t^5/20)``) and the drift of order 1.
"""

import mpmath as mp
import numpy as np
import pytest
import scipy.linalg as sl

from bayes_imu.drift.navigation import (
    EARTH_RADIUS,
    GRAVITY,
    NavLoop,
    loop_functions,
    schuler_period_s,
)
from bayes_imu.errors import InputError
from bayes_imu.noise.model import REGISTRY

PARAMS = {
    "white": {"noise_variance": 2.0},
    "quantization": {"quantization": 0.3},
    "filtered_white": {"filtered_variance": 0.7},
    "hf_correlated": {"correlated_variance": 0.8, "correlated_time_constant": 1.2},
    "bias_instability": {"bias_instability": 0.4},
    "gauss_markov": {"bias_variance": 1.5, "time_constant": 3.0},
    "gauss_markov_2": {"bias_variance_2": 0.6, "time_constant_2": 40.0},
    "random_walk": {"rate_random_walk": 0.2},
    "ramp": {"rate_ramp": 0.05},
    "vibration": {"vibration_frequency": 0.37, "vibration_amplitude": 0.5},
}
STRONG_R = 200.0  # a Schuler period of 28 s: the coupling matters within the brute-force horizons


def expm_weights(sensor, k, dt, radius):
    """``W[j]`` ``(k, 3)``: (tilt, velocity, position) from a unit sample ``k-1-j`` steps back."""
    f = np.zeros((4, 4))
    f[0, 1] = 0.0 if radius is None else 1.0 / radius
    f[1, 0] = -GRAVITY
    f[2, 1] = 1.0
    f[0 if sensor == "gyro" else 1, 3] = 1.0
    e = sl.expm(f * dt)
    out = np.empty((k, 3))
    x = e[:3, 3].copy()
    for j in range(k):
        out[j] = x
        x = e[:3, :3] @ x
    return out[::-1]


def sample_cov(name, params, idx, dt, bias_start):
    """Covariance (ramp: outer product of the values) of samples ``idx``, from the definitions."""
    i, j = np.meshgrid(idx, idx, indexing="ij")
    lag = np.abs(i - j)
    if name == "white":
        return params["noise_variance"] * (lag == 0)
    if name == "quantization":
        q = params["quantization"] / dt
        return q * q * (2.0 * (lag == 0) - (lag == 1))
    if name == "filtered_white":
        return params["filtered_variance"] * (2.0 * (lag == 0) + (lag == 1))
    if name in ("hf_correlated", "gauss_markov", "gauss_markov_2"):
        s2, t = (params[p] for p in REGISTRY[name].parameters)
        phi = np.exp(-dt / t)
        cov = s2 * phi**lag
        return cov * (1.0 - phi ** (2.0 * np.minimum(i, j))) if bias_start == "zero" else cov
    if name == "random_walk":
        return params["rate_random_walk"] ** 2 * dt * np.minimum(i, j)
    if name == "vibration":
        omega = 2.0 * np.pi * params["vibration_frequency"] * dt
        return 0.5 * params["vibration_amplitude"] ** 2 * np.cos(omega * lag)
    if name == "ramp":
        y = params["rate_ramp"] * dt * idx
        return np.outer(y, y)
    raise KeyError(name)


def brute(name, params, sensor, k, dt, bias_start, n_cal, radius):
    """Variance ``(3,)`` by the explicit quadratic form over the samples."""
    w = expm_weights(sensor, k, dt, radius)
    if name == "bias_instability" and bias_start != "calibrated":
        bias_start, n_cal = "calibrated", k
    if bias_start != "calibrated":
        cov = sample_cov(name, params, np.arange(k, dtype=float), dt, bias_start)
        return np.einsum("pi,pq,qi->i", w, cov, w)
    c = np.vstack([np.repeat(-w.sum(0)[None] / n_cal, n_cal, axis=0), w])
    if name in ("ramp",):
        cov = sample_cov(name, params, np.arange(-n_cal, k, dtype=float), dt, bias_start)
        return np.einsum("pi,pq,qi->i", c, cov, c)
    a = np.zeros((c.shape[0] + 1, 3))
    a[1:] += c
    a[:-1] -= c
    p = np.arange(a.shape[0], dtype=float)
    d = REGISTRY[name].structure(np.abs(p[:, None] - p[None, :]), params, dt)
    return -0.5 * np.einsum("pi,pq,qi->i", a, d, a)


def arrays(params):
    return {key: np.asarray(value, float) for key, value in params.items()}


def test_every_registered_term_has_a_reference():
    """A new term must bring its brute-force reference here (and its nav_variance)."""
    assert set(PARAMS) == set(REGISTRY)


@pytest.mark.parametrize("name", sorted(REGISTRY))
@pytest.mark.parametrize("sensor", ["gyro", "accel"])
@pytest.mark.parametrize("bias_start", ["calibrated", "zero", "stationary"])
@pytest.mark.parametrize("radius", [STRONG_R, None])
def test_term_matches_brute_force(name, sensor, bias_start, radius):
    dt, n_cal = 0.5, 7
    k = np.array([1.0, 2.0, 9.0, 60.0])
    loop = NavLoop(sensor, schuler=radius is not None, radius=radius or EARTH_RADIUS)
    got = REGISTRY[name].nav_variance(
        loop, k, arrays(PARAMS[name]), dt, bias_start=bias_start, n_cal=n_cal
    )
    ref = np.array(
        [brute(name, PARAMS[name], sensor, int(n), dt, bias_start, n_cal, radius) for n in k]
    )
    assert got.shape == (k.size, 3)
    scale = np.max(
        np.abs(ref), axis=0, keepdims=True
    )  # tilt from an accelerometer is 0 without Schuler
    # a line's undamped rotation, powered by doubling, loses ~1e-10 relative where its weights
    # nearly cancel over whole periods (|sum w e^(i omega t)| small against its parts)
    rtol = 1e-9 if name == "vibration" else 1e-11
    np.testing.assert_allclose(got, ref, rtol=rtol, atol=1e-13 * scale.max())
    np.testing.assert_array_less(np.abs(got - ref), rtol * np.abs(ref) + 1e-14 * scale + 1e-300)


@pytest.mark.parametrize("name", ["gauss_markov", "hf_correlated", "random_walk", "white"])
def test_batch_equals_loop(name):
    """Broadcast parameters ``(n,)`` give the per-draw results."""
    loop = NavLoop("gyro")
    scale = np.array([0.5, 1.0, 3.0])
    params = {p: v * scale for p, v in PARAMS[name].items()}
    k = np.array([3.0, 50.0, 2000.0])
    batch = REGISTRY[name].nav_variance(loop, k, params, 0.01, n_cal=100)
    assert batch.shape == (3, k.size, 3)
    for i in range(3):
        one = REGISTRY[name].nav_variance(
            loop, k, {p: v[i] for p, v in params.items()}, 0.01, n_cal=100
        )
        np.testing.assert_allclose(batch[i], one, rtol=1e-13)


@pytest.mark.parametrize("w", [0.0, 1.2407e-3, 1.0])
def test_loop_functions_against_mpmath(w):
    """``S, K, J`` on both sides of J's series switch (``w t = 0.5``) and down to ``w t = 1e-8``."""
    mp.mp.dps = 40
    z = np.array([1e-8, 1e-3, 0.3, 0.4999, 0.5, 0.5001, 0.9, 2.0, 30.0, 26.8])
    t = z / w if w else z
    s, k, j = loop_functions(w, t)
    for ti, si, ki, ji in zip(t, s, k, j):
        tm, wm = mp.mpf(ti), mp.mpf(w)
        if w == 0:
            ref = (tm, tm**2 / 2, tm**3 / 6)
        else:
            ref = (
                mp.sin(wm * tm) / wm,
                (1 - mp.cos(wm * tm)) / wm**2,
                (wm * tm - mp.sin(wm * tm)) / wm**3,
            )
        for got, r in zip((si, ki, ji), ref):
            assert abs(got - float(r)) <= 1e-14 * abs(float(r)) + 1e-300  # a few ulp (sinc of z/pi)


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
@pytest.mark.parametrize("schuler", [True, False])
def test_transition_is_the_matrix_exponential(sensor, schuler):
    loop = NavLoop(sensor, schuler=schuler)
    for dt in (0.01, 1.0, 300.0):
        phi, gam = loop.transition(dt)
        ref = expm_weights(sensor, 2, dt, EARTH_RADIUS if schuler else None)
        np.testing.assert_allclose(gam, ref[1], rtol=1e-12, atol=1e-300)
        f = np.zeros((3, 3))
        f[0, 1], f[1, 0], f[2, 1] = (1.0 / EARTH_RADIUS if schuler else 0.0), -GRAVITY, 1.0
        np.testing.assert_allclose(phi, sl.expm(f * dt), rtol=1e-12, atol=1e-15)


def test_schuler_period():
    assert schuler_period_s() / 60.0 == pytest.approx(84.4, abs=0.05)


def mp_white_sum(sensor, quantity, k, dt, n_cal, w):
    """``sum c_i^2`` of the calibrated white-noise error in mpmath (closed-form ZOH weights)."""
    g = mp.mpf(GRAVITY)
    d = mp.mpf(dt)

    def cum(t):  # response to a unit constant input over [0, t]
        s, c = mp.sin(w * t) / w, (1 - mp.cos(w * t)) / w**2
        jj = (w * t - mp.sin(w * t)) / w**3
        return {"accel": (w * w / g * c, s, c), "gyro": (s, -g * c, -g * jj)}[sensor][quantity]

    prev, total = mp.mpf(0), mp.mpf(0)
    for j in range(1, k + 1):
        cur = cum(j * d)
        total += (cur - prev) ** 2
        prev = cur
    return total + prev**2 / n_cal


@pytest.mark.parametrize(
    "t, dt", [(0.01, 0.01), (0.05, 0.01), (10.0, 0.01), (600.0, 0.5), (21600.0, 10.0)]
)
def test_white_against_mpmath_from_10ms_to_6h(t, dt):
    mp.mp.dps = 40
    w = mp.sqrt(mp.mpf(GRAVITY) / EARTH_RADIUS)
    k, n_cal = int(round(t / dt)), int(round(60.0 / dt))
    for sensor in ("gyro", "accel"):
        got = REGISTRY["white"].nav_variance(
            NavLoop(sensor), np.array([float(k)]), {"noise_variance": 1.0}, dt, n_cal=n_cal
        )[0]
        for i, quantity in enumerate((0, 1, 2)):
            ref = float(mp_white_sum(sensor, quantity, k, dt, n_cal, w))
            assert got[i] == pytest.approx(ref, rel=2e-12)


@pytest.mark.parametrize(
    "horizons", [(0.02, 1.0, 300.0, 3600.0), pytest.param((21600.0,), marks=pytest.mark.slow)]
)
def test_white_and_random_walk_stable_at_100hz_to_6h(horizons):
    """At 100 Hz out to 6 h (2.16e6 samples; 6 h is ``slow``): white against ``sum c_i^2`` and
    random walk against ``sum_n H(n)^2 + H(k)^2 (N-1)(2N-1)/(6N)``, both from product forms
    summed in extended precision."""
    dt, n_cal = 0.01, 6000
    w = np.sqrt(GRAVITY / EARTH_RADIUS)
    ld = np.longdouble
    for t in horizons:
        k = int(round(t / dt))
        j = np.arange(k, dtype=ld)
        m = (j + ld(0.5)) * ld(dt)
        s1 = np.sin(ld(w) * ld(dt) / 2) / ld(w)
        c_pos = 2 * s1 * np.sin(ld(w) * m) / ld(w)  # accelerometer -> position per sample
        n = np.arange(1, k + 1, dtype=ld) * ld(dt)
        h_pos = (
            2 * (np.sin(ld(w) * n / 2) / ld(w)) ** 2
        )  # accelerometer -> position, constant input
        white_ref = float(np.sum(c_pos**2) + h_pos[-1] ** 2 / n_cal)
        rw_ref = float(
            dt * (np.sum(h_pos**2) + h_pos[-1] ** 2 * (n_cal - 1) * (2 * n_cal - 1) / (6 * n_cal))
        )
        kk = np.array([float(k)])
        white = REGISTRY["white"].nav_variance(
            NavLoop("accel"), kk, {"noise_variance": 1.0}, dt, n_cal=n_cal
        )
        walk = REGISTRY["random_walk"].nav_variance(
            NavLoop("accel"), kk, {"rate_random_walk": 1.0}, dt, n_cal=n_cal
        )
        assert white[0, 2] == pytest.approx(white_ref, rel=1e-10)
        assert walk[0, 2] == pytest.approx(rw_ref, rel=1e-10)


@pytest.mark.parametrize("name", sorted(REGISTRY))
@pytest.mark.parametrize("bias_start", ["calibrated", "zero", "stationary"])
def test_schuler_off_tilt_and_velocity_are_the_drift_of_order_one(name, bias_start):
    """Loop off: gyro -> tilt and accelerometer -> velocity are ``dt sum e_i``, the drift."""
    k = np.array([1.0, 4.0, 33.0, 500.0])
    params, dt, n_cal = arrays(PARAMS[name]), 0.02, 40
    drift = REGISTRY[name].drift_variance(1, k, params, dt, bias_start=bias_start, n_cal=n_cal)
    for sensor, column in (("gyro", 0), ("accel", 1)):
        nav = REGISTRY[name].nav_variance(
            NavLoop(sensor, schuler=False), k, params, dt, bias_start=bias_start, n_cal=n_cal
        )
        np.testing.assert_allclose(nav[:, column], drift, rtol=1e-10, atol=1e-300)


def test_textbook_uncoupled_forms():
    """Constant gyro bias: position ``g b t^3/6``; ARW ``g N sqrt(t^5/20)`` as dt -> 0."""
    loop = NavLoop("gyro", schuler=False)
    t = np.array([0.01, 10.0, 3600.0])
    np.testing.assert_allclose(-loop.response(t)[2], GRAVITY * t**3 / 6.0, rtol=1e-15)
    dt, q = 0.001, 1e-6  # N^2 = q dt
    for t in (1.0, 10.0):
        var = REGISTRY["white"].nav_variance(
            loop, np.array([t / dt]), {"noise_variance": q}, dt, bias_start="zero"
        )
        textbook = GRAVITY**2 * q * dt * t**5 / 20.0
        assert var[0, 2] == pytest.approx(textbook, rel=3 * (dt / t) ** 2)


def test_schuler_bounds_the_gyro_bias_error():
    """Constant gyro bias, loop on: position ``-(g/w^2)(t - sin(wt)/w)``, velocity oscillates."""
    loop = NavLoop("gyro")
    w = loop.omega
    t = np.array([1.0, 600.0, schuler_period_s(), 6 * 3600.0])
    mp.mp.dps = 30
    ref = [float(-mp.mpf(GRAVITY) / w**2 * (ti - mp.sin(w * ti) / w)) for ti in t]
    np.testing.assert_allclose(loop.response(t)[2], ref, rtol=1e-13)
    assert abs(loop.response(schuler_period_s())[1]) < 1e-9  # velocity back to 0 after one period


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_monte_carlo_of_an_independent_simulation(sensor, rng):
    """White + Gauss-Markov + random walk simulated with the terms' simulators, the loop stepped
    with expm (strong Schuler loop), calibrated: sample variances within 5 sigma (chi-square
    relative sd sqrt(2/n) = 2.2 % at n = 4000)."""
    dt, n_cal, k, n = 0.5, 20, 80, 4000
    radius = STRONG_R
    names = ("white", "gauss_markov", "random_walk")
    f = np.zeros((4, 4))
    f[0, 1], f[1, 0], f[2, 1] = 1.0 / radius, -GRAVITY, 1.0
    f[0 if sensor == "gyro" else 1, 3] = 1.0
    e = sl.expm(f * dt)
    y = np.zeros((n, n_cal + k))
    for name in names:
        y += np.array([REGISTRY[name].simulate(PARAMS[name], n_cal + k, dt, rng) for _ in range(n)])
    err = y[:, n_cal:] - y[:, :n_cal].mean(axis=1, keepdims=True)
    x = np.zeros((n, 3))
    for i in range(k):
        x = x @ e[:3, :3].T + err[:, i : i + 1] * e[:3, 3]
    loop = NavLoop(sensor, radius=radius)
    exact = sum(
        REGISTRY[name].nav_variance(
            loop, np.array([float(k)]), arrays(PARAMS[name]), dt, n_cal=n_cal
        )[0]
        for name in names
    )
    sample = x.var(axis=0)
    for i in range(3) if sensor == "gyro" else range(3):
        assert abs(sample[i] / exact[i] - 1.0) < 5 * np.sqrt(2.0 / n), (i, sample[i], exact[i])


def test_bad_sensor():
    with pytest.raises(InputError, match="sensor='magnetometer'"):
        NavLoop("magnetometer")


def _flicker_form(sensor, k, n_cal, dt):
    """The calibrated error's flicker variance (tilt, velocity, position) at B = 1 as the
    phase-structure quadratic form, summed in extended precision, over expm_weights' response."""
    w = expm_weights(sensor, k, dt, EARTH_RADIUS)
    c = np.vstack([np.repeat(-w.sum(0)[None] / n_cal, n_cal, axis=0), w]).astype(np.longdouble)
    a = np.zeros((c.shape[0] + 1, 3), dtype=np.longdouble)
    a[1:] += c
    a[:-1] -= c
    lag = np.arange(a.shape[0], dtype=np.longdouble)
    d = np.zeros(lag.shape, dtype=np.longdouble)
    d[1:] = -(lag[1:] ** 2) * np.log(lag[1:]) / np.pi  # flicker D(l) at B = 1
    idx = np.arange(a.shape[0])
    dmat = d[np.abs(idx[:, None] - idx[None, :])]
    return np.array([-0.5 * (a[:, i] @ dmat @ a[:, i]) for i in range(3)], dtype=float)


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_flicker_fft_at_long_outages(sensor):
    """The FFT quadratic form against the phase-structure form summed in extended precision
    (2300 samples, realistic Schuler loop, 100 Hz)."""
    dt, n_cal, k = 0.01, 300, 2000
    ref = _flicker_form(sensor, k, dt=dt, n_cal=n_cal)
    got = REGISTRY["bias_instability"].nav_variance(
        NavLoop(sensor), np.array([float(k)]), {"bias_instability": 1.0}, dt, n_cal=n_cal
    )[0]
    np.testing.assert_allclose(got, ref, rtol=1e-10)


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_flicker_outages_of_one_call(sensor):
    """Several outages and windows in one ``increment_variance`` call (the response and the
    increments' autocovariance computed once, for the longest, and sliced for the others) against
    the extended-precision form of each alone; an outage under one sample is 0; the
    autocovariance is asked for once."""
    from bayes_imu.noise.bias_instability import flicker_increment_acov

    dt = 0.05
    k = np.array([1.0, 7.0, 0.5, 150.0, 40.0, 600.0])
    n_cal = np.array([40.0, 300.0, 10.0, 20.0, 1.0, 300.0])
    calls = []

    def acov(size):
        calls.append(size)
        return flicker_increment_acov(size, 1.0)

    got = NavLoop(sensor).increment_variance(k, dt, n_cal, acov)
    assert calls == [int(max(n + kk for n, kk in zip(n_cal, k))) - 1]
    np.testing.assert_array_equal(got[2], 0.0)
    for i in (0, 1, 3, 4, 5):
        ref = _flicker_form(sensor, int(k[i]), dt=dt, n_cal=int(n_cal[i]))
        np.testing.assert_allclose(got[i], ref, rtol=1e-10, atol=1e-14 * ref.max(),
                                   err_msg=f"outage {k[i]}, window {n_cal[i]}")


@pytest.mark.slow  # ~20 s: the grade table's 3.6e5 covariance steps per grade
def test_grade_table_matches_van_loan():
    """scripts/validate_navigation.py grades: Groves' three grade models, nav_variance against the
    step-by-step Van Loan propagation, within 1e-6 relative (exit status 0)."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "scripts" / "validate_navigation.py"
    proc = subprocess.run([sys.executable, str(script), "grades"], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    worst = float(re.search(r"Worst relative difference ([\d.e+-]+)", proc.stdout).group(1))
    assert worst < 1e-6


def test_flicker_increment_acov_against_mpmath():
    """``gamma(l) = (h/2) delta^4 (l^2 ln l)`` at 50 digits, both sides of the series switch (lag
    16)."""
    from bayes_imu.noise.bias_instability import flicker_increment_acov

    mp.mp.dps = 50

    def f(lag):
        return mp.mpf(lag) ** 2 * mp.log(lag) if lag > 0 else mp.mpf(0)

    lags = [0, 1, 2, 15, 16, 17, 100, 1000, 100000]
    got = flicker_increment_acov(lags[-1] + 1, 1.0)
    for lag in lags:
        terms = 6 * f(lag) - 4 * f(lag + 1) - 4 * f(abs(lag - 1)) + f(lag + 2) + f(abs(lag - 2))
        ref = float(terms / (2 * mp.pi))
        assert got[lag] == pytest.approx(ref, rel=1e-14 if lag < 16 else 1e-15), lag


def test_propagated_diagonal_against_the_step_recursion():
    """_propagate_diagonal (the compiled binary powering that carries only the rows its diagonal
    needs) against the plain recursion P_(m+1) = A P_m A' + Q stepped one sample at a time: eight
    lengths to 2999 samples, compared as the recursion passes them, batched and broadcast, with a
    Schuler-like rotation, a decaying state and an integrator of a constant (a Jordan block:
    eigenvalue 1 twice, an error growing with the length), to 1e-11 relative; and the first rows'
    diagonal of the full matrices (_propagate, numpy) to the same. Edge cases: no length, lengths
    all 0 (the start's diagonal), an unbatched A beside a batched input, more rows than states."""
    from bayes_imu.drift.navigation import _propagate, _propagate_diagonal

    rng = np.random.default_rng(11)
    w = 2 * np.pi / 500.0
    base = np.zeros((5, 5))
    base[:2, :2] = [[np.cos(w), np.sin(w)], [-np.sin(w), np.cos(w)]]
    base[2, 1], base[2, 2] = 0.01, 1.0  # integrates the rotation's second state
    base[:2, 3] = [0.02, -0.01]
    base[3, 3] = 0.999  # a Gauss-Markov state
    base[4, 4] = 1.0  # a constant (the calibration's mean)
    base[2, 4] = 0.01  # integrated by state 2: a Jordan block of eigenvalue 1
    a = np.stack([base, base * np.r_[1.0, 1.0, 1.0, 0.5, 1.0][:, None]])
    b = rng.standard_normal((2, 5, 2)) * 0.1
    p0 = np.eye(5) * 0.3  # broadcast over the batch
    k = np.array([0, 1, 2, 3, 17, 250, 1024, 2999], dtype=float)
    got = _propagate_diagonal(a, b, p0, k, 3)
    assert got.shape == (2, k.size, 3)
    for i in range(2):
        p, q = np.broadcast_to(p0, (5, 5)).copy(), b[i] @ b[i].T
        for m in range(int(k.max()) + 1):
            hit = np.flatnonzero(k == m)
            if hit.size:
                np.testing.assert_allclose(got[i, hit[0]], np.diag(p)[:3], rtol=1e-11)
            p = a[i] @ p @ a[i].T + q
    full = _propagate(a, b, p0, k)
    np.testing.assert_allclose(got, np.diagonal(full, axis1=-2, axis2=-1)[..., :3], rtol=1e-11)
    assert _propagate_diagonal(a, b, p0, np.zeros(0), 3).shape == (2, 0, 3)
    start = np.diag(np.arange(1.0, 6.0))
    np.testing.assert_array_equal(_propagate_diagonal(a, b, start, np.zeros(4), 3),
                                  np.broadcast_to([1.0, 2.0, 3.0], (2, 4, 3)))
    one = _propagate_diagonal(base, b, p0, k, 2)  # A unbatched, B batched
    np.testing.assert_allclose(one[0], got[0, :, :2], rtol=1e-11)
    with pytest.raises(ValueError, match="n=6"):
        _propagate_diagonal(a, b, p0, k, 6)


@pytest.mark.parametrize("build", ["loaded", "jit"])
def test_the_propagation_kernel_leaves_the_interpreter_free(build, monkeypatch):
    """The compiled propagation releases the GIL while it runs (setup.py's RELEASE_GIL for the
    precompiled build, nogil for the JIT build): this thread runs Python while the kernel works on
    a batch in another, so the picture's import overlaps the bands (report.nav). Held, this thread
    would run only after the kernel's end. ``loaded``: the build the package loads (the
    precompiled one where it was built); ``jit``: numba's JIT build, as without the extension."""
    import importlib
    import threading
    import time

    from bayes_imu.allan import kernels

    module = importlib.import_module("bayes_imu.drift.navigation")
    if build == "jit":
        monkeypatch.setattr(kernels, "precompiled", lambda: None)
        monkeypatch.setattr(module, "_diagonal_kernel", None)
    rng = np.random.default_rng(2)
    n = 16000
    k = np.ascontiguousarray(np.round(np.geomspace(1, 720000, 33)).astype(np.int64))
    a = np.broadcast_to(np.eye(6) * 0.999, (n, 6, 6)).copy()
    q = rng.standard_normal((n, 6, 6))
    p0 = np.broadcast_to(np.eye(6), (n, 6, 6)).copy()
    out = np.empty((n, k.size, 3))
    module._propagate_diagonal(a[:1], q[:1, :, :1], p0[:1], k, 3)  # the kernel loaded
    kernel = module._diagonal_kernel

    def spin(event):
        """This thread's loop count until ``event`` is set."""
        count = 0
        while not event.is_set():
            count += 1
        return count

    stop = threading.Event()
    start = time.perf_counter()
    threading.Timer(0.1, stop.set).start()
    rate = spin(stop) / (time.perf_counter() - start)  # the loop alone, per second
    started, done, took = threading.Event(), threading.Event(), []

    def work():
        started.set()
        begin = time.perf_counter()
        kernel(a, q, p0, k, out)
        took.append(time.perf_counter() - begin)
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    started.wait()
    spins = spin(done)
    worker.join()
    # the share of the kernel's time this loop ran: ~1 where the kernel leaves the interpreter
    # free (less on a busy machine: the threads share its CPUs), ~0.01 where it holds it (measured:
    # 0.97-1.02 and 0.012-0.028)
    assert spins / (rate * took[0]) > 0.1, (spins, rate, took[0])
