"""Hostile and careless input (issue 37): each class of the issue, its reproductions, in the default suite.

Every case asserts the outcome a user needs: the right number, or exit status 2 with one line
naming what was wrong, and never a file lost. Logs are small (a few hundred samples), so the
whole corpus runs in seconds; the commands run in-process (``main``).
"""

import hashlib
import json

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.io.timebase import TIME_UNITS, check_time, unit_from_name


def _snapshot(folder):
    """Every file and folder below ``folder`` with a hash of its content."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


def _log(path, n=400, *, time=None, name="time", columns=("gx",), rng=None, scale=0.05):
    """A small CSV log: an optional time column ``name`` holding ``time`` (raw stamps), white noise columns."""
    rng = np.random.default_rng(7) if rng is None else rng
    x = scale * rng.standard_normal((n, len(columns)))
    head = ([name] if time is not None else []) + list(columns)
    rows = [",".join(([repr(float(time[i]))] if time is not None else []) + [f"{v:.6f}" for v in x[i]])
            for i in range(n)]
    path.write_text(",".join(head) + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _one_error(capsys, *fragments):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bayes-imu: error: "), err
    for f in fragments:
        assert f in err, err
    return err


# ------------------------------------------------------------------ 1. time stamps

@pytest.mark.parametrize("name, unit", [("t_ms", "ms"), ("time_us", "us"), ("timestamp_ns", "ns"), ("time [s]", "s"),
                                        ("Time (msec)", "ms"), ("t_\u00b5s", "us"), ("time", None), ("stamp", None),
                                        ("t", None), ("gyro_x", None), ("samples", None)])
def test_time_unit_from_column_name(name, unit):
    assert unit_from_name(name) == unit


@pytest.mark.parametrize("unit", list(TIME_UNITS))
def test_stamps_in_every_unit_give_the_true_rate(unit):
    """100 Hz stamped in each unit: named in the column, given, or agreeing with the rate: 100 Hz, never 0.1."""
    raw = np.arange(500) * (0.01 / TIME_UNITS[unit])
    for kwargs in ({"column": f"t_{unit}"}, {"time_unit": unit}, {"rate_hz": 100.0}):
        base = check_time(raw, **kwargs)
        assert base.rate_hz == pytest.approx(100.0, rel=1e-12) and base.time_unit == unit, kwargs
        assert base.to_json()["time_unit"] == unit


def test_unstated_units_are_refused_with_the_likely_one():
    """Milliseconds or microseconds read as seconds (issue 37): refused, naming every unit's rate and the likely
    unit (microseconds no longer hinted as nanoseconds); time_unit='s' keeps seconds where they are meant."""
    with pytest.raises(InputError, match=r"0\.1 Hz if its stamps are seconds.*ms: 100 Hz.*likely unit is ms"):
        check_time(np.arange(500) * 10.0, column="t")
    with pytest.raises(InputError, match=r"us: 100 Hz.*likely unit is us: give time_unit='us'"):
        check_time(np.arange(500) * 1e4, column="t")
    assert check_time(np.arange(500) * 10.0, time_unit="s").rate_hz == pytest.approx(0.1)
    # the column's unit and the rate disagree: one line naming both
    with pytest.raises(InputError, match=r"gives 100 Hz .*stamps in ms \(column name 't_ms'\).* but rate_hz is 50 Hz"):
        check_time(np.arange(500) * 10.0, column="t_ms", rate_hz=50)
    with pytest.raises(InputError, match=r"none agrees with the rate given \(50 Hz\)"):
        check_time(np.arange(500) * 10.0, rate_hz=50)


def test_bursty_host_stamps_are_answered_with_the_mean_rate(rng):
    """Stamps of a host reading a 99.3 Hz sensor in bursts: both gap policies name the mean rate and --rate."""
    n = 3000
    steps = np.where(rng.random(n - 1) < 0.7, 1e-3 * (1 + 0.1 * rng.standard_normal(n - 1)), 0.0)
    steps[steps == 0] = ((n - 1) / 99.3 - steps.sum()) / np.count_nonzero(steps == 0)
    t = np.concatenate(([0.0], np.cumsum(steps)))
    for gaps in ("error", "longest"):
        with pytest.raises(InputError, match=r"mean rate over the log is 99\.3 Hz.*give rate_hz=99\.3"):
            check_time(t, gaps=gaps)


def test_cli_time_unit_printed_stored_and_checked(tmp_path, capsys):
    """fit on a 100 Hz log stamped in ms (column t_ms): 100 Hz, the unit printed and in summary.json."""
    log = _log(tmp_path / "ms.csv", time=np.arange(400) * 10.0, name="t_ms")
    assert main(["allan", str(log), "--column", "gx", "--time-column", "t_ms", "--out", str(tmp_path / "a")]) == 0
    assert "time stamps in ms (column name 't_ms'): 100 Hz" in capsys.readouterr().out
    plain = _log(tmp_path / "plain.csv", time=np.arange(400) * 10.0, name="t")
    assert main(["allan", str(plain), "--column", "gx", "--time-column", "t", "--out", str(tmp_path / "b")]) == 2
    _one_error(capsys, "likely unit is ms: give --time-unit ms", "--time-unit s keeps seconds")
    assert main(["allan", str(plain), "--column", "gx", "--time-column", "t", "--time-unit", "ms",
                 "--out", str(tmp_path / "b")]) == 0
    assert main(["allan", str(plain), "--column", "gx", "--rate", "100", "--time-unit", "ms",
                 "--out", str(tmp_path / "c")]) == 2
    _one_error(capsys, "--time-unit ms goes with --time-column")


# ------------------------------------------------------------------ 2. --force and markers

def _result(target, files, force=False):
    """A bayes_imu result written through staged_folder: ``files`` = {relative path: text}."""
    from bayes_imu.report.output import staged_folder

    with staged_folder(target, force=force) as tmp:
        for rel, text in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_text(text)


def test_force_refuses_foreign_files_in_sub_folders(tmp_path):
    """A user's notes in a sub-folder of a previous result: --force refuses naming it; nothing is removed. Without
    them the previous files (whose hashes match) are replaced, sub-folders included."""
    out = tmp_path / "res"
    _result(out, {"summary.json": "{}", "gx/summary.json": "1", "gy/fit.npz": "2"})
    (out / "gx" / "notes.txt").write_text("mine")
    before = _snapshot(out)
    with pytest.raises(InputError, match=r"force=True would leave 'gx/notes.txt'"):
        _result(out, {"summary.json": "{}"}, force=True)
    assert _snapshot(out) == before
    (out / "gx" / "notes.txt").unlink()
    (out / "gy" / "empty_user_folder").mkdir()
    with pytest.raises(InputError, match=r"'gy/empty_user_folder'"):
        _result(out, {"summary.json": "{}"}, force=True)
    (out / "gy" / "empty_user_folder").rmdir()
    _result(out, {"summary.json": "new", "gz/a.csv": "3"}, force=True)
    assert sorted(_snapshot(out)) == [".bayes_imu.json", "gz", "gz/a.csv", "summary.json"]


def test_force_refuses_a_changed_file_and_a_forged_marker(tmp_path):
    """A file edited since the run, or listed by a forged marker (a hash that is not its content, or an older
    marker without hashes): refused by name, the file kept."""
    out = tmp_path / "res"
    _result(out, {"drift.csv": "1", "a/b.txt": "2"})
    (out / "a" / "b.txt").write_text("edited by the user")
    with pytest.raises(InputError, match=r"'a/b\.txt'.*or changed since"):
        _result(out, {"x": "1"}, force=True)
    assert (out / "a" / "b.txt").read_text() == "edited by the user"
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "thesis.tex").write_text("years of work")
    forged = {"bayes_imu": "0", "entries": ["thesis.tex"],
              "files": {"thesis.tex": hashlib.sha256(b"something else").hexdigest()}, "folders": []}
    (victim / ".bayes_imu.json").write_text(json.dumps(forged))
    with pytest.raises(InputError, match="'thesis.tex'"):
        _result(victim, {"x": "1"}, force=True)
    (victim / ".bayes_imu.json").write_text(json.dumps({"bayes_imu": "0", "entries": ["thesis.tex"]}))
    with pytest.raises(InputError, match="no .bayes_imu.json marker with file hashes"):
        _result(victim, {"x": "1"}, force=True)
    assert (victim / "thesis.tex").read_text() == "years of work"


def test_force_on_a_multi_column_fit_keeps_notes_in_its_sub_folders(tmp_path, capsys):
    """The issue's reproduction: fit gx,gy into res, notes into res/gx, fit again with --force: exit 2 naming
    res/gx/notes.txt, which stays; the previous result byte for byte."""
    log = _log(tmp_path / "imu.csv", n=256, columns=("gx", "gy"))
    args = ["fit", str(log), "--column", "gx,gy", "--rate", "100", "--terms", "white", "--out", str(tmp_path / "res"),
            "--quiet"]
    assert main(args) == 0
    (tmp_path / "res" / "gx" / "notes.txt").write_text("notes")
    before = _snapshot(tmp_path / "res")
    assert main(args + ["--force"]) == 2
    _one_error(capsys, "--force would leave 'gx/notes.txt'")
    assert _snapshot(tmp_path / "res") == before


def test_file_target_force_needs_its_own_marker(tmp_path):
    """kalibr --out FILE --force: a file bayes_imu wrote (sidecar marker with its hash) is replaced; a user's file
    that merely looks like one (a '# bayes_imu' first line, a JSON object with bayes_imu_version: another fit
    folder's summary.json), or ours edited since, is refused."""
    from bayes_imu.report.output import staged_file

    target = tmp_path / "imu.yaml"
    with staged_file(target) as tmp:
        tmp.write_text("# bayes_imu one\n")
    with staged_file(target, force=True) as tmp:
        tmp.write_text("# bayes_imu two\n")
    assert target.read_text() == "# bayes_imu two\n"
    for name, text in (("notes.yaml", "# bayes_imu is great\nmy notes\n"),
                       ("summary.json", '{"bayes_imu_version": "1", "unit": "rad/s"}')):
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError, match="replaces only a file a bayes_imu run wrote"):
            with staged_file(tmp_path / name, force=True) as tmp:
                tmp.write_text("x")
        assert (tmp_path / name).read_text() == text
    target.write_text("# bayes_imu two\nedited\n")
    with pytest.raises(InputError, match="or was changed since"):
        with staged_file(target, force=True) as tmp:
            tmp.write_text("x")
    assert target.read_text() == "# bayes_imu two\nedited\n"


