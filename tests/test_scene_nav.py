"""Scenes with a navigation requirement (:mod:`bayes_imu.report.scene_nav`): the keys and their
one-line errors, the longest outage against an exact rational reference, and a ranking that the
accelerometer-only position bound gets wrong."""

import dataclasses
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.drift.navigation import GRAVITY
from bayes_imu.errors import InputError
from bayes_imu.inference.fit import FitResult
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.report.scene import (AxisResult, Scene, SensorReport, SensorSpec, max_outage,
                                    read_scene)
from bayes_imu.report.scene_nav import imu_reports, rank_imus

DT = 0.01
Z95 = 1.959963984540054  # the 97.5 % normal quantile (scipy.stats.norm.ppf(0.975))

SCENE = """
[scene]
name = "nav"
outages_s = [10, 60]
[navigation]
quantity = "position"
max_error = "5 m"
after_s = 60
[[imu]]
name = "A"
gyro = "g"
accel = "a"
[[sensor]]
name = "g"
kind = "gyro"
log = "g.csv"
column = "x"
rate_hz = 100
units = "rad/s"
[[sensor]]
name = "a"
kind = "accel"
log = "a.csv"
column = "x"
rate_hz = 100
units = "m/s^2"
"""


def _scene(tmp_path, text=SCENE):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return read_scene(path)


def test_navigation_keys_are_read(tmp_path):
    scene = _scene(tmp_path, SCENE.replace('max_error = "5 m"', 'max_error = "0.5 km"'))
    req = scene.navigation
    assert req["max_error"] == 500.0 and req["after_s"] == 60.0 and req["quantity"] == "position"
    assert req["credibility"] == 0.95 and req["statistic"] == "bound" and req["schuler"] is True
    assert [(i.name, i.gyro, i.accel) for i in scene.imus] == [("A", "g", "a")]
    plain = SCENE.split("[navigation]")[0] + SCENE.split('accel = "a"')[1]
    assert _scene(tmp_path, plain).imus == ()


@pytest.mark.parametrize(
    "patch, message",
    [
        (('quantity = "position"', 'quantity = "heading"'), "quantity='heading'"),
        (('max_error = "5 m"', 'max_error = "5 deg"'), "max_error"),
        (('max_error = "5 m"', "max_error = -5"), "max_error"),
        (('max_error = "5 m"', ""), "missing key 'max_error'"),
        (("after_s = 60", "after_s = 0"), "after_s=0"),
        (("after_s = 60", 'after_s = "1 min"'), "after_s"),
        (("after_s = 60", "credibility = 1.0"), "credibility=1.0"),
        (("after_s = 60", 'statistic = "3sigma"'), "statistic='3sigma'"),
        (("after_s = 60", 'schuler = "on"'), "schuler='on'"),
        (("after_s = 60", "speed = 3"), "unknown key 'speed'"),
        (('gyro = "g"', 'gyro = "a"'), "is an accel sensor; expected a gyro"),
        (('accel = "a"', 'accel = "nope"'), "no [[sensor]] of that name"),
        (('accel = "a"', "accel = 3"), "accel=3"),
        (('name = "A"', 'name = "A"\ncolour = "red"'), "unknown key 'colour'"),
        (("[[imu]]", "[[imu]]\nname = 'B'\ngyro = 'g'\naccel = 'a'\n[[imu]]"), None),
        (('[navigation]\nquantity = "position"\nmax_error = "5 m"\nafter_s = 60\n', ""),
         "need a [navigation] table"),
    ],
)
def test_bad_navigation_values_are_one_line(tmp_path, patch, message):
    text = SCENE.replace(*patch, 1)
    if message is None:  # two IMUs of the same name
        text = text.replace("name = 'B'", "name = 'A'")
        message = "names must be unique"
    with pytest.raises(InputError) as info:
        _scene(tmp_path, text)
    text = str(info.value)
    assert message in text and "\n" not in text and "scene.toml" in text


def _point_fit(terms, values):
    """A posterior concentrated on one parameter vector (its 95 % bound is 1.96 sigma)."""
    samples = np.tile(np.asarray(values, float), (40, 1))
    return FitResult(NoiseModel(terms, DT), samples, np.zeros(40), None, (), 0, {}, "test", None)


def _sensor(name, kind, fit):
    spec = SensorSpec(name, (Path(name),), ("x",), 100.0, kind, "SI")
    return SensorReport(spec, (AxisResult("x", fit, fit),), (), None, (), 0)


