"""``bayes-imu export``: fit folders to filter noise files (formats: test_exports.py)."""

import json
import math
import re

import numpy as np
import pytest
import yaml

from bayes_imu.cli.main import main


@pytest.fixture(scope="module")
def gyro_fit(tmp_path_factory):
    """A white + random-walk gyro fitted in deg/s (values then exported in rad)."""
    tmp = tmp_path_factory.mktemp("export")
    rng = np.random.default_rng(5)
    n, dt = 2**14, 0.01
    y = 0.05 * rng.standard_normal(n) + np.cumsum(2e-3 * math.sqrt(dt) * rng.standard_normal(n))
    log = tmp / "imu.csv"
    log.write_text("gx\n" + "".join(f"{v:.8f}\n" for v in y))
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "gx",
                "--rate",
                "100",
                "--units",
                "deg/s",
                "--terms",
                "white,random_walk",
                "--out",
                str(tmp / "g"),
                "--quiet",
            ]
        )
        == 0
    )
    return tmp


def test_export_point_values_match_kalibr_and_are_si(gyro_fit, tmp_path):
    assert main(["kalibr", "--gyro", str(gyro_fit / "g"), "--out", str(tmp_path / "k.yaml")]) == 0
    assert (
        main(
            [
                "export",
                "--gyro",
                str(gyro_fit / "g"),
                "--format",
                "vins",
                "--out",
                str(tmp_path / "v.yaml"),
                "--quiet",
            ]
        )
        == 0
    )
    kalibr = yaml.safe_load((tmp_path / "k.yaml").read_text())
    vins = yaml.safe_load((tmp_path / "v.yaml").read_text().replace("%YAML:1.0\n", "", 1))
    assert vins["gyr_n"] == pytest.approx(
        kalibr["gyroscope_noise_density"], rel=1e-6
    )  # kalibr prints 7 digits
    assert vins["gyr_w"] == pytest.approx(kalibr["gyroscope_random_walk"], rel=1e-6)
    summary = json.loads((gyro_fit / "g" / "summary.json").read_text())
    assert summary["unit"] == "rad/s"  # --units deg/s: converted to SI when read
    assert vins["gyr_n"] == pytest.approx(
        summary["parameters"]["noise_density"]["median"], rel=1e-9
    )
    assert set(vins) == {"gyr_n", "gyr_w"}


def test_export_overbound_says_the_factor_and_bounds_the_point(gyro_fit, tmp_path, capsys):
    out = tmp_path / "imu_chain.yaml"
    assert (
        main(
            [
                "export",
                "--gyro",
                str(gyro_fit / "g"),
                "--format",
                "openvins",
                "--overbound",
                "--t-max",
                "60",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    said = capsys.readouterr().out
    assert "over the posterior median" in said and "tight at attitude" in said
    text = out.read_text()
    doc = yaml.safe_load(text.replace("%YAML:1.0\n", "", 1))["imu0"]
    point = re.search(
        r"gyroscope_noise_density \[[^]]+\]: point \(posterior median\) (\S+); overbound (\S+)",
        text,
    )
    assert float(point.group(2)) == doc["gyroscope_noise_density"] >= float(point.group(1))
    assert doc["update_rate"] == 100.0 and doc["rostopic"] == "/imu0"


def test_export_errors_are_one_line(gyro_fit, tmp_path, capsys):
    assert main(["export", "--format", "kalibr", "--out", str(tmp_path / "a.yaml")]) == 2
    assert "--gyro" in capsys.readouterr().err
    assert (
        main(
            [
                "export",
                "--gyro",
                str(gyro_fit / "g"),
                "--format",
                "kalibr",
                "--t-max",
                "10",
                "--out",
                str(tmp_path / "a.yaml"),
            ]
        )
        == 2
    )
    assert "--overbound" in capsys.readouterr().err
    assert not (tmp_path / "a.yaml").exists()


def test_force_replaces_an_export_of_any_format_it_wrote_and_the_docs_say_so(gyro_fit, tmp_path,
                                                                              capsys):
    """docs/cli.md said OpenVINS, VINS and MATLAB files cannot be replaced with --force ("remove
    such a file by hand"), but --force replaces any file an export wrote: its sidecar
    ``.NAME.bayes_imu.json`` records the file's hash, whatever the format. It refuses a file
    without that sidecar and one changed since, and without --force any existing file."""
    from pathlib import Path

    def export(fmt, out, *extra):
        return main(["export", "--gyro", str(gyro_fit / "g"), "--format", fmt, "--out", str(out),
                     "--quiet", *extra])

    for fmt, name in (("openvins", "kalibr_imu_chain.yaml"), ("vins", "vins.yaml"),
                      ("matlab", "imu.m")):
        out = tmp_path / name
        assert export(fmt, out) == 0 and (tmp_path / f".{name}.bayes_imu.json").is_file()
        assert export(fmt, out) == 2
        assert "file exists; use --force" in capsys.readouterr().err
        written = out.read_text()
        out.write_text("stale\n")  # changed since: refused, kept
        assert export(fmt, out, "--force") == 2
        assert "--force replaces only a file a bayes_imu run wrote" in capsys.readouterr().err
        assert out.read_text() == "stale\n"
        out.write_text(written)  # as written: replaced
        assert export(fmt, out, "--force") == 0 and out.read_text() == written
    foreign = tmp_path / "other.m"  # no sidecar: another tool's file
    foreign.write_text("% gyro = gyroparams;\n")
    assert export("matlab", foreign, "--force") == 2
    assert "replaces only a file a bayes_imu run wrote" in capsys.readouterr().err
    docs = (Path(__file__).resolve().parents[1] / "docs" / "cli.md").read_text(encoding="utf-8")
    section = " ".join(docs.split("## `export`")[1].split("\n## ")[0].split())
    assert "remove such a file by hand to rewrite it" not in section
    assert "`--force` replaces a file of any format that a bayes_imu run wrote" in section
    assert "`.NAME.bayes_imu.json`" in section and "changed since" in section