# ------------------------------------------------------------------ 3. numbers before pictures

def test_dollar_signs_in_names_keep_the_fit(tmp_path, capsys):
    """``run$1_$2.csv``, column ``g$x$`` (issue 37: mathtext rejected the label, exit 1, the fit discarded): exit 0,
    every output written, the label drawn literally."""
    from bayes_imu.report.plots import plain_text

    log = _log(tmp_path / "run$1_$2.csv", n=256, columns=("g$x$",))
    out = tmp_path / "fit"
    assert main(["fit", str(log), "--column", "g$x$", "--rate", "100", "--terms", "white", "--sensor", "gyro",
                 "--horizon", "10", "--out", str(out), "--quiet"]) == 0
    assert {"summary.json", "fit.npz", "allan_fit.png", "corner.png", "drift.csv", "drift.png"} <= {
        p.name for p in out.iterdir()}
    assert plain_text("run$1_$2") == r"run\$1_\$2" and plain_text("a\x1b[2Jb") == "a?[2Jb"


def test_a_failing_picture_costs_only_the_picture(tmp_path, capsys, monkeypatch):
    """Any error while drawing: one warning line, exit status 3 (PICTURE_FAILED_STATUS), the numbers kept and
    moved into place, no partial picture."""
    import bayes_imu.report.plots as plots
    from bayes_imu.report.worker import PICTURE_FAILED_STATUS, PictureFailure, _call, draw_picture

    def broken(*args, **kwargs):
        with open(args[1], "wb") as f:
            f.write(b"partial")
        raise ValueError("mathtext: unknown symbol\nsecond line")

    monkeypatch.setattr(plots, "plot_allan", broken)
    log = _log(tmp_path / "log.csv")
    out = tmp_path / "a"
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert err == ("bayes-imu: warning: allan.png was not drawn (ValueError: mathtext: unknown symbol); the numbers "
                   "were written\n")
    assert sorted(p.name for p in out.iterdir()) == [".bayes_imu.json", "allan.csv"] and PICTURE_FAILED_STATUS == 3
    # the worker's path: a picture's failure comes back as a record, not an exception that stops the others
    outcome = _call((draw_picture, (broken, None, tmp_path / "x.png"), {}))
    assert isinstance(outcome, PictureFailure) and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("option, value", [("--horizon", "1e300"), ("--times", "1,1e300"), ("--calibration", "1e300"),
                                           ("--horizon", "inf"), ("--calibration", "0")])