def _exact_sigma(k, q_gyro, q_accel):
    """Position 1-sigma after ``k`` samples, loop off, both sensors white, errors from zero: held
    samples integrated exactly (Fractions in units of dt). Accelerometer: weight ``(m - 1/2)
    dt^2`` of the sample ``m`` periods before the end; gyro: ``g dt^3 (m/2 - 1/3 + (m-1)^2/2)``
    (the tilt ramps over the sample's period, then holds)."""
    acc = Fraction(sum((2 * m - 1) ** 2 for m in range(1, k + 1)), 4)  # integers: exact
    gyr = Fraction(sum((3 * m - 2 + 3 * (m - 1) ** 2) ** 2 for m in range(1, k + 1)), 36)
    return np.sqrt(float(acc) * DT**4 * q_accel + float(gyr) * GRAVITY**2 * DT**6 * q_gyro)


def test_navigation_ranking_beats_the_accelerometer_only_bound():
    """IMU A: a poor gyro with a good accelerometer; B: a good gyro with a worse accelerometer.
    The accelerometer-only position bound (the sensors' own ranking) prefers A's
    accelerometer; through the tilt the navigation error is the gyro's, and B keeps 5 m longer.
    Each longest outage is checked against the exact error of the loop without Schuler."""
    q = Q
    scene, reports = _ranking_scene()
    own = {n: max_outage(r.posterior, "position", 5.0, 0.95, "zero", rng=0)
           for n, r in zip(q, reports) if n[0] == "a"}
    assert own["aA"] > own["aB"]  # the accelerometer-only bound prefers A
    imus = imu_reports(scene, reports, np.random.default_rng(0))
    order, reason = rank_imus(scene, imus)
    assert order == ("B", "A") and "longest outage" in reason
    _check_exact(imus, q)


#: per-sample white variances (SI) of the ranking test's gyros and accelerometers
Q = {"gA": 1e-6, "aA": 1e-6, "gB": 1e-12, "aB": 1e-4}


def _ranking_scene():
    from bayes_imu.report.scene_nav import ImuSpec

    reports = [_sensor(n, "gyro" if n[0] == "g" else "accel", _point_fit(("white",), [v]))
               for n, v in Q.items()]
    scene = Scene("t", (10.0, 60.0), 0.95, tuple(r.spec for r in reports), bias_start="zero",
                  navigation={"quantity": "position", "max_error": 5.0, "unit": "m",
                              "given": None, "after_s": None, "credibility": 0.95,
                              "statistic": "bound", "schuler": False},
                  imus=tuple(ImuSpec(n, "g" + n, "a" + n) for n in ("A", "B")))
    return scene, reports


def _check_exact(imus, q):
    for r in imus:
        k = int(round(r.longest_outage_s / DT))
        args = (q["g" + r.name], q["a" + r.name])
        assert Z95 * _exact_sigma(k, *args) <= 5.0 * (1 + 1e-9)
        assert Z95 * _exact_sigma(int(k * 1.03) + 1, *args) > 5.0  # within the refined grid
        row = next(w for w in r.rows if w["outage_s"] == 10.0 and w["quantity"] == "position")
        assert row["predictive_bound"] == pytest.approx(Z95 * _exact_sigma(1000, *args), rel=1e-9)
    a, b = imus
    assert a.rows[2]["dominant"] == "gyro" and b.longest_outage_s > a.longest_outage_s


@pytest.mark.slow
def test_navigation_json_page_and_picture():
    """The report's navigation part: JSON (strict), the HTML section in ranking order, and
    comparison.png with the IMU row drawn (the IMUs of the ranking test)."""
    import io
    import json

    scene, reports = _ranking_scene()
    imus = imu_reports(scene, reports, np.random.default_rng(0))
    order, reason = rank_imus(scene, imus)
    from bayes_imu.report.html import _comparison_figure
    from bayes_imu.report.scene import Report
    from bayes_imu.report.scene_nav import navigation_json, navigation_section

    report = Report(scene, tuple(reports), (), "", imus, order, reason)
    doc = json.loads(json.dumps(navigation_json(report), allow_nan=False))
    assert doc["ranking"] == ["B", "A"] and doc["imus"][0]["rows"][0]["quantity"] == "tilt"
    page = navigation_section(report)
    assert page.index("<li>B:") < page.index("<li>A:") and page.count("<img") == 2
    buffer = io.BytesIO()
    _comparison_figure(report, buffer)
    assert buffer.getvalue()[:8] == b"\x89PNG\r\n\x1a\n"


