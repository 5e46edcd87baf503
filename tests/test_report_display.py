"""``bayes-imu report --display-units deg`` (issue 38): report.html, report.json and comparison.png
in degrees beside SI, against the exact factors 180/pi and sqrt(3600 s/h), the SI values
unchanged."""

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.report import html as report_html
from bayes_imu.report.html import write_report
from bayes_imu.report.scene import build_report, read_scene

DATA = Path(__file__).resolve().parents[1] / "data_synthetic"
DEG = 180.0 / math.pi  # rad -> deg, by definition
SCENE = """
[scene]
name = "display"
allow_outside = true
outages_s = [10, 60]
{display}
[requirement]
quantity = "attitude"
max_error = "1 deg"
[[sensor]]
name = "budget"
log = "{data}/gyro_lowgrade.csv.gz"
column = "gyro_x_dps"
rate_hz = 100
kind = "gyro"
units = "deg/s"
datasheet = "{data}/gyro_datasheet.toml"
"""


def _scene(folder, display=""):
    path = folder / "scene.toml"
    path.write_text(SCENE.format(data=DATA, display=display))
    return path


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """One report written twice: as given (SI) and with ``display_units = "deg"``."""
    folder = tmp_path_factory.mktemp("display")
    report = build_report(read_scene(_scene(folder)), rng=0)
    deg = dataclasses.replace(report, scene=dataclasses.replace(report.scene, display_units="deg"))
    write_report(report, folder / "si")
    write_report(deg, folder / "deg")
    return report, deg, folder


def _json(folder):
    return json.loads((folder / "report.json").read_text())


def test_report_json_gives_display_values_beside_unchanged_si(written):
    _, _, folder = written
    si, deg = _json(folder / "si"), _json(folder / "deg")
    added = {"display_units", "requirement_display"}
    assert not added & set(si) and added <= set(deg)
    assert {k: v for k, v in deg.items() if k not in added | {"sensors"}} == {
        k: v for k, v in si.items() if k != "sensors"}
    (s_si,), (s_deg,) = si["sensors"], deg["sensors"]
    assert {k: v for k, v in s_deg.items() if not k.endswith("_display")} == s_si
    assert deg["display_units"] == "deg"
    assert deg["requirement_display"]["unit"] == "deg"
    assert deg["requirement_display"]["max_error"] == pytest.approx(1.0, rel=1e-15)  # "1 deg"
    for b, shown in zip(s_si["bounds"], s_deg["bounds_display"]):
        assert b["unit"] == "rad" and shown["unit"] == "deg" and shown["outage_s"] == b["outage_s"]
        for key in ("bound", "median"):
            assert shown[key] == pytest.approx(b[key] * DEG, rel=1e-14)
    # a variance by (180/pi)^2, a density by 180/pi, a time constant not at all
    powers = {"noise_variance": 2, "bias_variance": 2, "noise_density": 1, "time_constant": 0}
    for name, power in powers.items():
        p, shown = s_si["parameters"][name], s_deg["parameters_display"][name]
        for key in ("median", "q05", "q95"):
            assert shown[key] == pytest.approx(p[key] * DEG**power, rel=1e-14), (name, key)
    assert s_deg["parameters_display"]["noise_density"]["unit"] == "deg/s/sqrt(Hz)"
    # the log was simulated in deg/s with a white variance of 0.25 (deg/s)^2 (truth.json)
    truth = json.loads((DATA / "truth.json").read_text())["gyro_lowgrade"]["parameters"]
    assert s_deg["parameters_display"]["noise_variance"]["median"] == pytest.approx(
        truth["noise_variance"], rel=0.02)


def _cells(page, first):
    """The cells of the table rows of ``page`` whose first cell is ``first``."""
    rows = re.findall(rf"<tr><td>{re.escape(first)}</td>(.*?)</tr>", page)
    return [re.findall(r"<td>(.*?)</td>", row) for row in rows]


