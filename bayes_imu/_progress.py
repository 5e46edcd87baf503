"""Progress bars on standard error: tqdm when asked for and available, else a silent stand-in.

The command line asks for them only when standard error is a terminal and ``--quiet`` is
not given; library functions take ``progress=False`` and stay silent by default.
"""

import sys

__all__ = ["progress_bar", "show_progress"]


class _Silent:
    """The part of tqdm's interface bayes_imu uses, doing nothing."""

    def update(self, n=1):
        pass

    def set_postfix_str(self, text):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def progress_bar(*, total=None, desc="", unit="it", enabled=False):
    """A tqdm bar on standard error (closed on exit of the ``with`` block), or a silent stand-in."""
    if not enabled:
        return _Silent()
    try:
        from tqdm import tqdm
    except ImportError:  # optional: no bar rather than an error
        return _Silent()
    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        unit_scale=unit == "B",
        leave=False,
        file=sys.stderr,
        dynamic_ncols=True,
    )


def show_progress(quiet=False, stream=None):
    """Whether a command should draw progress bars: a terminal on standard error and not
    ``quiet``."""
    stream = sys.stderr if stream is None else stream
    return not quiet and hasattr(stream, "isatty") and stream.isatty()
