"""Bad input through the command line: exit 2, one line on stderr, nothing written, input untouched.

Each case runs ``bayes-imu`` in-process and asserts the exit status, that stderr is one
line naming what was wrong, that the output folder does not exist and that the input
folder holds exactly what it held before (no partial folder left behind).
"""

import gzip
import hashlib
import importlib
import json

from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main

GOOD = (
    "time,gx,gy\n"
    + "\n".join(f"{i / 100:.2f},{np.sin(i * 1.3):.6f},{np.cos(i * 0.7):.6f}" for i in range(400))
    + "\n"
)


def _time_rows(mutate):
    rows = [f"{i / 100:.2f},{np.sin(i * 1.3):.6f},{np.cos(i):.6f}" for i in range(400)]
    mutate(rows)
    return ("time,gx,gy\n" + "\n".join(rows) + "\n").encode()


def _set(index, text):
    def mutate(rows):
        rows[index] = text
    return mutate


CASES = [  # (id, file bytes or None, extra arguments, message fragment)
    (
        "missing_file",
        None,
        ["fit", "{dir}/nope.csv", "--column", "gx", "--rate", "100"],
        "nope.csv: no such file",
    ),
    ("directory", None, ["fit", "{dir}", "--column", "gx", "--rate", "100"], "is a directory"),
    ("empty", b"", ["fit", "{log}", "--column", "gx", "--rate", "100"], "empty file"),
    (
        "header_only",
        b"time,gx\n",
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "header row but no samples",
    ),
    (
        "too_few_for_fit",
        GOOD[:200].rsplit("\n", 1)[0].encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "expected at least 32 for fit",
    ),
    (
        "one_sample",  # a single sample is not reported as a constant signal
        b"gx\n0.1\n",
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "1 sample; expected at least 32 for fit",
    ),
    (
        "too_few_for_allan",
        b"gx\n1\n2\n3\n",
        ["allan", "{log}", "--column", "gx", "--rate", "100"],
        "3 samples; expected at least 4 for allan",
    ),
    (
        "nan",
        _time_rows(_set(10, "0.10,nan,1")),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "line 12, column 'gx': got 'nan'",
    ),
    (
        "inf",
        _time_rows(_set(10, "0.10,inf,1")),
        ["allan", "{log}", "--column", "gx", "--rate", "100"],
        "got 'inf'",
    ),
    (
        "non_numeric",
        _time_rows(_set(20, "0.20,1.2.3,1")),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "line 22, column 'gx': got '1.2.3'; expected a finite number",
    ),
    (
        "missing_column",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gz", "--rate", "100"],
        "no column 'gz'",
    ),
    (
        "ragged",
        _time_rows(_set(5, "0.05,1,2,3")),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "line 7: 4 fields; expected 3",
    ),
    (
        "constant",
        ("gx\n" + "0.5\n" * 100).encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "constant signal",
    ),
    (
        "binary",
        bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8)),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "binary data",
    ),
    (
        "corrupt_gzip",
        gzip.compress(GOOD.encode())[:40],
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "a corrupt or truncated gzip file",
    ),
    (
        "zero_rate",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "0"],
        "--rate: expected a sample rate from 0.01 Hz",
    ),
    (
        "negative_rate",
        GOOD.encode(),
        ["allan", "{log}", "--column", "gx", "--rate", "-100"],
        "--rate: expected a sample rate from 0.01 Hz to 1e+06 Hz, got '-100'",
    ),
    (
        "text_rate",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "fast"],
        "--rate: expected a plain number in Hz (no unit written: --rate 100), got 'fast'",
    ),
    (
        "nan_rate",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "nan"],
        "--rate: expected a sample rate from 0.01 Hz to 1e+06 Hz, got 'nan'",
    ),
    (
        "no_rate",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx"],
        "give --rate HZ or a --time-column",
    ),
    (
        "overflow",
        _time_rows(_set(3, "0.03,1e200,1")),
        ["fit", "{log}", "--column", "gx", "--rate", "100"],
        "expected |value| <= 1e+100",
    ),
    (
        "time_backwards",
        _time_rows(_set(100, "0.5,0.1,0.2")),
        ["fit", "{log}", "--column", "gx", "--time-column", "time"],
        "line 102: time goes backwards from 0.99 s to 0.5 s",
    ),
    (
        "time_repeats",
        _time_rows(_set(100, "0.99,0.1,0.2")),
        ["fit", "{log}", "--column", "gx", "--time-column", "time"],
        "line 102: time stamp 0.99 s repeats",
    ),
    (
        "time_gap",
        _time_rows(_set(100, "1.50,0.1,0.2")),
        ["fit", "{log}", "--column", "gx", "--time-column", "time"],
        "line 102: gap from 0.99 s to 1.5 s",
    ),
    (
        "rate_disagrees",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--time-column", "time", "--rate", "200"],
        "but --rate is 200 Hz",
    ),
    (  # the unit the rate picks is not said to "agree" with it (it did), and rate_hz is --rate
        "rate_picks_the_unit_and_disagrees",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--time-column", "time", "--rate", "150"],
        "the time column gives 100 Hz, a step of 0.01 s with stamps in s (the unit nearest --rate "
        "150), but --rate is 150 Hz; expected them to agree within 1%",
    ),
    (  # a unit written after the number: not a number, not a rate out of range
        "rate_with_its_unit",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100Hz"],
        "--rate: expected a plain number in Hz (no unit written: --rate 100), got '100Hz'",
    ),
    (
        "horizon_with_its_unit",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--horizon", "1h"],
        "--horizon: expected a plain number in s (no unit written), got '1h'",
    ),
    (
        "unknown_units",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--units", "rpm"],
        "invalid choice: 'rpm'",
    ),
    (
        "units_sensor_mismatch",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--units", "g", "--sensor", "gyro"],
        "--units g is an accel unit but --sensor is gyro",
    ),
    (
        "bad_column_list",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx,,gy", "--rate", "100"],
        "expected column names or indices separated by commas",
    ),
    (
        "allan_two_columns",
        GOOD.encode(),
        ["allan", "{log}", "--column", "gx,gy", "--rate", "100"],
        "allan takes one column",
    ),
    ("unknown_command", None, ["fitt", "{log}"], "invalid choice: 'fitt'"),
    (
        "no_column_lists_them",
        GOOD.encode(),
        ["fit", "{log}", "--rate", "100"],
        "needs --column (a header name or 0-based index); its columns: 'time', 'gx', 'gy'",
    ),
    (
        "bad_terms",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--terms", "white,pink"],
        "pink",
    ),
    # issue 13: inputs that used to turn into plausible nonsense with exit 0, and option values
    # checked first
    (
        "header_shorter_than_rows",
        ("gx,gy\n" + "".join(f"{i},{np.sin(i):.5f},{np.cos(i):.5f}\n" for i in range(99))).encode(),
        ["fit", "{log}", "--column", "gy", "--rate", "100"],
        "the header has 2 fields but line 2 has 3",
    ),
    (
        "decimal_commas",
        "".join(f"{np.sin(i):.5f};{np.cos(i):.5f}\n".replace(".", ",") for i in range(99)).encode(),
        ["allan", "{log}", "--column", "0", "--rate", "100"],
        "uses decimal commas",
    ),
    (
        "nanosecond_stamps",
        (
            "t,gx\n"
            + "".join(
                f"{1403636579758555392 + i * 10_000_000},{np.sin(i):.5f}\n" for i in range(99)
            )
        ).encode(),
        ["fit", "{log}", "--column", "gx", "--time-column", "t"],
        "the likely unit is ns: give --time-unit ns",
    ),
    (
        "implausible_rate",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "1e-300"],
        "--rate: expected a sample rate from 0.01 Hz",
    ),
    (
        "negative_seed",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--seed", "-1"],
        "--seed: expected a whole number from 0 to 2**32 - 1",
    ),
    (
        "zero_workers",
        GOOD.encode(),
        ["fit-batch", "{log}", "--column", "gx", "--rate", "100", "--workers", "0"],
        "--workers: expected at least 1 worker process",
    ),
    (
        "negative_horizon",
        GOOD.encode(),
        ["fit", "{log}", "--column", "gx", "--rate", "100", "--horizon", "-5"],
        "--horizon: expected a number from 1e-06 to 1e+09 s",
    ),
    (
        "json_boolean_rate",
        b'{"kind": "gyro", "rate_hz": true, "noise_density": 1e-3}',
        ["drift", "{log}"],
        "rate_hz=True: expected a number",
    ),
    (
        "json_unknown_key",
        b'{"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3, "bias_strat": 1}',
        ["drift", "{log}"],
        "unknown key 'bias_strat'",
    ),
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
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        if p.is_file()
        else "dir"
        for p in sorted(folder.rglob("*"))
    }


