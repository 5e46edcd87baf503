"""Reading static IMU logs: delimited text (CSV, TSV, whitespace), optionally gzip-compressed.

Accepted without options: a header row or none (detected: a first row of numbers is
data), comma, semicolon, tab or whitespace delimiters (detected from the first rows),
a UTF-8 byte-order mark, CRLF line ends, spaces around fields, blank lines, ``#``
comment lines and trailing ``# ...`` comments, gzip compression (detected from the
content, not the file name). Columns are chosen by header name or by 0-based index.

A plain table of decimals (one-character delimiter, no spaces, quotes or comments, every row of the
header's length, at most 256 MiB of text) is parsed by the compiled exact parser of
:mod:`bayes_imu.io.fastcsv` (the correctly rounded value of each field, as numpy and pandas give).
Otherwise parsing runs in numpy's C reader where the file is a plain table whose converted columns
are numbers (every column of a log of one or two, the wanted ones and the last of a wider delimited
log whose delimiters are counted: :func:`_parse_plain`), else in pandas' C reader (quoted fields,
ragged rows, text in a converted column, whitespace-separated wide logs; hundreds of MB/s,
``scripts/bench_io.py``); when that meets anything wrong, a line-by-line pass in Python finds the
first offending line and the error names the file, the line (1-based, counting every line of the
file), the column, what was found and what was expected. All conversion to float64 and all
validation of the numbers happens here: later modules can trust finite 1-D float64 arrays.
"""

import gzip
import re
import io
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._progress import progress_bar
from ..errors import InputError

__all__ = [
    "LogData",
    "read_log",
    "read_columns",
    "check_columns",
    "read_text",
    "check_signal",
    "SignalExtent",
    "positive_number",
    "excerpt",
    "read_json_object",
    "MAX_TEXT_BYTES",
    "UNITS",
    "to_si",
    "MAX_MAGNITUDE",
]

#: input units and their factor to SI (rad/s for rates, m/s^2 for specific force)
UNITS = {
    "rad/s": ("gyro", 1.0),
    "deg/s": ("gyro", np.pi / 180.0),
    "deg/h": ("gyro", np.pi / 180.0 / 3600.0),
    "mrad/s": ("gyro", 1e-3),
    "m/s^2": ("accel", 1.0),
    "g": ("accel", 9.80665),
    "mg": ("accel", 9.80665e-3),
    "ug": ("accel", 9.80665e-6),
}
#: the SI unit of each sensor kind's rate samples
SI_UNITS = {"gyro": "rad/s", "accel": "m/s^2"}
#: units of delta-angle / delta-velocity increments: sensor kind and factor to SI (rad, m/s)
INCREMENT_UNITS = {
    "rad": ("gyro", 1.0),
    "deg": ("gyro", np.pi / 180.0),
    "m/s": ("accel", 1.0),
}
#: largest accepted |sample| and smallest accepted spread: beyond them squares in the
#: Allan variance overflow (1e100**2 * 1e9 samples < 1e308) or underflow to zero
MAX_MAGNITUDE = 1e100
_MIN_SPREAD = 1e-100
_SNIFF_BYTES = 1 << 16
_DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}


def excerpt(value, limit=80, *, quoted=True):
    """``repr(value)`` (or ``str`` with ``quoted=False``) for an error message: control characters
    as ``?``, at
    most ``limit`` characters (a file's content is never quoted at length: a 100 MB field, or the
    first line of
    a private file)."""
    text = "".join(c if c.isprintable() else "?" for c in (repr(value) if quoted else str(value)))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_json_object(path, what):
    """A JSON file holding one object (``what`` names it in the errors): the dict, or one-line
    errors."""
    import json

    try:
        doc = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg})"
        ) from None
    except RecursionError:
        raise InputError(f"{path}: JSON nested too deeply; expected {what}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object ({what})")
    return doc


#: largest scene, sensor or summary file read (bytes): a larger one, a pipe or a device is refused
#: unread
MAX_TEXT_BYTES = 16 * 2**20


