"""A scene sensor's ``datasheet``: report.json's datasheet_check and the report's column."""

import json
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.errors import InputError
from bayes_imu.report.html import write_report
from bayes_imu.report.scene import build_report, read_scene

DATA = Path(__file__).resolve().parents[1] / "data_synthetic"
SCENE = """
[scene]
name = "datasheet scene"
allow_outside = true
outages_s = [10, 60]
[[sensor]]
name = "budget"
log = "{data}/gyro_lowgrade.csv.gz"
column = "gyro_x_dps"
rate_hz = 100
kind = "gyro"
units = "deg/s"
datasheet = "{sheet}"
"""


def test_scene_datasheet_probability_column_and_verdict(tmp_path):
    (tmp_path / "sheet.json").write_text(
        json.dumps({"kind": "gyro", "angle_random_walk": 100.0, "rate_random_walk": 1.0})
    )
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(data=DATA, sheet="sheet.json"))
    rep = build_report(read_scene(path), rng=0)
    write_report(rep, tmp_path / "out")
    check = json.loads((tmp_path / "out" / "report.json").read_text())["sensors"][0][
        "datasheet_check"
    ]
    arw = check["values"]["angle_random_walk"]
    fit = rep.sensors[0].fit
    expected = (
        np.median(fit.draws("noise_density")) * 60 * 180 / np.pi
    )  # rad/s/sqrt(Hz) -> deg/sqrt(h)
    assert arw["median"] == pytest.approx(expected, rel=1e-12) and arw["probability"] == 1.0
    assert check["file"].endswith("sheet.json") and check["verdict"]
    page = (tmp_path / "out" / "report.html").read_text()
    assert "P(within spec)" in page and "angle_random_walk" in page


def test_scene_datasheet_of_the_wrong_kind_is_refused(tmp_path):
    (tmp_path / "acc.toml").write_text('kind = "accel"\nvelocity_random_walk = 0.1\n')
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(data=DATA, sheet="acc.toml"))
    with pytest.raises(InputError, match="accel datasheet for a gyro"):
        read_scene(path)
