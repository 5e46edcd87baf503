"""Reading logs: every accepted form gives the same numbers; every malformed file one precise error.

Reference for the valid forms: the same samples written as a plain comma-separated file
with a header; the values must be bit-identical (the text holds the same decimal strings).
"""

import gzip
import re

import numpy as np
import pytest

from bayes_imu.errors import InputError
from bayes_imu.io.readers import MAX_MAGNITUDE, check_signal, read_columns, read_log


@pytest.fixture
def samples(rng):
    return np.round(rng.standard_normal((200, 2)), 6)


def _rows(values, sep=",", fmt="{:.6f}"):
    return [sep.join(fmt.format(v) for v in row) for row in values]


def _plain(tmp_path, values):
    path = tmp_path / "plain.csv"
    path.write_text("gx,gy\n" + "\n".join(_rows(values)) + "\n", encoding="utf-8")
    return read_columns(path, columns=["gx", "gy"]).values


VALID = {
    "bom_crlf_spaces_blank_tail": lambda v: (
        "\ufeff gx , gy \r\n"
        + "\r\n".join(" " + r.replace(",", " , ") + " " for r in _rows(v))
        + "\r\n\r\n\r\n"
    ).encode("utf-8"),
    "semicolon": lambda v: ("gx;gy\n" + "\n".join(_rows(v, ";")) + "\n").encode(),
    "tab": lambda v: ("gx\tgy\n" + "\n".join(_rows(v, "\t")) + "\n").encode(),
    "whitespace_runs": lambda v: ("gx   gy\n" + "\n".join(_rows(v, "   ")) + "\n").encode(),
    "comments_everywhere": lambda v: (
        "# logger 1.2\n# rate 100 Hz\ngx,gy\n"
        + "\n".join(
            r + ("  # note" if i % 7 == 0 else "") + ("\n# pause" if i == 50 else "")
            for i, r in enumerate(_rows(v))
        )
        + "\n"
    ).encode(),
    "gzip_without_gz_suffix": lambda v: gzip.compress(
        ("gx,gy\n" + "\n".join(_rows(v)) + "\n").encode()
    ),
    "no_trailing_newline": lambda v: ("gx,gy\n" + "\n".join(_rows(v))).encode(),
    "text_column_elsewhere": lambda v: (
        "status,gx,gy\n" + "\n".join("ok," + r for r in _rows(v)) + "\n"
    ).encode(),
    "trailing_delimiter": lambda v: (
        "gx,gy,\n" + "\n".join(r + "," for r in _rows(v)) + "\n"
    ).encode(),
}


@pytest.mark.parametrize("form", sorted(VALID))
def test_unusual_but_valid_files_read_identically(tmp_path, samples, form):
    path = tmp_path / "log.dat"
    path.write_bytes(VALID[form](samples))
    got = read_columns(path, columns=["gx", "gy"]).values
    np.testing.assert_array_equal(got, _plain(tmp_path, samples))


# the same forms with a third column: numpy's wide path (the wanted columns and the last one)
WIDE_VALID = {
    "bom_crlf_spaces_blank_tail": lambda v: (
        "\ufeff gx , gy , gz \r\n"
        + "\r\n".join(" " + r.replace(",", " , ") + " , 0.5 " for r in _rows(v))
        + "\r\n\r\n\r\n"
    ).encode("utf-8"),
    "semicolon": lambda v: (
        "gx;gy;gz\n" + "\n".join(r + ";7" for r in _rows(v, ";")) + "\n"
    ).encode(),
    "tab": lambda v: (
        "gx\tgy\tgz\n" + "\n".join(r + "\t-1e3" for r in _rows(v, "\t")) + "\n"
    ).encode(),
    "comments_everywhere": lambda v: (
        "# logger 1.2\n# rate 100 Hz\ngx,gy,gz\n"
        + "\n".join(
            r + ",0" + ("  # note" if i % 7 == 0 else "") + ("\n# pause" if i == 50 else "")
            for i, r in enumerate(_rows(v))
        )
        + "\n"
    ).encode(),
    "gzip_without_gz_suffix": lambda v: gzip.compress(
        ("gx,gy,gz\n" + "\n".join(r + ",1" for r in _rows(v)) + "\n").encode()
    ),
    "no_trailing_newline": lambda v: (
        "gx,gy,gz\n" + "\n".join(r + ",2" for r in _rows(v))
    ).encode(),
}


