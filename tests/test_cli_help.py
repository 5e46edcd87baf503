"""What the command line tells a user: help texts, display units, units in sensor files and
requirements."""

import json
import math

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.drift.display import parse_amount
from bayes_imu.errors import InputError
from bayes_imu.noise import TERMS


def _help(capsys, *args):
    with pytest.raises(SystemExit) as exc:
        main([*args, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


def test_fit_help_names_outputs_terms_and_examples(capsys):
    text = _help(capsys, "fit")
    for word in (
        "drift.csv",
        "summary.json",
        "--sensor",
        "examples:",
        "--allan-table",
        "--input",
        "increments",
        "correlated",
        "copula",
        "independent",
        "--display-units",
    ):
        assert word in text, word
    for term in TERMS:
        assert term in text, term


def test_report_help_explains_the_scene(capsys):
    text = _help(capsys, "report")
    for word in (
        "[scene]",
        "outages_s",
        "[requirement]",
        "max_error",
        "[[sensor]]",
        "logs =",
        "fit =",
        "column",
    ):
        assert word in text, word
    assert "README" not in text


@pytest.mark.parametrize("command", ["allan", "fit-population", "kalibr", "drift", "fit-batch"])
def test_every_command_has_help(capsys, command):
    text = _help(capsys, command)
    assert "--out" in text


def test_drift_command_reads_units_and_shows_degrees(tmp_path, capsys):
    si = {"kind": "gyro", "rate_hz": 100, "noise_density": 0.01 * math.pi / 180}
    deg = {"kind": "gyro", "rate_hz": 100, "noise_density": 0.01, "units": "deg/s"}
    (tmp_path / "si.json").write_text(json.dumps(si))
    (tmp_path / "deg.json").write_text(json.dumps(deg))
    assert (
        main(["drift", str(tmp_path / "si.json"), "--out", str(tmp_path / "a"), "--horizon", "100"])
        == 0
    )
    assert (
        main(
            [
                "drift",
                str(tmp_path / "deg.json"),
                "--out",
                str(tmp_path / "b"),
                "--horizon",
                "100",
                "--display-units",
                "deg",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "deg (order 1)" in out
    a = np.genfromtxt(
        tmp_path / "a" / "drift.csv", delimiter=",", names=True, dtype=None, encoding="utf-8"
    )
    b = np.genfromtxt(
        tmp_path / "b" / "drift.csv", delimiter=",", names=True, dtype=None, encoding="utf-8"
    )
    # 9 printed digits
    np.testing.assert_allclose(b["total"], a["total"] * 180 / math.pi, rtol=1e-8)
    # white noise, zero bias: sigma(t) = N sqrt(t) exactly, here 0.01 deg/sqrt(s) * 10 at 100 s
    assert b["total"][-1] == pytest.approx(0.1, rel=1e-9) and set(b["unit"]) == {"deg"}
    (tmp_path / "bad.json").write_text(json.dumps({**deg, "units": "g"}))
    assert main(["drift", str(tmp_path / "bad.json"), "--out", str(tmp_path / "c")]) == 2
    assert "for a gyro" in capsys.readouterr().err


def test_fit_drift_in_degrees(tmp_path):
    rng = np.random.default_rng(4)
    (tmp_path / "g.csv").write_text(
        "g\n" + "".join(f"{v:.8f}\n" for v in 0.05 * rng.standard_normal(4096))
    )
    common = [
        "fit",
        str(tmp_path / "g.csv"),
        "--column",
        "g",
        "--rate",
        "100",
        "--units",
        "deg/s",
        "--terms",
        "white",
        "--sensor",
        "gyro",
        "--times",
        "1,10",
        "--quiet",
    ]
    assert main(common + ["--out", str(tmp_path / "rad")]) == 0
    assert main(common + ["--out", str(tmp_path / "deg"), "--display-units", "deg"]) == 0
    rad = (tmp_path / "rad" / "drift.csv").read_text().splitlines()[1:]
    deg = (tmp_path / "deg" / "drift.csv").read_text().splitlines()[1:]
    for r, d in zip(rad, deg):
        r, d = r.split(","), d.split(",")
        assert (r[5], d[5]) == ("rad", "deg")
        assert float(d[3]) == pytest.approx(float(r[3]) * 180 / math.pi, rel=1e-8)
    # the parameters too, beside SI (issue 38): a variance by (180/pi)^2, a density by 180/pi
    si = json.loads((tmp_path / "rad" / "summary.json").read_text())
    shown = json.loads((tmp_path / "deg" / "summary.json").read_text())
    assert "parameters_display" not in si and shown["parameters"] == si["parameters"]
    variance, density = (shown["parameters_display"][k]
                         for k in ("noise_variance", "noise_density"))
    assert variance["unit"] == "(deg/s)^2" and density["unit"] == "deg/s/sqrt(Hz)"
    for key in ("median", "q05", "q95"):
        assert variance[key] == pytest.approx(si["parameters"]["noise_variance"][key]
                                              * (180 / math.pi) ** 2, rel=1e-12)
        assert density[key] == pytest.approx(si["parameters"]["noise_density"][key] * 180 / math.pi,
                                             rel=1e-12)


@pytest.mark.parametrize(
    "given, quantity, si",
    [
        ("0.5 deg", "attitude", 0.5 * math.pi / 180),
        ("2 mrad", "attitude", 2e-3),
        (0.01, "attitude", 0.01),
        ("30 arcmin", "attitude", 0.5 * math.pi / 180),
        ("1.5 km", "position", 1500.0),
        ("10cm", "position", 0.1),
        ("36 km/h", "velocity", 10.0),
        ("3 ft", "position", 0.9144),
    ],
)
def test_requirement_units(given, quantity, si):
    assert parse_amount(given, quantity, "req") == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("given", ["0.5 m", "deg", "-1 deg", True, "1e400 rad"])
def test_requirement_unit_errors(given):
    with pytest.raises(InputError, match="req"):
        parse_amount(given, "attitude", "req")


def test_ranking_reason_echoes_a_requirement_as_given():
    """A requirement of "1 deg" was echoed as 0.0174533 rad only (issue 38): now as given, SI
    beside it."""
    from types import SimpleNamespace

    from bayes_imu.report.scene import _rank

    req = {"quantity": "attitude", "max_error": math.pi / 180, "unit": "rad", "given": "1 deg"}
    scene = SimpleNamespace(outages_s=(10.0,), requirement=req, credibility=0.95)
    reports = [SimpleNamespace(spec=SimpleNamespace(name=n, kind="gyro"), max_outage_s=t,
                               bounds=({"outage_s": 10.0, "quantity": "attitude", "bound": b},))
               for n, t, b in (("a", 5.0, 0.1), ("b", 50.0, 0.01))]
    order, reason = _rank(scene, reports)
    assert order == ("b", "a") and "within 1 deg (0.0174533 rad)" in reason
