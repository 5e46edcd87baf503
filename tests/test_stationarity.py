"""The between-segment stationarity check: segment Allan variances against the estimator written
out, the false-alarm rate on stationary logs (Monte Carlo), the spread of a log whose noise
steps (exact), the widening of the drift bands, the archive, and the command's warning."""

import dataclasses
import json
import re

import numpy as np
import pytest

from bayes_imu import allan_variance, fit_allan
from bayes_imu.allan.estimator import greenhall_edf, segment_allan
from bayes_imu.inference.archive import load_fit, save_fit
from bayes_imu.drift.bands import drift_draws
from bayes_imu.noise import NoiseModel
from bayes_imu.noise.simulate import simulate_log
from bayes_imu.inference.stationarity import (
    STATIONARITY_ALPHA,
    Stationarity,
    segment_test,
    stationarity_check,
)

DT = 0.01


def _brute_avar(y, m):
    """SP1065 eq 14 written out: phase by cumulative sum, every overlapping second difference."""
    x = np.concatenate([[0.0], np.cumsum(y - y.mean())])
    d = x[2 * m:] - 2 * x[m:-m] + x[: -2 * m]
    return np.sum(d * d) / (2.0 * m * m * d.size)


def test_segment_allan_is_each_part_s_allan_variance(rng):
    y = rng.standard_normal(10_003).cumsum() * 1e-3 + rng.standard_normal(10_003)
    seg = segment_allan(y, np.array([1, 2, 4, 8, 16, 64, 512, 1024]), 4)
    assert seg.n_samples == 2500 and seg.n_segments == 4
    assert seg.m.tolist() == [1, 2, 4, 8, 16, 64, 512]  # a quarter of a segment at most
    for k in range(4):
        part = y[k * 2500:(k + 1) * 2500]
        np.testing.assert_allclose(seg.avar[k], [_brute_avar(part, m) for m in seg.m], rtol=1e-10)
    assert allan_variance(y, rate_hz=100, segments=0).segments is None
    assert segment_allan(y[:12], np.array([1, 2]), 4) is None  # segments of 3 samples: no size fits


@pytest.mark.parametrize(
    "terms, params",
    [
        pytest.param(
            ("white", "random_walk"),
            {"noise_variance": 1e-4, "rate_random_walk": 3e-4},
            marks=pytest.mark.slow,
        ),
        (
            ("white", "gauss_markov"),
            {"noise_variance": 1e-4, "bias_variance": 1e-6, "time_constant": 2.0},
        ),
    ],
)
def test_false_alarm_rate_on_stationary_logs(rng, terms, params):
    """150 logs drawn from the model: the share flagged at alpha = 0.01 stays below 1% + 3 binomial
    standard errors (Bonferroni makes it conservative), and at a nominal 10% below 10% + 3 se."""
    model = NoiseModel(terms, DT)
    n_logs = 150
    p = np.array(
        [
            stationarity_check(
                allan_variance(simulate_log(model, params, 2**15, rng=rng), rate_hz=1 / DT),
                model,
                params,
            ).p_value
            for _ in range(n_logs)
        ]
    )
    for level in (STATIONARITY_ALPHA, 0.1):
        assert np.mean(p < level) <= level + 3 * np.sqrt(level * (1 - level) / n_logs)


def test_a_noise_step_is_flagged_with_its_exact_spread(rng):
    """White noise whose variance is 4x larger in the second half: the four segments' ln AVAR are
    (0, 0, ln 4, ln 4) + sampling error, whose sample standard deviation is ln(4) / sqrt(3) =
    0.800."""
    model = NoiseModel(("white",), DT)
    y = np.concatenate([rng.standard_normal(2**16), 2.0 * rng.standard_normal(2**16)])
    check = stationarity_check(allan_variance(y, rate_hz=1 / DT), model, {"noise_variance": 2.5})
    assert not check.stationary and check.p_value < 1e-6
    assert check.spread[0] == pytest.approx(np.log(4) / np.sqrt(3), abs=0.03)
    assert np.all(np.diff(check.spread) >= 0)
    assert check.largest_ratio() == pytest.approx(2.0, rel=0.05)
    assert check.drift_log_sd(0.01) == pytest.approx(check.spread[0] / 2)
    # held beyond the sizes checked
    assert check.drift_log_sd(1e6) == pytest.approx(check.spread[-1] / 2)
    # the same test with the white-noise power-law EDF instead of the model's gives the same spread
    seg = allan_variance(y, rate_hz=1 / DT).segments
    free = segment_test(
        seg, greenhall_edf(np.zeros(seg.m.size, dtype=int), seg.m, seg.n_samples + 1), 1 / DT
    )
    assert not free.stationary and free.spread[0] == pytest.approx(np.log(4) / np.sqrt(3), abs=0.03)
    assert free.p_each.shape == free.tau_s.shape and free.p_value == pytest.approx(
        min(1, free.p_each.min() * free.p_each.size)
    )
    # the decision's rate is reported beside the p-value (summary.json), and is what decides
    assert check.to_dict()["alpha"] == 0.01
    lenient = segment_test(seg, greenhall_edf(np.zeros(seg.m.size, dtype=int), seg.m,
                                              seg.n_samples + 1), 1 / DT, alpha=free.p_value / 2)
    assert lenient.stationary and lenient.to_dict()["alpha"] == free.p_value / 2


