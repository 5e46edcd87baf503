"""Reading static IMU logs: CSV (optionally gzip) with a header row, columns by name.

All conversion to float64 and all validation of the numbers happens here, at the
boundary: later modules can trust a finite 1-D float64 array.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["LogData", "read_log", "read_text", "UNITS", "to_si"]

#: input units and their factor to SI (rad/s for rates, m/s^2 for specific force)
UNITS = {
    "rad/s": ("gyro", 1.0),
    "deg/s": ("gyro", np.pi / 180.0),
    "deg/h": ("gyro", np.pi / 180.0 / 3600.0),
    "m/s^2": ("accel", 1.0),
    "g": ("accel", 9.80665),
    "mg": ("accel", 9.80665e-3),
}


def read_text(path):
    """A small UTF-8 text file (scene, sensor or summary file), with one-line errors."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory; expected a file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None


def to_si(values, unit, *, where=""):
    """Convert samples from ``unit`` (a key of :data:`UNITS`) to SI (rad/s or m/s^2)."""
    if unit not in UNITS:
        raise InputError(f"{where}unit {unit!r}: expected one of {', '.join(UNITS)}")
    return np.asarray(values, dtype=np.float64) * UNITS[unit][1]


@dataclass(frozen=True)
class LogData:
    """One column of a log.

    Attributes
    ----------
    values : ndarray, shape (n_samples,)
        The samples, float64, finite.
    column : str
        Column name.
    path : str
        Source file.
    rate_hz : float or None
        Sample rate derived from the time column (Hz), if one was given.
    """

    values: np.ndarray
    column: str
    path: str
    rate_hz: float | None = None


def read_log(path, *, column, time_column=None):
    """Read one numeric column (and optionally a time column in seconds) from a CSV log.

    Parameters
    ----------
    path : str or Path
        CSV file with a header row; ``.gz`` files are decompressed on the fly.
    column : str
        Name of the data column.
    time_column : str, optional
        Name of a time column (s); the rate is ``1 / median(diff(t))``.

    Raises
    ------
    InputError
        Missing file or column, unreadable or non-numeric content, non-finite values,
        non-increasing time stamps.
    """
    import pandas as pd

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory; expected a CSV file")
    wanted = [column] if time_column is None else [column, time_column]
    try:
        frame = pd.read_csv(path, usecols=lambda name: name.strip() in wanted, skipinitialspace=True, comment="#", engine="c")
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: empty file; expected a header row and samples") from None
    except (pd.errors.ParserError, UnicodeDecodeError, OSError, EOFError) as exc:
        raise InputError(f"{path}: cannot parse as CSV ({str(exc).splitlines()[0]})") from None
    frame.columns = [name.strip() for name in frame.columns]
    for name in wanted:
        if name not in frame.columns:
            raise InputError(f"{path}: no column {name!r}; expected one of the header names")
    values = _numeric(frame[column], path, column)
    rate = None
    if time_column is not None:
        t = _numeric(frame[time_column], path, time_column)
        steps = np.diff(t)
        if steps.size == 0 or np.any(steps <= 0):
            row = int(np.argmax(steps <= 0)) + 3 if steps.size else 2
            raise InputError(f"{path}: column {time_column!r} row {row}: time stamps must increase")
        rate = 1.0 / float(np.median(steps))
    return LogData(values=values, column=column, path=str(path), rate_hz=rate)


def _numeric(series, path, name):
    import pandas as pd

    numbers = pd.to_numeric(series, errors="coerce").to_numpy(dtype=np.float64)
    bad = ~np.isfinite(numbers)
    if bad.any():
        index = int(np.argmax(bad))
        raise InputError(
            f"{path}: column {name!r} row {index + 2}: got {series.iloc[index]!r}; expected a finite number"
        )
    if numbers.size == 0:
        raise InputError(f"{path}: column {name!r} has no samples")
    return numbers
