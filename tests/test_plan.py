"""Record-length plan (:mod:`bayes_imu.drift.plan`).

References: Monte Carlo (the spread of the generalised-least-squares estimate of ``ln q`` from the
octave Allan variances of simulated white-noise logs, the estimator whose variance the Fisher
information predicts; n = 400 logs, 4-sigma tolerance on an sd: 4 / sqrt(2 n) = 14%), and the
exact Jacobian of a white + random-walk model (AVAR linear in each parameter).
"""

import numpy as np
import pytest

from bayes_imu.allan import allan_variance
from bayes_imu.drift.plan import Z90, plan_record_length
from bayes_imu.errors import InputError
from bayes_imu.noise import NoiseModel
from bayes_imu.noise.avar_covariance import avar_covariance


def test_white_noise_width_matches_the_spread_of_the_estimate(rng):
    n, dt, q = 4096, 0.01, 2.0
    model = NoiseModel(("white",), dt)
    plan = plan_record_length(model, {"noise_variance": q}, lengths_s=[n * dt])
    m = 2 ** np.arange(11)  # octave sizes up to n / 4
    cov = avar_covariance(model, {"noise_variance": q}, m, n)
    avar = q / m
    corr_log = cov / np.outer(avar, avar)  # delta method: covariance of log AVAR
    weights = np.linalg.solve(corr_log, np.ones(m.size))
    estimates = []
    for _ in range(400):
        a = allan_variance(np.sqrt(q) * rng.standard_normal(n), rate_hz=1 / dt, m=m)
        estimates.append(weights @ (np.log(a.avar) - np.log(1.0 / m)) / weights.sum())
    assert plan.log_sd[0, 0] == pytest.approx(np.std(estimates, ddof=1), rel=0.14)


def test_longer_records_shrink_white_noise_as_one_over_root_length():
    model = NoiseModel(("white", "random_walk"), 0.01)
    plan = plan_record_length(
        model,
        {"noise_variance": 1e-4, "rate_random_walk": 1e-5},
        lengths_s=[3600.0, 4 * 3600.0, 16 * 3600.0],
        horizons_s=[1.0, 100.0],
        quantity="attitude",
    )
    white = plan.log_sd[:, 0]
    assert white[0] / white[1] == pytest.approx(2.0, rel=0.05) and white[1] / white[
        2
    ] == pytest.approx(2.0, rel=0.05)
    assert np.all(np.diff(plan.log_sd, axis=0) < 0) and np.all(
        np.diff(plan.drift_log_sd, axis=0) < 0
    )
    assert plan.width90 == pytest.approx(np.exp(2 * Z90 * plan.log_sd))
    rows = plan.rows()
    assert len(rows) == 3 * 4 and rows[2]["what"] == "attitude drift at 1 s"


def test_bad_plans_are_input_errors():
    model = NoiseModel(("white",), 0.01)
    with pytest.raises(InputError, match="noise_variance"):
        plan_record_length(model, {"noise_variance": -1.0})
    with pytest.raises(InputError, match="16 samples"):
        plan_record_length(model, {"noise_variance": 1.0}, lengths_s=[0.1])
    with pytest.raises(InputError, match="quantity"):
        plan_record_length(model, {"noise_variance": 1.0}, horizons_s=[1.0])


def test_pilot_check_warns_where_the_pilot_is_wider_than_the_plan_at_its_length():
    """A white-noise pilot of 200 000 samples: its record-alone interval at its own length is what
    the plan predicts there (ratio within 15%), no warning. The same noise with its variance
    doubled half-way: its stationarity check fails, it reports the spread between its parts
    (summary.json ``parameters``), far wider than the record-alone Fisher prediction, and the
    check says so."""
    import warnings

    from bayes_imu.drift.plan import PILOT_EXCESS, pilot_check
    from bayes_imu.inference.fit import fit_allan

    y = np.random.default_rng(4).standard_normal(200_000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        steady = fit_allan(allan_variance(y, rate_hz=100.0), terms=("white",), rng=0)
        y[100_000:] *= np.sqrt(2.0)
        changed = fit_allan(allan_variance(y, rate_hz=100.0), terms=("white",), rng=0)
    check = pilot_check(steady)
    assert check.length_s == 2000.0 and abs(check.ratio()[0] - 1.0) < 0.15
    assert check.stationary and check.warning("x") is None
    wider = pilot_check(changed)
    assert not wider.stationary and wider.ratio("reported")[0] >= PILOT_EXCESS
    assert "noise_variance" in wider.warning("x") and "lower bounds" in wider.warning("x")
    assert set(wider.to_dict()["reported_upper_halfwidth"]) == {"noise_variance"}
    assert check.to_dict()["widened"] is False


def test_pilot_warning_names_the_cause_the_fit_had():
    """A record-alone interval wider than predicted is blamed on the model discrepancy only where
    the pilot's fit was widened; otherwise on the posterior's shape (a user read the discrepancy on
    an adequate fit); the parts' spread only where the stationarity check failed."""
    from bayes_imu.drift.plan import PilotCheck

    def check(**fields):
        return PilotCheck(3600.0, ("a", "b"), np.array([0.1, 0.5]), np.array([0.1, 0.5]),
                          np.array([0.1, 0.1]), **fields)

    adequate = check().warning("x")
    assert "b is" in adequate and "Gaussian approximation" in adequate
    assert "discrepancy" not in adequate and "log's parts" not in adequate
    assert "model discrepancy its fit needed" in check(widened=True).warning("x")
    assert PilotCheck(3600.0, ("a",), np.array([0.1]), np.array([0.5]),
                      np.array([0.1]), stationary=False).warning("x").count("log's parts") == 1
    assert PilotCheck(3600.0, ("a",), np.array([0.1]), np.array([0.5]), np.array([0.1])
                      ).warning("x") is None