def test_huge_option_values_refused_before_any_work(tmp_path, capsys, option, value):
    log = _log(tmp_path / "log.csv")
    before = _snapshot(tmp_path)
    assert main(["fit", str(log), "--column", "gx", "--rate", "100", "--sensor", "gyro", option, value,
                 "--out", str(tmp_path / "o")]) == 2
    _one_error(capsys, option, "from 1e-06", "1e+09")
    assert _snapshot(tmp_path) == before


def test_drift_json_and_scene_values_have_ranges(tmp_path, capsys):
    sensor = tmp_path / "s.json"
    for key, value, fragment in (("noise_density", 1e300, "expected a number from 0 to 1e+100"),
                                 ("time_constant", 1e300, "expected a number from 1e-09 to 1e+15 s (or inf)"),
                                 ("rate_hz", 1e300, "expected 0.01 Hz to 1e+06 Hz")):
        doc = {"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3, key: value}
        sensor.write_text(json.dumps(doc))
        assert main(["drift", str(sensor), "--out", str(tmp_path / "d")]) == 2
        _one_error(capsys, key, fragment)
    from bayes_imu.report.scene import read_scene

    scene = tmp_path / "scene.toml"
    for line, fragment in (("calibration_s = 1e308", "calibration_s=1e+308: expected a number from 1e-06 to 1e+09 s"),
                           ("outages_s = [10, 1e308]", "each from 1e-06 to 1e+09")):
        text = f'[scene]\n{line}\n' + ("outages_s = [10]\n" if "outages" not in line else "")
        scene.write_text(text + '[[sensor]]\nname = "a"\nkind = "gyro"\nfit = "f"\n')
        with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace("+", r"\+").replace(")", r"\)")):
            read_scene(scene)