def read_text(path):
    """A small UTF-8 text file (scene, sensor or summary file), with one-line errors.

    Only a regular file of at most :data:`MAX_TEXT_BYTES` is read (a named pipe, ``/dev/zero`` or
    ``/dev/urandom`` is refused at once, never waited on or read without end); a UTF-8 byte-order
    mark is dropped."""
    import errno
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a pipe with no writer: no wait
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory; expected a file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read "
                         f"({exc.strerror or errno.errorcode.get(exc.errno, exc)})") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(f"{path}: is a directory; expected a file")
        if not stat.S_ISREG(info.st_mode):
            raise InputError(f"{path}: not a regular file (a pipe or device); expected a text file")
        if info.st_size > MAX_TEXT_BYTES:
            raise InputError(f"{path}: {info.st_size} bytes; expected a text file of at most "
                             f"{MAX_TEXT_BYTES} bytes")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(MAX_TEXT_BYTES + 1)
        return data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                         f"{exc.start})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def positive_number(name, value, *, what="number"):
    """``float(value)``, or a one-line :class:`InputError` unless it is positive and finite."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}={excerpt(value)}: expected a positive, finite {what}") from None
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"{name}={number!r}: expected a positive, finite {what}")
    return number


def to_si(values, unit, *, where=""):
    """Convert samples from ``unit`` (a key of :data:`UNITS`) to SI (rad/s or m/s^2)."""
    if unit not in UNITS:
        raise InputError(f"{where}unit {excerpt(unit)}: expected one of {', '.join(UNITS)}")
    return np.asarray(values, dtype=np.float64) * UNITS[unit][1]


@dataclass(frozen=True)
class LogData:
    """Columns read from a log.

    Attributes
    ----------
    values : ndarray, shape (n_samples,) or (n_samples, n_columns)
        The samples, float64, finite; 1-D from :func:`read_log`.
    columns : tuple of str
        Column names (``"3"`` for the 4th column of a file without header).
    path : str
        Source file.
    time_s : ndarray, shape (n_samples,) or None
        The time column (s), if one was asked for.
    lines : ndarray of int, shape (n_samples,) or None
        1-based file line of every sample (only with a time column, for its messages).
    delimiter : str
        ``"comma"``, ``"semicolon"``, ``"tab"`` or ``"whitespace"``.
    header : bool
        Whether the file has a header row.
    time_name : str or None
        The time column's name (its unit may be in it:
        :func:`bayes_imu.io.timebase.unit_from_name`).
    time_iso : bool
        Whether the time column held ISO 8601 stamps (``time_s`` then in seconds).
    """

    values: np.ndarray
    columns: tuple
    path: str
    time_s: np.ndarray | None = None
    lines: np.ndarray | None = None
    delimiter: str = "comma"
    header: bool = True
    time_name: str | None = None
    time_iso: bool = False

    @property
    def column(self):
        """The single column's name (:func:`read_log`)."""
        return self.columns[0]


def read_log(path, *, column, time_column=None, progress=False):
    """Read one numeric column (and optionally a time column, s) of a log; see
    :func:`read_columns`."""
    data = read_columns(path, columns=[column], time_column=time_column, progress=progress)
    return LogData(
        data.values[:, 0],
        data.columns,
        data.path,
        data.time_s,
        data.lines,
        data.delimiter,
        data.header,
        data.time_name,
        data.time_iso,
    )


def read_columns(path, *, columns, time_column=None, progress=False, signal=True, where=None):
    """Read numeric columns of a delimited text log (module docstring for the accepted forms).

    Parameters
    ----------
    path : str or Path
    columns : sequence of str or int
        Header names, or 0-based column indices (an integer-looking string is an index
        unless the header has a column of that name).
    time_column : str or int, optional
        Time stamps (their unit is resolved by :mod:`bayes_imu.io.timebase`, which checks them).
    progress : bool
        Show a progress bar (bytes read) on standard error.
    signal : bool
        Check each column as a sensor signal (:func:`check_signal`: not constant, not absurdly
        large);
        ``False`` for tables of other numbers (an Allan deviation table, whose column may be flat).
    where : str or RowFilter, optional
        Keep only the rows satisfying it (:mod:`bayes_imu.io.rows`: ``"period == 0"``).

    A time column of ISO 8601 stamps (``2026-11-25T12:00:00.123Z``) is read as seconds since its
    first stamp (:func:`bayes_imu.io.rows.iso_seconds`; ``LogData.time_iso``).

    Returns
    -------
    LogData
        ``values`` of shape ``(n_samples, len(columns))``.

    Raises
    ------
    InputError
        One line: missing, empty, binary or corrupt file, no data rows, a missing
        column, a ragged row, text or a non-finite value where a number belongs, a
        constant or absurdly large signal.
    """
    path = Path(path)
    fmt = sniff_file(path)
    wanted, rows, filtered = _resolve_columns(path, fmt, columns, time_column, where)
    stamps = None if time_column is None else _iso_stamps(path, fmt, wanted[-1])
    numeric = wanted[:-1] if stamps is not None else wanted
    read = sorted(set(numeric) | set(filtered))
    parsed = _parse(path, fmt, read, progress)
    table = np.column_stack([parsed[:, [read.index(i) for i in numeric]]]
                            + ([] if stamps is None else [stamps]))
    names = tuple(fmt["names"][i] for i in wanted)
    lines = None if time_column is None else _data_line_numbers(path, fmt)
    if rows is not None:
        keep = rows.mask({c: parsed[:, read.index(i)] for c, i in zip(rows.columns, filtered)})
        if not keep.any():
            raise InputError(f"{path}: no row satisfies where={excerpt(rows.text)}; expected some "
                             "rows to keep")
        table, lines = table[keep], None if lines is None else lines[keep]
    for j, name in enumerate(names[: len(columns)] if signal else ()):
        check_signal(table[:, j], where=f"{path}: column {excerpt(name, 40)}")
    values = np.ascontiguousarray(table[:, : len(columns)])
    time_s = None if time_column is None else np.ascontiguousarray(table[:, -1])
    return LogData(
        values,
        names[: len(columns)],
        str(path),
        time_s,
        lines,
        fmt["delimiter_name"],
        fmt["header"],
        names[-1] if time_column is not None and fmt["header"] else None,
        stamps is not None,
    )