@pytest.fixture
def log(tmp_path):
    path = tmp_path / "in" / "log.csv"
    path.parent.mkdir()
    path.write_text(GOOD)
    return path


def test_existing_output_refused_and_force_replaces_only_a_previous_result(tmp_path, log, capsys):
    """A folder with a user's file: refused, with or without --force, naming the file, which stays.
    A previous bayes_imu result (marker file): refused without --force, replaced with it."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("keep me")
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"]
    assert main(args) == 2
    assert "folder exists and is not empty ('old.txt')" in capsys.readouterr().err
    assert main(args + ["--force"]) == 2
    assert "--force replaces only a previous bayes_imu result" in capsys.readouterr().err
    assert (
        sorted(p.name for p in out.iterdir()) == ["old.txt"]
        and (out / "old.txt").read_text() == "keep me"
    )
    result = tmp_path / "result"
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(result), "--quiet"]
    assert main(args) == 0
    first = _snapshot(result)
    assert main(args) == 2 and _snapshot(result) == first
    assert main(args + ["--force"]) == 0
    assert sorted(p.name for p in result.iterdir()) == [".bayes_imu.json", "allan.csv", "allan.png"]
    # no partial or old folder left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out", "result"]


def test_force_leaves_files_the_run_did_not_create(tmp_path, log, capsys):
    """A user's notes saved into a result folder: --force refuses and names them (nothing
    deleted)."""
    out = tmp_path / "out"
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"]
    assert main(args) == 0
    (out / "notes.txt").write_text("mine")
    assert main(args + ["--force"]) == 2
    assert "would leave 'notes.txt'" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "mine"


def test_output_claimed_by_another_run_is_refused_at_once(tmp_path, log, capsys):
    """Two runs into one --out: the claim file of the first stops the second before any work."""
    out = tmp_path / "out"
    out.mkdir()
    (out / ".bayes_imu.claim").write_text("")
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"])
        == 2
    )
    assert "another bayes-imu run is writing there" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == [".bayes_imu.claim"]


def test_files_saved_into_out_during_the_run_are_kept(tmp_path, log, monkeypatch):
    """The run claims a new --out at the start; a file the user saves there meanwhile is kept,
    on success and on failure (the folder then stays, holding only the user's file)."""
    import bayes_imu.report.plots

    out = tmp_path / "out"
    real = bayes_imu.report.plots.plot_allan

    def user_saves_notes(*args, **kwargs):
        assert out.is_dir()  # claimed before the work
        (out / "notes.txt").write_text("mine")
        return real(*args, **kwargs)

    monkeypatch.setattr(bayes_imu.report.plots, "plot_allan", user_saves_notes)
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--quiet"]
    assert main(args + ["--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".bayes_imu.json",
        "allan.csv",
        "allan.png",
        "notes.txt",
    ]

    def fails_after_notes(*args, **kwargs):
        (tmp_path / "out2" / "notes.txt").write_text("mine")
        raise ValueError("boom")

    # a failure that is not a picture's (a picture's own failure keeps the numbers:
    # tests/test_hostile.py)
    runs = importlib.import_module("bayes_imu.report.runs")  # where the run draws its picture
    monkeypatch.setattr(runs, "draw_picture", fails_after_notes)
    assert main(args + ["--out", str(tmp_path / "out2")]) == 1
    assert sorted(p.name for p in (tmp_path / "out2").iterdir()) == ["notes.txt"]


def test_kalibr_never_overwrites_its_input(tmp_path, capsys):
    """kalibr --out pointing at a fit folder's own summary.json, even with --force: refused, the
    fit folder byte-identical (an output may never be an input)."""
    rows = np.random.default_rng(5).standard_normal((2**12, 2))
    log = tmp_path / "imu.csv"
    log.write_text("g,a\n" + "".join(f"{g:.6f},{a:.6f}\n" for g, a in rows))
    for column, units in (("g", "deg/s"), ("a", "g")):
        assert (
            main(
                [
                    "fit",
                    str(log),
                    "--column",
                    column,
                    "--rate",
                    "100",
                    "--units",
                    units,
                    "--terms",
                    "white",
                    "--out",
                    str(tmp_path / column),
                    "--quiet",
                ]
            )
            == 0
        )
    before = _snapshot(tmp_path / "g")
    assert main(["kalibr", "--gyro", str(tmp_path / "g"), "--accel", str(tmp_path / "a"),
                 "--out", str(tmp_path / "g" / "summary.json"), "--force"]) == 2
    assert "is or contains the input" in capsys.readouterr().err
    assert _snapshot(tmp_path / "g") == before


def test_output_is_a_file_or_holds_the_input(tmp_path, log, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(target)]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    # --force on the folder holding the log would delete the log: always refused
    assert (
        main(
            [
                "allan",
                str(log),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(log.parent),
                "--force",
            ]
        )
        == 2
    )
    assert "is or contains the input" in capsys.readouterr().err and log.read_text() == GOOD


def test_failure_while_writing_leaves_nothing_and_keeps_old_output(
    tmp_path, log, capsys, monkeypatch
):
    """An error after some outputs were written: no partial folder, and --force keeps the old
    results."""

    def broken(*args, **kwargs):
        raise OSError("disk full")

    runs = importlib.import_module("bayes_imu.report.runs")  # where the run draws its picture
    monkeypatch.setattr(runs, "draw_picture", broken)
    out = tmp_path / "deep" / "new" / "out"
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--quiet"]
    assert main(args + ["--out", str(out)]) == 1
    assert "internal error: OSError: disk full" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]  # created parents removed too
    old = tmp_path / "old"
    monkeypatch.undo()
    assert main(args + ["--out", str(old)]) == 0  # a previous result
    before = _snapshot(old)
    monkeypatch.setattr(runs, "draw_picture", broken)
    assert main(args + ["--out", str(old), "--force"]) == 1
    assert _snapshot(old) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "old"]


