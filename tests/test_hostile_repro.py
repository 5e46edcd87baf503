"""Issue 37's reproductions, each run as the issue gives it (its command, on a small log), with the
answer a user needs: the right number, or exit status 2 and one line, never a file lost.

``tests/test_hostile.py`` holds the classes' wider cases; this file adds the reproductions that
had no exact test there. ``docs/validation/hostile.md`` maps every reproduction of the issue to
its test. Logs are a few hundred samples and fits use ``--terms white``: the file runs in seconds.
"""

import contextlib
import io
import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main
from test_hostile import SCENE_HEAD, _log, _one_error, _sensor, _snapshot

#: the 100 Hz gyro log's white noise (deg/s per sample) and its density in rad/s/sqrt(Hz)
SIGMA_DEG_S = 0.05
DENSITY = SIGMA_DEG_S * math.pi / 180 / math.sqrt(100.0)


def _fit(argv):
    return main(["fit", *argv, "--terms", "white", "--quiet"])


def _summary(folder):
    return json.loads((folder / "summary.json").read_text())


@pytest.fixture(scope="module")
def ms_fit(tmp_path_factory):
    """``bayes-imu fit ms.csv --column gx --time-column t_ms --units deg/s --out fit_ms`` on a
    100 Hz log stamped in milliseconds (the issue's first reproduction), fitted once."""
    folder = tmp_path_factory.mktemp("ms")
    log = _log(folder / "ms.csv", n=512, time=np.arange(512) * 10.0, name="t_ms",
               scale=SIGMA_DEG_S)
    out = folder / "fit_ms"
    argv = [str(log), "--column", "gx", "--time-column", "t_ms", "--units", "deg/s"]
    assert _fit(argv + ["--out", str(out)]) == 0
    return out


# ------------------------------------------------------------------ silently wrong


def test_millisecond_stamps_give_100_hz_and_the_true_density(ms_fit):
    """Read as seconds the stamps gave 0.1 Hz and a density 31.6x too large. Now 100 Hz, the
    unit and its source in summary.json, and the white density within 15% of the simulated one
    (sigma / sqrt(rate); the estimate's own spread at 512 samples is about 3%)."""
    summary = _summary(ms_fit)
    assert summary["rate_hz"] == 100.0
    assert summary["input"]["time_unit"] == "ms"
    assert summary["input"]["time_unit_source"] == "column name 't_ms'"
    assert summary["parameters"]["noise_density"]["median"] == pytest.approx(DENSITY, rel=0.15)


def test_microsecond_stamps_are_hinted_as_us_and_the_hint_works(tmp_path, capsys, ms_fit):
    """Microsecond stamps: the hint named nanoseconds (followed, 100 kHz and an ARW 30x too
    small). Now the hint names us, and following it fits the same samples as the ms stamps."""
    log = _log(tmp_path / "us.csv", n=512, time=np.arange(512) * 1e4, name="t", scale=SIGMA_DEG_S)
    argv = [str(log), "--column", "gx", "--time-column", "t", "--units", "deg/s"]
    assert _fit(argv + ["--out", str(tmp_path / "a")]) == 2
    err = _one_error(capsys, "us: 100 Hz", "the likely unit is us: give --time-unit us")
    assert "--time-unit ns" not in err
    assert _fit(argv + ["--time-unit", "us", "--out", str(tmp_path / "b")]) == 0
    got, ms = _summary(tmp_path / "b"), _summary(ms_fit)
    assert got["rate_hz"] == pytest.approx(100.0, rel=1e-12) and got["input"]["time_unit"] == "us"
    for name, p in ms["parameters"].items():  # the same samples at the same rate (to rounding)
        assert got["parameters"][name]["median"] == pytest.approx(p["median"], rel=1e-9), name


def test_the_same_log_twice_is_not_two_units(tmp_path, capsys):
    """``fit-population a.csv a.csv`` (and ``./a.csv``): refused naming both, before any fit."""
    log = _log(tmp_path / "a.csv")
    for second in (str(log), str(tmp_path / "." / "a.csv")):
        argv = ["fit-population", str(log), second, "--column", "gx", "--rate", "100"]
        assert main(argv + ["--out", str(tmp_path / "pop")]) == 2
        _one_error(capsys, "are the same file or folder", "give each unit once")
        assert not (tmp_path / "pop").exists()