def check_columns(path, *, columns, time_column=None, where=None):
    """The 0-based indices of ``columns``, then of ``time_column``, in a text log's header, read
    from the log's first bytes alone (:func:`sniff_file`).

    A name not in the header (with the nearest name as a hint), an index out of range, a column
    asked for twice, or a column of ``where`` not in the header is refused exactly as
    :func:`read_columns` refuses it, without reading the samples: a caller about to read several
    logs (a scene's sensors) checks them all before the first long step.

    Raises
    ------
    InputError
        The first wrong column, in one line that names the file.
    """
    path = Path(path)
    return _resolve_columns(path, sniff_file(path), columns, time_column, where)[0]


def _resolve_columns(path, fmt, columns, time_column, where):
    """``(wanted, rows, filtered)``: the indices of ``columns`` then ``time_column``, the row filter
    of ``where`` (or ``None``) and the indices of its columns."""
    wanted = [resolve_column(path, fmt, c) for c in columns]
    if time_column is not None:
        wanted.append(resolve_column(path, fmt, time_column))
    if len(set(wanted)) != len(wanted):
        raise InputError(
            f"{path}: the same column is asked for twice "
            f"({', '.join(fmt['names'][i] for i in wanted)})"
        )
    rows = None if where is None else _row_filter(where)
    filtered = [] if rows is None else [resolve_column(path, fmt, c) for c in rows.columns]
    return wanted, rows, filtered


def _row_filter(where):
    from .rows import parse_where

    return parse_where(where)


def _iso_stamps(path, fmt, index):
    """Seconds since the first stamp where the time column ``index`` holds ISO 8601 stamps (its
    first data row decides), else ``None`` (numeric stamps, read with the other columns)."""
    from .rows import iso_seconds, looks_iso

    rows = _data_lines(path, fmt)
    first = next(rows, None)
    rows.close()
    if first is None or len(first[1]) <= index or not looks_iso(first[1][index]):
        return None
    pairs = [(n, f[index] if len(f) > index else "") for n, f in _data_lines(path, fmt)]
    where = f"{path}: column {excerpt(fmt['names'][index], 40)}"
    return iso_seconds([t for _, t in pairs], [n for n, _ in pairs], where)


def check_signal(values, *, where):
    """Reject a signal no Allan variance can be computed from: empty, constant, absurd magnitude."""
    SignalExtent().update(values).check(where)