def test_interrupt_leaves_nothing(tmp_path, log, monkeypatch):
    import bayes_imu.report.plots

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bayes_imu.report.plots, "plot_allan", interrupted)
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "out")])
        == 130
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_text_saved_with_a_binary_suffix_is_refused(tmp_path, capsys):
    """A text log named .bin would be read as floats (ADEV 1e20): refused in one line."""
    path = tmp_path / "log.bin"
    path.write_text(GOOD)
    assert main(["allan", str(path), "--rate", "100", "--out", str(tmp_path / "out")]) == 2
    assert "starts like text" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_pipe_without_writer_is_refused_not_waited_on(tmp_path, capsys):
    """A named pipe with no writer used to hang the read: now one line, exit 2, nothing written."""
    import os

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    assert (
        main(
            ["allan", str(fifo), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "out")]
        )
        == 2
    )
    assert (
        "a named pipe with no writer" in capsys.readouterr().err and not (tmp_path / "out").exists()
    )


@pytest.mark.parametrize("content", ["bad value", "corrupt gzip"])
def test_an_error_in_standard_input_names_it_not_its_temporary_copy(tmp_path, monkeypatch, capsys,
                                                                    content):
    """A bad value or a corrupt gzip piped to '-': exit 2 and one line that starts with '-' (what
    the user gave), never the path of the temporary copy the command spooled it to."""
    import io
    import sys

    data = (GOOD.replace("\n", "\n2.x\n", 3).encode() if content == "bad value"
            else gzip.compress(GOOD.encode())[:40])
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    capsys.readouterr()
    assert main(["fit", "-", "--column", "gx", "--rate", "100", "--quiet",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bayes-imu: error: -: ") and "\n" not in err, err
    assert "bayes-imu-input-" not in err and "stdin.csv" not in err, err


def test_stdin_and_pipes_are_read_as_streams(tmp_path, monkeypatch):
    """'-' reads standard input and a named pipe is read as its writer streams: the same allan.csv
    as the file itself; the summary names the source; no temporary copy is left behind."""
    import io
    import os
    import sys
    import tempfile
    import threading

    log = tmp_path / "log.csv"
    log.write_text(GOOD)
    args = ["allan", "--column", "gx", "--rate", "100", "--quiet", "--out"]
    assert main([args[0], str(log), *args[1:], str(tmp_path / "file")]) == 0
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(GOOD.encode())))
    assert main([args[0], "-", *args[1:], str(tmp_path / "stdin")]) == 0
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    # the writer must hold the pipe open before the command looks (a pipe with no writer is refused
    # at once): a placeholder reader lets its open return, and the command starts once it has
    placeholder = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    opened = threading.Event()

    def write():
        with open(fifo, "w") as f:
            opened.set()
            f.write(GOOD)

    writer = threading.Thread(target=write)
    writer.start()
    try:
        assert opened.wait(10)
        assert main([args[0], str(fifo), *args[1:], str(tmp_path / "pipe")]) == 0
    finally:
        writer.join()
        os.close(placeholder)
    reference = (tmp_path / "file" / "allan.csv").read_text()
    assert (tmp_path / "stdin" / "allan.csv").read_text() == reference
    assert (tmp_path / "pipe" / "allan.csv").read_text() == reference
    assert not list(Path(tempfile.gettempdir()).glob("bayes-imu-input-*"))


