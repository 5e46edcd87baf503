"""Reading speed of ``bayes_imu.io.readers.read_columns`` on large logs (MB/s of text, samples/s).

Writes, in a temporary folder, an IMU-like log (a time column and six channels, 8
significant digits, about 70 bytes per row) as plain CSV, gzip CSV and whitespace-separated
text, then times reading one column and three columns (best of ``--repeat``), naming the path
that read them: the exact compiled parser of plain decimal tables (``bayes_imu.io.fastcsv``), else
numpy's reader (the wanted columns
and the last one converted, the delimiters counted) or pandas' C reader (whitespace-separated
wide logs); then pandas' path alone on the same CSV, and ``numpy.loadtxt`` (a common baseline,
which checks no row); then a log of one channel with its time stamps; last, one column of the
gzip CSV read in a fresh process (imports included), and whether that process imported pandas.
Throughput is the uncompressed text size over the wall time.

    python scripts/bench_io.py [--rows 2000000] [--repeat 3]
"""

import argparse
import gzip
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_logs(folder, rows, rng):
    data = rng.standard_normal((rows, 6)) * [0.05, 0.05, 0.05, 0.003, 0.003, 0.003] + [
        0,
        0,
        0,
        0,
        0,
        -1.0,
    ]
    t = np.arange(rows) / 100.0
    table = np.column_stack([t, data])
    header = "time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"
    plain = folder / "log.csv"
    np.savetxt(plain, table, fmt="%.8g", delimiter=",", header=header, comments="")
    text = plain.read_bytes()
    (folder / "log.csv.gz").write_bytes(gzip.compress(text, compresslevel=6))
    (folder / "log.txt").write_bytes(text.replace(b",", b" "))
    return {"csv": plain, "csv.gz": folder / "log.csv.gz", "whitespace": folder / "log.txt"}, len(
        text
    )


def best_time(fn, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=float, default=2e6)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    from bayes_imu.io.readers import _parse_pandas, read_columns, sniff_file

    rows = int(args.rows)
    with tempfile.TemporaryDirectory() as tmp:
        files, n_bytes = write_logs(Path(tmp), rows, np.random.default_rng(0))
        print(f"{rows} rows x 7 columns, {n_bytes / 1e6:.1f} MB of text "
              f"(gzip {files['csv.gz'].stat().st_size / 1e6:.1f} MB)\n")
        print(
            f"{'file':11s} {'columns read':>12s} {'time_s':>7s} {'MB/s':>6s} {'Msamples/s':>10s}  "
            "path"
        )
        for name, path in files.items():
            for cols in (["gyro_x"], ["gyro_x", "gyro_y", "gyro_z"]):
                t = best_time(lambda: read_columns(path, columns=cols), args.repeat)
                print(
                    f"{name:11s} {len(cols):12d} {t:7.2f} {n_bytes / 1e6 / t:6.0f} "
                    f"{rows * len(cols) / 1e6 / t:10.1f}  {_path_taken(path, len(cols))}"
                )
        fmt = sniff_file(files["csv"])
        t = best_time(lambda: _parse_pandas(files["csv"], fmt, [1], False), args.repeat)
        print(
            f"{'csv':11s} {1:12d} {t:7.2f} {n_bytes / 1e6 / t:6.0f} {rows / 1e6 / t:10.1f}  pandas "
            "(its path alone)"
        )
        t = best_time(lambda: np.loadtxt(files["csv"], delimiter=",", skiprows=1, usecols=[1]), 1)
        print(
            f"{'csv':11s} {1:12d} {t:7.2f} {n_bytes / 1e6 / t:6.0f} {rows / 1e6 / t:10.1f}  "
            "numpy.loadtxt (no checks)"
        )
        # one channel with its time stamps: numpy's reader, the fast path (no pandas import)
        two = Path(tmp) / "channel.csv"
        np.savetxt(
            two,
            np.column_stack(
                [np.arange(rows) / 100.0, np.random.default_rng(1).standard_normal(rows) * 0.05]
            ),
            fmt="%.8g",
            delimiter=",",
            header="time,gyro_x",
            comments="",
        )
        size = two.stat().st_size
        t = best_time(lambda: read_columns(two, columns=["gyro_x"]), args.repeat)
        print(
            f"\n{'time,gyro_x':11s} {1:12d} {t:7.2f} {size / 1e6 / t:6.0f} {rows / 1e6 / t:10.1f}  "
            f"{_path_taken(two, 1)} (a 2-column log, {size / 1e6:.0f} MB)"
        )
        fresh = (
            "import sys, time; start = time.perf_counter(); from bayes_imu.io.readers import "
            f"read_columns; read_columns({str(files['csv.gz'])!r}, columns=['gyro_x']); "
            "print(time.perf_counter() - start, 'pandas' in sys.modules)"
        )
        times = []
        for _ in range(args.repeat):
            out = subprocess.run(
                [sys.executable, "-c", fresh], capture_output=True, text=True, check=True
            ).stdout.split()
            times.append(float(out[0]))
        print(
            f"\none column of the gzip CSV in a fresh process (imports included): {min(times):.2f} "
            f"s, best of {args.repeat}; pandas imported: {out[1]}"
        )


def _path_taken(path, n_columns):
    """Which reader takes ``n_columns`` of ``path`` in this process now: the exact compiled parser
    (``exact``, :mod:`bayes_imu.io.fastcsv`), numpy's (where that one refuses the file) or pandas'
    (where numpy's is not tried, :func:`~bayes_imu.io.readers._numpy_first`, or leaves the file to
    pandas)."""
    from bayes_imu._progress import progress_bar
    from bayes_imu.io.fastcsv import read_plain_fast
    from bayes_imu.io.readers import _numpy_first, _parse_plain, open_binary, sniff_file

    fmt, columns = sniff_file(path), list(range(1, 1 + n_columns))
    if read_plain_fast(path, fmt, columns, open_binary) is not None:
        return "exact"
    if not _numpy_first(fmt, columns):
        return "pandas"
    with progress_bar(total=1, enabled=False) as bar:
        return "pandas" if _parse_plain(path, fmt, columns, bar) is None else "numpy"


if __name__ == "__main__":
    main()
