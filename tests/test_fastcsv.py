"""The exact fast path of plain delimited logs (bayes_imu.io.fastcsv, io/_sources.parse_table).

References: Python's ``float(str)`` (correctly rounded, David Gay's algorithm) for every field, and
numpy's own reader (the streaming path, forced by removing the kernel) for whole files; a value is
compared bit for bit."""

import gzip

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bayes_imu.io import fastcsv
from bayes_imu.io._sources import parse_table
from bayes_imu.io.readers import read_columns, read_log


def _kernels():
    """The parser as the package runs it (precompiled) and as compiled from its source here."""
    import numba

    out = [numba.njit(parse_table)]
    compiled = fastcsv._kernel()
    if compiled is not None:
        out.append(compiled)
    return out


KERNELS = _kernels()


def _parse(text, n_columns, wanted, header=False, delimiter=","):
    buf = np.frombuffer(text.encode(), dtype=np.uint8)
    results = []
    for kernel in KERNELS:
        out = np.full((text.count("\n") + 1, len(wanted)), np.nan)
        rows = kernel(buf, ord(delimiter), n_columns, int(header), np.asarray(wanted, np.int64),
                      out)
        results.append((rows, out[:max(rows, 0)].copy()))
    for rows, values in results[1:]:  # the precompiled kernel is its source's
        assert rows == results[0][0]
        np.testing.assert_array_equal(values.view(np.int64), results[0][1].view(np.int64))
    return results[0]


def _bits(x):
    return np.asarray(x, dtype=np.float64).view(np.int64)


decimals = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.floats(min_value=-1e6, max_value=1e6, allow_nan=False).map(lambda v: f"{v:.5f}"),
    st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).map(lambda v: f"{v:.9g}"),
    st.floats(min_value=-1e30, max_value=1e30, allow_nan=False).map(lambda v: f"{v:.6e}"),
    st.integers(-10**17, 10**17).map(str),
    st.tuples(st.integers(0, 10**9), st.integers(-25, 25), st.sampled_from(["e", "E"]),
              st.sampled_from(["", "+", "-"])).map(
        lambda t: f"{t[0]}{t[2]}{'-' if t[1] < 0 else t[3].replace('-', '')}{abs(t[1])}"),
    st.sampled_from(["0", "-0", "-0.0", ".5", "5.", "-.25", "+1.5", "00012.500", "0.00333",
                     "1e22", "9007199254740993", "123456789012345678", "1e-22", "2.5E+3"]),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(decimals, min_size=3, max_size=3), min_size=1, max_size=6),
       st.booleans(), st.sampled_from(["\n", "\r\n"]), st.booleans())
def test_each_field_is_the_correctly_rounded_double_or_the_table_is_refused(rows, header, end,
                                                                            last_end):
    """Every field the parser accepts is Python's correctly rounded ``float`` of its text, bit for
    bit; where it refuses (-1), some field lies outside the exact fast path (more than 2**53 in its
    significant digits, or a power of ten beyond 22), never a plain one."""
    lines = (["a,b,c"] if header else []) + [",".join(r) for r in rows]
    text = end.join(lines) + (end if last_end else "")
    n, values = _parse(text, 3, [2, 0], header=header)
    if n == -1:
        assert any(not _exact_path(f) for r in rows for f in r), rows
        return
    assert n == len(rows)
    expected = np.array([[float(r[2]), float(r[0])] for r in rows])
    np.testing.assert_array_equal(_bits(values), _bits(expected))


def _exact_path(field):
    """Whether a decimal lies on the exact fast path, read independently of the parser: its
    significant digits (as written, trailing zeros included) an integer of at most 18 digits and
    at most 2**53, its power of ten within 22."""
    from decimal import Decimal

    d = Decimal(field)
    if d == 0:
        return True
    _, digits, exponent = d.as_tuple()
    return len(digits) <= 18 and int("".join(map(str, digits))) <= 2**53 and abs(exponent) <= 22


@pytest.mark.parametrize(
    "text",
    [
        "1, 2\n",  # a space after the delimiter
        " 1,2\n",
        '"1",2\n',  # quotes
        "# comment\n1,2\n",
        "1,2 # trailing comment\n",
        "nan,2\n",
        "inf,2\n",
        "1,2,3\n",  # a longer row
        "1\n",  # a shorter row
        "1,\n",  # an empty field
        ",2\n",
        "1,2,\n",  # a trailing delimiter
        "1,2\r3,4\n",  # a lone carriage return
        "\ufeff1,2\n",  # a byte-order mark on a data row
        "1e23,2\n",  # beyond 10**22
        "1e-23,2\n",
        "1234567890123456789,2\n",  # 19 significant digits
        "9007199254740993,2\n",  # 2**53 + 1
        "1e,2\n",
        "1.2.3,4\n",
        "-,2\n",
        ".,2\n",
        "0x10,2\n",
        "1;2\n",
    ],
)
def test_anything_off_the_plain_path_is_refused(text):
    """The parser returns -1 (the reader then reads the file as before) for every field or row it
    does not convert exactly."""
    n, _ = _parse(text, 2, [0, 1])
    assert n == -1


