"""Command-line tests: exit status, outputs, one-line errors."""

import json
from pathlib import Path

import numpy as np

from bayes_imu import drift_sigma
from bayes_imu.cli import main


def test_drift_command_writes_csv_matching_api(tmp_path, capsys):
    sensor = {"kind": "accel", "rate_hz": 200, "noise_density": 2e-3, "bias_variance": 1e-6, "time_constant": 300}
    path = tmp_path / "s.json"
    path.write_text(json.dumps(sensor))
    assert main(["drift", str(path), "--out", str(tmp_path / "o"), "--horizon", "60"]) == 0
    rows = (tmp_path / "o" / "drift.csv").read_text().splitlines()
    assert rows[0] == "t_s,quantity,white,bias,random_walk,total"
    last_position = [r.split(",") for r in rows[1:] if r.split(",")[1] == "position"][-1]
    expected = drift_sigma(60.0, quantity="position", dt=1 / 200, noise_density=2e-3, bias_variance=1e-6, time_constant=300)
    assert float(last_position[0]) == 60.0
    np.testing.assert_allclose(float(last_position[5]), expected.total, rtol=1e-8)


def test_drift_command_user_errors_exit_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"kind": "gyro", "rate_hz": 100,')
    assert main(["drift", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.json" in err and "invalid JSON" in err
    assert main(["drift", str(tmp_path / "missing.json"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err
    bad.write_text('{"kind": "lidar", "rate_hz": 100, "noise_density": 1}')
    assert main(["drift", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "expected 'gyro' or 'accel'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_allan_command_writes_csv_and_png(tmp_path, rng):
    log = tmp_path / "log.csv"
    y = rng.standard_normal(4096) * 0.01
    log.write_text("time,gyro_x\n" + "\n".join(f"{i / 100:.2f},{v:.9f}" for i, v in enumerate(y)) + "\n")
    assert main(["allan", str(log), "--column", "gyro_x", "--rate", "100", "--out", str(tmp_path / "o")]) == 0
    rows = (tmp_path / "o" / "allan.csv").read_text().splitlines()
    assert rows[0] == "tau,m,adev,adev_low,adev_high,edf"
    first = [float(v) for v in rows[1].split(",")]
    assert first[0] == 0.01 and first[1] == 1 and first[3] < first[2] < first[4]
    assert (tmp_path / "o" / "allan.png").stat().st_size > 10_000


def test_allan_command_missing_column(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("a,b\n1,2\n3,4\n")
    assert main(["allan", str(log), "--column", "gyro", "--rate", "100", "--out", str(tmp_path / "o")]) == 2
    assert "no column 'gyro'" in capsys.readouterr().err


def test_fit_command_writes_all_outputs(tmp_path, capsys):
    """bayes-imu fit on a shipped log: summary.json keys, posterior.nc readable, figures, same seed same numbers."""
    import json

    from bayes_imu.cli import main

    data = Path(__file__).resolve().parents[1] / "data_synthetic" / "gyro_highgrade.csv.gz"
    args = [str(data), "--column", "gyro_x_dps", "--rate", "100", "--seed", "3", "--unit", "deg/s"]
    assert main(["fit", *args, "--out", str(tmp_path / "a")]) == 0
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["model"] == ["white"]
    assert set(summary["parameters"]) == {"noise_variance", "noise_density"}
    assert summary["parameters"]["noise_density"]["unit"] == "deg/s/sqrt(Hz)"
    assert set(summary["diagnostics"]) >= {"rhat_max", "ess_bulk_min", "converged"}
    assert summary["seed"] == 3 and summary["bayes_imu_version"]
    for name in ("posterior.nc", "allan_fit.png", "corner.png"):
        assert (tmp_path / "a" / name).stat().st_size > 0
    from bayes_imu.fit import _arviz

    idata = _arviz().from_netcdf(str(tmp_path / "a" / "posterior.nc"))
    assert {"posterior", "sample_stats", "observed_data", "log_likelihood"} <= set(idata.groups())
    assert main(["fit", *args, "--out", str(tmp_path / "b")]) == 0
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["parameters"] == summary["parameters"]


def test_fit_command_bad_terms_exit_2(tmp_path, capsys):
    from bayes_imu.cli import main

    data = Path(__file__).resolve().parents[1] / "data_synthetic" / "gyro_highgrade.csv.gz"
    code = main(["fit", str(data), "--column", "gyro_x_dps", "--rate", "100", "--terms", "white,pink", "--out", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pink" in err[0]