def test_a_step_is_warned_and_recorded_in_the_fit(tmp_path, capsys, ms_fit):
    """A 20-sigma step halfway was fitted as adequate and stationary without a word. Now one
    warning line with its sample, and what was read records it (``summary.json``'s ``input`` is
    that record, as the ms fit's shows), read in memory or out of core (there from the log's
    first STREAMED_CHECK samples)."""
    import warnings

    from bayes_imu.allan.pipeline import LogSource, allan_from_source
    from bayes_imu.io.plausible import PlausibilityWarning

    x = np.random.default_rng(5).standard_normal(320)
    x[160:] += 20.0
    log = tmp_path / "step.csv"
    log.write_text("gx\n" + "".join(f"{v:.6f}\n" for v in x))
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--quiet",
                 "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its level steps by" in err and "at sample 161" in err, err
    steps = []
    for stream in (False, True):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            read = allan_from_source(LogSource(log=log, column="gx", rate=100.0, stream=stream))
        assert [w.category for w in caught] == [PlausibilityWarning]
        steps.append(read.info["steps"]["gx"])
    # its size: the noise is estimated from 319 differences (about 6% spread): 20 within 20%
    assert steps[0] == steps[1] and steps[0]["sample"] == 161
    assert abs(steps[0]["sigmas"] - 20.0) < 4.0
    ms_read = allan_from_source(LogSource(log=ms_fit.parent / "ms.csv", column="gx",
                                          time_column="t_ms", units="deg/s"))
    assert _summary(ms_fit)["input"] == {**ms_read.info, "log": str(ms_fit.parent / "ms.csv")}


@pytest.mark.parametrize("stream", [False, True])
def test_a_g_column_declared_mg_is_named(tmp_path, capsys, stream):
    """``--units mg`` on an accelerometer's gravity axis in g (1 g, 200 ug/sqrt(Hz)): the velocity
    random walk came out 1000x too small without a word. Now a warning naming g (in memory and
    out of core, where the start of the log is checked)."""
    values = 1.0 + 0.002 * np.random.default_rng(6).standard_normal(512)
    log = tmp_path / "accz.csv"
    log.write_text("az\n" + "".join(f"{v:.6f}\n" for v in values))
    argv = ["allan", str(log), "--column", "az", "--rate", "100", "--units", "mg", "--quiet"]
    assert main(argv + ["--out", str(tmp_path / "o")] + (["--stream"] if stream else [])) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "in mg the log shows" in err
    assert "plausible in m/s^2 or g" in err


def test_a_deg_s_gyro_declared_rad_s_is_named_by_fit(tmp_path, capsys):
    """The MPU6050 case through ``fit`` (a 4.5 deg/s bias read as 4.5 rad/s): one warning naming
    deg/s; the fit is written (the user may know better: ``--trust-units`` silences it)."""
    log = tmp_path / "mpu.csv"
    values = 4.5 + 0.05 * np.random.default_rng(8).standard_normal(256)
    log.write_text("gx\n" + "".join(f"{v:.6f}\n" for v in values))
    assert _fit([str(log), "--column", "gx", "--rate", "100", "--units", "rad/s",
                 "--out", str(tmp_path / "f")]) == 0
    err = capsys.readouterr().err
    assert "a mean rate of 4.5 rad/s" in err and "plausible in deg/s" in err, err


def test_bursty_host_stamps_through_the_command(tmp_path, capsys):
    """The MPU6050 host-stamp log (mean 99.3 Hz): ``--gaps longest`` was suggested and failed with
    18 samples. Both gap policies now state the mean rate and the option that fits."""
    rng = np.random.default_rng(9)
    n = 1200
    steps = np.where(rng.random(n - 1) < 0.7, 1e-3 * (1 + 0.1 * rng.standard_normal(n - 1)), 0.0)
    steps[steps == 0] = ((n - 1) / 99.3 - steps.sum()) / np.count_nonzero(steps == 0)
    log = _log(tmp_path / "bursty.csv", n=n, time=np.concatenate(([0.0], np.cumsum(steps))))
    for gaps in ("error", "longest"):
        argv = [str(log), "--column", "gx", "--time-column", "time", "--gaps", gaps]
        assert _fit(argv + ["--out", str(tmp_path / "o")]) == 2
        err = _one_error(capsys, "the mean rate over the log is 99.3 Hz",
                         "drop --time-column and give --rate 99.3")
        assert "--gaps longest" not in err


