"""Filter noise exports (:mod:`bayes_imu.report.exports`).

Published references (continuous-time Kalibr densities):

* EuRoC MAV dataset, ADIS16448 ``imu0/sensor.yaml``: gyroscope_noise_density 1.6968e-04
  rad/s/sqrt(Hz), gyroscope_random_walk 1.9393e-05 rad/s^2/sqrt(Hz), accelerometer_noise_density
  2.0000e-3 m/s^2/sqrt(Hz), accelerometer_random_walk 3.0000e-3 m/s^3/sqrt(Hz), 200 Hz.
* TUM-VI dataset, BMI160 ``dso/imu_config.yaml``: accelerometer_noise_density 0.0028,
  accelerometer_random_walk 0.00086, gyroscope_noise_density 0.00016, gyroscope_random_walk
  0.000022, update_rate 200.0 (the file as copied in several public repositories' tests).

Each file is read back by an independent parser (PyYAML, json, the Python snippet executed
against a stand-in ``gtsam`` module, a regular expression for MATLAB), then converted back.
"""

import json
import re
import sys
import types

import numpy as np
import pytest
import yaml

from bayes_imu.errors import InputError
from bayes_imu.report.exports import (
    FORMATS,
    ExportValues,
    ImuNoise,
    from_fields,
    render_export,
    to_fields,
)

EUROC = ImuNoise(1.6968e-04, 1.9393e-05, 2.0000e-3, 3.0000e-3, 200.0)
TUM_VI = ImuNoise(0.00016, 0.000022, 0.0028, 0.00086, 200.0)


def _parse(text, fmt):
    """The format's fields as a parser of that format reads them."""
    if fmt == "gtsam":
        doc = json.loads(text)
        return {k: v for k, v in doc.items() if k.endswith("Covariance")}
    if fmt == "gtsam-py":
        captured = {}

        class Params:
            def __getattr__(self, name):
                return lambda matrix: captured.__setitem__(name[3].lower() + name[4:], matrix)

        fake = types.SimpleNamespace(
            PreintegrationCombinedParams=types.SimpleNamespace(MakeSharedU=lambda g: Params())
        )
        sys.modules["gtsam"] = fake
        try:
            exec(compile(text, "snippet.py", "exec"), {})
        finally:
            del sys.modules["gtsam"]
        for name, matrix in captured.items():
            assert np.array_equal(matrix, np.eye(3) * matrix[0, 0])
        return {name: matrix[0, 0] for name, matrix in captured.items()}
    if fmt == "matlab":
        assert re.search(r"^gyro = gyroparams;$", text, re.M) or "gyro." not in text
        return {
            m.group(1): float(m.group(2))
            for m in re.finditer(r"^((?:gyro|accel)\.\w+) = (\S+);$", text, re.M)
        }
    doc = yaml.safe_load(text.replace("%YAML:1.0\n", "", 1))
    if fmt == "openvins":
        doc = doc["imu0"]
    names = set(FORMATS[fmt].names.values())
    return {k: v for k, v in doc.items() if k in names}


@pytest.mark.parametrize("published", [EUROC, TUM_VI], ids=["euroc", "tum-vi"])
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_published_values_round_trip_through_every_format(published, fmt):
    values = ExportValues(
        published, published, per_axis={k: [("x", v, None)] for k, v in published.present().items()}
    )
    text = render_export(values, fmt)
    back = from_fields(_parse(text, fmt), fmt)
    for key, value in published.present().items():
        assert getattr(back, key) == pytest.approx(value, rel=1e-12), key


def test_field_units_are_each_formats_own():
    """GTSAM covariances are the squared densities; the others take the densities themselves."""
    assert to_fields(EUROC, "gtsam")["gyroscopeCovariance"] == pytest.approx(
        1.6968e-04**2, rel=1e-15
    )
    assert to_fields(EUROC, "vins") == {
        "gyr_n": 1.6968e-04,
        "gyr_w": 1.9393e-05,
        "acc_n": 2e-3,
        "acc_w": 3e-3,
    }
    assert to_fields(EUROC, "matlab")["accel.RandomWalk"] == 3e-3


def test_one_sensor_alone_writes_only_its_fields():
    gyro = ImuNoise(gyroscope_noise_density=1e-4, gyroscope_random_walk=1e-5, update_rate=100.0)
    values = ExportValues(
        gyro, gyro, per_axis={k: [("x", v, None)] for k, v in gyro.present().items()}
    )
    for fmt in FORMATS:
        fields = _parse(render_export(values, fmt), fmt)
        assert set(fields) == {FORMATS[fmt].names[k] for k in gyro.present()}, fmt


def test_unknown_format_and_fields_are_input_errors():
    with pytest.raises(InputError, match="format"):
        to_fields(EUROC, "rovio")
    with pytest.raises(InputError, match="fields"):
        from_fields({"acc_noise": 1.0}, "vins")