class SignalExtent:
    """Running extent of a signal, so that :func:`check_signal` also works chunk by chunk.

    ``update(chunk, start)`` for each chunk (``start``: index of its first sample), then
    ``check(where)`` raises the one-line :class:`InputError` of an empty, constant,
    overflowing or underflowing signal.
    """

    def __init__(self):
        self.n, self.low, self.high = 0, np.inf, -np.inf
        self.big, self.big_index, self.big_value, self.first = 0.0, 0, 0.0, None

    def update(self, values, start=0):
        if values.size == 0:
            return self
        if self.first is None:
            self.first = float(values[0])
        i = int(np.argmax(np.abs(values)))
        if abs(values[i]) > self.big:
            self.big, self.big_index, self.big_value = (
                float(abs(values[i])),
                start + i,
                float(values[i]),
            )
        self.low, self.high = (
            min(self.low, float(values.min())),
            max(self.high, float(values.max())),
        )
        self.n += values.size
        return self

    def check(self, where):
        if self.n == 0:
            raise InputError(f"{where}: no samples")
        if self.big > MAX_MAGNITUDE:
            raise InputError(
                f"{where}: sample {self.big_index + 1} is {self.big_value!r}; expected |value| <= "
                f"{MAX_MAGNITUDE:g} (a rate or specific force; larger values overflow the Allan "
                "variance)"
            )
        if self.n == 1:
            return  # no spread to judge: the caller's sample count names what is missing
        spread = self.high - self.low
        if spread == 0.0:
            raise InputError(f"{where}: constant signal (all {self.n} samples are {self.first!r}); "
                             "expected a varying sensor output")
        if spread < _MIN_SPREAD:
            raise InputError(
                f"{where}: samples vary by only {spread:g}; expected a spread above "
                f"{_MIN_SPREAD:g} "
                "(smaller values underflow the Allan variance: rescale the column)"
            )


#: a gzip log may decompress to at most this many times its compressed size (plus
#: :data:`GZIP_ALLOWANCE`): a
#: numeric log compresses 3-10x; a 6 MB file of 4 GiB is a decompression bomb, refused as it streams
MAX_GZIP_RATIO = 100
GZIP_ALLOWANCE = 16 * 2**20
#: the format is detected from at most this many bytes: a longer comment preamble or first line is
#: refused
MAX_SNIFF_BYTES = 16 * 2**20


class _Bounded(io.RawIOBase):
    """A gzip stream that raises :class:`InputError` once it has given more than
    :data:`MAX_GZIP_RATIO` times the
    compressed bytes read so far (plus :data:`GZIP_ALLOWANCE`): memory and time bounded by the
    file's size."""

    def __init__(self, stream, raw, path):
        self._stream, self._raw, self._path, self._out = stream, raw, path, 0

    def readable(self):
        return True

    def readinto(self, buffer):
        data = self._stream.read(len(buffer))
        self._out += len(data)
        if self._out > GZIP_ALLOWANCE and self._out > MAX_GZIP_RATIO * self._raw.tell():
            raise InputError(f"{self._path}: the gzip data expands more than {MAX_GZIP_RATIO} "
                             "times "
                             f"({self._out} bytes from {self._raw.tell()}); expected a compressed "
                             "log, not a "
                             "decompression bomb (decompress it yourself if it is meant)")
        buffer[: len(data)] = data
        return len(data)

    def read(self, size=-1):
        if size is None or size < 0:
            chunks = []
            while chunk := super().read(1 << 20):
                chunks.append(chunk)
            return b"".join(chunks)
        return super().read(size)


def open_binary(path):
    """File object of the (decompressed) bytes; gzip detected by its magic number, its expansion
    bounded
    (:data:`MAX_GZIP_RATIO`)."""
    raw = open(path, "rb")
    magic = raw.read(2)
    raw.seek(0)
    return (
        (_Bounded(gzip.GzipFile(fileobj=raw), raw, path), raw)
        if magic == b"\x1f\x8b"
        else (raw, raw)
    )


def _head(path, size=_SNIFF_BYTES):
    """The first ``size`` bytes of the (decompressed) file, with one-line errors for what is not a
    file."""
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory; expected a CSV file")
    if not path.is_file():
        raise InputError(
            f"{path}: not a regular file (a pipe or device); save the log to a file first"
        )
    try:
        stream, raw = open_binary(path)
        with raw:
            head = stream.read(size)
    except (OSError, EOFError, zlib.error) as exc:
        raise read_failure(path, exc) from None
    return head


def _first_line(exc):
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def read_failure(path, exc):
    """The one-line :class:`InputError` of a file that could not be read (``exc``): a gzip stream
    that ends early or whose data, length or checksum are wrong (EOFError, zlib.error,
    gzip.BadGzipFile) is named as such, with what was expected; any other error is quoted."""
    if isinstance(exc, (EOFError, zlib.error, gzip.BadGzipFile)):
        return InputError(f"{path}: a corrupt or truncated gzip file ({_first_line(exc)}); "
                          "expected a complete gzip stream (a copy cut short, or changed bytes?)")
    return InputError(f"{path}: cannot read ({_first_line(exc)})")


