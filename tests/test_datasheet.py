"""Datasheet units: each conversion against the unit's definition (one unit in, 1.0 out)."""

import math

import numpy as np
import pytest

from bayes_imu import NoiseModel
from bayes_imu.noise.datasheet import datasheet
from bayes_imu.inference.population import UnitPosterior

DT = 0.01
RAD = math.pi / 180.0  # one degree in rad


def _posterior(terms, values):
    model = NoiseModel(terms, DT)
    return UnitPosterior(model, np.array([[values[n] for n in model.parameter_names]] * 3), 100.0)


def test_gyro_units():
    one_arw = RAD / 60.0  # 1 deg/sqrt(h) in rad/sqrt(s)
    values = {
        "noise_variance": one_arw**2 / DT,
        "bias_instability": RAD / 3600.0,
        "rate_random_walk": RAD / 3600.0 / 60.0,
        "bias_variance": (2 * RAD / 3600.0) ** 2,
        "time_constant": 50.0,
        # 1 arcsec; 1 deg/h^2
        "quantization": RAD / 3600.0,
        "rate_ramp": RAD / 3600.0 / 3600.0,
    }
    table = datasheet(
        _posterior(
            ("white", "quantization", "bias_instability", "gauss_markov", "random_walk", "ramp"),
            values,
        ),
        "gyro",
    )
    expected = {
        "angle_random_walk": 1.0,
        "bias_instability": 1.0,
        "rate_random_walk": 1.0,
        "gauss_markov_sigma": 2.0,
        "gauss_markov_time_constant": 50.0,
        "quantization": 1.0,
        "rate_ramp": 1.0,
    }
    assert set(table) == set(expected)
    for name, value in expected.items():
        assert table[name]["median"] == pytest.approx(value, rel=1e-12), name
    assert (
        table["angle_random_walk"]["unit"] == "deg/sqrt(h)"
        and table["bias_instability"]["unit"] == "deg/h"
    )


def test_accel_units():
    values = {"noise_variance": (1.0 / 60.0) ** 2 / DT, "bias_instability": 9.80665e-6,
              "rate_random_walk": 1.0 / 3600.0 / 60.0, "correlated_variance": (3 * 9.80665e-6) ** 2,
              "correlated_time_constant": 0.03}
    table = datasheet(
        _posterior(("white", "hf_correlated", "bias_instability", "random_walk"), values), "accel"
    )
    # the fast correlated term adds its white equivalent to the VRW: compare with the white term
    # alone
    white_only = datasheet(_posterior(("white",), values), "accel")
    assert white_only["velocity_random_walk"]["median"] == pytest.approx(1.0, rel=1e-12)
    assert table["velocity_random_walk"]["median"] > 1.0
    assert table["bias_instability"]["median"] == pytest.approx(1.0, rel=1e-12)
    assert table["acceleration_random_walk"]["median"] == pytest.approx(1.0, rel=1e-12)
    assert table["fast_correlated_sigma"]["median"] == pytest.approx(3.0, rel=1e-12)
    assert table["bias_instability"]["unit"] == "ug"
