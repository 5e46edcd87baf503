"""``bayes-imu plan`` and ``fit --datasheet`` (the predictions themselves: test_plan.py)."""

import csv
import json

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.noise import NoiseModel
from bayes_imu.noise.simulate import simulate_log


@pytest.fixture(scope="module")
def pilot(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plan")
    model = NoiseModel(("white", "gauss_markov"), 0.1)
    y = simulate_log(
        model, {"noise_variance": 1e-5, "bias_variance": 1e-6, "time_constant": 30.0}, 6000, rng=4
    )
    (tmp / "pilot.csv").write_text("gx\n" + "".join(f"{v:.9g}\n" for v in y))
    (tmp / "spec.toml").write_text(
        'kind = "gyro"\nangle_random_walk = 1.0\ngauss_markov_sigma = 100.0\n'
        "gauss_markov_time_constant = 30.0\n"
    )
    assert (
        main(
            [
                "fit",
                str(tmp / "pilot.csv"),
                "--column",
                "gx",
                "--rate",
                "10",
                "--units",
                "rad/s",
                "--terms",
                "white,gauss_markov",
                "--datasheet",
                str(tmp / "spec.toml"),
                "--out",
                str(tmp / "fit"),
                "--quiet",
            ]
        )
        == 0
    )
    return tmp


def test_fit_datasheet_check_in_summary(pilot):
    check = json.loads((pilot / "fit" / "summary.json").read_text())["datasheet_check"]
    arw = check["values"]["angle_random_walk"]
    # N = sqrt(1e-5 * 0.1) = 1e-3 rad/s/sqrt(Hz) = 3.44 deg/sqrt(h): far above a 1.0 spec
    assert arw["probability"] == 0.0 and arw["median"] == pytest.approx(
        1e-3 * 60 * 180 / np.pi, rel=0.05
    )
    assert check["verdict"].startswith("OUTSIDE") and check["kind"] == "gyro"


def test_fit_datasheet_errors(pilot, tmp_path, capsys):
    (tmp_path / "bad.json").write_text('{"kind": "gyro", "arw": 0.1}')
    assert (
        main(
            [
                "fit",
                str(pilot / "pilot.csv"),
                "--column",
                "gx",
                "--rate",
                "10",
                "--datasheet",
                str(tmp_path / "bad.json"),
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    assert "'arw'" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_plan_from_pilot_fit_writes_table_json_and_figure(pilot, tmp_path, capsys):
    out = tmp_path / "plan"
    assert (
        main(
            [
                "plan",
                str(pilot / "fit"),
                "--lengths",
                "10min,1h,4h",
                "--horizons",
                "10",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    said = capsys.readouterr().out
    assert "upper half-width" in said and "attitude drift 10 s" in said
    with open(out / "plan.csv") as f:
        rows = list(csv.DictReader(f))
    assert {r["what"] for r in rows} == {
        "noise_variance",
        "bias_variance",
        "time_constant",
        "attitude drift at 10 s",
    }
    widths = {(float(r["length_s"]), r["what"]): float(r["width90"]) for r in rows}
    for what in (
        "noise_variance",
        "time_constant",
        "attitude drift at 10 s",
    ):  # longer records, narrower intervals
        assert widths[(600.0, what)] > widths[(3600.0, what)] > widths[(14400.0, what)] > 1.0
    # white noise: the interval shrinks as 1/sqrt(length) (log-width ratio 2 from 1 h to 4 h)
    ratio = np.log(widths[(3600.0, "noise_variance")]) / np.log(widths[(14400.0, "noise_variance")])
    assert ratio == pytest.approx(2.0, rel=0.05)
    assert (out / "plan.png").stat().st_size > 10000 and json.loads(
        (out / "plan.json").read_text()
    )["axes"]["gx"]


def test_plan_from_datasheet_and_its_errors(pilot, tmp_path, capsys):
    assert (
        main(
            [
                "plan",
                "--datasheet",
                str(pilot / "spec.toml"),
                "--rate",
                "100",
                "--lengths",
                "1h,24h",
                "--out",
                str(tmp_path / "p"),
                "--quiet",
            ]
        )
        == 0
    )
    assert (
        main(["plan", "--datasheet", str(pilot / "spec.toml"), "--out", str(tmp_path / "q")]) == 2
    )
    assert "--rate" in capsys.readouterr().err
    assert main(["plan", "--out", str(tmp_path / "r")]) == 2
    assert (
        main(["plan", str(pilot / "fit"), "--lengths", "1h,-2", "--out", str(tmp_path / "s")]) == 2
    )


@pytest.mark.parametrize(
    "command, words",
    [
        ("export", ("--overbound", "--format", "--t-max", "openvins")),
        ("plan", ("--lengths", "--horizons", "--datasheet", "plan.png")),
    ],
)
def test_new_commands_have_help(capsys, command, words):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert all(w in text for w in words), text


def test_plan_given_two_folders_says_so_in_one_line(pilot, tmp_path, capsys):
    """A new user's finding: two folders gave argparse's 'unrecognized arguments'."""
    folder = str(pilot / "fit")
    assert main(["plan", folder, folder, "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "2 pilot fit folders" in err and "expected one" in err
    assert not (tmp_path / "p").exists()


@pytest.mark.slow
def test_plan_carries_an_inadequate_pilot_fit_warning(pilot, tmp_path, capsys):
    """A new user's finding: a plan from a misfitting pilot fit said nothing of it. White noise
    alone fitted to white + Gauss-Markov fails the check; the plan warns and records it."""
    fit = tmp_path / "white_only"
    argv = ["fit", str(pilot / "pilot.csv"), "--column", "gx", "--rate", "10", "--units",
            "rad/s", "--terms", "white", "--out", str(fit), "--quiet"]
    assert main(argv) == 0
    assert json.loads((fit / "summary.json").read_text())["adequacy"]["adequate"] is False
    capsys.readouterr()
    out = tmp_path / "plan"
    assert main(["plan", str(fit), "--lengths", "10min,1h", "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "failed its goodness-of-fit check" in err
    assert "goodness-of-fit" in json.loads((out / "plan.json").read_text())["warnings"][0]
    good = tmp_path / "plan_good"
    assert main(["plan", str(pilot / "fit"), "--lengths", "1h", "--out", str(good), "--quiet"]) == 0
    assert json.loads((good / "plan.json").read_text())["warnings"] == []
