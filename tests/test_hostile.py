"""Hostile and careless input (issue 37): each class of the issue, its reproductions, in the
default suite.

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
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        if p.is_file()
        else "dir"
        for p in sorted(folder.rglob("*"))
    }


def _log(path, n=400, *, time=None, name="time", columns=("gx",), rng=None, scale=0.05):
    """A small CSV log: an optional time column ``name`` holding ``time`` (raw stamps), white noise
    columns."""
    rng = np.random.default_rng(7) if rng is None else rng
    x = scale * rng.standard_normal((n, len(columns)))
    head = ([name] if time is not None else []) + list(columns)
    rows = [
        ",".join(([repr(float(time[i]))] if time is not None else []) + [f"{v:.6f}" for v in x[i]])
        for i in range(n)
    ]
    path.write_text(",".join(head) + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _one_error(capsys, *fragments):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bayes-imu: error: "), err
    for f in fragments:
        assert f in err, err
    return err


# ------------------------------------------------------------------ 1. time stamps


@pytest.mark.parametrize(
    "name, unit",
    [
        ("t_ms", "ms"),
        ("time_us", "us"),
        ("timestamp_ns", "ns"),
        ("time [s]", "s"),
        ("Time (msec)", "ms"),
        ("t_\u00b5s", "us"),
        ("time", None),
        ("stamp", None),
        ("t", None),
        ("gyro_x", None),
        ("samples", None),
    ],
)
def test_time_unit_from_column_name(name, unit):
    assert unit_from_name(name) == unit


@pytest.mark.parametrize("unit", list(TIME_UNITS))
def test_stamps_in_every_unit_give_the_true_rate(unit):
    """100 Hz stamped in each unit: named in the column, given, or agreeing with the rate: 100 Hz,
    never 0.1."""
    raw = np.arange(500) * (0.01 / TIME_UNITS[unit])
    for kwargs in ({"column": f"t_{unit}"}, {"time_unit": unit}, {"rate_hz": 100.0}):
        base = check_time(raw, **kwargs)
        assert base.rate_hz == pytest.approx(100.0, rel=1e-12) and base.time_unit == unit, kwargs
        assert base.to_json()["time_unit"] == unit


def test_unstated_units_are_refused_with_the_likely_one():
    """Milliseconds or microseconds read as seconds (issue 37): refused, naming every unit's rate
    and the likely
    unit (microseconds no longer hinted as nanoseconds); time_unit='s' keeps seconds where they are
    meant."""
    with pytest.raises(
        InputError, match=r"0\.1 Hz if its stamps are seconds.*ms: 100 Hz.*likely unit is ms"
    ):
        check_time(np.arange(500) * 10.0, column="t")
    with pytest.raises(InputError, match=r"us: 100 Hz.*likely unit is us: give time_unit='us'"):
        check_time(np.arange(500) * 1e4, column="t")
    assert check_time(np.arange(500) * 10.0, time_unit="s").rate_hz == pytest.approx(0.1)
    # the column's unit and the rate disagree: one line naming both
    with pytest.raises(
        InputError,
        match=r"gives 100 Hz, .*stamps in ms \(column name 't_ms'\), but rate_hz is 50 Hz",
    ):
        check_time(np.arange(500) * 10.0, column="t_ms", rate_hz=50)
    with pytest.raises(InputError, match=r"none agrees with the rate given \(50 Hz\)"):
        check_time(np.arange(500) * 10.0, rate_hz=50)


def test_bursty_host_stamps_are_answered_with_the_mean_rate(rng):
    """Stamps of a host reading a 99.3 Hz sensor in bursts: both gap policies name the mean rate
    and --rate."""
    n = 3000
    steps = np.where(rng.random(n - 1) < 0.7, 1e-3 * (1 + 0.1 * rng.standard_normal(n - 1)), 0.0)
    steps[steps == 0] = ((n - 1) / 99.3 - steps.sum()) / np.count_nonzero(steps == 0)
    t = np.concatenate(([0.0], np.cumsum(steps)))
    for gaps in ("error", "longest"):
        with pytest.raises(
            InputError, match=r"mean rate over the log is 99\.3 Hz.*give rate_hz=99\.3"
        ):
            check_time(t, gaps=gaps)


def test_cli_time_unit_printed_stored_and_checked(tmp_path, capsys):
    """fit on a 100 Hz log stamped in ms (column t_ms): 100 Hz, the unit printed and in
    summary.json."""
    log = _log(tmp_path / "ms.csv", time=np.arange(400) * 10.0, name="t_ms")
    assert (
        main(
            [
                "allan",
                str(log),
                "--column",
                "gx",
                "--time-column",
                "t_ms",
                "--out",
                str(tmp_path / "a"),
            ]
        )
        == 0
    )
    assert "time stamps in ms (column name 't_ms'): 100 Hz" in capsys.readouterr().out
    plain = _log(tmp_path / "plain.csv", time=np.arange(400) * 10.0, name="t")
    assert (
        main(
            [
                "allan",
                str(plain),
                "--column",
                "gx",
                "--time-column",
                "t",
                "--out",
                str(tmp_path / "b"),
            ]
        )
        == 2
    )
    _one_error(capsys, "likely unit is ms: give --time-unit ms", "--time-unit s keeps seconds")
    assert (
        main(
            [
                "allan",
                str(plain),
                "--column",
                "gx",
                "--time-column",
                "t",
                "--time-unit",
                "ms",
                "--out",
                str(tmp_path / "b"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "allan",
                str(plain),
                "--column",
                "gx",
                "--rate",
                "100",
                "--time-unit",
                "ms",
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 2
    )
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
    """A user's notes in a sub-folder of a previous result: --force refuses naming it; nothing is
    removed. Without
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
    """A file edited since the run, or listed by a forged marker (a hash that is not its content,
    or an older
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
    forged = {
        "bayes_imu": "0",
        "entries": ["thesis.tex"],
        "files": {"thesis.tex": hashlib.sha256(b"something else").hexdigest()},
        "folders": [],
    }
    (victim / ".bayes_imu.json").write_text(json.dumps(forged))
    with pytest.raises(InputError, match="'thesis.tex'"):
        _result(victim, {"x": "1"}, force=True)
    (victim / ".bayes_imu.json").write_text(
        json.dumps({"bayes_imu": "0", "entries": ["thesis.tex"]})
    )
    with pytest.raises(InputError, match="no .bayes_imu.json marker with file hashes"):
        _result(victim, {"x": "1"}, force=True)
    assert (victim / "thesis.tex").read_text() == "years of work"


def test_force_on_a_multi_column_fit_keeps_notes_in_its_sub_folders(tmp_path, capsys):
    """The issue's reproduction: fit gx,gy into res, notes into res/gx, fit again with --force:
    exit 2 naming
    res/gx/notes.txt, which stays; the previous result byte for byte."""
    log = _log(tmp_path / "imu.csv", n=256, columns=("gx", "gy"))
    args = [
        "fit",
        str(log),
        "--column",
        "gx,gy",
        "--rate",
        "100",
        "--terms",
        "white",
        "--out",
        str(tmp_path / "res"),
        "--quiet",
    ]
    assert main(args) == 0
    (tmp_path / "res" / "gx" / "notes.txt").write_text("notes")
    before = _snapshot(tmp_path / "res")
    assert main(args + ["--force"]) == 2
    _one_error(capsys, "--force would leave 'gx/notes.txt'")
    assert _snapshot(tmp_path / "res") == before


def test_file_target_force_needs_its_own_marker(tmp_path):
    """kalibr --out FILE --force: a file bayes_imu wrote (sidecar marker with its hash) is
    replaced; a user's file
    that merely looks like one (a '# bayes_imu' first line, a JSON object with bayes_imu_version:
    another fit
    folder's summary.json), or ours edited since, is refused."""
    from bayes_imu.report.output import staged_file

    target = tmp_path / "imu.yaml"
    with staged_file(target) as tmp:
        tmp.write_text("# bayes_imu one\n")
    with staged_file(target, force=True) as tmp:
        tmp.write_text("# bayes_imu two\n")
    assert target.read_text() == "# bayes_imu two\n"
    for name, text in (
        ("notes.yaml", "# bayes_imu is great\nmy notes\n"),
        ("summary.json", '{"bayes_imu_version": "1", "unit": "rad/s"}'),
    ):
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
    """``run$1_$2.csv``, column ``g$x$`` (issue 37: mathtext rejected the label, exit 1, the fit
    discarded): exit 0,
    every output written, the label drawn literally."""
    from bayes_imu.report.plots import plain_text

    log = _log(tmp_path / "run$1_$2.csv", n=256, columns=("g$x$",))
    out = tmp_path / "fit"
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "g$x$",
                "--rate",
                "100",
                "--terms",
                "white",
                "--sensor",
                "gyro",
                "--horizon",
                "10",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    assert {"summary.json", "fit.npz", "allan_fit.png", "corner.png", "drift.csv", "drift.png"} <= {
        p.name for p in out.iterdir()
    }
    assert plain_text("run$1_$2") == r"run\$1_\$2" and plain_text("a\x1b[2Jb") == "a?[2Jb"


def test_a_failing_picture_costs_only_the_picture(tmp_path, capsys, monkeypatch):
    """Any error while drawing: one warning line, exit status 3 (PICTURE_FAILED_STATUS), the
    numbers kept and
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
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"])
        == 3
    )
    err = capsys.readouterr().err
    assert err == (
        "bayes-imu: warning: allan.png was not drawn (ValueError: mathtext: unknown symbol); "
        "the numbers "
        "were written\n"
    )
    assert (
        sorted(p.name for p in out.iterdir()) == [".bayes_imu.json", "allan.csv"]
        and PICTURE_FAILED_STATUS == 3
    )
    # the worker's path: a picture's failure comes back as a record, not an exception that stops
    # the others
    outcome = _call((draw_picture, (broken, None, tmp_path / "x.png"), {}))
    assert isinstance(outcome, PictureFailure) and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize(
    "option, value",
    [
        ("--horizon", "1e300"),
        ("--times", "1,1e300"),
        ("--calibration", "1e300"),
        ("--horizon", "inf"),
        ("--calibration", "0"),
    ],
)
def test_huge_option_values_refused_before_any_work(tmp_path, capsys, option, value):
    log = _log(tmp_path / "log.csv")
    before = _snapshot(tmp_path)
    assert (
        main(
            [
                "fit",
                str(log),
                "--column",
                "gx",
                "--rate",
                "100",
                "--sensor",
                "gyro",
                option,
                value,
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    _one_error(capsys, option, "from 1e-06", "1e+09")
    assert _snapshot(tmp_path) == before


def test_drift_json_and_scene_values_have_ranges(tmp_path, capsys):
    sensor = tmp_path / "s.json"
    for key, value, fragment in (
        ("noise_density", 1e300, "expected a number from 0 to 1e+100"),
        ("time_constant", 1e300, "expected a number from 1e-09 to 1e+15 s (or inf)"),
        ("rate_hz", 1e300, "expected 0.01 Hz to 1e+06 Hz"),
    ):
        doc = {"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3, key: value}
        sensor.write_text(json.dumps(doc))
        assert main(["drift", str(sensor), "--out", str(tmp_path / "d")]) == 2
        _one_error(capsys, key, fragment)
    from bayes_imu.report.scene import read_scene

    scene = tmp_path / "scene.toml"
    for line, fragment in (
        ("calibration_s = 1e308", "calibration_s=1e+308: expected a number from 1e-06 to 1e+09 s"),
        ("outages_s = [10, 1e308]", "each from 1e-06 to 1e+09"),
    ):
        text = f"[scene]\n{line}\n" + ("outages_s = [10]\n" if "outages" not in line else "")
        scene.write_text(text + '[[sensor]]\nname = "a"\nkind = "gyro"\nfit = "f"\n')
        with pytest.raises(
            InputError, match=fragment.replace("(", r"\(").replace("+", r"\+").replace(")", r"\)")
        ):
            read_scene(scene)


# ------------------------------------------------------------------ 5. untrusted input

SCENE_HEAD = "[scene]\noutages_s = [10]\n"


def _sensor(source, value, extra='column = "gx"\nrate_hz = 100\nunits = "deg/s"\n'):
    shown = json.dumps(value)
    return f'[[sensor]]\nname = "s"\nkind = "gyro"\n{source} = {shown}\n' + (
        extra if source.startswith("log") else ""
    )


def test_scene_paths_are_confined_to_the_scene_folder(tmp_path):
    """log = "/etc/passwd" or "../..": refused before anything is read, the file's content never
    quoted;
    allow_outside (in the scene, or the argument) lets a trusted scene reach out."""
    from bayes_imu.report.scene import read_scene

    secret = tmp_path / "secret.csv"
    secret.write_text("root:SECRET-HASH\n" * 50)
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = folder / "scene.toml"
    for given in ("/etc/passwd", "../secret.csv", str(secret)):
        scene.write_text(SCENE_HEAD + _sensor("log", given))
        with pytest.raises(InputError, match="lies outside the scene's folder") as info:
            read_scene(scene)
        assert "SECRET" not in str(info.value)
    (folder / "link.csv").symlink_to(secret)  # a link inside pointing out is outside too
    scene.write_text(SCENE_HEAD + _sensor("log", "link.csv"))
    with pytest.raises(InputError, match="lies outside"):
        read_scene(scene)
    assert read_scene(scene, allow_outside=True).sensors[0].paths == (folder / "link.csv",)
    scene.write_text(
        SCENE_HEAD.replace("[scene]\n", "[scene]\nallow_outside = true\n")
        + _sensor("log", "../secret.csv")
    )
    assert read_scene(scene).sensors[0].paths == (folder / "../secret.csv",)
    # an error about such a file quotes at most a short, sanitised excerpt
    from bayes_imu.io.readers import read_log

    secret.write_text("a" * 10**6 + "\x1b[31m,b\n1,2\n3,4\n")
    with pytest.raises(InputError) as info:
        read_log(secret, column="zz")
    assert len(str(info.value)) < 250 and "\x1b" not in str(info.value)


def test_scene_path_messages_name_the_flag_the_link_and_the_nearest_key(tmp_path, capsys):
    """A path outside the scene's folder pointed at the Python API ("(or allow_outside=True)") on
    the command line: it names --allow-outside there (the scene key too). A symbolic link inside
    the folder that resolves outside got the same words as "../x": it now says it is a link and
    where it leads (the file itself, or a folder on its way). An unknown key gets the nearest
    known one ("unit": did you mean 'units'?)."""
    from bayes_imu.report.scene import read_scene

    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "x.csv").write_text("gx\n1\n2\n")
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "link.csv").symlink_to(outside / "x.csv")
    (folder / "data").symlink_to(outside)
    scene = folder / "scene.toml"
    rule = "paths are confined to it unless allow_outside = true in [scene]"
    # the target is shown by its last 80 characters (a long temporary folder is cut at its start)
    cases = (("../outside/x.csv", "lies outside the scene's folder; ", None),
             ("link.csv",
              "lies outside the scene's folder: it is a symbolic link that resolves to ",
              str(outside / "x.csv")),
             ("data/x.csv", "lies outside the scene's folder: its folder 'data' is a symbolic link "
                            "that resolves to ", str(outside)))
    for given, why, target in cases:
        scene.write_text(SCENE_HEAD + _sensor("log", given))
        with pytest.raises(InputError) as info:
            read_scene(scene)
        for text, flag in ((str(info.value), "allow_outside=True"), (None, "--allow-outside")):
            if text is None:
                assert main(["report", str(scene), "--out", str(tmp_path / "r")]) == 2
                err = capsys.readouterr().err
                assert err.startswith("bayes-imu: error: ") and err.endswith("\n")
                assert err.count("\n") == 1
                text = err[len("bayes-imu: error: "):-1]
            head = f"{scene}: [[sensor]] #1: log path {given!r} {why}"
            assert text.startswith(head) and text.endswith(f"; {rule} (or {flag})")
            if target is not None:
                shown = text[len(head):-len(f"; {rule} (or {flag})")]
                assert shown[0] == shown[-1] == "'" and len(shown) <= 82
                assert target.endswith(shown[1:-1].removeprefix("..."))
        assert main(["report", str(scene), "--out", str(tmp_path / "r"), "--allow-outside"]) == 2
        err = capsys.readouterr().err  # read, not refused (too short to fit)
        assert "lies outside" not in err and "2 samples; expected at least 32" in err, err
    scene.write_text(SCENE_HEAD + _sensor("log", "link.csv").replace("units =", "unit ="))
    assert main(["report", str(scene), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "unknown key 'unit' (did you mean 'units'?); expected keys: " in err
    scene.write_text(SCENE_HEAD.replace("outages_s", "outage_s") + _sensor("log", "link.csv"))
    with pytest.raises(InputError, match=r"unknown key 'outage_s' \(did you mean 'outages_s'\?\)"):
        read_scene(scene)
    scene.write_text(SCENE_HEAD + _sensor("log", "link.csv") + "colour = 'red'\n")
    with pytest.raises(InputError) as info:
        read_scene(scene)
    assert "unknown key 'colour'; expected keys" in str(info.value)  # nothing near: no hint


def test_scene_units_and_population_logs_must_be_distinct(tmp_path, capsys):
    """The same log twice, a copy of it, or one fit folder twice: refused by name (one unit counted
    twice)."""
    from bayes_imu.report.scene import read_scene

    a = _log(tmp_path / "a.csv")
    (tmp_path / "copy.csv").write_bytes(a.read_bytes())
    scene = tmp_path / "scene.toml"
    for logs, fragment in (
        (["a.csv", "./a.csv"], "the same file or folder"),
        (["a.csv", "copy.csv"], "files with the same content"),
    ):
        scene.write_text(SCENE_HEAD + _sensor("logs", logs))
        with pytest.raises(InputError, match=fragment):
            read_scene(scene)
    (tmp_path / "fit1").mkdir()
    scene.write_text(SCENE_HEAD + _sensor("fits", ["fit1", "fit1/"]))
    with pytest.raises(InputError, match="the same file or folder"):
        read_scene(scene)
    assert (
        main(
            [
                "fit-population",
                str(a),
                str(tmp_path / "copy.csv"),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "pop"),
            ]
        )
        == 2
    )
    _one_error(capsys, "copy.csv", "are files with the same content")


@pytest.fixture(scope="module")
def fit_folder(tmp_path_factory):
    """One small white-noise fit folder (gyro, SI), shared by the archive and label tests."""
    folder = tmp_path_factory.mktemp("fit")
    log = _log(folder / "g.csv", n=256)
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
                "white",
                "--out",
                str(folder / "g"),
                "--quiet",
            ]
        )
        == 0
    )
    return folder / "g"


def _rewrite_archive(source, target, **changes):
    with np.load(source / "fit.npz") as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    target.mkdir()
    for name in ("summary.json",):
        (target / name).write_bytes((source / name).read_bytes())
    np.savez_compressed(target / "fit.npz", **data)
    return target


@pytest.mark.parametrize(
    "field, value",
    [
        ("samples", np.nan),
        ("samples", 0.0),
        ("allan_avar", -1.0),
        ("allan_tau", np.inf),
        ("covariance", np.nan),
    ],
)
def test_damaged_archives_are_refused_naming_the_field(tmp_path, capsys, fit_folder, field, value):
    """NaN or zero noise values from a crafted fit.npz must not reach imu.yaml: exit 2 naming the
    field."""
    from bayes_imu.inference.archive import load_fit

    with np.load(fit_folder / "fit.npz") as z:
        array = z[field].copy()
    array.flat[0] = value
    bad = _rewrite_archive(fit_folder, tmp_path / "bad", **{field: array})
    with pytest.raises(InputError, match=f"field '{field}'"):
        load_fit(bad)
    assert main(["kalibr", "--gyro", str(bad), "--out", str(tmp_path / "imu.yaml")]) == 2
    _one_error(capsys, f"field '{field}'")
    assert not (tmp_path / "imu.yaml").exists()


def test_archive_sizes_checked_before_allocation(tmp_path, fit_folder):
    """A small archive whose array header declares 6 GiB: refused from the header, nothing
    allocated; shapes
    that disagree with the model's terms are refused too."""
    import zipfile

    from bayes_imu.inference.archive import load_fit

    bad = _rewrite_archive(fit_folder, tmp_path / "huge")
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (6 * 2**30 // 8,)
    buffer = __import__("io").BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    with zipfile.ZipFile(bad / "fit.npz", "a") as z:
        z.writestr("huge.npy", buffer.getvalue() + b"\0" * 64)
    with pytest.raises(InputError, match="declare .* bytes, more than 64 times"):
        load_fit(bad)
    with np.load(fit_folder / "fit.npz") as z:
        samples = z["samples"]
    two = _rewrite_archive(fit_folder, tmp_path / "shape", samples=np.hstack([samples, samples]))
    with pytest.raises(
        InputError, match=r"field 'samples' has shape .*expected \(draws, 1\) for white"
    ):
        load_fit(two)


def test_datasheet_of_an_unknown_kind_raises(fit_folder):
    from bayes_imu.inference.archive import load_fit
    from bayes_imu.noise.datasheet import datasheet

    fit = load_fit(fit_folder)
    assert (
        datasheet(fit, "gyro").keys() != datasheet(fit, "accel").keys()
    )  # each kind its own table
    with pytest.raises(InputError, match="'magnetometer': expected 'gyro' or 'accel'"):
        datasheet(fit, "magnetometer")


def test_a_folder_name_cannot_inject_yaml_keys(tmp_path, fit_folder):
    """A fit folder named 'g\\naccelerometer_noise_density: 1e-12' (and other line breaks):
    imu.yaml parses to the
    Kalibr keys alone, with the fit's values."""
    import shutil

    import yaml

    evil = tmp_path / "g\naccelerometer_noise_density: 1e-12\r\x85\u2028x"
    shutil.copytree(fit_folder, evil)
    other = tmp_path / "h"
    shutil.copytree(fit_folder, other)
    out = tmp_path / "imu.yaml"
    assert main(["kalibr", "--gyro", str(evil), str(other), "--out", str(out)]) == 0
    doc = yaml.safe_load(out.read_text())
    assert set(doc) == {
        "gyroscope_noise_density",
        "gyroscope_random_walk",
        "rostopic",
        "update_rate",
    }
    assert (
        main(
            [
                "kalibr",
                "--gyro",
                str(other),
                "--topic",
                "/imu0\nupdate_rate: 1",
                "--out",
                str(tmp_path / "x.yaml"),
            ]
        )
        == 2
    )


@pytest.mark.parametrize("kind", ["fifo", "device", "bom", "deep_json", "deep_toml"])
def test_special_files_answer_at_once(tmp_path, capsys, kind):
    """A FIFO (no writer) or /dev/urandom as a scene, sensor JSON or summary.json: one line, exit
    2, no wait, no
    read without end; a UTF-8 BOM is accepted; deeply nested TOML / JSON is a user error (exit 2),
    not 1."""
    import os

    if kind == "fifo":
        path = tmp_path / "scene.toml"
        os.mkfifo(path)
        argvs = [["report", str(path)], ["drift", str(path)], ["kalibr", "--gyro", str(tmp_path)]]
        (tmp_path / "summary.json").unlink(missing_ok=True)
        os.mkfifo(tmp_path / "summary.json")
        fragment = "not a regular file"
    elif kind == "device":
        argvs, fragment = [["report", "/dev/urandom"], ["drift", "/dev/zero"]], "not a regular file"
    elif kind == "bom":
        scene = tmp_path / "scene.toml"
        scene.write_text("\ufeff" + SCENE_HEAD + _sensor("fit", "nowhere"), encoding="utf-8")
        argvs, fragment = (
            [["report", str(scene)]],
            "nowhere",
        )  # parsed: the error is the missing fit folder
    elif kind == "deep_json":
        path = tmp_path / "s.json"
        path.write_text("[" * 100000 + "]" * 100000)
        argvs, fragment = [["drift", str(path)]], "nested too deeply"
    else:
        path = tmp_path / "s.toml"
        path.write_text("a = " + "[" * 100000 + "]" * 100000)
        argvs, fragment = [["report", str(path)]], "nested too deeply"
    for argv in argvs:
        assert main(argv + ["--out", str(tmp_path / "out")]) == 2, argv
        _one_error(capsys, fragment)


# ------------------------------------------------------------------ 4. bounds on memory and time


def test_gzip_bomb_refused_as_it_streams(tmp_path, capsys, monkeypatch):
    """A gzip expanding far beyond MAX_GZIP_RATIO is refused once its output passes the bound (here
    lowered
    to 64 KiB, so the test reads 1 MB): memory and time bounded by the compressed size."""
    import gzip

    import bayes_imu.io.readers as readers

    monkeypatch.setattr(readers, "GZIP_ALLOWANCE", 1 << 16)
    log = tmp_path / "bomb.csv.gz"
    log.write_bytes(gzip.compress(b"gx\n" + b"0.1\n" * 250_000, 9))
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "o")])
        == 2
    )
    _one_error(capsys, "expands more than 100 times")
    ordinary = tmp_path / "ok.csv.gz"  # an ordinary log compresses a few times: read as before
    ordinary.write_bytes(gzip.compress(_log(tmp_path / "x.csv", n=4000).read_bytes()))
    assert (
        main(
            [
                "allan",
                str(ordinary),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 0
    )


def test_long_preamble_and_long_field_answer_in_one_short_line(tmp_path, capsys, monkeypatch):
    import bayes_imu.io.readers as readers

    monkeypatch.setattr(readers, "MAX_SNIFF_BYTES", 1 << 18)
    log = tmp_path / "pre.csv"
    log.write_text("#" * (1 << 19) + "\ngx\n1\n2\n")
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "o")])
        == 2
    )
    _one_error(capsys, "no header and data row within the first 262144 bytes")
    field = tmp_path / "field.csv"
    field.write_text("gx\n" + "1\n" * 10 + "9" * 10**6 + "x\n" + "2\n" * 10)
    assert (
        main(["allan", str(field), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "o")])
        == 2
    )
    err = _one_error(capsys, "line 12, column 'gx'")
    assert len(err) < 300
    monkeypatch.setattr(
        readers, "MAX_LINE_BYTES", 1 << 16
    )  # beyond it, refused as the line streams past
    for text in (
        "gx\n" + "1\n" * 10 + "9" * (1 << 18) + "\n",
        "gx\n" + "1\n" * 10 + "9" * 1000 + "\n",
    ):
        field.write_text(text)
        assert (
            main(
                [
                    "allan",
                    str(field),
                    "--column",
                    "gx",
                    "--rate",
                    "100",
                    "--out",
                    str(tmp_path / "o"),
                ]
            )
            == 2
        )
        _one_error(
            capsys, "a line longer than 65536 bytes" if len(text) > 1 << 16 else "got '99999"
        )