def test_report_html_shows_degrees_beside_si(written):
    report, _, folder = written
    si = (folder / "si" / "report.html").read_text()
    deg = (folder / "deg" / "report.html").read_text()
    assert "(shown)" not in si and "angle random walk" not in si
    bounds = _json(folder / "si")["sensors"][0]["bounds"]
    rows = _cells(deg, "budget")
    assert len(rows) == len(bounds)
    for cells, b in zip(rows, bounds):
        assert cells[2:] == [f"{b['median']:.4g}", f"{b['bound']:.4g}", "rad",
                             f"{b['median'] * DEG:.4g}", f"{b['bound'] * DEG:.4g}", "deg"]
    q = report.sensors[0].fit.repeatability_quantiles()
    (variance,) = _cells(deg, "noise_variance")
    assert variance == [f"{v:.4g}" for v in q["noise_variance"]] + ["(rad/s)^2"] + [
        f"{v * DEG**2:.4g}" for v in q["noise_variance"]] + ["(deg/s)^2"]
    # a density per sqrt(h), as a datasheet gives it: deg/sqrt(s) times sqrt(3600 s / 1 h)
    (arw,) = _cells(deg, "angle random walk (noise_density)")
    assert arw[3] == "rad/s/sqrt(Hz)"
    assert arw[4:] == [f"{v * DEG * math.sqrt(3600.0):.4g}" for v in q["noise_density"]] + [
        "deg/sqrt(h)"]
    # the datasheet table is in the datasheet's own units whichever display: the same in both
    table = re.compile(r'<table class="datasheet">.*?</table>', re.S)
    assert table.findall(deg) == table.findall(si) != []
    assert "at most 0.01745 rad (given as 1 deg)" in deg


def test_comparison_chart_in_degrees(written, figures):
    report, deg, _ = written
    for r in (report, deg):
        report_html._comparison_figure(r, Path("/dev/null"))
    (ax_si,), (ax_deg,) = (fig.axes for fig in figures)
    assert ax_si.get_ylabel() == "1-sigma attitude drift (rad)"
    assert ax_deg.get_ylabel() == "1-sigma attitude drift (deg)"
    assert len(ax_si.lines) == len(ax_deg.lines) >= 3
    scaled = 0
    for a, b in zip(ax_si.lines, ax_deg.lines):
        assert list(b.get_xdata()) == list(a.get_xdata())
        if b.get_transform() == ax_deg.get_xaxis_transform():  # an outage's line (axes fraction)
            assert list(b.get_ydata()) == list(a.get_ydata())
            continue
        assert np.asarray(b.get_ydata()) == pytest.approx(
            np.asarray(a.get_ydata()) * DEG, rel=1e-14
        )
        scaled += 1
    assert scaled == 4  # bound, median, requirement, longest acceptable outage
    # the amount as given beside the amount shown, only where they differ (it read "1 deg (1 deg)")
    requirement = [line for line in ax_deg.lines if "requirement" in str(line.get_label())]
    assert requirement[0].get_label() == "requirement 1 deg"
    requirement = [line for line in ax_si.lines if "requirement" in str(line.get_label())]
    assert requirement[0].get_label() == "requirement 0.01745 rad (1 deg)"


def test_display_units_from_the_scene_and_the_command(tmp_path, capsys, monkeypatch):
    assert read_scene(_scene(tmp_path, 'display_units = "deg"')).display_units == "deg"
    assert read_scene(_scene(tmp_path)).display_units == "si"
    path = _scene(tmp_path, 'display_units = "grad"')
    with pytest.raises(InputError, match=r"display_units='grad': expected one of si, deg") as info:
        read_scene(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
    # the command's --display-units wins over the scene's (what the report is built from)
    import bayes_imu.report.scene as scene_module

    seen = []

    def stop(scene, **options):
        seen.append(scene.display_units)
        raise InputError("stopped")

    monkeypatch.setattr(scene_module, "build_report", stop)
    path = _scene(tmp_path, 'display_units = "deg"')
    for given, expected in ((["--display-units", "si"], "si"), ([], "deg")):
        assert main(["report", str(path), "--out", str(tmp_path / "out"), *given, "--quiet"]) == 2
        assert seen.pop() == expected and "stopped" in capsys.readouterr().err
    assert main(["report", str(path), "--out", str(tmp_path / "bad"), "--display-units",
                 "grad"]) == 2
    assert "invalid choice: 'grad'" in capsys.readouterr().err and not (tmp_path / "bad").exists()
