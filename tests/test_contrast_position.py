"""The calibrated-outage position (order 2) error measured from the record: the estimator
(allan.contrast.position_mean_square), its covariance and EDF (noise.contrast_covariance,
``order=2``) and the position bands built on them (drift.direct, drift.bands).

References, none of them the package's own formulas:

* explicit loops over every outage start of the paper's Euler sums (``v_j = dt sum_{i<j} e_i``,
  ``p = dt sum_{j<k} v_j``, ``e_i = y_i - mean of the N samples before the outage``) in exact
  float sums (``math.fsum``);
* the estimator's own quadratic form ``V_hat_2 = y' Q y`` (read off the estimator by
  polarisation) against the rate samples' generalised covariance ``G`` built from the structure
  function: ``E V_hat_2 = tr(Q G)``, which must equal the model's order-2 drift variance;
* the covariance of two starts ``d`` apart as ``w' G w_d`` over explicit Euler weights;
* Monte Carlo with the stated tolerance.
"""

import math

import numpy as np
import pytest

from bayes_imu.allan.contrast import contrast_stride, phase_contrasts
from bayes_imu.allan.estimator import allan_variance
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.contrast_covariance import contrast_edf, position_covariance
from bayes_imu.noise.simulate import simulate_log

DT = 0.1
MODELS = [
    (("white",), {"noise_variance": 1.0}),
    (("white", "gauss_markov"), {"noise_variance": 1.0, "bias_variance": 0.05,
                                 "time_constant": 3.0}),
    (("white", "random_walk"), {"noise_variance": 1.0, "rate_random_walk": 0.05}),
    (("white", "bias_instability"), {"noise_variance": 1.0, "bias_instability": 0.3}),
    (("white", "quantization"), {"noise_variance": 1.0, "quantization": 0.5}),
]


def _euler_position(y, j, k, n_cal, dt):
    """``p_k`` of the outage starting at sample ``j`` by the Euler sums (exact float sums)."""
    bias = math.fsum(y[j - n_cal:j]) / n_cal
    v = [dt * math.fsum(y[j + i] - bias for i in range(m)) for m in range(k)]
    return dt * math.fsum(v)


def _brute_force(y, k, n_cal, dt, stride=1):
    """Mean square of ``p_k`` over the starts ``N, N + stride, ..., <= n - k``, and their count."""
    squares = [_euler_position(y, j, k, n_cal, dt) ** 2
               for j in range(n_cal, y.size - k + 1, stride)]
    return math.fsum(squares) / len(squares), len(squares)


@pytest.mark.parametrize("k,n_cal", [(2, 1), (2, 3), (3, 7), (7, 3), (5, 5), (20, 9), (9, 31)])
def test_position_estimator_equals_the_euler_sums(rng, k, n_cal):
    # a large offset (gravity) and a ramp in the rate: the contrast annihilates both of the
    # phase's constant and linear parts, the ramp's quadratic part is the drift it leaves
    y = 9810.0 + rng.standard_normal(90) + 0.05 * np.arange(90)
    c = phase_contrasts(y, rate_hz=1 / DT, calibration_s=n_cal * DT, k=[k])
    expected, count = _brute_force(y, k, n_cal, DT)
    np.testing.assert_allclose(c.mean_square_2[0], expected, rtol=1e-9)
    assert c.n_terms[0] == count


def test_position_estimator_without_offset_to_1e_12(rng):
    y = rng.standard_normal(120)
    for k, n_cal in ((2, 3), (7, 3), (20, 9)):
        c = phase_contrasts(y, rate_hz=1 / DT, calibration_s=n_cal * DT, k=[k])
        np.testing.assert_allclose(c.mean_square_2[0], _brute_force(y, k, n_cal, DT)[0],
                                   rtol=1e-12)