# ------------------------------------------------------------------ 7. exit statuses: 2 for what
# the user can fix


def test_path_errors_exit_2_with_one_line(tmp_path, capsys, monkeypatch):
    """--out under a regular file, a name too long, a symbolic-link loop, a read-only file system,
    a full
    TMPDIR while spooling standard input: exit 2 and one line (they exited 1, "internal error",
    before)."""
    import errno
    import io
    import os
    import sys

    log = _log(tmp_path / "log.csv")
    base = ["allan", str(log), "--column", "gx", "--rate", "100", "--quiet", "--out"]
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    for out, fragment in (
        (log / "x", "Not a directory"),
        (tmp_path / ("a" * 300), "File name too long"),
        (tmp_path / "loop1" / "x", "a loop of symbolic links"),
    ):
        assert main(base + [str(out)]) == 2, out
        _one_error(capsys, "cannot write there", fragment)
    assert (
        main(
            [
                "allan",
                str(tmp_path / ("b" * 300 + ".csv")),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    _one_error(capsys, "File name too long")

    real_mkdir = os.mkdir

    def read_only(path, *args, **kwargs):
        if "ro_out" in str(path):
            raise OSError(errno.EROFS, "Read-only file system", str(path))
        return real_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", read_only)
    assert main(base + [str(tmp_path / "ro_out")]) == 2
    _one_error(capsys, "Read-only file system")
    monkeypatch.undo()

    import tempfile

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", "/tmp/spool")

    monkeypatch.setattr(tempfile, "mkdtemp", full)
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(log.read_bytes())))
    assert (
        main(["allan", "-", "--column", "gx", "--rate", "100", "--out", str(tmp_path / "s")]) == 2
    )
    _one_error(capsys, "No space left on device")


def test_valid_inputs_refused_before_are_accepted(tmp_path):
    """A flat Allan deviation table (bias instability alone), a quoted field holding the delimiter,
    a scene with
    a UTF-8 byte-order mark and a .npy log (read_scene and the report's reader)."""
    from bayes_imu.allan.table import read_allan_table
    from bayes_imu.io.readers import read_log
    from bayes_imu.report.scene import SensorSpec, read_scene

    flat = tmp_path / "flat.csv"
    flat.write_text("tau,adev\n" + "".join(f"{0.01 * 2**k},1e-3\n" for k in range(10)))
    result, _ = read_allan_table(flat, rate_hz=100)
    assert np.all(result.adev == 1e-3)
    quoted = tmp_path / "quoted.csv"
    quoted.write_text("name,gx\n" + "".join(f'"unit 1, left",{i * 0.25}\n' for i in range(8)))
    assert read_log(quoted, column="gx").values.tolist() == [i * 0.25 for i in range(8)]
    scene = tmp_path / "scene.toml"
    scene.write_bytes(
        "\ufeff".encode()
        + (
            SCENE_HEAD + _sensor("log", "x.npy", 'column = "0"\nrate_hz = 100\nunits = "deg/s"\n')
        ).encode()
    )
    spec = read_scene(scene).sensors[0]
    x = np.random.default_rng(1).standard_normal(512)
    np.save(tmp_path / "x.npy", x)
    allan = _scene_allan(spec, spec.paths[0])
    m1 = (
        np.mean(np.diff(x * np.pi / 180) ** 2) / 2
    )  # AVAR at m = 1 of the samples in rad/s, from its definition
    assert allan.m[0] == 1 and allan.avar[0] == pytest.approx(m1, rel=1e-12)
    assert isinstance(spec, SensorSpec)


# ------------------------------------------------------------------ 6. plausibility of units, steps


def test_units_a_static_log_contradicts_are_named(rng):
    """A deg/s gyro log (bias 4.5 deg/s) declared rad/s: 4.5 rad/s, implausible, deg/s named; three
    accelerometer
    axes in g declared mg: a 0.001 g norm, g named; the right units pass; a log no unit explains is
    fatal."""
    from bayes_imu.io.plausible import check_units

    n = 5000
    gyro = 4.5 + 0.1 * rng.standard_normal(n)
    found = check_units(gyro, "rad/s", 100.0)
    # 4.5 mrad/s is a plausible static bias too (mrad/s accepted since issue 38)
    assert "mean rate of 4.5 rad/s" in str(found) and found.likely == ("deg/s", "mrad/s")
    assert not found.fatal
    assert check_units(gyro, "deg/s", 100.0) is None
    accel = np.column_stack(
        [
            0.004 * rng.standard_normal(n),
            0.004 * rng.standard_normal(n),
            1.0 + 0.004 * rng.standard_normal(n),
        ]
    )
    found = check_units(accel, "mg", 100.0)
    assert "norm of 0.001 g" in str(found) and found.likely == ("g",)
    assert check_units(accel, "g", 100.0) is None
    assert check_units(1e9 + rng.standard_normal(n), "deg/h", 100.0).fatal


def test_a_step_in_the_middle_is_flagged(rng):
    """A 20-sigma step halfway: found where it is, its size within 1 sigma of 20 (the window means'
    noise is 0.18 sigma); white noise and a random walk of the same per-sample noise are not
    flagged; steps a window from either end are found where they are too."""
    from bayes_imu.io.plausible import find_step

    x = rng.standard_normal(20000)
    assert find_step(x) is None
    assert find_step(x + np.cumsum(0.01 * rng.standard_normal(20000))) is None
    x[10000:] += 20.0
    at, size = find_step(x)
    assert at == 10000 and abs(size - 20.0) < 1.0
    # a step as near either end as a window from each side allows (the running sum's first and last
    # window pairs): found at its sample
    from bayes_imu.io.plausible import STEP_WINDOW

    for first_after in (STEP_WINDOW, x.size - STEP_WINDOW):
        y = rng.standard_normal(20000)
        y[first_after:] += 20.0
        assert find_step(y)[0] == first_after


def test_cli_warns_of_units_and_steps_and_refuses_nonsense(tmp_path, capsys):
    gyro = tmp_path / "gyro.csv"
    values = 4.5 + 0.1 * np.random.default_rng(3).standard_normal(400)
    gyro.write_text("gx\n" + "".join(f"{v:.6f}\n" for v in values))
    args = ["allan", str(gyro), "--column", "gx", "--rate", "100", "--quiet", "--units", "rad/s"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning" in err and "plausible in deg/s" in err
    assert main(args + ["--out", str(tmp_path / "b"), "--trust-units"]) == 0
    assert capsys.readouterr().err == ""
    nonsense = tmp_path / "n.csv"
    nonsense.write_text("gx\n" + "".join(f"{1e9 + v:.6f}\n" for v in values))
    assert (
        main(
            [
                "allan",
                str(nonsense),
                "--column",
                "gx",
                "--rate",
                "100",
                "--units",
                "deg/h",
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 2
    )
    _one_error(capsys, "no unit makes it plausible", "--trust-units")
    step = tmp_path / "step.csv"
    x = np.random.default_rng(4).standard_normal(2000)
    x[1000:] += 20
    step.write_text("gx\n" + "".join(f"{v:.6f}\n" for v in x))
    assert (
        main(
            [
                "allan",
                str(step),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "d"),
                "--quiet",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its level steps by" in err and "at sample 1001" in err, err


# ------------------------------------------------------------------ 8. names through every output
# format

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: pieces of hostile names: shell, YAML, HTML, TeX/mathtext, control and line-separator characters
_PIECES = [
    "$",
    "$x$",
    "\\",
    "_",
    "^",
    "{",
    "}",
    "%",
    "#",
    "&",
    "<script>",
    "</b>",
    "'",
    '"',
    "`",
    ";",
    "|",
    "&&",
    "$(rm -rf ~)",
    "\n",
    "\r",
    "\x85",
    "\u2028",
    "\u2029",
    "\x1b[2J",
    "\t",
    "\x00",
    ": ",
    "- ",
    "key: 1e-12",
    "---",
    "...",
    "!!python/object",
    "*alias",
    "&anchor",
    "--terms=white",
    "-",
    ".",
    "..",
    "/",
    "~",
    "=",
    "\u00b5",
    "\U0001f600",
    " ",
]
_NAMES = st.lists(st.sampled_from(_PIECES) | st.text(max_size=3), min_size=1, max_size=8).map(
    "".join
)


@settings(max_examples=60, deadline=None)
@given(name=_NAMES)
def test_hostile_names_through_yaml_json_folders_and_messages(name):
    """A name made of shell, YAML, HTML, TeX and control characters: imu.yaml still parses to
    exactly the Kalibr
    keys and values (the name only in sanitised comments), JSON round-trips it, a folder made from
    it is one plain
    path component, and an error excerpt of it is one printable line of at most 80 characters."""
    import tempfile
    from pathlib import Path

    import yaml

    from bayes_imu.io.readers import excerpt
    from bayes_imu.report.kalibr import KalibrValues, write_kalibr_yaml
    from bayes_imu.report.output import safe_folder_name

    values = {
        "gyroscope_noise_density": 1.5e-4,
        "gyroscope_random_walk": 2.5e-6,
        "update_rate": 200.0,
    }
    per_axis = {
        "gyroscope_noise_density": [(name, 1.5e-4), ("b", 1e-4)],
        "gyroscope_random_walk": [(name, 2.5e-6), ("b", 1e-6)],
    }
    result = KalibrValues(values, per_axis, "posterior medians", (name,))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "imu.yaml"
        write_kalibr_yaml(result, path)
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert doc == {**values, "rostopic": "/imu0"}
    assert json.loads(json.dumps({"name": name}))["name"] == name
    folder = safe_folder_name(name)
    assert folder not in ("", ".", "..") and all(
        c.isalnum() and c.isascii() or c in "_.-" for c in folder
    )
    line = excerpt(name)
    assert len(line) <= 80 and line.isprintable()


@pytest.fixture(scope="module")
def small_report(fit_folder):
    """A report of one sensor read from the shared fit folder (no refit)."""
    from bayes_imu.report.scene import build_report, read_scene

    scene = fit_folder.parent / "scene.toml"
    scene.write_text(SCENE_HEAD + '[[sensor]]\nname = "s"\nkind = "gyro"\nfit = "g"\n')
    return build_report(read_scene(scene), rng=0)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(name=_NAMES)
def test_hostile_names_through_html(small_report, name):
    """The same names as a sensor's name: the HTML page has exactly the elements and attributes it
    has for a plain
    name (no tag, script or attribute of the name survives), and shows the name's text as often as
    the plain one
    (the sections' pictures are left out here: tests below draw them)."""
    import dataclasses
    from html.parser import HTMLParser
    from unittest import mock

    import bayes_imu.report.html as report_html_module

    sensor = small_report.sensors[0]

    def page_of(text):
        renamed = dataclasses.replace(sensor, spec=dataclasses.replace(sensor.spec, name=text))
        report = dataclasses.replace(small_report, sensors=(renamed,), ranking=(text,))
        with mock.patch.object(report_html_module, "_png", lambda *args, **kwargs: ""):
            return report_html_module.report_html(report, b"")

    class Collect(HTMLParser):
        def __init__(self, page):
            super().__init__(convert_charrefs=True)
            self.tags, self.text = [], []
            self.feed(page)
            self.close()

        def handle_starttag(self, tag, attrs):
            self.tags.append((tag, sorted(k for k, _ in attrs)))

        def handle_data(self, data):
            self.text.append(data)

    plain, parsed = Collect(page_of("PLAIN")), Collect(page_of(name))
    assert parsed.tags == plain.tags
    if name.strip() and not any(
        c in name for c in "\r\x00"
    ):  # HTML parsing normalises CR and drops NUL
        assert "".join(parsed.text).count(name) >= "".join(plain.text).count("PLAIN") > 0


@pytest.mark.parametrize(
    "name",
    [
        "run$1_$2",
        "$x^2$ \\frac{a}{b}",
        "<script>alert(1)</script>",
        "a\nb\r\x1b[2J",
        "\u2028\x85 & \\$",
    ],
)
def test_hostile_names_through_pictures(small_report, name):
    """A sensor or log name of TeX, HTML and control characters: the comparison chart and a
    labelled Allan plot
    draw (no mathtext from user text)."""
    import dataclasses
    import io

    from bayes_imu.report.html import _comparison_figure
    from bayes_imu.report.plots import plot_allan

    sensor = small_report.sensors[0]
    renamed = dataclasses.replace(sensor, spec=dataclasses.replace(sensor.spec, name=name))
    _comparison_figure(
        dataclasses.replace(small_report, sensors=(renamed,), ranking=(name,)), io.BytesIO()
    )
    plot_allan(sensor.fit.allan, io.BytesIO(), label=name)


def test_scene_time_column_and_unit(tmp_path):
    """A scene's sensor may give time_column (its unit from the name, or time_unit) instead of
    rate_hz: the log stamped in ms gives 100 Hz, and a contradicting rate is refused naming both."""
    from bayes_imu.report.scene import read_scene

    _log(tmp_path / "ms.csv", n=512, time=np.arange(512) * 10.0, name="t_ms")
    _log(tmp_path / "plain.csv", n=512, time=np.arange(512) * 10.0, name="t")
    scene = tmp_path / "scene.toml"
    columns = 'column = "gx"\nunits = "deg/s"\n'
    for log, extra in (("ms.csv", 'time_column = "t_ms"\n'),
                       ("plain.csv", 'time_column = "t"\ntime_unit = "ms"\n')):
        scene.write_text(SCENE_HEAD + _sensor("log", log, columns + extra))
        spec = read_scene(scene).sensors[0]
        allan = _scene_allan(spec, spec.paths[0])
        assert spec.rate_hz is None and allan.rate_hz == pytest.approx(100.0)
    extra = 'rate_hz = 50\ntime_column = "t_ms"\n'
    scene.write_text(SCENE_HEAD + _sensor("log", "ms.csv", columns + extra))
    spec = read_scene(scene).sensors[0]
    with pytest.raises(InputError, match="gives 100 Hz.*but rate_hz is 50 Hz"):
        _scene_allan(spec, spec.paths[0])


def _scene_allan(spec, path):
    """The Allan variance of one of a scene sensor's logs, read as the report reads it (the
    pipeline of ``bayes-imu fit``, :func:`bayes_imu.allan.pipeline.allan_from_source`)."""
    import dataclasses

    from bayes_imu.allan.pipeline import allan_from_source

    return allan_from_source(dataclasses.replace(spec.reading, log=path)).results[0]  # in SI