# ------------------------------------------------------------------ data lost


def test_fit_batch_force_keeps_notes_in_its_sub_folders(tmp_path, capsys):
    """``fit-batch ... --out res``, notes saved in ``res/<log>/``, the same batch with --force:
    refused naming the notes, the previous result byte for byte."""
    log = _log(tmp_path / "imu.csv", n=256)
    argv = ["fit-batch", str(log), "--column", "gx", "--rate", "100", "--terms", "white",
            "--serial", "--quiet", "--out", str(tmp_path / "res")]
    assert main(argv) == 0
    (tmp_path / "res" / "imu" / "notes.txt").write_text("notes")
    before = _snapshot(tmp_path / "res")
    assert main(argv + ["--force"]) == 2
    _one_error(capsys, "--force would leave 'imu/notes.txt'")
    assert _snapshot(tmp_path / "res") == before


def test_kalibr_force_never_replaces_another_folders_summary(tmp_path, capsys, ms_fit):
    """``kalibr --out FILE --force`` replaced any JSON object with a bayes_imu_version key: another
    fit folder's summary.json (that folder then unreadable), or notes whose first line starts
    with '# bayes_imu'. Both refused now, untouched; its own earlier imu.yaml is replaced."""
    other = tmp_path / "other"
    shutil.copytree(ms_fit, other)
    notes = tmp_path / "notes.yaml"
    notes.write_text("# bayes_imu notes\nmine\n")
    for target in (other / "summary.json", notes):
        text = target.read_text()
        assert main(["kalibr", "--gyro", str(ms_fit), "--out", str(target), "--force"]) == 2
        _one_error(capsys, "replaces only a file a bayes_imu run wrote")
        assert target.read_text() == text
    mine = tmp_path / "imu.yaml"
    for force in ([], ["--force"]):
        assert main(["kalibr", "--gyro", str(ms_fit), "--out", str(mine), *force]) == 0
    assert "gyroscope_noise_density" in mine.read_text()


@pytest.mark.parametrize("command", ["fit", "fit-population"])
@pytest.mark.parametrize("option", ["--horizon", "--times", "--calibration"])
def test_huge_values_refused_by_every_fitting_command(tmp_path, capsys, command, option):
    """``--horizon 1e300`` (and --times, --calibration) crashed after the fit ("NaN is not JSON
    compliant", once in a worker): every command taking them refuses before reading."""
    argv = [command, str(tmp_path / "never_read.csv")] + (
        [str(tmp_path / "b.csv")] if command == "fit-population" else [])
    assert main(argv + ["--column", "gx", "--rate", "100", option, "1e300",
                        "--out", str(tmp_path / "o")]) == 2
    _one_error(capsys, option, "1e+09")


# ------------------------------------------------------------------ unbounded memory or time


@pytest.mark.parametrize("command", ["report", "drift"])
@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_devices_as_scene_or_sensor_answer_at_once(tmp_path, capsys, command, device):
    """``report /dev/zero`` exhausted memory; ``report /dev/urandom`` ignored SIGTERM."""
    assert main([command, device, "--out", str(tmp_path / "o")]) == 2
    _one_error(capsys, "not a regular file")


@pytest.mark.parametrize("command", ["allan", "fit"])
@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom", "/dev/null"])
def test_devices_as_logs_answer_at_once(tmp_path, capsys, command, device):
    assert main([command, device, "--column", "0", "--rate", "100",
                 "--out", str(tmp_path / "o")]) == 2
    _one_error(capsys, "not a regular file")


class _Endless(io.RawIOBase):
    """A pipe that never ends (``yes 0.1 |``)."""

    def readable(self):
        return True

    def readinto(self, buffer):
        buffer[:] = (b"0.1\n" * (len(buffer) // 4 + 1))[: len(buffer)]
        return len(buffer)


def test_a_never_ending_pipe_ends_at_the_spool_bound(tmp_path, capsys, monkeypatch):
    """``yes 0.1 | bayes-imu allan -`` spooled to the temporary folder for as long as it ran. It
    ends at MAX_SPOOL_BYTES (lowered here to 4 MiB), exit 2, the spool removed; a pipe below the
    bound is read as before."""
    import tempfile

    import bayes_imu.allan.pipeline as pipeline

    monkeypatch.setattr(pipeline, "MAX_SPOOL_BYTES", 4 * 2**20)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(_Endless())))
    argv = ["allan", "-", "--column", "0", "--rate", "100", "--quiet"]
    assert main(argv + ["--out", str(tmp_path / "o")]) == 2
    _one_error(capsys, "more than 0.00390625 GiB came from standard input without an end")
    assert not list(tmp_path.glob("bayes-imu-input-*")) and not (tmp_path / "o").exists()
    log = _log(tmp_path / "log.csv")
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(log.read_bytes())))
    assert main(["allan", "-", "--column", "gx", "--rate", "100", "--quiet",
                 "--out", str(tmp_path / "o")]) == 0