def sniff_file(path):
    """Delimiter, header and column names of a text log (:func:`_sniff` on a window that grows
    until it holds data rows, so a long comment preamble or a long line is read whole, up to
    :data:`MAX_SNIFF_BYTES`)."""
    size = _SNIFF_BYTES
    while True:
        head = _head(path, size)
        complete = len(head) < size
        fmt = _sniff(path, head, complete=complete)
        if fmt is not None:
            return fmt
        if complete:
            raise InputError(
                f"{path}: no data rows (only blank or comment lines); expected a header row and "
                "samples"
            )
        if size >= MAX_SNIFF_BYTES:
            raise InputError(f"{path}: no header and data row within the first {MAX_SNIFF_BYTES} "
                             "bytes (a comment "
                             "preamble or a line longer than that); expected a delimited text log")
        size = min(4 * size, MAX_SNIFF_BYTES)


def _sniff(path, head, *, complete=None):
    """Delimiter, header and column names from the first bytes (``None``: no data row in them
    yet)."""
    complete = len(head) < _SNIFF_BYTES if complete is None else complete
    if not head:
        raise InputError(f"{path}: empty file; expected a header row and samples")
    nul = head.find(b"\x00")
    if nul >= 0:
        raise InputError(
            f"{path}: binary data (NUL byte at offset {nul}); expected a delimited text log"
        )
    try:  # a multi-byte character may be cut at the end of the sample
        text = head.decode("utf-8") if complete else head[:-4].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{path}: not UTF-8 text (byte 0x{head[exc.start]:02x} at offset {exc.start}); "
            "expected a delimited text log"
        ) from None
    text = text.removeprefix("\ufeff")
    rows = []  # (line number, content) of the first non-blank, non-comment lines
    for number, line in enumerate(text.splitlines() if complete else text.splitlines()[:-1], 1):
        content = line.split("#", 1)[0].strip()
        if content:
            rows.append((number, content))
        if len(rows) == 20:
            break
    if not rows:
        return None
    if len(rows) == 1 and not complete:  # a header alone in the window: look further for its rows
        return None
    _refuse_decimal_commas(path, rows)
    delimiter = _delimiter(rows)
    first = _split(rows[0][1], delimiter)
    header = not all(_is_number(_unquote(f)) for f in first)
    if header and len(rows) > 1:
        counts = {len(_split(r, delimiter)) for _, r in rows[1:]}
        if len(counts) == 1 and (n := counts.pop()) != len(first):
            raise InputError(
                f"{path}: line {rows[0][0]}: the header has {len(first)} fields but line "
                f"{rows[1][0]} has {n}; expected one name per column (a missing or extra header "
                "field would shift every column)"
            )
    names = (
        [f.strip().strip('"').strip("'") for f in first]
        if header
        else [str(i) for i in range(len(first))]
    )
    if header and len(rows) == 1:
        raise InputError(f"{path}: a header row but no samples; expected samples below the header")
    dupes = sorted({n for n in names if names.count(n) > 1})
    # whether the sampled rows end in a number: numpy's reader converts a wide log's last column
    # (_parse_plain)
    last_numeric = all(
        _is_number(_split(r, delimiter)[-1]) for _, r in (rows[1:] if header else rows)
    )
    return {
        "delimiter": delimiter,
        "delimiter_name": _DELIMITERS.get(delimiter, "whitespace"),
        "header": header,
        "names": names,
        "dupes": dupes,
        "first_line": rows[0][0],
        "last_numeric": last_numeric,
    }


def _delimiter(rows):
    """The candidate splitting every sampled row into the same number (> 1) of fields."""
    for delimiter in (",", ";", "\t", None):
        counts = {len(_split(r, delimiter)) for _, r in rows}
        if len(counts) == 1 and counts.pop() > 1:
            return delimiter
    for delimiter in (",", ";", "\t"):  # ragged rows: the delimiter present in the first row
        if delimiter in rows[0][1]:
            return delimiter
    return None  # one column, or whitespace-separated


def _split(content, delimiter):
    """The fields of one row; a quoted field may hold the delimiter (``"a,b",1.5``), as pandas
    reads it."""
    if delimiter is None:
        return content.split()
    if '"' in content:
        import csv

        return next(csv.reader([content], delimiter=delimiter, skipinitialspace=True))
    return content.split(delimiter)


_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+([eE][+-]?\d+)?$")