def test_comparison_numbers_the_imus_by_their_ranking():
    """comparison.png's ``#n`` is the IMU's place in the ranking, not in the scene (a user read
    "#1 IMU 2" beside a ranking that put IMU 3 first); IMUs the ranking leaves out follow."""
    from types import SimpleNamespace

    from bayes_imu.report.scene_nav import ranked_imus

    imus = tuple(SimpleNamespace(name=n) for n in ("IMU 2", "IMU 3", "IMU 4"))
    report = SimpleNamespace(imus=imus, imu_ranking=("IMU 3", "IMU 2"))
    assert [r.name for r in ranked_imus(report)] == ["IMU 3", "IMU 2", "IMU 4"]
    assert [r.name for r in ranked_imus(SimpleNamespace(imus=imus, imu_ranking=()))] == [
        "IMU 2", "IMU 3", "IMU 4"]


def test_the_extrapolation_footnote_appears_only_with_a_marked_row(monkeypatch):
    """The navigation table's "* beyond the shorter log" footnote only where some outage is marked
    (a user read it under a table with no mark); the IMUs' pictures are left out here."""
    import bayes_imu.report.scene_nav as scene_nav
    from bayes_imu.report.scene import Report
    from bayes_imu.report.scene_nav import navigation_section

    monkeypatch.setattr(scene_nav, "_figure", lambda *args, **kwargs: "")
    scene, reports = _ranking_scene()
    imus = imu_reports(scene, reports, np.random.default_rng(0))
    order, reason = rank_imus(scene, imus)
    report = Report(scene, tuple(reports), (), "", imus, order, reason)
    marked = any(row["outage_s"] > r.record_s for r in imus for row in r.rows)
    page = navigation_section(report)
    assert ("* beyond the shorter log" in page) == marked
    assert page.count("*</td>") == sum(row["outage_s"] > r.record_s
                                       and row["quantity"] == "position"
                                       for r in imus for row in r.rows)
    # rows and pictures in the ranking's order, as the ranked list above them
    assert order == ("B", "A") and page.index("<h3>B</h3>") < page.index("<h3>A</h3>")
    assert page.index("<tr><td>B</td>") < page.index("<tr><td>A</td>")
    for record_s, n_marked in ((1e9, 0), (30.0, 2)):  # no outage beyond it; each IMU's 60 s
        imus_at = tuple(dataclasses.replace(r, record_s=record_s) for r in imus)
        page = navigation_section(Report(scene, tuple(reports), (), "", imus_at, order, reason))
        assert page.count("*</td>") == n_marked
        assert ("* beyond the shorter log" in page) == (n_marked > 0)


def test_comparison_gives_every_series_its_own_colour(figures):
    """comparison.png drew the second sensor ("u1 accel x") and the second IMU ("#2 ADIS unit 2")
    in the same colour ("C1" for both: each row counted from C0). The sensors' and the IMUs'
    series now take their colours from one list for the whole figure: one colour per series, the
    same in each panel it appears in, no two series alike."""
    import io
    from types import SimpleNamespace

    from matplotlib.colors import to_hex

    from bayes_imu.drift.bands import SENSOR_QUANTITIES
    from bayes_imu.report.html import _comparison_figure
    from bayes_imu.report.scene import Report

    scene, reports = _ranking_scene()
    t = np.geomspace(0.1, 100.0, 20)

    def band(quantity, scale):
        return SimpleNamespace(quantity=quantity, t_s=t, quantiles=(0.05, 0.5, 0.95),
                               total=np.vstack([0.5 * scale * t, scale * t, 2.0 * scale * t]))

    drawn = [dataclasses.replace(r, bands=tuple(band(q, 1.0 + i)
                                                for q in SENSOR_QUANTITIES[r.spec.kind]))
             for i, r in enumerate(reports)]
    imus = imu_reports(scene, reports, np.random.default_rng(0))
    order, reason = rank_imus(scene, imus)
    _comparison_figure(Report(scene, tuple(drawn), (), "", imus, order, reason), io.BytesIO())
    colours = {}
    for ax in figures[-1].axes:
        for line in ax.get_lines():
            label = line.get_label()
            if label.endswith("% bound)") or label.startswith("#"):  # a sensor's, an IMU's
                colours.setdefault(label, set()).add(to_hex(line.get_color()))
    assert len(colours) == len(reports) + len(imus) == 6, colours
    assert all(len(c) == 1 for c in colours.values()), colours
    assert len(set.union(*colours.values())) == len(colours), colours