@pytest.mark.parametrize("form", sorted(WIDE_VALID))
def test_unusual_but_valid_wide_files_read_identically_by_numpy(tmp_path, samples, form):
    """The valid forms above with a third column: read by numpy's wide path (except where a comment
    line comes before the header: pandas' path), with the plain file's values."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_plain, sniff_file

    path = tmp_path / "log.dat"
    path.write_bytes(WIDE_VALID[form](samples))
    np.testing.assert_array_equal(
        read_columns(path, columns=["gx", "gy"]).values, _plain(tmp_path, samples)
    )
    with progress_bar(total=1, enabled=False) as bar:
        taken = _parse_plain(path, sniff_file(path), [0, 1], bar)
    assert (taken is None) == (form == "comments_everywhere")


def test_no_header_columns_by_index(tmp_path, samples):
    path = tmp_path / "nohead.csv"
    path.write_text("\n".join(_rows(samples)) + "\n")
    data = read_columns(path, columns=[1, "0"])
    assert not data.header and data.columns == ("1", "0")
    np.testing.assert_array_equal(data.values, _plain(tmp_path, samples)[:, ::-1])


def test_header_column_by_index_and_time_lines(tmp_path, samples):
    path = tmp_path / "t.csv"
    text = (
        "# c\ntime,gx,gy\n"
        + "\n".join(f"{i / 100:.2f}," + r for i, r in enumerate(_rows(samples)))
        + "\n"
    )
    path.write_text(text)
    data = read_log(path, column=2, time_column="time")
    assert data.column == "gy"
    np.testing.assert_array_equal(data.values, samples[:, 1])
    np.testing.assert_array_equal(data.lines, np.arange(3, 3 + len(samples)))  # 1-based file lines
    np.testing.assert_allclose(data.time_s, np.arange(len(samples)) / 100, atol=1e-12)


def test_real_adis_log_reads_every_channel():
    from conftest import shared_file

    path = shared_file("smac_imudata", "adis_16405_imu1.csv.gz")
    data = read_columns(path, columns=["gyro_x_dps", "accel_z_g"])
    assert data.values.shape == (1_000_000, 2)
    # SOURCE.md: gyro values are multiples of the 0.05 deg/s LSB; accel z reads about -1.017 g
    np.testing.assert_allclose(
        data.values[:, 0] / 0.05, np.round(data.values[:, 0] / 0.05), atol=1e-6
    )
    assert -1.03 < np.mean(data.values[:, 1]) < -1.0


MALFORMED = [  # (name, bytes, column, message fragment)
    ("empty", b"", "b", "empty file"),
    ("header_only", b"a,b\n", "b", "a header row but no samples"),
    ("only_comments", b"# nothing\n\n# here\n", "b", "no data rows"),
    (
        "nan",
        b"a,b\n1,2\n3,nan\n4,5\n",
        "b",
        "line 3, column 'b': got 'nan'; expected a finite number",
    ),
    ("inf", b"a,b\n1,2\n3,-inf\n4,5\n", "b", "line 3, column 'b': got '-inf'"),
    ("overflowing_literal", b"a,b\n1,2\n3,1e400\n4,5\n", "b", "got '1e400'"),
    ("text", b"a,b\n1,2\n# c\n3,abc\n4,5\n", "b", "line 4, column 'b': got 'abc'"),
    ("empty_field", b"a,b\n1,2\n3,\n4,5\n", "b", "line 3, column 'b': got an empty field"),
    (
        "missing_column",
        b"a,b\n1,2\n3,4\n",
        "zz",
        "no column 'zz'; expected one of the header names ('a', 'b')",
    ),
    (
        "index_out_of_range",
        b"a,b\n1,2\n3,4\n",
        "9",
        "column index 9 out of range; the file has 2 columns",
    ),
    (
        "ragged_long",
        b"a,b\n1,2\n3,4\n5,6,7\n8,9\n",
        "a",
        "line 4: 3 fields; expected 2 (as in the header)",
    ),
    ("ragged_short", b"a,b\n1,2\n3\n8,9\n", "b", "line 3: 1 field; expected 2"),
    ("constant", b"a,b\n1,2\n3,2\n4,2\n", "b", "constant signal (all 3 samples are 2.0)"),
    (
        "absurd_magnitude",
        b"a,b\n1,2\n3,1e150\n4,5\n",
        "b",
        f"expected |value| <= {MAX_MAGNITUDE:g}",
    ),
    ("underflowing_spread", b"a,b\n1,1e-300\n3,2e-300\n4,0\n", "b", "underflow"),
    ("binary", bytes(range(256)) * 8, "b", "binary data (NUL byte at offset 0)"),
    (
        "not_utf8",
        "a,b\u00b0\n1,2\n".encode("latin-1"),
        "b",
        "not UTF-8 text (byte 0xb0 at offset 3)",
    ),
    ("duplicate_header", b"a,b,b\n1,2,3\n4,5,6\n", "b", "column name 'b' appears more than once"),
]


@pytest.mark.parametrize("name, content, column, message", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_files_give_one_precise_line(tmp_path, name, content, column, message):
    path = tmp_path / f"{name}.csv"
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_log(path, column=column)
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(path)) and message in text, text


@pytest.mark.parametrize("damage", ["cut", "length", "checksum"])
def test_corrupt_gzip_is_reported(tmp_path, rng, damage):
    """A gzip file cut in half, or with its trailer's length or checksum overwritten: one line that
    names the file, says it is a corrupt or truncated gzip file and what was expected, with gzip's
    own words in brackets (random content does not compress: the cut lands inside the data
    stream). (Bytes changed inside the data may still inflate, to text that is then refused where
    it stops being numbers.)"""
    body = "a,b\n" + "\n".join(f"{x:.9f},{y:.9f}" for x, y in rng.standard_normal((20000, 2)))
    blob = bytearray(gzip.compress(body.encode()))
    if damage == "cut":
        blob = blob[: len(blob) // 2]
    elif damage == "length":
        blob[-4:] = (12345).to_bytes(4, "little")
    else:
        blob[-8:-4] = bytes(4)
    path = tmp_path / "bad.csv.gz"
    path.write_bytes(bytes(blob))
    with pytest.raises(InputError) as info:
        read_log(path, column="b")
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{path}: a corrupt or truncated gzip file (")
    assert text.endswith("expected a complete gzip stream (a copy cut short, or changed bytes?)")


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_log(tmp_path / "nope.csv", column="a")
    with pytest.raises(InputError, match="is a directory; expected a CSV file"):
        read_log(tmp_path, column="a")


def test_same_column_twice_is_refused(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("a,b\n1,2\n3,4\n")
    with pytest.raises(InputError, match="asked for twice"):
        read_columns(path, columns=["a", "0"])


def test_check_signal_accepts_gravity_offset_tiny_noise(rng):
    """An accelerometer axis reading gravity with micro-g noise is an ordinary signal."""
    check_signal(9.80665 + 1e-7 * rng.standard_normal(1000), where="z")


@pytest.mark.parametrize("form", sorted(VALID))
def test_unusual_but_valid_files_through_the_command(tmp_path, samples, form, capsys):
    """Exit status 0, nothing on stderr, and the same allan.csv as the plain CSV."""
    from bayes_imu.cli.main import main

    plain = tmp_path / "plain.csv"
    plain.write_text("gx,gy\n" + "\n".join(_rows(samples)) + "\n", encoding="utf-8")
    path = tmp_path / "log.dat"
    path.write_bytes(VALID[form](samples))
    for log, out in ((plain, "a"), (path, "b")):
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
                    str(tmp_path / out),
                    "--quiet",
                ]
            )
            == 0
        )
    assert capsys.readouterr().err == ""
    assert (tmp_path / "a" / "allan.csv").read_text() == (tmp_path / "b" / "allan.csv").read_text()


def _both_parsers(path):
    """(numpy's fast path or None, pandas' path) of every column of ``path``."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_pandas, _parse_plain, sniff_file

    fmt = sniff_file(path)
    columns = list(range(len(fmt["names"])))
    with progress_bar(total=1, enabled=False) as bar:
        plain = _parse_plain(path, fmt, columns, bar)
    return plain, _parse_pandas(path, fmt, columns, False)