def test_a_warning_about_a_piped_log_names_standard_input(tmp_path, monkeypatch, capsys):
    """A step in a log read from standard input is warned of as '-', the name the user gave, not
    as the temporary copy the command spools it to (which it used to name)."""
    import io
    import sys

    x = np.random.default_rng(0).standard_normal(3000)
    x[1000:] += 20
    text = "gx\n" + "".join(f"{v:.6f}\n" for v in x)
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(text.encode())))
    assert main(["allan", "-", "--column", "gx", "--rate", "100", "--quiet", "--out",
                 str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("bayes-imu: warning: -: column 'gx': its level steps by"), err
    assert "stdin.csv" not in err and "bayes-imu-input" not in err


@pytest.mark.parametrize("kind", ["preamble", "long_line"])
def test_long_preamble_and_long_lines_are_read(tmp_path, kind):
    """A 90 KB comment preamble, or a header line longer than the sniffing window, used to read as
    'no data rows': the values now equal those of the clean file."""
    from bayes_imu.io import readers
    from bayes_imu.io.readers import read_columns

    clean = tmp_path / "clean.csv"
    clean.write_text(GOOD)
    odd = tmp_path / "odd.csv"
    if kind == "preamble":
        odd.write_text("".join(f"# note {i:06d} {'x' * 80}\n" for i in range(1000)) + GOOD)
    else:
        header = "time,gx,gy," + ",".join(f"extra{i}" for i in range(8000))
        assert len(header) > 1.2 * readers._SNIFF_BYTES  # longer than the first sniffing window
        odd.write_text(header + "\n"
                       + "\n".join(row + ",0" * 8000 for row in GOOD.splitlines()[1:]) + "\n")
    ref = read_columns(clean, columns=["gx"]).values
    np.testing.assert_array_equal(read_columns(odd, columns=["gx"]).values, ref)


def test_headerless_quoted_numbers_keep_every_sample(tmp_path):
    """'"1.5","2.5"' rows: quoted numbers are numbers, not a header (the first sample used to be
    lost)."""
    from bayes_imu.io.readers import read_columns

    path = tmp_path / "q.csv"
    rows = [(np.sin(i), np.cos(i)) for i in range(50)]
    path.write_text("".join(f'"{a:.6f}","{b:.6f}"\n' for a, b in rows))
    np.testing.assert_allclose(
        read_columns(path, columns=["1"]).values[:, 0], [round(b, 6) for _, b in rows]
    )


def test_sigterm_is_handled_like_ctrl_c(tmp_path, log, capsys, monkeypatch):
    """SIGTERM during the work: one line, exit 143, the claimed folder and created parents
    removed."""
    import os
    import signal

    import bayes_imu.report.plots

    def terminated(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(bayes_imu.report.plots, "plot_allan", terminated)
    out = tmp_path / "new" / "out"
    assert main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out)]) == 143
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "terminated (SIGTERM)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL or callable(
        signal.getsignal(signal.SIGTERM)
    )