def _refuse_decimal_commas(path, rows):
    """Fields like ``1,25`` between semicolons or tabs: decimal commas, which would be cut at the
    comma."""
    for number, content in rows:
        for sep in (";", "\t"):
            fields = [_unquote(f.strip()) for f in content.split(sep)]
            if len(fields) > 1 and any(_DECIMAL_COMMA.match(f) for f in fields):
                raise InputError(f"{path}: line {number}: {excerpt(content[:40])} uses decimal "
                                 "commas; expected decimal "
                                 "points (export the log with '.' as the decimal separator)")


def _unquote(field):
    return field.strip().strip('"').strip("'")


def _is_number(field):
    try:
        float(field)
    except ValueError:
        return False
    return True


def resolve_column(path, fmt, column):
    """0-based index of a column given by name or index."""
    names = fmt["names"]
    key = str(column).strip()
    if key in names:
        if key in fmt["dupes"]:
            raise InputError(f"{path}: column name {excerpt(key, 40)} appears more than once in "
                             "the header; "
                             "give the column by its 0-based index")
        return names.index(key)
    try:
        index = int(key)
    except ValueError:
        shown = excerpt(
            ", ".join(repr(n) for n in names[:12]) + (", ..." if len(names) > 12 else ""),
            quoted=False,
        )
        import difflib

        near = ([n for n in names if n.lower() == key.lower()]  # names are case-sensitive
                or difflib.get_close_matches(key, names, n=1, cutoff=0.75))
        raise InputError(f"{path}: no column {excerpt(key, 40)}; expected one of the header names "
                         f"({shown}) "
                         "or a 0-based column index"
                         + (f"; did you mean {excerpt(near[0], 40)}?" if near else "")) from None
    if not 0 <= index < len(names):
        raise InputError(
            f"{path}: column index {index} out of range; the file has {len(names)} columns "
            f"(0 to {len(names) - 1})"
        )
    return index


#: the widest log whose every field numpy's reader converts (:func:`_parse_plain`; a wider one: the
#: wanted columns and the last)
PLAIN_COLUMNS = 2


def _parse(path, fmt, usecols, progress):
    """The columns ``usecols`` of the data rows: the exact fast path of plain decimal tables
    (:func:`bayes_imu.io.fastcsv.read_plain_fast`), else :func:`_parse_plain`, else pandas' C reader
    on the selected columns; anything odd goes to :func:`diagnose_text`."""
    from .fastcsv import read_plain_fast

    table = read_plain_fast(path, fmt, usecols, open_binary)
    if table is not None and progress:
        with progress_bar(total=path.stat().st_size, desc=f"reading {path.name}", unit="B",
                          enabled=progress) as bar:
            bar.update(path.stat().st_size)
    if table is None and _numpy_first(fmt, usecols):
        with progress_bar(
            total=path.stat().st_size, desc=f"reading {path.name}", unit="B", enabled=progress
        ) as bar:
            table = _parse_plain(path, fmt, usecols, bar)
    if table is None:
        table = _parse_pandas(path, fmt, usecols, progress)
    if table.shape[0] == 0:
        raise InputError(f"{path}: a header row but no samples; expected samples below the header")
    if not np.all(np.isfinite(table)):  # NaN: also a too-short row that leaves a wanted field empty
        diagnose_text(path, fmt, usecols)
    return table


def _numpy_first(fmt, usecols):
    """Whether :func:`_parse` tries numpy's reader first: always where pandas is not imported yet
    (its import is most of what numpy saves), else for a log of at most :data:`PLAIN_COLUMNS`
    columns or a wide log of which at most two columns are converted (the wanted ones and the
    last), where numpy is as fast as pandas; converting more columns, numpy is slower
    (timings: docs/speed_under_load.md#reading-logs)."""
    import sys

    n_columns = len(fmt["names"])
    return ("pandas" not in sys.modules or n_columns <= PLAIN_COLUMNS
            or len(set(usecols) | {n_columns - 1}) <= 2)


