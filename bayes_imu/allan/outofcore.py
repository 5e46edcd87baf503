"""Allan variance of logs larger than memory: the same numbers, in bounded memory.

:func:`allan_variance_file` reads a log in chunks, three times over, never holding it:

1. count, mean and validation of the samples (as :func:`bayes_imu.io.readers.check_signal`);
2. the compensated running sum (phase) of the mean-removed samples, written to a
   temporary float64 file; chunks are multiples of 256 samples and the compensation
   state is carried between them, so the phase is the in-memory sequential pass's bit for bit
   (up to the last bits of the mean): that of a log shorter than 2**21 samples; a longer log's
   in-memory running sum rounds its block totals differently, within a few ulp. The phase values
   that the noise identification needs (at most 2**18 + 1 per cluster size) are collected on the
   way;
3. per cluster size ``m``, the second differences ``x[i+2m] - 2 x[i+m] + x[i]`` from three
   chunk-sized reads of the phase file.

Peak memory is a few chunks (``chunk_samples`` x 8 bytes each, 4M samples by default)
plus the identification samples (at most ~2 MB per cluster size); the temporary phase
file needs 8 bytes per sample of free disk. Sources: ``.npy`` (any real dtype; header
parsed, data read sequentially), raw little-endian binary (``dtype``, default float64),
or delimited text (CSV/TSV/whitespace, optionally gzip: :mod:`bayes_imu.io.readers` detection,
one ``column``) parsed by pandas in chunks.
"""

import os
import tempfile
from pathlib import Path

import zlib

import numpy as np

from .kernels import phase_chunk, second_difference_sum, threads_for_pass
from .._progress import progress_bar
from .estimator import (
    assemble_result,
    check_options,
    cluster_sizes,
    identification_span,
    noise_from_phase_samples,
)
from ..errors import InputError
from ..io.readers import SignalExtent, read_failure

__all__ = ["allan_variance_file", "head_samples", "BINARY_SUFFIXES"]

# not .dat: text logs use it too (PHASE.DAT)
BINARY_SUFFIXES = (".npy", ".bin", ".raw", ".f64", ".f32")
_TEXT = (".csv", ".tsv", ".txt", ".gz")
_ALIGN = 256  # the phase kernel's block: chunk boundaries on multiples keep it bit-identical