# ------------------------------------------------------------------ untrusted files


@pytest.mark.parametrize("given", ["/etc/shadow", "../../..", "../../../etc/passwd"])
def test_scene_paths_of_the_issue_are_refused_unread(tmp_path, given):
    from bayes_imu.errors import InputError
    from bayes_imu.report.scene import read_scene

    scene = tmp_path / "a" / "b" / "scene.toml"
    scene.parent.mkdir(parents=True)
    scene.write_text(SCENE_HEAD + _sensor("log", given))
    with pytest.raises(InputError, match="lies outside the scene's folder"):
        read_scene(scene)


def test_folder_names_inject_no_statement_into_exports(tmp_path, ms_fit):
    """A fit folder named with a newline and a statement: every export format keeps it inside one
    comment line (gtsam-py and matlab files ran it as code), and plan.csv keeps it one field."""
    import csv

    evil = tmp_path / 'g\nimport os; os.system("x")\r\u2028gyro.NoiseDensity = 1;'
    shutil.copytree(ms_fit, evil)
    shutil.copytree(ms_fit, tmp_path / "h")
    for fmt, mark in (("gtsam-py", "#"), ("matlab", "%"), ("openvins", "#"), ("vins", "#")):
        out = tmp_path / f"x.{fmt}"
        assert main(["export", "--gyro", str(evil), str(tmp_path / "h"), "--format", fmt,
                     "--out", str(out), "--quiet"]) == 0
        lines = out.read_text().split("\n")
        assert not any("os.system" in line and not line.startswith(mark) for line in lines), fmt
        assert all(line.isprintable() for line in lines), fmt
    from bayes_imu.report.planning import csv_field

    for name in ('a,b', 'x\ny', '"q"', " s ", "\u2028", "plain"):
        row = next(csv.reader(io.StringIO(csv_field(name) + ",1\n", newline="")))
        assert row == [name, "1"]


# ------------------------------------------------------------------ exit statuses, messages


def test_the_top_level_help_exits_0(capsys):
    """``bayes-imu --help`` crashed (exit 1, a traceback) on a '%' in ``plan``'s summary."""
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0 and "plan" in capsys.readouterr().out


def test_messages_point_the_right_way(tmp_path, capsys, ms_fit):
    """Messages the attack found pointing the wrong way (docs/validation/hostile.md lists them)."""
    log = tmp_path / "GX.csv"
    log.write_text("GX\n" + "".join(f"{v:.6f}\n" for v in np.random.default_rng(2).random(64)))
    cases = [
        (["allan", str(log), "--column", "gx", "--rate", "100"], "did you mean 'GX'?"),
        (["kalibr", "--gyro", str(tmp_path), "--out", str(tmp_path / "k.yaml")],
         "no summary.json in it: not a folder written by bayes-imu fit"),
        (["kalibr", "--accel", str(ms_fit), "--out", str(tmp_path / "k.yaml")],
         "a gyro unit; expected an accelerometer fit (give this folder with --gyro)"),
        (["kalibr", "--gyro", str(ms_fit), "--out", str(tmp_path / "dir") + "/"],
         "expected a file name"),
    ]
    for argv, fragment in cases:
        assert main(argv + (["--out", str(tmp_path / "o")] if "--out" not in argv else [])) == 2
        _one_error(capsys, fragment)
    assert not (tmp_path / "dir").exists() and not (tmp_path / "k.yaml").exists()
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE_HEAD + '[[sensor]]\nname = "a"\nkind = "gyro"\nfitt = "f"\n')
    assert main(["report", str(scene), "--out", str(tmp_path / "r")]) == 2
    assert "time_unit, gaps" in _one_error(capsys, "unknown key 'fitt'")  # a key, not a flag
    shutil.copytree(ms_fit, tmp_path / "g")
    scene.write_text(SCENE_HEAD.replace("[scene]\n", "[scene]\nallow_outside = true\n")
                     + f'[[sensor]]\nname = "a"\nkind = "accel"\nfit = "{tmp_path / "g"}"\n')
    assert main(["report", str(scene), "--out", str(tmp_path / "r")]) == 2
    _one_error(capsys, "it is a gyro fit: is kind = 'accel' right?")
    short = tmp_path / "short.csv"  # the warning comes before the log is read: no fit needed
    short.write_text("gx\n" + "".join(f"{v:.3f}\n" for v in np.arange(10) % 3))
    assert _fit([str(short), "--column", "gx", "--rate", "100", "--horizon", "10",
                 "--out", str(tmp_path / "h")]) == 2
    err = capsys.readouterr().err.split("\n")
    assert err[0] == ("bayes-imu: warning: --horizon without --sensor: no drift is computed (give "
                      "--sensor gyro or accel)") and "10 samples" in err[1]


