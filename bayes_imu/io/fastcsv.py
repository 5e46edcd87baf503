"""The exact fast path for plain delimited logs of decimal numbers.

A log is read here when its whole decompressed text fits in :data:`FAST_MAX_BYTES` and every row
is a plain list of decimals that the compiled parser converts exactly
(:func:`bayes_imu.io._sources.parse_table`: the correctly rounded double of each decimal, which is
what numpy's and pandas' readers give). Anything else (spaces around fields, quotes, comments,
``nan``, a ragged row, more significant digits or a larger exponent than the exact path takes, a
log larger than memory should hold at once, a build without the compiled extension) returns
``None`` before any value is used, and :mod:`bayes_imu.io.readers` reads the file as before, with
the same errors and messages. So what is accepted or refused, and every value, is unchanged; the
common log is parsed at a few nanoseconds per byte instead of numpy's ~100 ns per field
(``scripts/bench_io.py``).
"""

import zlib

import numpy as np

__all__ = ["read_plain_fast", "FAST_MAX_BYTES"]

#: largest decompressed text (bytes) read whole by the fast path (its peak memory is the text
#: once, or about twice while the array grows past a file's announced size); a longer log streams
#: through numpy's reader in bounded memory as before
FAST_MAX_BYTES = 256 << 20
#: bytes read at a time
_CHUNK = 4 << 20

_KERNEL = []


def _kernel():
    """The precompiled parser, or ``None`` where the extension lacks it (no JIT compilation: the
    reader then streams through numpy, as fast as before)."""
    if not _KERNEL:
        try:
            from .. import _compiled

            _KERNEL.append(getattr(_compiled, "parse_table", None))
        except ImportError:
            _KERNEL.append(None)
    return _KERNEL[0]


def read_plain_fast(path, fmt, usecols, open_binary):
    """The columns ``usecols`` ``(rows, len(usecols))`` of the log at ``path`` (format ``fmt``, as
    sniffed by :func:`bayes_imu.io.readers.sniff_file`), or ``None`` where the fast path does not
    read it (module docstring). ``open_binary``: the readers' opener (gzip detected, expansion
    bounded: a decompression bomb raises its :class:`~bayes_imu.errors.InputError` here, or in the
    streaming reader where the file announces more than this path takes)."""
    kernel = _kernel()
    delimiter = fmt.get("delimiter")
    if delimiter is None and len(fmt["names"]) == 1:
        # one column (sniffed as whitespace-separated): a line holds one number and nothing else;
        # a comma in it would make a second field, which the parser refuses
        delimiter = ","
    if kernel is None or delimiter is None or len(delimiter) != 1 or ord(delimiter) > 127:
        return None
    wanted = np.asarray(usecols, dtype=np.int64)
    if wanted.size == 0 or len(set(usecols)) != wanted.size:
        return None
    buf = _whole_text(path, open_binary)
    if buf is None:
        return None
    # rows <= line ends + 1, counted a chunk at a time (no temporary the size of the text)
    max_rows = 1 + sum(int(np.count_nonzero(buf[i:i + _CHUNK] == 10))
                       for i in range(0, buf.size, _CHUNK))
    out = np.empty((max_rows, wanted.size))
    rows = kernel(buf, ord(delimiter), len(fmt["names"]), int(bool(fmt["header"])), wanted, out)
    if rows <= 0:
        return None
    return np.ascontiguousarray(out[:rows])


def _whole_text(path, open_binary):
    """The decompressed bytes of ``path`` as a uint8 array, or ``None`` beyond
    :data:`FAST_MAX_BYTES` or where reading fails (the streaming reader then reads, and reports,
    it). The text is read into one array sized from the file (:func:`_expected_size`), grown where
    the file holds more: one copy of each byte from the decompressor, no list of chunks held
    meanwhile (a file larger than it announces peaks at about twice its text while the array
    grows).

    Through a list of chunks copied into the array afterwards, ``scripts/bench_io.py --rows
    1000000`` (84 MB of text) read one column of its gzip CSV in 0.50-0.61 s, 0.70-0.80 s in a
    fresh process; so, 0.43-0.46 s and 0.58-0.62 s (two runs each, idle)."""
    stream, raw = open_binary(path)
    try:
        with raw:
            size = _expected_size(raw, gzipped=stream is not raw)
            if size > FAST_MAX_BYTES:
                return None
            # one byte more than expected: a full array means the file holds more
            text = np.empty(size + 1, dtype=np.uint8)
            start = 0
            while got := stream.readinto(memoryview(text)[start:start + _CHUNK]):
                start += got
                if start == text.size:
                    if start > FAST_MAX_BYTES:
                        return None
                    grown = np.empty(min(2 * text.size, FAST_MAX_BYTES + 1), dtype=np.uint8)
                    grown[:start] = text
                    text = grown
    except (OSError, EOFError, zlib.error):
        return None
    return text[:start]


def _expected_size(raw, gzipped):
    """The bytes the file object ``raw`` (at its start, left there) will give decompressed: with
    ``gzipped`` (the readers' opener found the gzip magic number), the file's trailer (ISIZE,
    RFC 1952: the last member's size modulo 2**32, so a guess for a file of several members or of
    4 GiB or more), at most the expansion the readers allow
    (:data:`~bayes_imu.io.readers.MAX_GZIP_RATIO` times the file, or
    :data:`~bayes_imu.io.readers.GZIP_ALLOWANCE`: a crafted trailer reserves no more than a bomb
    could fill before it is refused), else its size on disk."""
    import os

    from .readers import GZIP_ALLOWANCE, MAX_GZIP_RATIO

    size = os.fstat(raw.fileno()).st_size
    if not gzipped or size < 18:  # shorter than a gzip header and trailer: its read fails
        return size
    raw.seek(size - 4)
    expanded = int.from_bytes(raw.read(4), "little")
    raw.seek(0)
    return min(expanded, max(GZIP_ALLOWANCE, MAX_GZIP_RATIO * size))