def test_disk_full_while_writing_keeps_the_previous_result(tmp_path, log, capsys, monkeypatch):
    """ENOSPC while the outputs are written: one line naming the folder, exit 2, the previous
    result byte-identical, no staging folder left."""
    import errno

    import bayes_imu.report.plots

    out = tmp_path / "out"
    args = ["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(out), "--quiet"]
    assert main(args) == 0
    before = _snapshot(tmp_path)

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(bayes_imu.report.plots, "plot_allan", full)
    assert main(args + ["--force"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {out}: the disk is full" in err
    assert _snapshot(tmp_path) == before


def test_low_disk_space_refused_before_any_work(tmp_path, log, capsys, monkeypatch):
    """Too little free space on the target's file system: one line, exit 2, nothing created."""
    import shutil

    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=10 * 2**20))
    assert (
        main(["allan", str(log), "--column", "gx", "--rate", "100", "--out", str(tmp_path / "out")])
        == 2
    )
    assert "MiB free" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_time_column_rate_and_units_in_outputs(tmp_path, log):
    out = tmp_path / "out"
    assert main(["allan", str(log), "--column", "gy", "--time-column", "time", "--units", "deg/s",
                 "--out", str(out), "--quiet"]) == 0
    rows = [r.split(",") for r in (out / "allan.csv").read_text().splitlines()]
    assert rows[0] == ["tau", "m", "adev", "adev_low", "adev_high", "edf", "unit"]
    assert float(rows[1][0]) == pytest.approx(0.01, rel=1e-9) and rows[1][6] == "rad/s"
    # the same column read in deg/s without conversion: ADEV scales by exactly pi/180
    assert (
        main(
            [
                "allan",
                str(log),
                "--column",
                "gy",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "raw"),
                "--quiet",
            ]
        )
        == 0
    )
    raw = [r.split(",") for r in (tmp_path / "raw" / "allan.csv").read_text().splitlines()]
    np.testing.assert_allclose(
        [float(r[2]) for r in rows[1:]], [float(r[2]) * np.pi / 180 for r in raw[1:]], rtol=1e-8
    )
    assert raw[1][6] == "u"