def test_fast_path_reads_the_shipped_and_real_logs_as_pandas_does():
    """numpy's reader (the fast path, no pandas import) against pandas' C reader on every shipped
    log and on two real logs where ../shared has them: it takes every one of these plain tables, and
    gives the same float64 values, bit for bit."""
    from pathlib import Path

    from conftest import SHARED_DATA

    from bayes_imu._progress import progress_bar
    from bayes_imu.io import readers

    logs = sorted((Path(__file__).resolve().parents[1] / "data_synthetic").glob("*.csv.gz"))
    logs += [
        p
        for p in (SHARED_DATA / "smac_imudata" / f"adis_16405_imu{i}.csv.gz" for i in (1, 4))
        if p.exists()
    ]
    assert len(logs) >= 7
    for path in logs:
        # the real logs' six columns: the wide path, every column asked for
        plain, pandas = _both_parsers(path)
        assert plain is not None, path
        np.testing.assert_array_equal(plain.view(np.int64), pandas.view(np.int64))
        # one column of six: the wanted one and the last converted
        if path.parent.name == "smac_imudata":
            fmt = readers.sniff_file(path)
            with progress_bar(total=1, enabled=False) as bar:
                one = readers._parse_plain(path, fmt, [2], bar)
            np.testing.assert_array_equal(one.view(np.int64), pandas[:, [2]].view(np.int64))


