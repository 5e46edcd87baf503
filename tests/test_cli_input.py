"""Bad input through the command line: exit 2, one line on stderr, nothing written, input untouched.

Each case runs ``bayes-imu`` in-process and asserts the exit status, that stderr is one
line naming what was wrong, that the output folder does not exist and that the input
folder holds exactly what it held before (no partial folder left behind).
"""

import gzip
import hashlib
import json

import numpy as np
import pytest

from bayes_imu.cli import main

GOOD = "time,gx,gy\n" + "\n".join(f"{i / 100:.2f},{np.sin(i * 1.3):.6f},{np.cos(i * 0.7):.6f}" for i in range(400)) + "\n"


def _time_rows(mutate):
    rows = [f"{i / 100:.2f},{np.sin(i * 1.3):.6f},{np.cos(i):.6f}" for i in range(400)]
    mutate(rows)
    return ("time,gx,gy\n" + "\n".join(rows) + "\n").encode()


def _set(index, text):
    def mutate(rows):
        rows[index] = text
    return mutate


CASES = [  # (id, file bytes or None, extra arguments, message fragment)
    ("missing_file", None, ["fit", "{dir}/nope.csv", "--column", "gx", "--rate", "100"], "nope.csv: no such file"),
    ("directory", None, ["fit", "{dir}", "--column", "gx", "--rate", "100"], "is a directory"),
    ("empty", b"", ["fit", "{log}", "--column", "gx", "--rate", "100"], "empty file"),
    ("header_only", b"time,gx\n", ["fit", "{log}", "--column", "gx", "--rate", "100"], "header row but no samples"),
    ("too_few_for_fit", GOOD[:200].rsplit("\n", 1)[0].encode(), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "expected at least 32 for fit"),
    ("too_few_for_allan", b"gx\n1\n2\n3\n", ["allan", "{log}", "--column", "gx", "--rate", "100"],
     "3 samples; expected at least 4 for allan"),
    ("nan", _time_rows(_set(10, "0.10,nan,1")), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "line 12, column 'gx': got 'nan'"),
    ("inf", _time_rows(_set(10, "0.10,inf,1")), ["allan", "{log}", "--column", "gx", "--rate", "100"], "got 'inf'"),
    ("non_numeric", _time_rows(_set(20, "0.20,1.2.3,1")), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "line 22, column 'gx': got '1.2.3'; expected a finite number"),
    ("missing_column", GOOD.encode(), ["fit", "{log}", "--column", "gz", "--rate", "100"], "no column 'gz'"),
    ("ragged", _time_rows(_set(5, "0.05,1,2,3")), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "line 7: 4 fields; expected 3"),
    ("constant", ("gx\n" + "0.5\n" * 100).encode(), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "constant signal"),
    ("binary", bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8)),
     ["fit", "{log}", "--column", "gx", "--rate", "100"], "binary data"),
    ("corrupt_gzip", gzip.compress(GOOD.encode())[:40], ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "cannot read"),
    ("zero_rate", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--rate", "0"], "--rate=0.0: expected a positive"),
    ("negative_rate", GOOD.encode(), ["allan", "{log}", "--column", "gx", "--rate", "-100"], "--rate=-100.0"),
    ("text_rate", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--rate", "fast"], "invalid float value: 'fast'"),
    ("nan_rate", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--rate", "nan"], "--rate=nan"),
    ("no_rate", GOOD.encode(), ["fit", "{log}", "--column", "gx"], "give --rate HZ or a --time-column"),
    ("overflow", _time_rows(_set(3, "0.03,1e200,1")), ["fit", "{log}", "--column", "gx", "--rate", "100"],
     "expected |value| <= 1e+100"),
    ("time_backwards", _time_rows(_set(100, "0.5,0.1,0.2")), ["fit", "{log}", "--column", "gx", "--time-column", "time"],
     "line 102: time goes backwards from 0.99 s to 0.5 s"),
    ("time_repeats", _time_rows(_set(100, "0.99,0.1,0.2")), ["fit", "{log}", "--column", "gx", "--time-column", "time"],
     "line 102: time stamp 0.99 s repeats"),
    ("time_gap", _time_rows(_set(100, "1.50,0.1,0.2")), ["fit", "{log}", "--column", "gx", "--time-column", "time"],
     "line 102: gap from 0.99 s to 1.5 s"),
    ("rate_disagrees", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--time-column", "time", "--rate", "200"],
     "but --rate is 200 Hz"),
    ("unknown_units", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--rate", "100", "--units", "rpm"],
     "invalid choice: 'rpm'"),
    ("units_sensor_mismatch", GOOD.encode(),
     ["fit", "{log}", "--column", "gx", "--rate", "100", "--units", "g", "--sensor", "gyro"],
     "--units g is a accel unit but --sensor is gyro"),
    ("bad_column_list", GOOD.encode(), ["fit", "{log}", "--column", "gx,,gy", "--rate", "100"],
     "expected column names or indices separated by commas"),
    ("allan_two_columns", GOOD.encode(), ["allan", "{log}", "--column", "gx,gy", "--rate", "100"],
     "allan takes one column"),
    ("unknown_command", None, ["fitt", "{log}"], "invalid choice: 'fitt'"),
    ("bad_terms", GOOD.encode(), ["fit", "{log}", "--column", "gx", "--rate", "100", "--terms", "white,pink"], "pink"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, case):
    name, content, args, message = case
    folder = tmp_path / "in"
    folder.mkdir()
    log = folder / "log.csv"
    if content is not None:
        log.write_bytes(content)
    before = _snapshot(tmp_path)
    out = tmp_path / "out"
    argv = [a.format(dir=folder, log=log) for a in args] + ["--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bayes-imu: error: ") and message in err, err
    assert not out.exists() and _snapshot(tmp_path) == before


def _snapshot(folder):
    """Every file and folder below ``folder`` with a hash of its content."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


@pytest.fixture
def log(tmp_path):
    path = tmp_path / "in" / "log.csv"
    path.parent.mkdir()
    path.write_text(GOOD)
    return path


def test_existing_output_refused_then_replaced_with_force(tmp_path, log, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("keep me")
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"]
    assert main(args) == 2
    assert "folder exists and is not empty; use --force" in capsys.readouterr().err
    assert (out / "old.txt").read_text() == "keep me"
    assert main(args + ["--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["allan.csv", "allan.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]  # no partial or old folder left


def test_output_is_a_file_or_holds_the_input(tmp_path, log, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(target)]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    # --force on the folder holding the log would delete the log: always refused
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(log.parent), "--force"]) == 2
    assert "contains the input" in capsys.readouterr().err and log.read_text() == GOOD


def test_failure_while_writing_leaves_nothing_and_keeps_old_output(tmp_path, log, capsys, monkeypatch):
    """An error after some outputs were written: no partial folder, and --force keeps the old results."""
    import bayes_imu.plots

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(bayes_imu.plots, "plot_allan", broken)
    out = tmp_path / "deep" / "new" / "out"
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--quiet"]
    assert main(args + ["--out", str(out)]) == 1
    assert "internal error: OSError: disk full" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]  # created parents removed too
    old = tmp_path / "old"
    old.mkdir()
    (old / "allan.csv").write_text("previous")
    assert main(args + ["--out", str(old), "--force"]) == 1
    assert (old / "allan.csv").read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "old"]


def test_interrupt_leaves_nothing(tmp_path, log, monkeypatch):
    import bayes_imu.plots

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bayes_imu.plots, "plot_allan", interrupted)
    with pytest.raises(KeyboardInterrupt):
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "out")])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_time_column_rate_and_units_in_outputs(tmp_path, log):
    out = tmp_path / "out"
    assert main(["allan", str(log), "--column", "gy", "--time-column", "time", "--units", "deg/s",
                 "--out", str(out), "--quiet"]) == 0
    rows = [r.split(",") for r in (out / "allan.csv").read_text().splitlines()]
    assert rows[0] == ["tau", "m", "adev", "adev_low", "adev_high", "edf", "unit"]
    assert float(rows[1][0]) == pytest.approx(0.01, rel=1e-9) and rows[1][6] == "rad/s"
    # the same column read in deg/s without conversion: ADEV scales by exactly pi/180
    assert main(["allan", str(log), "--column", "gy", "--rate", "100", "--out", str(tmp_path / "raw"), "--quiet"]) == 0
    raw = [r.split(",") for r in (tmp_path / "raw" / "allan.csv").read_text().splitlines()]
    np.testing.assert_allclose([float(r[2]) for r in rows[1:]], [float(r[2]) * np.pi / 180 for r in raw[1:]],
                               rtol=1e-8)
    assert raw[1][6] == "u"


def test_gaps_longest_fits_segment_and_says_so(tmp_path):
    rng = np.random.default_rng(5)
    t = np.arange(3000) / 100.0
    t[1000:] += 2.0
    path = tmp_path / "gappy.csv"
    path.write_text("t;g\n" + "\n".join(f"{a:.2f};{b:.6f}" for a, b in zip(t, rng.standard_normal(3000))) + "\n")
    out = tmp_path / "out"
    assert main(["fit", str(path), "--column", "g", "--time-column", "t", "--gaps", "longest", "--terms", "white",
                 "--out", str(out), "--quiet"]) == 0
    info = json.loads((out / "summary.json").read_text())["input"]
    assert info["samples_used"] == 2000 and info["dropped_samples"] == 1000 and info["irregular_steps"] == 1
    assert info["first_line"] == 1002 and info["rate_source"] == "time column"
    assert "longest regular segment" in info["action"]
    assert json.loads((out / "summary.json").read_text())["n_samples"] == 2000


def test_kalibr_output_is_staged(tmp_path, capsys):
    target = tmp_path / "imu.yaml"
    target.write_text("old")
    missing = tmp_path / "nofit"
    assert main(["kalibr", "--gyro", str(missing), "--accel", str(missing), "--out", str(target)]) == 2
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["imu.yaml"]