def _parse_plain(path, fmt, usecols, bar):
    """``numpy.loadtxt`` on a plain table: every data line with as many numeric fields as the header
    (or the first row) names; ``None`` for any other file, which pandas then reads as before
    (:func:`_parse_pandas`).

    A log of at most :data:`PLAIN_COLUMNS` columns (one channel, with or without its time stamps)
    has every field converted, so a ragged row is refused by numpy itself. A wider log with a
    one-character delimiter has only the wanted columns converted, and the last one, so a row short
    of the last field is refused; the delimiters of the whole text are counted as it streams past,
    and unless they come to ``columns - 1`` a line (header included), some row is longer than the
    header, or a delimiter sits in a quoted field or a comment, and the file goes to pandas. So
    where the wide path reads a file, every row has exactly the header's fields, as pandas' path
    requires (it tokenises every column); the other columns are not converted there either (text is
    fine). A whitespace-separated wide log stays with pandas (its delimiters are runs of blanks),
    and so does one whose sampled rows end in text (``fmt["last_numeric"]``, :func:`sniff_file`:
    numpy would refuse it).

    Where numpy reads a field at all, its value is pandas' (both round each decimal string
    correctly: ``tests/test_io.py`` compares them on every shipped log, the real logs and edge
    cases), and every field numpy refuses (quotes, an empty field, a decimal comma, text in the last
    column) sends the file to pandas, so what is accepted or refused, and every error message, is as
    before. It spares a command the import of pandas (docs/speed_under_load.md#imports);
    :func:`_numpy_first` says when it is tried (``scripts/bench_io.py`` for large logs).
    """
    import warnings

    n_columns = len(fmt["names"])
    wide = n_columns > PLAIN_COLUMNS
    delimiter = fmt["delimiter"]
    if wide and (delimiter is None or not fmt.get("last_numeric", True)):
        return None
    read = sorted(set(usecols) | {n_columns - 1}) if wide else None
    stream, raw = open_binary(path)
    counting = _Counting(stream, raw, bar, ord(delimiter) if wide else None, path)
    try:
        with (
            raw,
            io.TextIOWrapper(
                io.BufferedReader(counting, buffer_size=1 << 20), encoding="utf-8-sig", newline=None
            ) as text,
            warnings.catch_warnings(),
        ):
            _read_in_megabytes(text)
            # "input contained no data": pandas' path says what is wrong
            warnings.simplefilter("error")
            table = np.loadtxt(text, dtype=np.float64, delimiter=delimiter, comments="#",
                               skiprows=1 if fmt["header"] else 0, ndmin=2, usecols=read)
    except InputError:  # a decompression bomb: no second reader tries it
        raise
    except (ValueError, UserWarning, UnicodeDecodeError, OSError, EOFError, zlib.error):
        return None
    if wide:
        lines = table.shape[0] + int(fmt["header"])
        if counting.delimiters != lines * (n_columns - 1):
            return None
        return np.ascontiguousarray(table[:, [read.index(c) for c in usecols]])
    if table.shape[1] != n_columns:
        return None
    return np.ascontiguousarray(table[:, usecols])


def _read_in_megabytes(text):
    """Let the text wrapper ``text`` read its bytes 1 MiB at a time instead of 8 KiB
    (``_CHUNK_SIZE``, an attribute of CPython's io implementations; without it, the same text in
    smaller reads): fewer reads, a little faster, and the delimiters are counted in megabyte
    chunks."""
    try:
        text._CHUNK_SIZE = 1 << 20
    except AttributeError:
        pass


def _parse_pandas(path, fmt, usecols, progress):
    """pandas' C reader on the selected columns (:func:`csv_options`); a file it cannot read goes to
    :func:`diagnose_text`."""
    import pandas as pd

    with progress_bar(
        total=path.stat().st_size, desc=f"reading {path.name}", unit="B", enabled=progress
    ) as bar:
        stream, raw = open_binary(path)
        try:
            with raw:
                frame = pd.read_csv(
                    io.BufferedReader(_Counting(stream, raw, bar, path=path), buffer_size=1 << 20),
                    low_memory=False,
                    **csv_options(fmt, usecols),
                )
        except InputError:
            raise
        except (ValueError, pd.errors.ParserError, UnicodeDecodeError):
            diagnose_text(path, fmt, usecols)
        except (OSError, EOFError, zlib.error) as exc:
            raise read_failure(path, exc) from None
    return np.column_stack([frame[i].to_numpy(dtype=np.float64) for i in usecols])


def csv_options(fmt, usecols):
    """``pandas.read_csv`` options for a sniffed format, converting the columns ``usecols``.

    Every column is tokenised (with ``usecols``, pandas would drop the extra fields of a
    too-long row silently); only the wanted ones are converted, so text elsewhere is fine.
    """
    return {
        "encoding": "utf-8-sig",
        "sep": r"\s+" if fmt["delimiter"] is None else fmt["delimiter"],
        "header": 0 if fmt["header"] else None,
        "names": range(len(fmt["names"])),
        "dtype": {i: np.float64 for i in usecols},
        "comment": "#",
        "skip_blank_lines": True,
        "skipinitialspace": True,
        "engine": "c",
    }