#: fields the fast path takes (same value as pandas); fields it leaves to pandas, which reads
#: them (quotes, an empty field, a decimal comma) or refuses them (underscores, hex, Fortran
#: exponents, text)
_FAST_FIELDS = ["1.0 ", " 2.5", "+1", ".5", "5.", "1e5", "-0", "4.9e-325", "1E+400", "Infinity",
                "0.1000000000000000055511151231257827"]
_PANDAS_READS = ['"1.5"', "", "1,5"]
_REFUSED = ["1_000", "0x10", "1.0d0", "1.0abc"]


@pytest.mark.parametrize("field", _FAST_FIELDS + _PANDAS_READS + _REFUSED)
def test_fast_path_agrees_with_pandas_or_leaves_the_file_to_it(tmp_path, field):
    """A field numpy reads has pandas' value; one it refuses (underscores, hex, quotes, an empty
    field, a decimal comma, text) sends the whole file to pandas' path, so nothing is read
    differently than before; each field's outcome is stated, so no case passes without an
    assertion."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_pandas, _parse_plain, sniff_file

    path = tmp_path / "log.csv"
    path.write_text(f"a,b\n1.0,{field}\n2.0,3.0\n")
    fmt = sniff_file(path)
    columns = list(range(len(fmt["names"])))
    with progress_bar(total=1, enabled=False) as bar:
        plain = _parse_plain(path, fmt, columns, bar)
    assert (plain is not None) == (field in _FAST_FIELDS)
    if field in _REFUSED:
        with pytest.raises(InputError):
            _parse_pandas(path, fmt, columns, False)
        return
    pandas = _parse_pandas(path, fmt, columns, False)
    assert pandas.shape == (2, 2)
    if plain is not None:
        np.testing.assert_array_equal(plain, pandas)


def test_fast_path_leaves_ragged_and_commented_preambles_to_pandas(tmp_path):
    """A row with an extra field or a comment line before the header: not the fast path's; it
    returns None and the file is read (or refused) by pandas' path as before."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_plain, sniff_file

    cases = {
        "ragged.csv": "a,b\n1,2\n3,4,5\n6,7\n",
        "preamble.csv": "# logged today\na,b\n1,2\n3,4\n",
    }
    for name, text in cases.items():
        path = tmp_path / name
        path.write_text(text)
        fmt = sniff_file(path)
        with progress_bar(total=1, enabled=False) as bar:
            assert _parse_plain(path, fmt, [0, 1], bar) is None, name
    np.testing.assert_array_equal(
        read_columns(tmp_path / "preamble.csv", columns=["a", "b"]).values, [[1.0, 2.0], [3.0, 4.0]]
    )


_TAIL = "".join(f"{i},{i + 1},{i + 2}\n" for i in range(30))  # rows past the sniffer's first twenty
#: wide logs (more than PLAIN_COLUMNS columns) the fast path reads: (text, columns asked for)
WIDE_READ = {
    "plain": ("a,b,c\n1,2,3\n4,5,6\n", [0]),
    "columns_out_of_order": ("a,b,c,d\n1,2,3,4\n5,6,7,8\n", [3, 0, 2]),
    "no_header": ("1,2,3\n4,5,6\n", [1]),
    "semicolon": ("a;b;c\n1.5;2;3\n4;5;6\n", [0, 2]),
    "tab": ("a\tb\tc\n1\t2\t3\n4\t5\t6\n", [1]),
    "text_and_empty_inside": ("t,status,y\n1,ok,3\n2,,4\n3,\"fine\",5\n", [0, 2]),
    "blank_lines_crlf_comments": ("a,b,c\r\n\r\n1,2,3  # note\r\n# pause\r\n4,5,6\r\n\r\n", [0, 1]),
}
#: wide logs it leaves to pandas (which reads them as before, or refuses them with its message)
WIDE_LEFT = {
    "row_too_long": "a,b,c\n1,2,3,4\n5,6,7\n",
    "row_too_short": "a,b,c\n1,2\n4,5,6\n",
    "long_and_short_rows": "a,b,c\n1,2,3,4\n5,6\n7,8,9\n",
    "quoted_delimiter": "a,b,c\n1,\"x,y\",3\n4,5,6\n",
    "delimiter_in_comment": "a,b,c\n1,2,3  # note, here\n4,5,6\n",
    "text_in_last_column": "a,b,c\n1,2,ok\n4,5,ok\n",
    "text_in_last_column_late": "a,b,c\n" + _TAIL + "1,2,ok\n",
    "empty_last_field_late": "a,b,c\n" + _TAIL + "1,2,\n",
    "whitespace": "a b c\n1 2 3\n4 5 6\n",
    "trailing_delimiter": "a,b,c,\n1,2,3,\n4,5,6,\n",
}