# ------------------------------------------------------------------ names through every format

from hypothesis import given, settings  # noqa: E402

from test_hostile import _NAMES  # noqa: E402


def _export_structure(name, fmt):
    """What a filter reads from an export whose axis (and inadequate, tight) labels are ``name``:
    the parsed document (YAML, JSON), the statements (Python's syntax tree) or the non-comment
    lines (MATLAB)."""
    import ast

    import yaml

    from bayes_imu.report.exports import ExportValues, ImuNoise, render_export

    point = ImuNoise(gyroscope_noise_density=2e-4, gyroscope_random_walk=3e-6, update_rate=200.0)
    bound = ImuNoise(gyroscope_noise_density=3e-4, gyroscope_random_walk=4e-6, update_rate=200.0)
    per_axis = {"gyroscope_noise_density": [(name, 2e-4, 3e-4), ("b", 1e-4, 2e-4)],
                "gyroscope_random_walk": [(name, 3e-6, 4e-6), ("b", 1e-6, 2e-6)]}
    values = ExportValues(bound, point, bound, per_axis, {"gyroscope": [(name, "attitude", 10.0)]},
                          "overbound", (name,))
    text = render_export(values, fmt)
    if fmt == "gtsam":
        return {k: v for k, v in json.loads(text).items() if k != "notes"}
    if fmt == "gtsam-py":
        return ast.dump(ast.parse(text))
    if fmt == "matlab":
        return [line for line in text.split("\n") if not line.startswith("%")]
    return yaml.safe_load(text.removeprefix("%YAML:1.0\n"))


@settings(max_examples=40, deadline=None)
@given(name=_NAMES)
def test_hostile_names_through_every_output_format(name):
    """A name of shell, YAML, HTML, TeX and control characters as an axis, log or column name:
    every export format reads exactly as with a plain name (YAML keys, JSON fields, Python
    statements, MATLAB lines), summary.json round-trips it, a plan.csv field holds it in one row,
    and a picture draws it literally (kalibr YAML, HTML and folder names: test_hostile.py)."""
    import csv

    from bayes_imu.report.planning import csv_field
    from bayes_imu.report.plots import plain_text
    from bayes_imu.report.writers import fit_summary

    for fmt in ("kalibr", "openvins", "vins", "gtsam", "gtsam-py", "matlab"):
        assert _export_structure(name, fmt) == _export_structure("PLAIN", fmt), fmt
    axes = {name: {"parameters": {}}, "b" if name != "b" else "c": {"parameters": {}}}
    doc = fit_summary(axes, info={"log": name, "columns": list(axes)}, seed=0,
                      folders=["x", "y"])
    assert json.loads(json.dumps(doc, allow_nan=False)) == doc and list(doc["axes"]) == list(axes)
    rows = list(csv.reader(io.StringIO(csv_field(name) + ",1.5\n", newline="")))
    assert rows == [[name, "1.5"]]
    import warnings

    figure = _figure()
    text = figure.text(0.1, 0.5, plain_text(name))
    try:
        with warnings.catch_warnings():  # a character the font lacks is drawn as a box: fine
            warnings.filterwarnings("ignore", r"Glyph \d+ .* missing from font", UserWarning)
            figure.canvas.draw()  # mathtext from user text raised here (run$1_$2)
    finally:
        text.remove()


def _figure(cache={}):
    """One small Agg figure outside pyplot's registry (no open figure is left behind)."""
    if "figure" not in cache:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        cache["figure"] = Figure(figsize=(2, 1))
        FigureCanvasAgg(cache["figure"])
    return cache["figure"]