def test_empty_lines_are_skipped_and_a_header_is_whatever_it_holds():
    n, values = _parse("time s; gyro (deg/s), x\n\n1,2\r\n\n3,4", 2, [1], header=True)
    assert n == 2
    np.testing.assert_array_equal(values[:, 0], [2.0, 4.0])


def _write(path, text, compress):
    data = text.encode()
    path.write_bytes(gzip.compress(data) if compress else data)


@pytest.mark.parametrize("compress", [False, True])
def test_read_log_gives_numpys_values_bit_for_bit(tmp_path, compress, monkeypatch, rng):
    """read_log through the fast path and through numpy's streaming reader (the kernel removed)
    give the same array, bit for bit, on a six-column log with a header (as the ADIS16405 logs)."""
    values = rng.standard_normal((2000, 6)) * np.array([0.3, 1.0, 50.0, 1e-3, 2e-4, 9.8])
    lines = ["gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z"] + [
        ",".join(f"{v:.{5 + j}g}" for j, v in enumerate(row)) for row in values]
    path = tmp_path / ("log.csv.gz" if compress else "log.csv")
    _write(path, "\n".join(lines) + "\n", compress)
    calls = []
    real = fastcsv._kernel()
    if real is None:
        pytest.skip("the package was built without its compiled extension")
    monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: calls.append(1) or real(*a)])
    fast = read_columns(path, columns=["gyro_z", "acc_x"]).values
    assert calls, "the fast path was not taken"
    monkeypatch.setattr(fastcsv, "_KERNEL", [None])
    slow = read_columns(path, columns=["gyro_z", "acc_x"]).values
    np.testing.assert_array_equal(_bits(fast), _bits(slow))


def test_a_log_the_fast_path_refuses_is_read_as_before(tmp_path, monkeypatch):
    """A comment line sends the log to numpy's reader: the same values as without the fast path."""
    path = tmp_path / "log.csv"
    _write(path, "# from the bench\nx,y\n1.5,2\n-3,4.25\n", False)
    fast = read_log(path, column="y").values
    monkeypatch.setattr(fastcsv, "_KERNEL", [None])
    np.testing.assert_array_equal(fast, read_log(path, column="y").values)
    np.testing.assert_array_equal(fast, [2.0, 4.25])


def test_a_log_longer_than_the_fast_paths_limit_streams(tmp_path, monkeypatch):
    """Beyond FAST_MAX_BYTES of text the log is not held whole: numpy's streaming reader reads it
    (the kernel is never called), to the same values."""
    path = tmp_path / "log.csv"
    _write(path, "x\n" + "\n".join(str(0.5 * i) for i in range(5000)) + "\n", False)
    monkeypatch.setattr(fastcsv, "FAST_MAX_BYTES", 1000)
    monkeypatch.setattr(fastcsv, "_CHUNK", 256)
    monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: pytest.fail("the kernel was called")])
    np.testing.assert_array_equal(read_log(path, column="x").values, 0.5 * np.arange(5000))


@pytest.mark.parametrize("layout", ["plain", "gzip", "gzip members", "members past the limit"])
def test_the_whole_text_is_read_whatever_size_the_file_announces(tmp_path, monkeypatch, layout):
    """The text is read into an array sized from the file (a gzip trailer's ISIZE, else the size on
    disk) and grown where the file holds more: a gzip file of three members announces only its last
    member's size, and is still read whole, byte for byte (gzip.decompress of the file), in reads
    of a few bytes; grown past FAST_MAX_BYTES, it is left to numpy's streaming reader (the kernel
    never called), to the same values."""
    text = "x\n" + "\n".join(str(0.25 * i) for i in range(600)) + "\n"
    data = text.encode()
    cut = [0, 7, len(data) // 2, len(data)]
    blob = {"plain": data, "gzip": gzip.compress(data)}.get(
        layout, b"".join(gzip.compress(data[a:b]) for a, b in zip(cut[:-1], cut[1:])))
    path = tmp_path / ("log.csv" if layout == "plain" else "log.csv.gz")
    path.write_bytes(blob)
    assert gzip.decompress(blob) == data if layout != "plain" else blob == data
    from bayes_imu.io.readers import open_binary

    monkeypatch.setattr(fastcsv, "_CHUNK", 100)
    if layout == "members past the limit":
        monkeypatch.setattr(fastcsv, "FAST_MAX_BYTES", len(data) - 10)
        assert len(data) // 2 < len(data) - 10  # the announced size is within it
        assert fastcsv._whole_text(path, open_binary) is None
        monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: pytest.fail("the kernel was called")])
    else:
        got = fastcsv._whole_text(path, open_binary)
        assert got.tobytes() == data
    np.testing.assert_array_equal(read_log(path, column="x").values, 0.25 * np.arange(600))