def test_strided_position_estimator_and_the_first_outage(rng):
    """Spans of 32 samples and more average every (k + N) // 32-th start (as order 1); at k = 1
    the position error is exactly 0, and position is measured from k = 2 on."""
    y = rng.standard_normal(700)
    for k, n_cal in ((40, 30), (100, 64), (7, 90)):
        stride = int(contrast_stride(k, n_cal))
        c = phase_contrasts(y, rate_hz=2.0, calibration_s=n_cal / 2.0, k=[k])
        expected, count = _brute_force(y, k, n_cal, 0.5, stride)
        np.testing.assert_allclose(c.mean_square_2[0], expected, rtol=1e-10)
        assert c.n_terms[0] == count
    c = phase_contrasts(y, rate_hz=2.0, calibration_s=5.0, k=[1, 2, 4])
    assert c.mean_square_2[0] == 0.0
    second = c.of_order(2)
    assert second.order == 2 and list(second.k) == [2, 4]
    np.testing.assert_array_equal(second.mean_square, c.mean_square_2[1:])
    assert c.of_order(1) is c and second.covers(np.array([0.5, 1.0, 2.0])).tolist() == [
        False, True, True]
    scaled = c.scaled(3.0)
    np.testing.assert_allclose(scaled.mean_square_2, 9.0 * c.mean_square_2, rtol=1e-15)


def _rate_covariance(model, params, n):
    """``(n, n)`` generalised covariance of the rate samples from the structure function."""
    lag = np.abs(np.arange(n)[:, None] - np.arange(n)[None, :]).astype(float)
    d = lambda l: model.structure_function(l, params)  # noqa: E731
    return 0.5 * (d(lag + 1.0) - 2.0 * d(lag) + d(np.abs(lag - 1.0)))


def _quadratic_form(n, k, n_cal):
    """``Q`` with ``V_hat_2 / dt^4 = y' Q y``, read off the estimator by polarisation."""
    def v(y):
        return phase_contrasts(y, rate_hz=1.0, calibration_s=float(n_cal), k=[k]).mean_square_2[0]

    eye = np.eye(n)
    diag = np.array([v(eye[i]) for i in range(n)])
    q = np.diag(diag)
    for i in range(n):
        for j in range(i + 1, n):
            q[i, j] = q[j, i] = 0.5 * (v(eye[i] + eye[j]) - diag[i] - diag[j])
    return q


@pytest.mark.parametrize("terms,params", MODELS)
def test_position_estimator_is_unbiased_for_the_exact_quadratic_form(terms, params):
    """``E V_hat_2 = tr(Q G)`` is the model's order-2 calibrated drift variance (any noise with
    stationary increments: random walk and flicker included)."""
    model = NoiseModel(terms, DT)
    n = 36
    g = _rate_covariance(model, params, n)
    for k, n_cal in ((2, 5), (6, 4), (11, 9)):
        q = _quadratic_form(n, k, n_cal)
        expected = DT**4 * np.trace(q @ g)
        drift = sum(t.drift_variance(2, np.array([float(k)]), params, DT,
                                     bias_start="calibrated", n_cal=float(n_cal))[0]
                    for t in model.components)
        np.testing.assert_allclose(expected, drift, rtol=1e-9)


def _euler_weights(k, n_cal):
    """``p_k / dt^2 = w' y`` over ``y_{-N} .. y_{k-1}``."""
    outage = k - 1 - np.arange(k, dtype=float)
    return np.concatenate([-outage.sum() / n_cal * np.ones(n_cal), outage])


@pytest.mark.parametrize("terms,params", MODELS)
def test_position_covariance_against_every_pair(terms, params):
    """``Cov(p_j, p_{j+d}) = w' G w_d`` (weights ``d`` samples apart): exact within 8 spans
    ``k + N`` (1e-9), the far region's moment term within 3% of the largest far value (exactly 0
    for a white, random-walk or quantization model)."""
    model = NoiseModel(terms, 1.0)
    for k, n_cal in ((2, 6), (5, 7), (12, 4)):
        span = k + n_cal
        d = np.array([0, 1, 2, 5, span - 1, span, span + 3, 4 * span, 8 * span, 9 * span,
                      12 * span, 20 * span], dtype=float)
        w = _euler_weights(k, n_cal)
        g = _rate_covariance(model, params, w.size + int(d.max()))
        ref = np.array([w @ g[: w.size, int(di): int(di) + w.size] @ w for di in d])
        got = position_covariance(model, params, [k], n_cal, [d])[0]
        near = d <= 8 * span
        scale = np.abs(ref).max()
        np.testing.assert_allclose(got[near], ref[near], rtol=1e-9, atol=1e-12 * scale)
        far_scale = max(np.abs(ref[~near]).max(), 1e-9 * scale)
        np.testing.assert_allclose(got[~near], ref[~near], atol=0.03 * far_scale)