def test_flagged_fit_widens_drift_bands_by_the_spread(rng, tmp_path):
    """Each draw's drift times exp(z s / 2), z standard normal: ln(widened / plain) has mean 0 and
    standard deviation s / 2 (Monte Carlo over the draws, 4 standard errors); a stationary fit is
    unchanged. The check survives the archive."""
    y = simulate_log(NoiseModel(("white",), DT), {"noise_variance": 1e-4}, 2**14, rng=rng)
    fit = fit_allan(allan_variance(y, rate_hz=1 / DT), terms=("white",), rng=1)
    assert fit.stationarity is not None and fit.stationarity.stationary
    t = np.array([1.0, 100.0])
    plain = drift_draws(fit, t, quantity="attitude", bias_start="zero", rng=2)["total"]
    np.testing.assert_array_equal(
        drift_draws(fit, t, quantity="attitude", bias_start="zero", rng=3)["total"], plain
    )
    st = fit.stationarity
    flagged = dataclasses.replace(
        fit,
        stationarity=Stationarity(
            False,
            1e-5,
            st.tau_s[-1],
            st.tau_s,
            st.segment_adev,
            np.linspace(0.2, 0.6, st.tau_s.size),
            alpha=0.05,
        ),
    )
    ratio = np.log(
        drift_draws(flagged, t, quantity="attitude", bias_start="zero", rng=2)["total"] / plain
    )
    n = ratio.shape[0]
    for i, s in enumerate(flagged.stationarity.drift_log_sd(t)):
        assert abs(ratio[:, i].mean()) < 4 * s / np.sqrt(n)
        assert ratio[:, i].std() == pytest.approx(s, rel=4 / np.sqrt(2 * n))
    assert np.allclose(
        drift_draws(
            flagged, t, quantity="attitude", bias_start="zero", rng=2, segment_spread=False
        )["total"],
        plain,
    )
    save_fit(flagged, tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    assert not back.stationarity.stationary and back.stationarity.p_value == 1e-5
    assert back.stationarity.alpha == 0.05
    np.testing.assert_array_equal(back.stationarity.spread, flagged.stationarity.spread)
    np.testing.assert_array_equal(back.allan.segments.avar, fit.allan.segments.avar)


def test_fit_command_warns_when_the_noise_changes(tmp_path, capsys, rng):
    from bayes_imu.cli.main import main

    y = np.concatenate([rng.standard_normal(2**15), 2.0 * rng.standard_normal(2**15)]) * 1e-2
    log = tmp_path / "log.csv"
    np.savetxt(log, y, header="gyro", comments="")
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "gyro",
                "--rate",
                "100",
                "--terms",
                "white",
                "--sensor",
                "gyro",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "the noise changes during the log" in err and "drift bands include that spread" in err
    # noise doubled half-way
    assert re.search(r"parts differ by (1\.9|2|2\.1)x in Allan deviation", err)
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["adequacy"]["stationarity"]["stationary"] is False
    assert summary["adequacy"]["stationarity"]["adev_ratio_at_worst_tau"] == pytest.approx(
        2.0, rel=0.05
    )


def test_small_changes_are_given_in_percent():
    """A long log resolves a change of a few percent: "differ by 1x" hid it; below 1.1x it reads in
    percent."""
    from bayes_imu.cli.main import _ratio_text

    assert _ratio_text(1.013) == "1.3%" and _ratio_text(1.0) == "0%"
    assert _ratio_text(1.1) == "1.1x" and _ratio_text(2.04) == "2x"