#: longest line of a text log (bytes): a longer one is refused as it streams past (memory stays
#: bounded)
MAX_LINE_BYTES = 1 << 20


class _Counting(io.RawIOBase):
    """Byte stream that advances a progress bar by the compressed bytes consumed, and counts the
    byte ``delimiter`` (an ASCII code) in what it passes on (:attr:`delimiters`) when given one. A
    line longer than
    :data:`MAX_LINE_BYTES` raises :class:`InputError` (naming ``path``) as it passes."""

    def __init__(self, stream, raw, bar, delimiter=None, path="log"):
        self._stream, self._raw, self._bar, self._seen = stream, raw, bar, 0
        self._delimiter, self.delimiters = delimiter, 0
        self._path, self._run = path, 0  # bytes since the last line end

    def readable(self):
        return True

    def readinto(self, buffer):
        data = self._stream.read(len(buffer))
        self._check_lines(data)
        buffer[: len(data)] = data
        if self._delimiter is not None:  # numpy's comparison: faster than bytes.count here
            self.delimiters += int(
                np.count_nonzero(np.frombuffer(data, np.uint8) == self._delimiter)
            )
        position = self._raw.tell()
        self._bar.update(position - self._seen)
        self._seen = position
        return len(data)

    def _check_lines(self, data):
        if len(data) > MAX_LINE_BYTES:  # a line may lie wholly inside: every line end
            codes = np.frombuffer(data, np.uint8)
            ends = np.flatnonzero((codes == 10) | (codes == 13))
        else:  # only the line running across the chunk's start can be long
            last = max(data.rfind(b"\n"), data.rfind(b"\r"))
            first = min((i for i in (data.find(b"\n"), data.find(b"\r")) if i >= 0), default=-1)
            ends = np.array([first, last] if first >= 0 else [], dtype=np.int64)
        longest = self._run + (int(ends[0]) if ends.size else len(data))
        if ends.size > 1:
            longest = max(longest, int(np.max(np.diff(ends))) - 1)
        self._run = len(data) - 1 - int(ends[-1]) if ends.size else self._run + len(data)
        if longest > MAX_LINE_BYTES:
            raise InputError(f"{self._path}: a line longer than {MAX_LINE_BYTES} bytes; expected "
                             "the rows of a "
                             "delimited text log")


def _data_lines(path, fmt):
    """Yield ``(line number, fields)`` of every data row (after the header), in file order."""
    stream, raw = open_binary(path)
    with raw, io.TextIOWrapper(stream, encoding="utf-8-sig", newline=None) as text:
        header_pending = fmt["header"]
        for number, line in enumerate(text, 1):
            content = line.split("#", 1)[0].strip()
            if not content:
                continue
            if header_pending:
                header_pending = False
                continue
            yield number, _split(content, fmt["delimiter"])


def diagnose_text(path, fmt, usecols):
    """Slow path: find the first bad line and raise its one-line :class:`InputError`."""
    try:
        _find_bad_line(path, fmt, usecols)
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{path}: not UTF-8 text ({exc.reason} in the data); expected a delimited text log"
        ) from None
    raise InputError(
        f"{path}: cannot parse as a delimited text log ({fmt['delimiter_name']}-separated, "
        f"{len(fmt['names'])} columns)"
    )


def _find_bad_line(path, fmt, usecols):
    n_fields = len(fmt["names"])
    for number, fields in _data_lines(path, fmt):
        if len(fields) != n_fields:
            raise InputError(
                f"{path}: line {number}: {len(fields)} field{'s' * (len(fields) != 1)}; expected "
                f"{n_fields} ({'as in the header' if fmt['header'] else 'as in the first row'})"
            )
        for i in usecols:
            text = fields[i].strip()
            try:
                value = float(text)
            except ValueError:
                value = None
            if value is None or not np.isfinite(value):
                found = excerpt(text, 40) if text else "an empty field"
                raise InputError(f"{path}: line {number}, column {excerpt(fmt['names'][i], 40)}: "
                                 f"got {found}; "
                                 "expected a finite number")


def _data_line_numbers(path, fmt):
    """1-based file line of every data row (for time-stamp messages)."""
    return np.fromiter((number for number, _ in _data_lines(path, fmt)), dtype=np.int64)
