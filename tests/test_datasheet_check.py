"""Datasheet check (:mod:`bayes_imu.noise.datasheet_check`).

References: the datasheet units by hand (1 rad = 180/pi deg, 1 h = 3600 s, g = 9.80665 m/s^2, IEEE
Std 952: ARW [deg/sqrt(h)] = 60 * 180/pi * N [rad/s/sqrt(Hz)], bias instability [deg/h] =
3600 * 180/pi
* B [rad/s]), and the draws' empirical probability computed from those.
"""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from bayes_imu.errors import InputError
from bayes_imu.noise import NoiseModel
from bayes_imu.noise.datasheet_check import (
    check_datasheet,
    datasheet_conversions,
    read_datasheet_spec,
    spec_model,
    verdict,
)


def _posterior(rng, n=4000, dt=0.01):
    model = NoiseModel(("white", "bias_instability", "gauss_markov"), dt)
    samples = np.column_stack(
        [
            (2e-4 * np.exp(0.05 * rng.standard_normal(n))) ** 2 / dt,
            1e-5 * np.exp(0.3 * rng.standard_normal(n)),
            (3e-5) ** 2 * np.ones(n),
            100.0 * np.ones(n),
        ]
    )
    draws = {
        "noise_variance": samples[:, 0],
        "bias_instability": samples[:, 1],
        "bias_variance": samples[:, 2],
        "time_constant": samples[:, 3],
        "noise_density": np.sqrt(samples[:, 0] * dt),
    }
    return SimpleNamespace(
        model=model,
        parameter_names=model.parameter_names,
        samples=samples,
        draws=lambda name: draws[name],
    )


def test_conversions_are_the_datasheet_units():
    rows = datasheet_conversions("gyro")
    assert rows["angle_random_walk"][:3] == (
        "noise_density",
        pytest.approx(60 * 180 / math.pi, rel=1e-14),
        1.0,
    )
    assert rows["bias_instability"][1] == pytest.approx(3600 * 180 / math.pi, rel=1e-14)
    assert rows["gauss_markov_sigma"][0] == "bias_variance" and rows["gauss_markov_sigma"][
        2
    ] == pytest.approx(0.5)
    accel = datasheet_conversions("accel")
    assert accel["bias_instability"][1] == pytest.approx(1e6 / 9.80665, rel=1e-14)


def test_probability_within_spec_is_the_share_of_draws(rng):
    post = _posterior(rng)
    b_deg_h = post.draws("bias_instability") * 3600 * 180 / math.pi
    spec = {
        "angle_random_walk": 1.0,
        "bias_instability": float(np.quantile(b_deg_h, 0.3)),
        "rate_random_walk": 0.1,
        "gauss_markov_sigma": 3e-5 * 3600 * 180 / math.pi * 0.5,
    }
    result = check_datasheet(post, "gyro", spec)
    # ARW median 2e-4 rad/s/sqrt(Hz) = 0.6875 deg/sqrt(h), 0.05 log-sd: far below 1.0
    assert result["angle_random_walk"]["probability"] == 1.0
    assert result["angle_random_walk"]["median"] == pytest.approx(
        2e-4 * 60 * 180 / math.pi, rel=0.01
    )
    assert result["bias_instability"]["probability"] == pytest.approx(
        np.mean(b_deg_h <= spec["bias_instability"]), abs=1e-12
    )
    assert (
        result["rate_random_walk"]["probability"] is None
        and not result["rate_random_walk"]["in_model"]
    )
    assert result["gauss_markov_sigma"]["probability"] == 0.0
    line = verdict(result)
    assert (
        line.startswith("OUTSIDE")
        and "gauss_markov_sigma P=0.00" in line
        and "angle_random_walk P=1.00" in line
    )


def test_spec_files_json_and_toml_and_their_errors(tmp_path):
    (tmp_path / "a.json").write_text(
        json.dumps(
            {
                "kind": "gyro",
                "angle_random_walk": 0.2,
                "bias_instability": {"value": 5, "unit": "deg/h"},
            }
        )
    )
    assert read_datasheet_spec(tmp_path / "a.json") == (
        "gyro",
        {"angle_random_walk": 0.2, "bias_instability": 5.0},
    )
    (tmp_path / "b.toml").write_text('kind = "accel"\nvelocity_random_walk = 0.03\n')
    assert read_datasheet_spec(tmp_path / "b.toml") == ("accel", {"velocity_random_walk": 0.03})
    for body, match in [
        ({"kind": "mag"}, "kind"),
        ({"kind": "gyro", "arw": 1}, "arw"),
        ({"kind": "gyro", "bias_instability": {"value": 5, "unit": "deg/s"}}, "unit"),
        ({"kind": "gyro", "bias_instability": -1}, "positive"),
        ({"kind": "gyro"}, "no datasheet"),
    ]:
        (tmp_path / "c.json").write_text(json.dumps(body))
        with pytest.raises(InputError, match=match):
            read_datasheet_spec(tmp_path / "c.json")


def test_spec_model_inverts_the_units():
    model, params = spec_model(
        "gyro", {"angle_random_walk": 0.6, "bias_instability": 3.6, "rate_random_walk": 1.0}, 100.0
    )
    assert model.terms == ("white", "bias_instability", "random_walk") and model.dt == 0.01
    assert params["noise_variance"] == pytest.approx(
        (0.6 / 60 * math.pi / 180) ** 2 * 100, rel=1e-14
    )
    assert params["bias_instability"] == pytest.approx(3.6 / 3600 * math.pi / 180, rel=1e-14)
    with pytest.raises(InputError, match="time constant"):
        spec_model("gyro", {"angle_random_walk": 0.6, "gauss_markov_sigma": 3.0}, 100.0)