@pytest.mark.parametrize("layout", ["plain", "gzip members"])
def test_a_text_of_exactly_the_fast_paths_limit_is_read_whole_and_one_byte_more_is_not(
        tmp_path, monkeypatch, layout):
    """FAST_MAX_BYTES is the largest text read whole, whether the file announces its size (plain)
    or the array grows to it (gzip members, the last one empty: ISIZE 0, so the array grows from one
    byte in many doublings): a text of exactly the limit is read whole, byte for byte, and one of a
    byte more is left to numpy's streaming reader, to the same values."""
    from bayes_imu.io.readers import open_binary

    text = ("x\n" + "\n".join(str(0.5 * i) for i in range(400)) + "\n").encode()
    path = tmp_path / ("log.csv" if layout == "plain" else "log.csv.gz")
    path.write_bytes(text if layout == "plain" else
                     gzip.compress(text[:100]) + gzip.compress(text[100:]) + gzip.compress(b""))
    monkeypatch.setattr(fastcsv, "_CHUNK", 64)
    monkeypatch.setattr(fastcsv, "FAST_MAX_BYTES", len(text))
    assert fastcsv._whole_text(path, open_binary).tobytes() == text
    monkeypatch.setattr(fastcsv, "FAST_MAX_BYTES", len(text) - 1)
    assert fastcsv._whole_text(path, open_binary) is None
    monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: pytest.fail("the kernel was called")])
    np.testing.assert_array_equal(read_log(path, column="x").values, 0.5 * np.arange(400))


def test_a_gzip_trailer_announcing_more_than_the_readers_allow_reserves_no_more(tmp_path):
    """The size a gzip trailer announces is capped at the expansion the readers allow (the file's
    size times MAX_GZIP_RATIO, or GZIP_ALLOWANCE): a trailer rewritten to announce 4 GiB reserves
    GZIP_ALLOWANCE for a small file, and the file (its size check now failing) is not read by the
    fast path; a true trailer is taken as it is."""
    from bayes_imu.io.readers import GZIP_ALLOWANCE, MAX_GZIP_RATIO, open_binary

    data = gzip.compress(b"x\n" + b"1.5\n" * 1000)
    path = tmp_path / "log.csv.gz"
    path.write_bytes(data)
    with open(path, "rb") as raw:
        assert fastcsv._expected_size(raw, gzipped=True) == 2 + 4 * 1000 and raw.tell() == 0
    path.write_bytes(data[:-4] + (2**32 - 1).to_bytes(4, "little"))
    with open(path, "rb") as raw:
        cap = max(GZIP_ALLOWANCE, MAX_GZIP_RATIO * len(data))
        assert fastcsv._expected_size(raw, gzipped=True) == cap
        assert raw.tell() == 0
    assert fastcsv._whole_text(path, open_binary) is None


def test_a_one_column_log_is_read_exactly_and_spaces_send_it_to_numpy(tmp_path, monkeypatch, rng):
    """A log of one column (sniffed as whitespace-separated) takes the fast path: numpy's values bit
    for bit; a line with a space around its number is refused by the parser and read by numpy."""
    values = rng.standard_normal(3000) * 0.02
    path = tmp_path / "one.csv"
    _write(path, "gyro_x_dps\n" + "\n".join(f"{v:.9g}" for v in values) + "\n", False)
    real = fastcsv._kernel()
    if real is None:
        pytest.skip("the package was built without its compiled extension")
    rows = []
    monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: rows.append(real(*a)) or rows[-1]])
    fast = read_log(path, column="gyro_x_dps").values
    assert rows == [3000]
    monkeypatch.setattr(fastcsv, "_KERNEL", [None])
    np.testing.assert_array_equal(_bits(fast), _bits(read_log(path, column="gyro_x_dps").values))
    spaced = tmp_path / "spaced.csv"
    _write(spaced, "x\n 1.5\n2.5 \n", False)
    monkeypatch.setattr(fastcsv, "_KERNEL", [lambda *a: rows.append(real(*a)) or rows[-1]])
    np.testing.assert_array_equal(read_log(spaced, column="x").values, [1.5, 2.5])
    assert rows[-1] == -1