def test_gaps_longest_fits_segment_and_says_so(tmp_path):
    rng = np.random.default_rng(5)
    t = np.arange(3000) / 100.0
    t[1000:] += 2.0
    path = tmp_path / "gappy.csv"
    path.write_text(
        "t;g\n" + "\n".join(f"{a:.2f};{b:.6f}" for a, b in zip(t, rng.standard_normal(3000))) + "\n"
    )
    out = tmp_path / "out"
    assert (
        main(
            [
                "fit",
                str(path),
                "--column",
                "g",
                "--time-column",
                "t",
                "--gaps",
                "longest",
                "--terms",
                "white",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    info = json.loads((out / "summary.json").read_text())["input"]
    assert (
        info["samples_used"] == 2000
        and info["dropped_samples"] == 1000
        and info["irregular_steps"] == 1
    )
    assert info["first_line"] == 1002 and info["rate_source"] == "time column"
    assert "longest regular segment" in info["action"]
    assert json.loads((out / "summary.json").read_text())["n_samples"] == 2000


def test_kalibr_output_is_staged(tmp_path, capsys):
    target = tmp_path / "imu.yaml"
    target.write_text("old")
    missing = tmp_path / "nofit"
    assert (
        main(["kalibr", "--gyro", str(missing), "--accel", str(missing), "--out", str(target)]) == 2
    )
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == [
        "imu.yaml"
    ]
