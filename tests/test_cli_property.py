"""Property test of the command line over mutated logs and argument lists (hypothesis).

Invariant of every run: exit 0, or exit 2 with exactly one line on stderr; never exit 1 or a
traceback; nothing written outside ``--out``; the input byte-identical. Mutations that keep the
data (comments, blank lines, CRLF, a BOM, quotes, padding, gzip) must give exit 0 and the same
``allan.csv`` as the clean log.
"""

import gzip
import hashlib

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bayes_imu.cli.main import main

ROWS = [f"{i / 100:.2f},{np.sin(i * 1.3):.6f},{np.cos(i * 0.7):.6f}" for i in range(300)]
CLEAN = ("time,gx,gy\n" + "\n".join(ROWS) + "\n").encode()


def _neutral(kind, data):
    text = data.decode()
    if kind == "comments":
        return (
            "# exported by a logger\n# units: deg/s\n" + text.replace("\n", "  # ok\n", 5)
        ).encode()
    if kind == "blank_lines":
        return text.replace("\n", "\n\n", 7).encode()
    if kind == "crlf":
        return text.replace("\n", "\r\n").encode()
    if kind == "bom":
        return b"\xef\xbb\xbf" + data
    if kind == "quotes":
        lines = text.splitlines()
        return (
            "\n".join(
                [lines[0]] + [",".join(f'"{f}"' for f in line.split(",")) for line in lines[1:]]
            )
            + "\n"
        ).encode()
    if kind == "padding":
        return text.replace(",", " , ").encode()
    return gzip.compress(data, mtime=0)


def _snapshot(folder):
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        if p.is_file()
        else "dir"
        for p in sorted(folder.rglob("*"))
    }


def _run(folder, data, extra, capsys):
    log = folder / "in" / "log.csv"
    log.parent.mkdir(exist_ok=True)
    log.write_bytes(data)
    out = folder / "out"
    before = _snapshot(folder)
    status = main(["allan", str(log), "--out", str(out), "--quiet"] + extra)
    err = capsys.readouterr().err
    assert status in (0, 2), err
    assert "Traceback" not in err
    if status == 2:
        assert err.count("\n") == 1 and err.startswith("bayes-imu: error: "), err
        assert _snapshot(folder) == before
    else:
        after = _snapshot(folder)
        # input untouched
        assert {k: v for k, v in after.items() if not k.startswith("out")} == before
    return status, (out / "allan.csv").read_text() if status == 0 else None


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    kind=st.sampled_from(["comments", "blank_lines", "crlf", "bom", "quotes", "padding", "gzip"])
)
def test_neutral_mutations_give_the_clean_result(tmp_path_factory, capsys, kind):
    args = ["--column", "gx", "--rate", "100"]
    _, clean = _run(tmp_path_factory.mktemp("clean"), CLEAN, args, capsys)
    status, mutated = _run(tmp_path_factory.mktemp("mutated"), _neutral(kind, CLEAN), args, capsys)
    assert status == 0 and mutated == clean


ARGS = st.lists(
    st.sampled_from(
        [
            ["--column", "gx"],
            ["--column", "gy"],
            ["--column", "2"],
            ["--column", "nope"],
            ["--column", "gx,gy"],
            ["--rate", "100"],
            ["--rate", "0"],
            ["--rate", "-3"],
            ["--rate", "1e300"],
            ["--rate", "x"],
            ["--time-column", "time"],
            ["--time-column", "gx"],
            ["--gaps", "longest"],
            ["--units", "deg/s"],
            ["--units", "furlong"],
            ["--grid", "decade"],
            ["--grid", "all"],
            ["--force"],
            ["--stream"],
        ]
    ),
    max_size=4,
).map(lambda parts: [a for p in parts for a in p])


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    position=st.integers(0, len(CLEAN) - 1),
    insert=st.binary(max_size=6),
    cut=st.integers(0, 6),
    extra=ARGS,
)
def test_mutated_logs_and_arguments_never_crash(
    tmp_path_factory, capsys, position, insert, cut, extra
):
    data = CLEAN[:position] + insert + CLEAN[position + cut:]
    _run(tmp_path_factory.mktemp("case"), data, extra, capsys)