def test_position_covariance_reuses_the_last_tables_of_a_point_to_the_bit(monkeypatch):
    """A bound search asks for one parameter point at outage after outage: within
    ``reused_sums``, the structure-function sums made for a longer table are reused for a shorter
    one (every term, and the far-lag terms alone), and give the same numbers, bit for bit, as
    tables made afresh; another point is computed anew; outside, nothing is kept."""
    import bayes_imu.noise.contrast_covariance as cc

    model = NoiseModel(("white", "gauss_markov", "vibration"), 1.0)
    params = {"noise_variance": 1.0, "bias_variance": 0.3, "time_constant": 40.0,
              "vibration_frequency": 0.11, "vibration_amplitude": 0.5}
    cases = [(400, [0.0, 3.0, 50.0, 9000.0, 20_000.0]), (30, [0.0, 1.0, 800.0, 3000.0]),
             (120, [0.0, 7.0, 2500.0])]
    monkeypatch.setattr(cc, "_LAST_SUMS", [])
    made = []
    real_sums = cc._sums

    def counted(structure, wanted, key=None):
        before = list(cc._LAST_SUMS)
        out = real_sums(structure, wanted, key)
        made.append(cc._LAST_SUMS != before)
        return out

    monkeypatch.setattr(cc, "_sums", counted)
    with cc.reused_sums():
        reused = [position_covariance(model, params, [k], 9, [np.array(d)])[0] for k, d in cases]
        assert made[:2] == [True, True] and not any(made[2:])  # two tables, then reused
        other = dict(params, time_constant=41.0)
        moved = position_covariance(model, other, [30], 9, [np.array(cases[1][1])])[0]
        assert made[-1] and len(cc._LAST_SUMS) == 2
    assert cc._LAST_SUMS == []  # dropped on leaving
    for (k, d), got in zip(cases, reused):  # afresh: no reuse outside
        np.testing.assert_array_equal(got, position_covariance(model, params, [k], 9,
                                                               [np.array(d)])[0])
    np.testing.assert_array_equal(moved, position_covariance(model, other, [30], 9,
                                                             [np.array(cases[1][1])])[0])
    assert not np.array_equal(moved, reused[1]) and cc._LAST_SUMS == []


def _monte_carlo_edf(model, params, n, n_cal, ks, rng, count):
    v = np.array([
        phase_contrasts(simulate_log(model, params, n, rng=rng), rate_hz=1 / model.dt,
                        calibration_s=n_cal * model.dt, k=ks).mean_square_2
        for _ in range(count)
    ])
    return 2 * v.mean(0) ** 2 / v.var(0, ddof=1)


def test_position_edf_of_white_noise_against_monte_carlo(rng):
    """200 records: the Monte Carlo EDF's relative standard error is about 0.1-0.15; bound 35%."""
    model, n, n_cal, ks = NoiseModel(("white",), DT), 2**11, 40, np.array([5, 40, 300])
    edf = contrast_edf(model, {"noise_variance": 1.0}, ks, n_cal, n,
                       contrast_stride(ks, n_cal), order=2)
    mc = _monte_carlo_edf(model, {"noise_variance": 1.0}, n, n_cal, ks, rng, 200)
    np.testing.assert_allclose(edf / mc, 1.0, atol=0.35)


