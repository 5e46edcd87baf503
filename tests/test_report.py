"""Reports: scene parsing, bounds, ranking, max outage, HTML (headless browser), Kalibr export."""

import json
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.report.scene import _bound, build_report, read_scene
from bayes_imu.report.html import write_report

DATA = Path(__file__).resolve().parents[1] / "data_synthetic"
SCENE = """
[scene]
name = "test scene"
allow_outside = true
outages_s = [10, 60, 300]
credibility = 0.95
bias_start = "zero"
[requirement]
quantity = "attitude"
max_error = 0.0175
[[sensor]]
name = "budget"
log = "{data}/gyro_lowgrade.csv.gz"
column = "gyro_x_dps"
rate_hz = 100
kind = "gyro"
units = "deg/s"
[[sensor]]
name = "tactical"
log = "{data}/gyro_highgrade.csv.gz"
column = "gyro_x_dps"
rate_hz = 100
kind = "gyro"
units = "deg/s"
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.toml"
    path.write_text(SCENE.format(data=DATA))
    rep = build_report(read_scene(path), rng=0)
    out = path.parent / "out"
    write_report(rep, out)
    return rep, out


def test_better_sensor_ranks_first_and_bounds_are_quantiles(report):
    rep, out = report
    assert rep.ranking == ("tactical", "budget")
    doc = json.loads((out / "report.json").read_text())
    assert doc["ranking"] == ["tactical", "budget"] and doc["credibility"] == 0.95
    budget = next(s for s in doc["sensors"] if s["name"] == "budget")
    assert budget["model"] == ["white", "gauss_markov"]
    assert [b["outage_s"] for b in budget["bounds"]] == [10, 60, 300]
    for b in budget["bounds"]:
        assert b["unit"] == "rad" and b["median"] < b["bound"] and b["extrapolated"] is False  # 1 h logs
    # the bound is the 95% posterior quantile of sigma(t), recomputed independently from the draws
    fit = rep.sensors[0].fit
    from bayes_imu.drift.closed_forms import drift_sigma

    from bayes_imu.noise import NoiseModel

    sig = []
    for component in fit.mixture:  # model-averaged: every candidate's draws, by probability
        assert set(component.terms) <= {"white", "gauss_markov", "random_walk", "bias_instability",
                                        "quantization", "filtered_white", "hf_correlated",
                                        "gauss_markov_2", "ramp"}, component.terms
        p = NoiseModel(component.terms, 0.01).unpack(component.samples)
        var = drift_sigma(300.0, quantity="attitude", dt=0.01, noise_variance=p["noise_variance"],
                          bias_variance=p.get("bias_variance", 0.0), time_constant=p.get("time_constant", np.inf),
                          random_walk=p.get("rate_random_walk", 0.0)).total ** 2
        # flicker, no calibration: two adjacent 300 s means differ by sqrt(2) ADEV (AVAR definition)
        var = var + 2.0 * (2.0 * np.log(2.0) / np.pi) * p.get("bias_instability", 0.0) ** 2 * 300.0**2
        var = var + 2.0 * p.get("quantization", 0.0) ** 2  # white angle noise: e_k - e_0
        k = 300.0 / 0.01
        var = var + p.get("filtered_variance", 0.0) * 0.01**2 * (4.0 * k - 2.0)  # Var(sum of k MA(1) samples)
        if "bias_variance_2" in p:
            var = var + drift_sigma(300.0, quantity="attitude", dt=0.01, bias_variance=p["bias_variance_2"],
                                    time_constant=p["time_constant_2"]).total ** 2
        var = var + (p.get("rate_ramp", 0.0) * 0.01**2 * k * (k - 1) / 2) ** 2  # deterministic ramp from zero
        if "correlated_variance" in p:  # Var(sum of k stationary AR(1) samples)
            phi = np.exp(-0.01 / p["correlated_time_constant"])
            var = var + p["correlated_variance"] * 0.01**2 * (k * (1 - phi**2) - 2 * phi * (1 - phi**k)) / (1 - phi) ** 2
        sig.append(np.sqrt(var))
    assert budget["bounds"][2]["bound"] == pytest.approx(np.quantile(np.concatenate(sig), 0.95), rel=1e-10)


def test_scene_defaults_to_the_calibrated_bias(tmp_path):
    """A scene without bias_start gets the conservative, actionable semantics: calibrated over 60 s."""
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(data=DATA).replace('bias_start = "zero"\n', ""))
    scene = read_scene(path)
    assert scene.bias_start == "calibrated" and scene.calibration_s == 60.0


def test_max_outage_meets_requirement_at_the_boundary(report):
    rep, _ = report
    budget = rep.sensors[0]
    t = budget.max_outage_s
    assert 10 < t < 300
    at = _bound(budget.fit, t, "attitude", 0.95, "zero")[0][0]
    after = _bound(budget.fit, t * 1.001, "attitude", 0.95, "zero")[0][0]
    assert at <= 0.0175 < after


class _Collect(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.images = set(), []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        if tag == "img":
            self.images.append(attrs["src"])


def test_html_is_self_contained_with_all_sections(report):
    import base64

    _, out = report
    page = (out / "report.html").read_text()
    parser = _Collect()
    parser.feed(page)
    assert {"scene", "ranking", "comparison", "bounds", "meaning", "sensors"} <= parser.ids
    assert len(parser.images) == 1 + 2 * 2
    for src in parser.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    for text in ("temperature", "scale-factor", "bias start", "tactical", "budget", "white + gauss_markov"):
        assert text in page


def test_html_renders_in_headless_chromium(report):
    """A real browser: every embedded picture decodes and the key elements are visible."""
    import os

    from playwright import sync_api as playwright  # a test dependency ([test] extra)

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None and os.environ.get("BAYES_IMU_NO_BROWSER") == "1":
        pytest.skip("BAYES_IMU_NO_BROWSER=1: no chromium on this machine (.ci/run installs it)")
    assert chromium is not None, ("no chromium binary: apt install chromium (.ci/run does), or set "
                                  "BAYES_IMU_NO_BROWSER=1 to skip this check on a machine without "
                                  "one")
    _, out = report
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        page = browser.new_page()
        page.goto((out / "report.html").as_uri())
        decoded = page.evaluate("Array.from(document.images).map(i => i.complete && i.naturalWidth > 0)")
        assert decoded and all(decoded)
        assert page.locator("#ranking li").count() == 2
        assert page.locator("h1").inner_text().startswith("IMU selection report")
        browser.close()


@pytest.mark.parametrize(
    "patch, message",
    [
        (("outages_s = [10, 60, 300]", "outages_s = []"), "outages_s"),
        (("credibility = 0.95", "credibility = 1.5"), "credibility"),
        (('quantity = "attitude"', 'quantity = "heading"'), "quantity"),
        (('units = "deg/s"', 'units = "m/s^2"'), "units"),
        (('kind = "gyro"', 'kind = "baro"'), "kind"),
        (("rate_hz = 100", "rate_hz = -1"), "rate_hz"),
        (("[scene]", "[scenery]"), "scene"),
        (('name = "tactical"', 'name = "budget"'), "unique"),
    ],
)
def test_scene_errors_are_one_line(tmp_path, patch, message):
    text = SCENE.format(data=DATA).replace(*patch, 1)
    path = tmp_path / "scene.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        read_scene(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_report_cli_missing_scene_exit_2(tmp_path, capsys):
    assert main(["report", str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_kalibr_export_from_fit_folders(tmp_path, capsys):
    """Nominal values equal the posterior medians converted to SI; conservative ones are larger."""
    gyro, accel = tmp_path / "g", tmp_path / "a"
    assert main(["fit", str(DATA / "gyro_lowgrade.csv.gz"), "--column", "gyro_x_dps", "--rate", "100",
                 "--unit", "deg/s", "--out", str(gyro)]) == 0
    assert main(["fit", str(DATA / "accel_gravity.csv.gz"), "--column", "accel_z_mps2", "--rate", "100",
                 "--unit", "m/s^2", "--out", str(accel)]) == 0
    assert main(["kalibr", "--gyro", str(gyro), "--accel", str(accel), "--out", str(tmp_path / "imu.yaml")]) == 0
    nominal = dict(line.split(": ") for line in (tmp_path / "imu.yaml").read_text().splitlines() if not line.startswith("#"))
    summary = json.loads((gyro / "summary.json").read_text())
    assert summary["unit"] == "rad/s"  # --unit deg/s: the fit ran on SI values
    density = summary["parameters"]["noise_density"]["median"]
    assert float(nominal["gyroscope_noise_density"]) == pytest.approx(density, rel=1e-3)
    assert float(nominal["update_rate"]) == 100
    assert main(["kalibr", "--gyro", str(gyro), "--accel", str(accel), "--out", str(tmp_path / "c.yaml"),
                 "--credibility", "0.95"]) == 0
    cons = dict(line.split(": ") for line in (tmp_path / "c.yaml").read_text().splitlines() if not line.startswith("#"))
    for key in ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density"):
        assert float(cons[key]) > float(nominal[key])
    assert main(["kalibr", "--gyro", str(accel), "--accel", str(accel), "--out", str(tmp_path / "x.yaml")]) == 2


def test_outage_longer_than_the_log_is_marked_extrapolated(report):
    """The tactical gyro stays within 1 deg far beyond its one-hour log: the ranking says so."""
    rep, out = report
    tactical = next(s for s in rep.sensors if s.spec.name == "tactical")
    assert tactical.max_outage_s > 3600.0
    page = (out / "report.html").read_text()
    assert "(beyond its 3600 s log: extrapolated)" in page


def _flagged_fit():
    """A log whose noise doubles halfway (flagged non-stationary: its drift draws include the random
    spread between its parts)."""
    from bayes_imu import allan_variance, fit_allan

    y = np.random.default_rng(11).standard_normal(40_000)
    y[20_000:] *= 2.0
    fit = fit_allan(allan_variance(y, rate_hz=100.0), terms=("white",), rng=0)
    assert not fit.stationarity.stationary
    return fit


def test_bounds_of_a_non_stationary_log_are_reproducible():
    """The conservative bound and the longest acceptable outage of a log flagged non-stationary come from the
    given rng (the part-to-part spread is drawn from it): the same rng gives the same numbers, and the
    bisection searches one deterministic bound (its draws shared by every time it tries)."""
    from bayes_imu.report.scene import _bound, max_outage

    fit = _flagged_fit()
    t = np.array([1.0, 10.0, 100.0])
    a = _bound(fit, t, "attitude", 0.95, "calibrated", rng=5)
    np.testing.assert_array_equal(a[0], _bound(fit, t, "attitude", 0.95, "calibrated", rng=5)[0])
    assert not np.array_equal(a[0], _bound(fit, t, "attitude", 0.95, "calibrated", rng=6)[0])
    limit = float(a[0][1])  # the bound at 10 s: the longest outage within it is about 10 s
    first = max_outage(fit, "attitude", limit, 0.95, rng=5)
    assert first == max_outage(fit, "attitude", limit, 0.95, rng=5)
    assert 5.0 < first < 20.0


def test_a_sensors_numbers_do_not_depend_on_the_sensors_beside_it(tmp_path, report):
    """Each sensor draws from its own stream spawned from the report's seed: with another log in place of the
    first sensor, the second sensor's bounds and longest outage are the same as in the original scene (with one
    stream through all sensors they moved with whatever the first sensor's fits had drawn)."""
    rep, _ = report
    other = SCENE.replace('name = "budget"\nlog = "{data}/gyro_lowgrade.csv.gz"',
                          'name = "budget"\nlog = "{data}/gyro_rrw.csv.gz"')
    assert other != SCENE
    path = tmp_path / "scene.toml"
    path.write_text(other.format(data=DATA))
    again = build_report(read_scene(path), rng=0)
    assert again.sensors[0].bounds != rep.sensors[0].bounds  # the first sensor did change
    assert again.sensors[1].bounds == rep.sensors[1].bounds
    assert again.sensors[1].max_outage_s == rep.sensors[1].max_outage_s