def test_a_named_pipe_whose_writer_opens_a_moment_later_is_read(tmp_path, capsys):
    """``producer > pipe & bayes-imu allan pipe``: the producer's open returns only once the reader
    has opened, a moment after; reading at once saw no writer and said so. The reader now waits
    up to 0.5 s for one (here the writer opens 0.1 s after the command starts)."""
    import os
    import threading

    pipe = tmp_path / "pipe.csv"
    os.mkfifo(pipe)
    text = _log(tmp_path / "log.csv").read_bytes()

    def write():
        try:
            with open(pipe, "wb") as f:
                f.write(text)
        except BrokenPipeError:  # the reader gave up (the test fails on its status)
            pass

    writer = threading.Timer(0.1, write)
    writer.start()
    try:
        assert main(["allan", str(pipe), "--column", "gx", "--rate", "100", "--quiet",
                     "--out", str(tmp_path / "o")]) == 0, capsys.readouterr().err
    finally:
        writer.join(timeout=5)
        if writer.is_alive():  # still blocked in open(): a reader that opens and leaves frees it
            os.close(os.open(pipe, os.O_RDONLY | os.O_NONBLOCK))
            writer.join()


@pytest.mark.slow  # ~40 s: 18 fresh processes, each under an address-space limit
def test_bench_hostile_quick_stays_within_its_bounds():
    """``scripts/bench_hostile.py --quick``: every hostile case exits 2 under ``ulimit -v`` 3 GiB
    within 60 s and 256 MiB resident (the documented bounds), the valid ones 0."""
    import subprocess

    script = Path(__file__).resolve().parents[1] / "scripts" / "bench_hostile.py"
    done = subprocess.run([sys.executable, str(script), "--quick", "--timeout", "60"],
                          capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0 and "all as expected" in done.stdout, done.stdout[-3000:]


def test_pictures_inside_report_html_never_cost_the_numbers(tmp_path, monkeypatch, ms_fit):
    """The report's page embeds each sensor's Allan fit and drift pictures: one that cannot be
    drawn used to stop the report (exit 1). Now the page and report.json are written, a line
    stands in the picture's place, and each failure is returned (the command: one warning line
    each, exit 3)."""
    import bayes_imu.report.html as report_html
    import bayes_imu.report.plots as plots
    from bayes_imu.report.scene import build_report, read_scene

    shutil.copytree(ms_fit, tmp_path / "g")
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE_HEAD + '[[sensor]]\nname = "s$1"\nkind = "gyro"\nfit = "g"\n')
    report = build_report(read_scene(scene), rng=0)

    def broken(*args, **kwargs):
        raise ValueError("cannot draw\nsecond line")

    def drawn(*args, **kwargs):  # a picture drawn (its bytes), without the drawing's time
        target = args[-1]
        with open(target, "wb") if isinstance(target, Path) else contextlib.nullcontext(
                target) as f:
            f.write(b"PNG")

    monkeypatch.setattr(plots, "plot_allan_fit", broken)
    monkeypatch.setattr(plots, "plot_drift", drawn)
    monkeypatch.setattr(report_html, "_comparison_figure", drawn)
    failures = report_html.write_report(report, tmp_path / "out")
    page = (tmp_path / "out" / "report.html").read_text()
    assert [str(f) for f in failures] == [
        "report.html: the Allan fit of s$1 was not drawn (ValueError: cannot draw); the numbers "
        "were written"]
    assert "Allan fit of s$1: the picture could not be drawn." in page
    assert page.count("data:image/png;base64,") == 2  # the comparison chart and the drift bands
    assert json.loads((tmp_path / "out" / "report.json").read_text())["sensors"]
    monkeypatch.setattr(plots, "plot_allan_fit", drawn)
    assert report_html.write_report(report, tmp_path / "again") == []


@pytest.mark.slow  # ~5 s of CPU: the plan's Fisher information over its default lengths
def test_plan_of_a_folder_named_with_dollars_draws_its_picture(tmp_path, ms_fit):
    """``bayes-imu plan 'd$1_$2'``: the folder's name in plan.png's title started mathtext (exit 1,
    nothing kept); drawn literally now, and a failing picture would cost only plan.png."""
    folder = tmp_path / "d$1_$2"
    shutil.copytree(ms_fit, folder)
    assert main(["plan", str(folder), "--out", str(tmp_path / "p"), "--quiet"]) == 0
    assert (tmp_path / "p" / "plan.png").stat().st_size > 10_000