@pytest.mark.parametrize("terms,params", [
    (("white", "gauss_markov"), {"noise_variance": 1.0, "bias_variance": 1e-2,
                                 "time_constant": 20.0}),
    (("white", "random_walk"), {"noise_variance": 1.0, "rate_random_walk": 3e-2}),
    (("white", "bias_instability"), {"noise_variance": 1.0, "bias_instability": 0.05}),
])
def test_position_edf_against_monte_carlo(rng, terms, params):
    """400 records each (relative standard error of the Monte Carlo EDF about 0.1, up to 0.15
    with the kurtosis of slow terms; bound 30%); the model-free cap lies below the true EDF."""
    from bayes_imu.drift.direct import record_edf_floor

    model, n, n_cal = NoiseModel(terms, DT), 2**12, 60
    ks = np.array([10, 60, 300, 1000])
    edf = contrast_edf(model, params, ks, n_cal, n, contrast_stride(ks, n_cal), order=2)
    mc = _monte_carlo_edf(model, params, n, n_cal, ks, rng, 400)
    np.testing.assert_allclose(edf / mc, 1.0, atol=0.3)
    contrasts = phase_contrasts(np.zeros(n), rate_hz=10.0, calibration_s=6.0, k=ks).of_order(2)
    assert np.all(record_edf_floor(contrasts, ks * DT) <= mc / 1.3)


def _white_fit_of_a_slow_bias(rng, n=2**15):
    """A white-only fit of white noise plus a slow Gauss-Markov bias the model cannot carry."""
    from bayes_imu.inference.fit import fit_allan

    model = NoiseModel(("white", "gauss_markov"), 0.01)
    y = simulate_log(model, {"noise_variance": 1e-4, "bias_variance": 4e-8,
                             "time_constant": 100.0}, n, rng=rng)
    return fit_allan(allan_variance(y, rate_hz=100.0, contrast_span_s=10.0), terms=("white",),
                     rng=1)


def test_position_band_contains_the_record_interval(rng):
    """Within the record the position band contains the record's own 90% interval (the drift
    check's ``direct_q05`` / ``direct_q95``) and is the model's beyond it, marked extrapolated;
    the velocity band of the same fit is unchanged by the position measurement."""
    from bayes_imu.drift.bands import drift_bands

    fit = _white_fit_of_a_slow_bias(rng)
    t = np.array([0.05, 0.5, 5.0, 50.0, 150.0, 1000.0])
    b = drift_bands(fit, t, quantity="position", calibration_s=10.0, rng=2)
    assert list(b.extrapolated) == [False] * 5 + [True]
    assert 150.0 <= b.measured_s < 1000.0
    inside = ~b.extrapolated
    check = b.check
    np.testing.assert_allclose(check.t_s, t[inside])
    assert np.all(b.total[0, inside] <= check.direct_low * (1 + 1e-12))
    assert np.all(b.total[-1, inside] >= check.direct_high * (1 - 1e-12))
    # a slow bias a white model misses: the record's interval widens the upper band at long
    # outages, and the check sees the misfit there
    assert b.total[-1, 4] > 1.5 * b.model_total[-1, 4]
    np.testing.assert_array_equal(b.total[:, ~inside], b.model_total[:, ~inside])
    assert np.all(check.edf_interval <= check.edf)
    v = drift_bands(fit, t, quantity="velocity", calibration_s=10.0, rng=2)
    a = drift_bands(fit, t, quantity="attitude", calibration_s=10.0, rng=2)
    np.testing.assert_array_equal(v.total, a.total)


