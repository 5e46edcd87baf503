"""IEEE Std 952 readings of the posterior Allan deviation (inference.allan_readout) and the
repeatability-between-parts intervals (inference.repeatability).

References: the textbook Allan variances of IEEE Std 952 Annex C (white rate N^2 / tau, rate random
walk K^2 tau / 3, flicker floor 2 ln 2 B^2 / pi) and the exact sampled white-noise AVAR q / m."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from bayes_imu.inference.allan_readout import BI_FLOOR, allan_readout
from bayes_imu.inference.fit import FitResult
from bayes_imu.inference.repeatability import (
    SPREAD_CONFIDENCE,
    repeatability_draws,
    repeatability_spread,
)
from bayes_imu.inference.stationarity import Stationarity
from bayes_imu.noise.avar_forms import NoiseModel


def _fit(terms, samples, dt=0.01, tau=(0.01, 1000.0)):
    model = NoiseModel(terms, dt)
    allan = SimpleNamespace(tau=np.array(tau), n_samples=int(4 * tau[-1] / dt))
    return FitResult(
        model, np.asarray(samples, float), np.zeros(len(samples)), allan, (), 0, {}, "test", None
    )


def test_white_noise_reads_its_density_at_one_second():
    """White noise: AVAR(m) = q / m exactly, so sigma(1 s) sqrt(1 s) = sqrt(q dt), the white
    density; no minimum inside the grid (at_edge = 1), and the +1/2 line is an upper bound (rising =
    0)."""
    q = np.array([[0.04], [0.09]])
    out = allan_readout(_fit(("white",), q), None, unit="rad/s")
    np.testing.assert_allclose(
        out["random_walk"]["median"], np.median(np.sqrt(q * 0.01)), rtol=1e-12
    )
    np.testing.assert_allclose(
        out["white_noise_density"]["median"], np.median(np.sqrt(q * 0.01)), rtol=1e-12
    )
    assert out["random_walk"]["tau_s"] == pytest.approx(1.0)
    assert out["bias_instability"]["at_edge"] == 1.0 and out["rate_random_walk"]["rising"] == 0.0
    gyro = allan_readout(_fit(("white",), q), "gyro")
    np.testing.assert_allclose(
        gyro["angle_random_walk"]["median"],
        out["random_walk"]["median"] * 180 / np.pi * 60,
        rtol=1e-12,
    )
    assert gyro["angle_random_walk"]["unit"] == "deg/sqrt(h)"


def test_rate_random_walk_and_flicker_readings():
    """A rate random walk dominating at long tau reads K (the +1/2 line, AVAR = K^2 tau / 3, within
    1% at tau = 1000 s where the white part adds N^2 / tau); flicker's floor / 0.664 reads B (within
    2%: the sampled flicker AVAR reaches its floor 2 ln 2 B^2 / pi only asymptotically)."""
    rrw = allan_readout(_fit(("white", "random_walk"), [[1e-4, 1e-2]]), None)["rate_random_walk"]
    assert (
        rrw["median"] == pytest.approx(1e-2, rel=0.01)
        and rrw["rising"] == 1.0
        and rrw["tau_s"] == 1000.0
    )
    bi = allan_readout(_fit(("white", "bias_instability"), [[1e-6, 1e-3]]), None)[
        "bias_instability"
    ]
    # the floor, approached from above up to the last tau
    assert bi["median"] == pytest.approx(1e-3, rel=0.02)
    assert BI_FLOOR == pytest.approx(0.6643, abs=1e-4)


def _flagged(spread, n_segments=4):
    tau = np.array([0.01, 1.0, 100.0])
    return Stationarity(False, 1e-4, 1.0, tau, np.ones((n_segments, 3)), np.asarray(spread, float))


def test_repeatability_widens_by_the_spread_between_parts(rng):
    """A flagged record: log-draws of an amplitude gain variance (p s_up)^2, s_up the spread at its
    90% upper confidence bound (chi-square, K - 1 = 3 degrees of freedom: s sqrt(3 / chi2_3(0.1)));
    a variance twice the log-sd of its amplitude; time constants and stationary records
    unchanged."""
    from scipy import stats

    st = _flagged([0.02, 0.05, 0.08])
    short, long = repeatability_spread(st)
    up = np.sqrt(3 / stats.chi2.ppf(1 - SPREAD_CONFIDENCE, 3))
    assert short == pytest.approx(0.02 * up) and long == pytest.approx(0.08 * up)
    draws = np.full(200_000, 2.0)
    sd = np.std(np.log(repeatability_draws("noise_density", draws, st, 0)))
    assert sd == pytest.approx(0.5 * short, rel=0.01)
    sd = np.std(np.log(repeatability_draws("noise_variance", draws, st, 1)))
    assert sd == pytest.approx(short, rel=0.01)
    sd = np.std(np.log(repeatability_draws("bias_variance", draws, st, 2)))
    assert sd == pytest.approx(long, rel=0.01)
    np.testing.assert_array_equal(repeatability_draws("time_constant", draws, st, 3), draws)
    np.testing.assert_array_equal(
        repeatability_draws("noise_density", draws, replace(st, stationary=True), 0), draws
    )


@pytest.mark.parametrize("stream", [0, 1, 2, 3, 5])
def test_normal_scores_are_standard_normal_without_random_state(stream):
    """The repeatability widening's scores: the same on every call, and distributed as N(0, 1)
    (Kolmogorov-Smirnov distance below 3e-3 at 20 000 scores, against 0.0096 for a 5% test of
    a random sample: the sequence is equidistributed, not random)."""
    from scipy import stats

    from bayes_imu.inference.repeatability import normal_scores

    z = normal_scores(20_000, stream)
    np.testing.assert_array_equal(z, normal_scores(20_000, stream))
    assert stats.kstest(z, "norm").statistic < 3e-3
