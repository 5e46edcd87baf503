"""Command-line tests: exit status, outputs, one-line errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from bayes_imu import drift_sigma
from bayes_imu.cli.main import main


def test_drift_command_writes_csv_matching_api(tmp_path, capsys):
    sensor = {
        "kind": "accel",
        "rate_hz": 200,
        "noise_density": 2e-3,
        "bias_variance": 1e-6,
        "time_constant": 300,
    }
    path = tmp_path / "s.json"
    path.write_text(json.dumps(sensor))
    assert main(["drift", str(path), "--out", str(tmp_path / "o"), "--horizon", "60"]) == 0
    rows = (tmp_path / "o" / "drift.csv").read_text().splitlines()
    assert rows[0] == "t_s,quantity,white,bias,random_walk,total,unit"
    last_position = [r.split(",") for r in rows[1:] if r.split(",")[1] == "position"][-1]
    expected = drift_sigma(
        60.0,
        quantity="position",
        dt=1 / 200,
        noise_density=2e-3,
        bias_variance=1e-6,
        time_constant=300,
    )
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
    log.write_text(
        "time,gyro_x\n" + "\n".join(f"{i / 100:.2f},{v:.9f}" for i, v in enumerate(y)) + "\n"
    )
    assert (
        main(
            ["allan", str(log), "--column", "gyro_x", "--rate", "100", "--out", str(tmp_path / "o")]
        )
        == 0
    )
    rows = (tmp_path / "o" / "allan.csv").read_text().splitlines()
    assert rows[0] == "tau,m,adev,adev_low,adev_high,edf,unit"
    first = [float(v) for v in rows[1].split(",")[:6]]
    assert first[0] == 0.01 and first[1] == 1 and first[3] < first[2] < first[4]
    assert (tmp_path / "o" / "allan.png").stat().st_size > 10_000


def test_allan_command_missing_column(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("a,b\n1,2\n3,4\n")
    assert (
        main(["allan", str(log), "--column", "gyro", "--rate", "100", "--out", str(tmp_path / "o")])
        == 2
    )
    assert "no column 'gyro'" in capsys.readouterr().err


def test_fit_command_writes_all_outputs(tmp_path, capsys):
    """bayes-imu fit on a shipped log: summary.json keys, posterior.nc readable, figures, same seed
    same numbers."""
    import json

    from bayes_imu.cli.main import main

    data = Path(__file__).resolve().parents[1] / "data_synthetic" / "gyro_highgrade.csv.gz"
    args = [str(data), "--column", "gyro_x_dps", "--rate", "100", "--seed", "3", "--unit", "deg/s"]
    assert main(["fit", *args, "--out", str(tmp_path / "a")]) == 0
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["model"] == ["white"]
    assert set(summary["parameters"]) == {"noise_variance", "noise_density"}
    # --unit deg/s converts to SI
    assert summary["parameters"]["noise_density"]["unit"] == "rad/s/sqrt(Hz)"
    assert summary["input"]["input_units"] == "deg/s" and summary["unit"] == "rad/s"
    assert set(summary["diagnostics"]) >= {"rhat_max", "ess_bulk_min", "converged"}
    assert summary["seed"] == 3 and summary["bayes_imu_version"]
    assert set(summary["adequacy"]) >= {
        "adequate",
        "p_value",
        "worst_tau_s",
        "at_prior_bound",
        "widened",
    }
    assert isinstance(summary["diagnostics"]["n_steps"], int) and isinstance(
        summary["diagnostics"]["n_walkers"], int
    )
    assert abs(sum(c["probability"] for c in summary["candidates"]) - 1.0) < 1e-9
    # each term's probability: the summed share of the averaged models that have it (white: all of
    # them)
    for term, p in summary["term_probability"].items():
        assert p == pytest.approx(
            sum(c["probability"] for c in summary["model_averaging"] if term in c["model"])
        )
    assert summary["term_probability"]["white"] == pytest.approx(1.0)
    for name in ("posterior.nc", "allan_fit.png", "corner.png"):
        assert (tmp_path / "a" / name).stat().st_size > 0
    from bayes_imu.inference.fit import import_arviz

    idata = import_arviz().from_netcdf(str(tmp_path / "a" / "posterior.nc"))
    assert {"posterior", "sample_stats", "observed_data", "log_likelihood"} <= set(idata.groups())
    assert main(["fit", *args, "--out", str(tmp_path / "b")]) == 0
    # determinism: the same input and seed give a byte-identical summary.json
    assert (tmp_path / "b" / "summary.json").read_bytes() == (
        tmp_path / "a" / "summary.json"
    ).read_bytes()


def test_drift_rows_at_exactly_the_requested_times(tmp_path, capsys, rng):
    """--times writes drift.csv at those times; a white-noise fit under the calibrated start gives
    sigma^2 = q dt^2 (k + k^2 / N) (the sum of k samples, plus k times the error of a mean of N),
    checked at the posterior median of q; the summary line is printed for the quantity."""
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    y = simulate_log(NoiseModel(("white",), 0.01), {"noise_variance": 4e-4}, 2**15, rng=rng)
    log = tmp_path / "g.csv"
    log.write_text("g\n" + "\n".join(f"{v:.9f}" for v in y) + "\n")
    out = tmp_path / "o"
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "g",
                "--rate",
                "100",
                "--terms",
                "white",
                "--sensor",
                "gyro",
                "--times",
                "0.1,1,10",
                "--calibration",
                "5",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert "attitude: 1-sigma drift after 10 s" in capsys.readouterr().out
    rows = (out / "drift.csv").read_text().splitlines()[1:]
    t = np.array([float(r.split(",")[0]) for r in rows])
    np.testing.assert_array_equal(t, [0.1, 1.0, 10.0])
    q = json.loads((out / "summary.json").read_text())["parameters"]["noise_variance"]["median"]
    k, n = t / 0.01, 5 / 0.01
    np.testing.assert_allclose(
        [float(r.split(",")[3]) for r in rows], np.sqrt(q * 0.01**2 * (k + k * k / n)), rtol=2e-3
    )


def test_fit_command_bad_terms_exit_2(tmp_path, capsys):
    from bayes_imu.cli.main import main

    data = Path(__file__).resolve().parents[1] / "data_synthetic" / "gyro_highgrade.csv.gz"
    code = main(
        [
            "fit",
            str(data),
            "--column",
            "gyro_x_dps",
            "--rate",
            "100",
            "--terms",
            "white,pink",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pink" in err[0]


def test_several_columns_one_summary_per_axis_and_worst_axis(tmp_path, rng):
    """Three white-noise axes with known variances: each axis fitted, the worst axis is the
    noisiest."""
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    variances = {"gx": 1e-2, "gy": 9e-2, "gz": 4e-2}
    model = NoiseModel(("white",), 0.01)
    cols = {
        c: simulate_log(model, {"noise_variance": v}, 2**14, rng=rng) for c, v in variances.items()
    }
    log = tmp_path / "imu.tsv"
    log.write_text(
        "gx\tgy\tgz\n"
        + "\n".join("\t".join(f"{cols[c][i]:.8f}" for c in cols) for i in range(2**14))
    )
    out = tmp_path / "out"
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "gx,gy,gz",
                "--rate",
                "100",
                "--terms",
                "white",
                "--units",
                "deg/s",
                "--sensor",
                "gyro",
                "--horizon",
                "60",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    top = json.loads((out / "summary.json").read_text())
    assert list(top["axes"]) == ["gx", "gy", "gz"]
    for c, v in variances.items():
        axis = json.loads((out / c / "summary.json").read_text())
        assert (
            axis["column"] == c
            and (out / c / "drift.csv").exists()
            and (out / c / "posterior.nc").exists()
        )
        p = axis["parameters"]["noise_variance"]
        assert (
            p["q05"] < v * (np.pi / 180) ** 2 < p["q95"]
            or abs(np.log(p["median"] / (v * (np.pi / 180) ** 2))) < 0.1
        )
    worst = top["worst_axis"]
    assert worst["noise_density"]["axis"] == "gy" and worst["drift_attitude"]["axis"] == "gy"
    assert worst["noise_variance"]["q95"] == max(
        top["axes"][c]["parameters"]["noise_variance"]["q95"] for c in variances
    )
    assert worst["drift_attitude"]["unit"] == "rad" and "time_constant" not in worst


def test_progress_bars_change_no_number(rng, capsys):
    """progress=True draws bars on stderr and returns bit-identical results; commands show them only
    on a tty."""
    import io

    from bayes_imu._progress import show_progress
    from bayes_imu.allan.estimator import allan_variance

    y = rng.standard_normal(50_000)
    quiet, loud = allan_variance(y, rate_hz=100.0), allan_variance(y, rate_hz=100.0, progress=True)
    np.testing.assert_array_equal(quiet.avar, loud.avar)
    assert "Allan variance" in capsys.readouterr().err

    class Tty(io.StringIO):
        def isatty(self):
            return True

    assert (
        show_progress(False, Tty())
        and not show_progress(True, Tty())
        and not show_progress(False, io.StringIO())
    )


def test_drift_beyond_the_log_is_flagged_as_extrapolation(tmp_path, rng, capsys):
    """A 41 s log and a 100 s horizon: one warning line, the drift.csv rows after 41 s flagged."""
    log = tmp_path / "short.csv"
    log.write_text("g\n" + "\n".join(f"{v:.6f}" for v in rng.standard_normal(2**12)))
    out = tmp_path / "out"
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "g",
                "--rate",
                "100",
                "--terms",
                "white",
                "--sensor",
                "gyro",
                "--horizon",
                "100",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert ("bayes-imu: warning: g: the drift horizon (100 s) is longer than the log (40.96 s)"
            in err)
    rows = [r.split(",") for r in (out / "drift.csv").read_text().splitlines()]
    assert rows[0][-1] == "extrapolated"
    assert all((float(r[0]) > 40.96) == (r[-1] == "true") for r in rows[1:])
    drift = json.loads((out / "summary.json").read_text())["drift"]["attitude"]
    assert drift["extrapolated"] and drift["record_s"] == 40.96


def test_drift_of_a_non_stationary_log_is_the_same_with_the_same_seed(tmp_path):
    """A log flagged non-stationary gets drift bands widened by random draws of the spread between
    its parts: they come from --seed, so two runs with the same seed write the same drift.csv and
    summary drift (they differed from run to run before), and another seed gives other draws."""
    y = np.random.default_rng(11).standard_normal(40_000)
    y[20_000:] *= 2.0
    log = tmp_path / "log.csv"
    log.write_text("g\n" + "\n".join(f"{v:.9g}" for v in y) + "\n")
    outs = []
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        assert (
            main(
                [
                    "fit",
                    str(log),
                    "--column",
                    "g",
                    "--rate",
                    "100",
                    "--units",
                    "rad/s",
                    "--sensor",
                    "gyro",
                    "--terms",
                    "white",
                    "--seed",
                    seed,
                    "--out",
                    str(tmp_path / name),
                    "--quiet",
                ]
            )
            == 0
        )
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        assert summary["adequacy"]["stationarity"]["stationary"] is False
        outs.append(((tmp_path / name / "drift.csv").read_text(), summary["drift"]))
    assert outs[0] == outs[1]
    assert outs[0][0] != outs[2][0]




def test_a_p_value_that_underflowed_is_not_printed_as_zero():
    """A new user read "goodness of fit p = 0" (the console, then allan_fit.png's residual panel):
    a p-value below what doubles resolve is printed as a bound, by one helper that every output
    uses (no module formats a p-value itself)."""
    import re

    import bayes_imu
    from bayes_imu.report.text import p_text

    assert p_text(0.0) == "< 1e-300"
    assert p_text(0.012) == "= 0.012"
    assert p_text(0.996) == "> 0.99" and p_text(0.994) == "= 0.99" and p_text(1.0) == "= 1"
    own = re.compile(r"p = \{[^}]*p_(value|combined)[^}]*\}")
    package = Path(bayes_imu.__file__).parent
    found = [f"{f.relative_to(package)}: {m.group(0)}" for f in sorted(package.rglob("*.py"))
             for m in own.finditer(f.read_text(encoding="utf-8"))]
    assert found == []


def test_degrees_for_an_accelerometer_are_refused_before_reading(tmp_path, capsys):
    """``--sensor accel --display-units deg`` was accepted and ignored (a new user's report):
    refused in one line, exit 2, before the log is read (a missing log is not reached) and with
    nothing written; the library's request refuses it as well."""
    from bayes_imu.allan.pipeline import LogSource
    from bayes_imu.errors import InputError
    from bayes_imu.report.writers import FitRequest

    out = tmp_path / "o"
    code = main(["fit", str(tmp_path / "missing.csv"), "--column", "a", "--rate", "100",
                 "--sensor", "accel", "--display-units", "deg", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--display-units deg" in err[0] and "--sensor accel" in err[0]
    assert "missing" not in err[0]
    assert not out.exists()
    with pytest.raises(InputError, match="accelerometer"):
        FitRequest(LogSource(), sensor="accel", display_units="deg")
    with pytest.raises(InputError, match="expected one of"):
        FitRequest(LogSource(), display_units="degrees")
    assert FitRequest(LogSource(), sensor="gyro", display_units="deg").display_units == "deg"


def test_horizon_and_times_together_are_refused(tmp_path, capsys):
    """``--horizon 100 --times 10,20`` wrote rows at the times and dropped the horizon without a
    word (a new user's report; docs/cli.md gives them as alternatives): one line, exit 2."""
    from bayes_imu.allan.pipeline import LogSource
    from bayes_imu.errors import InputError
    from bayes_imu.report.writers import FitRequest

    code = main(["fit", str(tmp_path / "missing.csv"), "--column", "a", "--rate", "100",
                 "--sensor", "gyro", "--horizon", "100", "--times", "10,20",
                 "--out", str(tmp_path / "o")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--horizon 100 and --times: give one" in err[0]
    with pytest.raises(InputError, match="give one"):
        FitRequest(LogSource(), horizon=100.0, times=(10.0,))
    assert FitRequest(LogSource(), times=(10.0,)).times == (10.0,)


def test_allan_readings_at_the_edge_are_said_to_be_bounds():
    """The console printed "bias_instability ... at tau = 655 s" for a curve still falling at its
    longest tau (summary.json knew: at_edge 0.999): a new user read it as a reading. Readings that
    are bounds on most draws say so; the others are printed as before."""
    from bayes_imu.cli.main import _reading_caveat

    assert "still falls at the longest tau in 100% of draws" in _reading_caveat({"at_edge": 0.999})
    assert "does not rise at the longest tau in 90% of draws" in _reading_caveat({"rising": 0.1})
    assert _reading_caveat({"at_edge": 0.4}) == _reading_caveat({"rising": 0.6}) == ""
    assert _reading_caveat({"median": 1.0}) == ""


def test_console_intervals_carry_the_digits_their_width_resolves():
    """report.text.interval_text: two significant digits more than median / width has (3 to 5),
    all three numbers to the same digits, trailing zeros kept; plain numbers from 1e-3 to 1e5,
    exponents outside. Two digits hid values (a new user's report: "90% [34, 1e+02] deg" for
    104.9 deg, "time_constant median 1.9e+02, 90% [59, 6.6e+02] s" for 192 s and 661 s,
    "[593, 1.05e+03] ug"). The console's parameter, reading and drift lines all use it (no
    f-string of its own)."""
    import re

    import bayes_imu
    from bayes_imu.report.text import interval_text, number_text

    # the intervals, as they print now
    assert interval_text(60.4, 34.5, 104.9) == "median 60.4, 90% [34.5, 105]"
    assert interval_text(192.0, 58.7, 661.0) == "median 192, 90% [58.7, 661]"
    assert interval_text(800.0, 593.0, 1050.0) == "median 800, 90% [593, 1050]"
    # a wide interval: 3 digits each (0.5495 is 0.549499... in binary); a tight one: 4; exponents
    # only beyond 1e5 and below 1e-3; a degenerate interval to the most digits
    assert interval_text(0.7891, 0.5495, 4.2) == "median 0.789, 90% [0.549, 4.20]"
    assert interval_text(51680.0, 25580.0, 229000.0) == "median 51700, 90% [25600, 2.29e+05]"
    assert interval_text(0.2589, 0.2457, 0.2686) == "median 0.2589, 90% [0.2457, 0.2686]"
    assert interval_text(2.7637e-5, 2.7636e-5, 2.7638e-5) == (
        "median 2.7637e-05, 90% [2.7636e-05, 2.7638e-05]")
    assert interval_text(3.0, 3.0, 3.0) == "median 3.0000, 90% [3.0000, 3.0000]"
    # rounded before the notation is chosen: 99999.7 to 3 digits is 1.00e+05, 0.0009996 is 0.00100
    assert [number_text(v) for v in (104.9, 661.0, 1050.0, 99999.7, 0.0009996, 0.00099, 0.0)] == [
        "105", "661", "1050", "1.00e+05", "0.00100", "9.90e-04", "0"]
    # the corner plot's titles (the diagonal panels, a one-parameter model's histogram) take the
    # same numbers, at most 4 digits
    from bayes_imu.report.text import interval_digits

    assert interval_digits(188.4, 75.2, 478.0, most=4) == 3
    assert interval_digits(0.0007011, 0.000615, 0.000803, most=4) == 3
    assert interval_digits(2.7637e-5, 2.7636e-5, 2.7638e-5, most=4) == 4
    plots = (Path(bayes_imu.__file__).parent / "report" / "plots.py").read_text(encoding="utf-8")
    assert "interval_numbers(q[1], q[0], q[2]" in plots and ":.4g}\\n[" not in plots
    assert not re.search(r"\{q\[\d\]:\.\{?\w*\}?g\}", plots)
    assert not re.search(r"median \{[^}]*:\.\d+g\}", plots)
    main = (Path(bayes_imu.__file__).parent / "cli" / "main.py").read_text(encoding="utf-8")
    assert not re.search(r"median \{[^}]*:\.\d+g\}", main)
    assert not re.search(r"\[\{[^}]*:\.2g\}", main)  # the population spread's 2-digit line


def test_each_warning_of_a_several_column_fit_names_its_column(tmp_path, rng, capsys,
                                                                monkeypatch):
    """A three-axis fit repeated a warning once per column without saying which (a new user's
    report: the drift horizon beyond the log, three times; the library's warnings raised while a
    column is fitted, such as the sampler's, likewise). Every warning of one column now starts
    with the column's name, as the model-adequacy warnings did."""
    import importlib
    import re
    import warnings

    fit_module = importlib.import_module("bayes_imu.inference.fit")
    real = fit_module.fit_allan

    def fit_allan(*args, **kwargs):  # a library warning raised while each column is fitted
        warnings.warn("planted: sampler not converged", UserWarning)
        return real(*args, **kwargs)

    monkeypatch.setattr(fit_module, "fit_allan", fit_allan)
    log = tmp_path / "imu.csv"
    y = rng.standard_normal((2**12, 3))
    log.write_text("gx,gy,gz\n" + "".join(f"{a:.6f},{b:.6f},{c:.6f}\n" for a, b, c in y))
    assert main(["fit", str(log), "--column", "gx,gy,gz", "--rate", "100", "--terms", "white",
                 "--sensor", "gyro", "--horizon", "100", "--out", str(tmp_path / "out"),
                 "--quiet"]) == 0
    said = [line for line in capsys.readouterr().err.splitlines()
            if line.startswith("bayes-imu: warning: ")]
    for column in ("gx", "gy", "gz"):
        own = [line for line in said if line.startswith(f"bayes-imu: warning: {column}: ")]
        assert f"bayes-imu: warning: {column}: planted: sampler not converged" in own, said
        assert any(f"{column}: the drift horizon (100 s) is longer than the log" in line
                   for line in own), said
    assert said and all(re.match(r"bayes-imu: warning: g[xyz]: ", line) for line in said), said


def test_console_parameters_name_their_model_and_print_their_digits(tmp_path, capsys):
    """The README's quick-start fit. The parameter block was headed "parameters (...)" below a
    model line that names the model average and the selected model: its values are the selected
    model's (summary.json ``model``), and the heading now says so, as does the datasheet block's.
    README.md described the model lines as "under `model:`", which the console never printed: the
    phrases it quotes are the console's. Every interval prints to at least three digits, without
    an exponent where its numbers lie between 1e-3 and 1e5 (the time constant printed "median
    1.9e+02, 90% [59, 6.6e+02] s")."""
    from bayes_imu.report.text import interval_text

    root = Path(__file__).resolve().parents[1]
    data = root / "data_synthetic" / "gyro_lowgrade.csv.gz"
    assert main(["fit", str(data), "--column", "gyro_x_dps", "--rate", "100", "--units", "deg/s",
                 "--out", str(tmp_path / "q")]) == 0
    out = capsys.readouterr().out.splitlines()
    summary = json.loads((tmp_path / "q" / "summary.json").read_text())
    head = next(i for i, line in enumerate(out)
                if line.startswith("  parameters of the selected model, "))
    assert out[head].startswith(f"  parameters of the selected model, "
                                f"{' + '.join(summary['model'])} (90% intervals include")
    block = out[head + 1: head + 1 + len(summary["parameters"])]
    assert [line.split()[0] for line in block] == list(summary["parameters"])
    assert "  datasheet units (the selected model):" in out
    plain = 0
    for line, p in zip(block, summary["parameters"].values()):
        assert interval_text(p["median"], p["q05"], p["q95"]) in line
        if all(1e-3 <= abs(p[k]) < 1e5 for k in ("median", "q05", "q95")):
            assert "e+" not in line and "e-" not in line, line
            plain += 1
    assert plain >= 1
    readme = " ".join((root / "README.md").read_text(encoding="utf-8").split())
    console = "\n".join(out)
    assert "under `model:`" not in readme
    for said in ("model average (what the drift bands use): ",
                 "simplest model within the evidence margin: ",
                 "parameters of the selected model"):
        assert said in readme and said in console, said


def test_fit_says_where_the_attitude_error_leaves_the_small_angle_model(tmp_path, rng, capsys):
    """A gyro's drift bands may reach hundreds of degrees (the integral of the rate error, exact);
    the console now says where the median passes 0.1 rad, as ``nav`` hatches it. White noise of
    1 rad/s per sample at 100 Hz: the attitude's 1-sigma error is 0.1 sqrt(t) rad with the bias
    known (slightly more with it calibrated), so the median passes 0.1 rad near t = 1 s; a quiet
    gyro (1e-4 rad/s) never does within its horizon, and is not told so."""
    for scale, expected in ((1.0, 1.0), (1e-4, None)):
        log = tmp_path / f"g{scale:g}.csv"
        log.write_text("g\n" + "\n".join(f"{v:.9g}" for v in scale * rng.standard_normal(2**14)))
        out = tmp_path / f"out{scale:g}"
        assert main(["fit", str(log), "--column", "g", "--rate", "100", "--units", "rad/s",
                     "--terms", "white", "--sensor", "gyro", "--horizon", "30",
                     "--out", str(out)]) == 0
        said = capsys.readouterr().out
        lines = [line for line in said.splitlines() if "small-angle" in line]
        if expected is None:
            assert lines == []
            continue
        assert len(lines) == 1
        t = float(lines[0].split(" s:")[0].split("after ")[-1])
        assert "passes 0.1 rad" in lines[0]
        assert 0.5 * expected < t < 1.5 * expected