def test_saved_fit_keeps_the_position_contrasts(rng, tmp_path):
    from bayes_imu.drift.direct import unmeasured_reason
    from bayes_imu.inference.archive import load_fit, save_fit

    fit = _white_fit_of_a_slow_bias(rng, n=2**13)
    save_fit(fit, tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    np.testing.assert_array_equal(back.allan.contrasts.mean_square_2,
                                  fit.allan.contrasts.mean_square_2)
    assert unmeasured_reason(back, "calibrated", 10.0, "position") is None


def test_summary_drift_check_covers_position_and_drift_csv_marks_it_measured(rng):
    """An accelerometer's ``adequacy.drift`` gains the position check (the velocity check stays
    the top level), and ``drift.csv``'s ``extrapolated`` is false for position within the
    record."""
    from pathlib import Path

    from bayes_imu.allan.pipeline import LogSource
    from bayes_imu.report.writers import FitRequest, drift_check_summary, drift_outputs

    fit = _white_fit_of_a_slow_bias(rng, n=2**13)
    request = FitRequest(source=LogSource(log=Path("a.csv")), terms=("white",), sensor="accel",
                         calibration=10.0, times=(0.5, 5.0, 30.0, 500.0))
    drift = drift_outputs(fit, request, "m/s^2")
    doc, check = drift_check_summary(fit, request, "m/s^2", drift)
    assert doc["available"] and doc["unit"] == "m/s" and check is drift.bands[0].check
    position = doc["position"]
    assert position["available"] and position["unit"] == "m"
    assert [h["t_s"] for h in position["horizons"]] == [0.5, 5.0, 30.0]
    assert [b.quantity for b in drift.bands] == ["velocity", "position"]
    assert drift.bands[1].extrapolated.tolist() == [False, False, False, True]


def test_position_covariance_of_long_tables_in_blocks(monkeypatch):
    """Beyond ``TABLE_MAX`` lags the sums are accumulated in blocks (bounded memory): the same
    covariance to rounding."""
    from bayes_imu.noise import contrast_covariance as cc

    model, params = MODELS[1][0], MODELS[1][1]
    model = NoiseModel(model, 1.0)
    d = np.array([0.0, 3.0, 40.0, 90.0, 200.0, 400.0])
    whole = position_covariance(model, params, [9, 30], 11, [d, d])
    monkeypatch.setattr(cc, "TABLE_MAX", 64)
    blocked = position_covariance(model, params, [9, 30], 11, [d, d])
    for a, b in zip(whole, blocked):
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_a_gyro_record_measures_no_position_and_the_same_attitude(rng):
    """A gyro has no position drift: ``allan_variance(..., sensor="gyro")`` leaves the order-2
    contrasts out (``mean_square_2`` None, ``of_order(2)`` None), and its order-1 contrasts are
    those of the same record of unknown kind, bit for bit; an accelerometer's (or an unknown
    kind's) record measures both."""
    y = rng.standard_normal(50_000)
    gyro = allan_variance(y, rate_hz=100.0, contrast_span_s=10.0, sensor="gyro").contrasts
    accel = allan_variance(y, rate_hz=100.0, contrast_span_s=10.0, sensor="accel").contrasts
    unknown = allan_variance(y, rate_hz=100.0, contrast_span_s=10.0).contrasts
    assert gyro.mean_square_2 is None and gyro.of_order(2) is None
    np.testing.assert_array_equal(gyro.mean_square, unknown.mean_square)
    np.testing.assert_array_equal(accel.mean_square_2, unknown.mean_square_2)
    assert np.all(accel.mean_square_2[accel.k >= 2] > 0)


def test_compiled_position_contrasts_of_a_long_record_are_exact(rng):
    """On a record the JIT kernels sum (longer than PRECOMPILED_BELOW), the position mean squares
    come from the compiled passes (kernels.position_mean_squares: 8-sample block sums in a
    compensated running pair, each window a difference of two pairs and at most seven samples at
    each end). Against an exact reference (each window summed by math.fsum, correctly rounded,
    the contrast in exact rationals, the squares by fsum) they agree to 1e-10 relative on
    outages from 2 samples to the whole record (windows reaching its last, partial block of 8;
    short windows added in order; starts many strides apart), with the block sums from their own
    pass and from allan_sums' fill alike. numpy's running sum about the mean (the shorter records'
    steps) misses that tolerance: it rounds at the running sum's magnitude. The phase contrasts of
    the same call are the attitude-only call's bits; a shorter record takes numpy's steps (None
    from the kernel)."""
    from fractions import Fraction

    from bayes_imu.allan import kernels
    from bayes_imu.allan.contrast import contrast_grid, position_mean_square

    n = kernels.PRECOMPILED_BELOW + 4_321  # n + 1 phase samples: a last block of 2
    assert (n + 1) % 8 == 2
    y = 3.0 + rng.standard_normal(n)
    y[-1] += 1e4  # a large phase sample in the last block (x[n - 1] = mean - y[n - 1])
    x, _, _, _, fill = kernels.allan_sums(y, [1, 2, 4], blocks=True)
    n_cal = 6000
    ks = np.array([2, 3, 9, 10, 17, 100, 1001, 40_000, n - n_cal - 3], dtype=np.int64)
    strides = np.array([20_011, 19_997, 21_023, 20_021, 18_061, 20_983, 21_013, 41_017, 1])
    got = kernels.position_mean_squares(x, ks, n_cal, strides)
    filled = kernels.position_mean_squares(x, ks, n_cal, strides, fill)
    exact = []
    for i, (k, st) in enumerate(zip(ks, strides)):
        k, st = int(k), int(st)
        c = Fraction(k * (k - 1), 2 * n_cal)
        squares = []
        for j in range(n_cal, n - k + 1, st):
            p = Fraction(math.fsum(x[j + 1:j + k])) - (k - 1 + c) * Fraction(x[j]) + c * Fraction(
                x[j - n_cal])
            squares.append(float(p * p))
        exact.append(math.fsum(squares) / len(squares))
        assert got[i, 1] == pytest.approx(exact[-1], rel=1e-10, abs=0)
        assert filled[i, 1] == pytest.approx(exact[-1], rel=1e-10, abs=0)
    # the reference tells the two apart: numpy's steps miss it by more than the tolerance
    assert abs(position_mean_square(x, 2, n_cal, 20_011) / exact[0] - 1.0) > 1e-10
    np.testing.assert_array_equal(got[:, 0], kernels.contrast_mean_squares(x, ks, n_cal, strides))
    grid = contrast_grid(n, n_cal)
    pc = phase_contrasts(x=x, rate_hz=100.0, calibration_s=60.0)
    both = kernels.position_mean_squares(x, grid, n_cal, contrast_stride(grid, n_cal))
    np.testing.assert_array_equal(pc.mean_square_2, both[:, 1] / 100.0**4)
    np.testing.assert_array_equal(
        pc.mean_square, phase_contrasts(x=x, rate_hz=100.0, position=False).mean_square)
    assert kernels.position_mean_squares(x[:1000], ks[:3], 100, strides[:3]) is None


def test_position_contrasts_from_the_fill(rng):
    """allan_variance of a long record sums the position contrasts' 8-sample blocks of x[1:] as it
    fills x (allan_sums' blocks=True: no further read of the record); its contrasts are
    phase_contrasts' from those block sums, the phase contrasts the attitude-only call's bits. The
    fill adds each block's 8 samples in its own fast-math loop, so in any order: within the
    rounding bound of 8 additions (14 eps sum |v|) of block_sums' fixed tree, which is numpy's
    same tree bit for bit; without blocks, allan_sums returns as before."""
    from bayes_imu.allan import kernels

    n = kernels.PRECOMPILED_BELOW + 4_321
    y = 3.0 + rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-3
    fused = allan_variance(y, rate_hz=100.0).contrasts
    x, _, _, _, pairs = kernels.allan_sums(y, [1, 2, 4], blocks=True)
    v = x[1:8 * (n // 8) + 1].reshape(-1, 8)
    tree = ((v[:, 0] + v[:, 1]) + (v[:, 2] + v[:, 3])) + ((v[:, 4] + v[:, 5]) + (v[:, 6] + v[:, 7]))
    alone = np.empty(n // 8)
    kernels._compile()["block_sums"](x[1:], 4096, alone)
    np.testing.assert_array_equal(alone, tree)
    bound = 14 * np.finfo(float).eps * np.abs(v).sum(axis=1)
    assert np.all(np.abs(pairs[1:, 0] - tree) <= bound)
    from_fill = phase_contrasts(x=x, rate_hz=100.0, pairs=pairs)
    np.testing.assert_array_equal(fused.mean_square_2, from_fill.mean_square_2)
    np.testing.assert_array_equal(
        fused.mean_square, phase_contrasts(x=x, rate_hz=100.0, position=False).mean_square)
    assert len(kernels.allan_sums(y, [1, 2, 4])) == 2