@pytest.mark.parametrize("name", sorted(WIDE_READ))
def test_fast_path_reads_wide_logs_as_pandas_does(tmp_path, name):
    """A log wider than PLAIN_COLUMNS: numpy converts the wanted columns and the last one and counts
    the delimiters; it reads these files, with pandas' values, in the order asked for."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_pandas, _parse_plain, sniff_file

    text, columns = WIDE_READ[name]
    path = tmp_path / "log.csv"
    path.write_bytes(text.encode())
    fmt = sniff_file(path)
    with progress_bar(total=1, enabled=False) as bar:
        plain = _parse_plain(path, fmt, columns, bar)
    assert plain is not None
    np.testing.assert_array_equal(plain, _parse_pandas(path, fmt, columns, False))


@pytest.mark.parametrize("name", sorted(WIDE_LEFT))
def test_fast_path_leaves_ragged_quoted_or_textual_wide_logs_to_pandas(tmp_path, name):
    """A wide row longer or shorter than the header (alone or two that make up each other's count),
    a delimiter inside quotes or a comment, text or nothing in the last column, runs of blanks as
    the delimiter: None, and the reader gives what pandas' path gives (the values or its one-line
    error)."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_pandas, _parse_plain, sniff_file

    path = tmp_path / "log.csv"
    path.write_bytes(WIDE_LEFT[name].encode())
    fmt = sniff_file(path)
    with progress_bar(total=1, enabled=False) as bar:
        assert _parse_plain(path, fmt, [0], bar) is None
    try:
        expected = _parse_pandas(path, fmt, [0], False)
    except InputError as exc:
        with pytest.raises(InputError, match="^" + re.escape(str(exc)) + "$"):
            read_columns(path, columns=["0" if not fmt["header"] else fmt["names"][0]])
        return
    np.testing.assert_array_equal(read_columns(path, columns=[fmt["names"][0]]).values, expected)


def test_numpy_is_tried_first_unless_pandas_is_loaded_and_reads_three_columns_or_more(monkeypatch):
    """The reader's choice of path (a matter of speed only: both give the same values, tested
    above)."""
    import sys

    from bayes_imu.io.readers import _numpy_first

    wide, narrow = {"names": ["t", "a", "b", "c"]}, {"names": ["t", "a"]}
    monkeypatch.setitem(sys.modules, "pandas", sys.modules.get("pandas", object()))
    assert _numpy_first(narrow, [0, 1]) and _numpy_first(wide, [1]) and _numpy_first(wide, [3])
    assert not _numpy_first(wide, [0, 1]) and not _numpy_first(wide, [0, 1, 2, 3])
    monkeypatch.delitem(sys.modules, "pandas")
    assert _numpy_first(wide, [0, 1, 2, 3])


def test_fast_path_on_random_wide_logs_agrees_with_pandas(tmp_path, rng):
    """Random small wide logs (rows of 2-5 fields under a 4-field header; numbers, text, empty,
    quoted fields): wherever the fast path reads one, pandas' path reads it too, to the same values;
    where pandas refuses it (a row too long), the fast path never reads it."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.readers import _parse_pandas, _parse_plain, sniff_file

    pieces = ["1", "-2.5", "3e2", "", "x", '"4"', '"5,6"']
    weights = np.array([6, 6, 6, 1, 1, 1, 1]) / 22.0
    read = 0
    for k in range(300):
        # numeric first rows: the sniffer sees four clean columns
        rows = ["a,b,c,d"] + ["1,2,3,4"] * 3
        for _ in range(int(rng.integers(1, 4))):
            n = int(rng.choice([3, 4, 4, 4, 4, 4, 5]))
            rows.append(
                ",".join(
                    str(rng.choice(pieces, p=weights)) if j else str(rng.integers(9))
                    for j in range(n)
                )
            )
        path = tmp_path / f"log{k}.csv"
        path.write_text("\n".join(rows) + "\n")
        fmt = sniff_file(path)
        with progress_bar(total=1, enabled=False) as bar:
            plain = _parse_plain(path, fmt, [0], bar)
        if plain is None:
            continue
        read += 1
        np.testing.assert_array_equal(plain, _parse_pandas(path, fmt, [0], False))
    assert 50 <= read < 300  # both kinds happened (about 80-100 read with seeds 0-2)