def allan_variance_file(
    path,
    *,
    rate_hz,
    column=None,
    dtype="<f8",
    m="octave",
    alpha=None,
    confidence=0.683,
    interval="exact",
    chunk_samples=1 << 22,
    workdir=None,
    progress=False,
):
    """Overlapping Allan variance of a log file too large for memory (same result as
    :func:`bayes_imu.allan.estimator.allan_variance` on the loaded samples, relative difference
    ~1e-13).

    Parameters
    ----------
    path : str or Path
        ``.npy``, raw binary (``.bin``, ``.raw``, ``.f64``, ``.f32``) or delimited text.
    rate_hz : float
        Sample rate (Hz).
    column : str or int, optional
        The column of a text log (required there).
    dtype : str
        Sample type of a raw binary file (numpy notation, default little-endian float64;
        ``.f32`` files default to ``"<f4"``).
    m, alpha, confidence, interval
        As :func:`bayes_imu.allan.estimator.allan_variance`.
    chunk_samples : int
        Samples per read (rounded to a multiple of 256); sets the memory used.
    workdir : str or Path, optional
        Folder of the temporary phase file (default: the system's temporary folder).
    progress : bool
        Progress bar over the three passes (samples processed) on standard error.

    Returns
    -------
    AllanResult
    """
    path = Path(path)
    rate_hz = check_options(rate_hz, confidence, interval)
    chunk = max(_ALIGN, int(chunk_samples) // _ALIGN * _ALIGN)
    source = _Source(path, column, dtype, chunk)
    n, mean = _first_pass(source)
    ms = cluster_sizes(m, n)
    free = _available_disk(workdir)
    if free < 8 * (n + 1):
        raise InputError(
            f"{path}: the temporary phase file needs {8 * (n + 1) / 1e9:.3g} GB; "
            f"{free / 1e9:.3g} GB free in {workdir or tempfile.gettempdir()} (use workdir=)"
        )
    spans = [identification_span(int(mi), n) for mi in ms]
    total = 2 * n + int(np.sum(n + 1 - 2 * ms))
    with (
        progress_bar(
            total=total, desc=f"Allan variance of {path.name}", unit="sample", enabled=progress
        ) as bar,
        tempfile.TemporaryDirectory(dir=workdir, prefix="bayes_imu_phase_") as tmp,
    ):
        bar.update(n)
        phase_path = Path(tmp) / "phase.f64"
        id_samples = _write_phase(source, mean, phase_path, ms, spans, bar)
        sums = _second_difference_sums(phase_path, ms, n, chunk, bar)
    alphas = noise_from_phase_samples(id_samples, ms) if alpha is None else alpha
    return assemble_result(ms, sums, alphas, n, rate_hz, confidence, interval,
                           identified=alpha is None)


def head_samples(path, *, column=None, dtype="<f8", n=1 << 16):
    """The first ``n`` samples (float64, fewer in a shorter log) of a log as
    :func:`allan_variance_file` reads it: for checks that need only the start of a log (the
    plausibility of its units, :mod:`bayes_imu.io.plausible`), at the cost of one chunk."""
    source = _Source(Path(path), column, dtype, max(_ALIGN, -(-int(n) // _ALIGN) * _ALIGN))
    chunks = iter(source)
    try:
        for _, values in chunks:
            return values[:n]
        return np.empty(0)
    finally:
        chunks.close()


class _Source:
    """Chunks of float64 samples from a file, read sequentially (any number of passes)."""

    def __init__(self, path, column, dtype, chunk):
        if not path.exists():
            raise InputError(f"{path}: no such file")
        if path.is_dir():
            raise InputError(f"{path}: is a directory; expected a log file")
        if not path.is_file():
            raise InputError(
                f"{path}: not a regular file (a pipe or device); save the log to a file first"
            )
        self.path, self.chunk = path, chunk
        suffix = path.suffix.lower()
        if suffix in _TEXT or (suffix not in BINARY_SUFFIXES and column is not None):
            if column is None:
                raise InputError(f"{path}: a text log needs a column (name or 0-based index)")
            from ..io.readers import resolve_column, sniff_file

            self.kind = "text"
            self.fmt = sniff_file(path)
            self.index = resolve_column(path, self.fmt, column)
        elif suffix == ".npy":
            self.kind = "npy"
            self.dtype, self.offset, self.count = _npy_layout(path)
        else:
            self.kind = "raw"
            self.dtype = np.dtype("<f4" if suffix == ".f32" and dtype == "<f8" else dtype)
            if self.dtype.kind != "f":
                raise InputError(
                    f"dtype={dtype!r}: expected a floating-point type such as '<f8' or '<f4'"
                )
            _refuse_text(path)
            size = path.stat().st_size
            if size % self.dtype.itemsize:
                raise InputError(
                    f"{path}: {size} bytes is not a whole number of {self.dtype} samples"
                )
            self.offset, self.count = 0, size // self.dtype.itemsize

    def __iter__(self):
        """Yield ``(first sample index, float64 chunk)``."""
        if self.kind == "text":
            yield from self._text_chunks()
            return
        with open(self.path, "rb") as handle:
            handle.seek(self.offset)
            done = 0
            while done < self.count:
                raw = np.fromfile(
                    handle, dtype=self.dtype, count=min(self.chunk, self.count - done)
                )
                if raw.size == 0:
                    raise InputError(f"{self.path}: ends after {done} of {self.count} samples")
                yield done, raw.astype(np.float64)
                done += raw.size

    def _text_chunks(self):
        import pandas as pd

        from ..io.readers import diagnose_text, open_binary, csv_options

        stream, raw = open_binary(self.path)
        done = 0
        with raw:
            try:
                reader = pd.read_csv(
                    stream, chunksize=self.chunk, **csv_options(self.fmt, [self.index])
                )
                for frame in reader:
                    values = frame[self.index].to_numpy(dtype=np.float64)
                    if not np.all(np.isfinite(values)):
                        diagnose_text(self.path, self.fmt, [self.index])
                    yield done, values
                    done += values.size
            except (ValueError, pd.errors.ParserError):
                diagnose_text(self.path, self.fmt, [self.index])
            except (OSError, EOFError, zlib.error) as exc:  # a corrupt or truncated gzip member
                raise read_failure(self.path, exc) from None


def _npy_layout(path):
    """``(dtype, data offset, sample count)`` of a 1-D (or single-column) ``.npy`` file."""
    with open(path, "rb") as handle:
        try:
            version = np.lib.format.read_magic(handle)
            reader = (
                np.lib.format.read_array_header_1_0
                if version == (1, 0)
                else np.lib.format.read_array_header_2_0
            )
            shape, fortran, dtype = reader(handle)
        except ValueError as exc:
            raise InputError(f"{path}: not a valid .npy file ({exc})") from None
        offset = handle.tell()
    if dtype.kind != "f" or dtype.hasobject:
        raise InputError(f"{path}: dtype {dtype}; expected floating-point samples")
    if len(shape) != 1 and not (len(shape) == 2 and shape[1] == 1 and not fortran):
        raise InputError(f"{path}: array of shape {shape}; expected one column of samples")
    return dtype, offset, int(shape[0])


def _first_pass(source):
    """Sample count and mean (compensated sum of chunk sums), with the checks of io.check_signal."""
    total, comp = 0.0, 0.0
    extent = SignalExtent()
    for start, values in source:
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                f"{source.path}: sample {start + i + 1} is {float(values[i])!r}; expected a finite "
                "number"
            )
        s = float(np.sum(values))
        t = total + s  # Neumaier summation of the chunk sums
        comp += (total - t) + s if abs(total) >= abs(s) else (s - t) + total
        total = t
        extent.update(values, start)
    extent.check(str(source.path))
    return extent.n, (total + comp) / extent.n


def _write_phase(source, mean, phase_path, ms, spans, bar):
    """Pass 2: the phase record to ``phase_path``; returns the identification samples per ``m``."""
    state = np.zeros(2)
    samples = [np.empty(len(range(a, b, int(m)))) for m, (a, b) in zip(ms, spans)]
    with open(phase_path, "wb") as handle:
        np.zeros(1).tofile(handle)  # x[0] = 0
        for start, values in source:
            x = phase_chunk(values, mean, state)  # phase indices start + 1 ... start + len
            x.tofile(handle)
            g0, g1 = start + 1, start + 1 + x.size
            for k, (m, (a, b)) in enumerate(zip(ms, spans)):
                m = int(m)
                if a == 0 and g0 == 1:
                    samples[k][0] = 0.0
                first = max(a, g0 + (-(g0 - a)) % m)  # first index >= g0 on the grid a, a + m, ...
                last = min(b, g1)
                if first < last:
                    samples[k][(first - a) // m:(last - 1 - a) // m + 1] = x[first - g0:last - g0:m]
            bar.update(values.size)
    return samples


def _second_difference_sums(phase_path, ms, n, chunk, bar):
    """Pass 3: ``sum_i (x[i+2m] - 2 x[i+m] + x[i])**2`` per ``m``, three reads per chunk."""
    sums = np.empty(ms.size)
    with open(phase_path, "rb") as handle:
        def read(first, count):
            handle.seek(8 * first)
            return np.fromfile(handle, dtype="<f8", count=count)

        # the threads a chunk of this size is worth (the sums do not depend on it)
        with threads_for_pass(chunk):
            for k, m in enumerate(ms):
                m = int(m)
                terms = n + 1 - 2 * m
                total = 0.0
                for lo in range(0, terms, chunk):
                    count = min(chunk, terms - lo)
                    total += second_difference_sum(
                        read(lo, count), read(lo + m, count), read(lo + 2 * m, count)
                    )
                    bar.update(count)
                sums[k] = total
    return sums


def _available_disk(folder=None):
    """Free bytes where the temporary phase file would go."""
    stat = os.statvfs(folder or tempfile.gettempdir())
    return stat.f_bavail * stat.f_frsize


def _refuse_text(path, n_bytes=4096):
    """A raw binary log whose first bytes are all printable text is a text log under a binary
    name."""
    with open(path, "rb") as handle:
        head = handle.read(n_bytes)
    printable = set(range(32, 127)) | {9, 10, 13}
    if head and all(b in printable for b in head):
        first = head.split(b"\n", 1)[0][:40].decode("ascii")
        raise InputError(
            f"{path}: starts like text ({first!r}), not raw float samples; rename a text log to "
            ".csv, or give a column to read it as text"
        )