@pytest.mark.parametrize("argv", [
    ["export", "--gyro", "g", "--format", "kalibr", "--overbound", "--t-max", "1e300"],
    ["export", "--gyro", "g", "--format", "kalibr", "--overbound", "--calibration", "1e300"],
    ["export", "--gyro", "g", "--format", "kalibr", "--seed", "-1"],
    ["nav", "--gyro", "g", "--accel", "a", "--calibration", "1e300"],
    ["nav", "--gyro", "g", "--accel", "a", "--times", "1e300"],
    ["nav", "--gyro", "g", "--accel", "a", "--horizon", "1e300"],
    ["nav", "--gyro", "g", "--accel", "a", "--speed", "1e300"],
    ["plan", "g", "--lengths", "1e300"],
    ["plan", "g", "--horizons", "1e300"],
    ["plan", "g", "--calibration", "1e300"],
    ["plan", "g", "--rate", "1e300"],
])
def test_the_newer_commands_check_their_ranges_first(tmp_path, capsys, argv):
    """export, nav and plan (added after the attack) took any positive number: exit 1 (linprog on
    inf, a negative seed, 512 GiB asked for) or NaN rows with exit 0. Each is refused first now,
    naming the range (docs/cli.md "Valid ranges")."""
    assert main(argv + ["--out", str(tmp_path / "o.yaml")]) == 2
    _one_error(capsys, argv[-2], "expected")


def test_plan_lengths_are_bounded_in_samples_and_exports_divide_safely():
    """A plan of 1e9 s at 100 Hz asked for 512 GiB (MemoryError, exit 1): refused above
    MAX_PLAN_SAMPLES. An overbound export whose point model lacks a term (random walk 0) divided
    by zero: its factor is infinite (or 1 where both are 0)."""
    from bayes_imu.drift.plan import MAX_PLAN_SAMPLES, plan_record_length
    from bayes_imu.errors import InputError
    from bayes_imu.noise import NoiseModel
    from bayes_imu.report.exports import ExportValues, ImuNoise

    model = NoiseModel(("white",), dt=0.01)
    with pytest.raises(InputError, match="expected records of at most"):
        plan_record_length(model, {model.parameter_names[0]: 1e-6},
                           lengths_s=[(MAX_PLAN_SAMPLES + 1) * 0.01])
    point = ImuNoise(gyroscope_noise_density=1e-4, gyroscope_random_walk=0.0, update_rate=100.0)
    for walk, factor in ((1e-6, math.inf), (0.0, 1.0)):
        bound = ImuNoise(gyroscope_noise_density=2e-4, gyroscope_random_walk=walk,
                         update_rate=100.0)
        got = ExportValues(bound, point, bound).factors()
        assert got == {"gyroscope_noise_density": 2.0, "gyroscope_random_walk": factor}


@pytest.mark.slow  # ~3 s: an accelerometer fit and the navigation bands
def test_a_failing_nav_picture_keeps_nav_csv(tmp_path, capsys, monkeypatch, ms_fit):
    """``nav``: nav.png that cannot be drawn used to stop the command (exit 1, nothing kept). Now
    one warning line, exit 3, nav.csv and summary.json written, no nav.png."""
    import bayes_imu.report.nav as nav

    values = 1.0 + 0.002 * np.random.default_rng(10).standard_normal(512)
    log = tmp_path / "az.csv"
    log.write_text("az\n" + "".join(f"{v:.6f}\n" for v in values))
    assert _fit([str(log), "--column", "az", "--rate", "100", "--units", "g",
                 "--out", str(tmp_path / "acc")]) == 0

    def broken(*args, **kwargs):
        raise ValueError("cannot draw")

    monkeypatch.setattr(nav, "plot_nav", broken)
    out = tmp_path / "nav"
    assert main(["nav", "--gyro", str(ms_fit), "--accel", str(tmp_path / "acc"), "--quiet",
                 "--out", str(out)]) == 3
    assert capsys.readouterr().err == ("bayes-imu: warning: nav.png was not drawn (ValueError: "
                                       "cannot draw); the numbers were written\n")
    assert sorted(p.name for p in out.iterdir()) == [".bayes_imu.json", "nav.csv", "summary.json"]
