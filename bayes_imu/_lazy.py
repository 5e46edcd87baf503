"""Imports made cheap: the one home of the package's import-time speed tricks.

* :class:`LazyModule`: a module imported on first use (``import bayes_imu`` stays fast; SciPy loads
  when a computation needs it).
* :func:`import_without`: a third-party library imported with one of *its* optional imports marked
  absent, because that import costs more than the work the command needs the library for, and
  given back a stand-in that imports it when first called. Two uses: emcee without
  ``scipy.stats`` (its KDE move, unused here;
  :func:`bayes_imu.inference.sampling.import_emcee`) and corner without ArviZ (its
  ``InferenceData`` entry point; ArviZ and xarray,
  :func:`bayes_imu.report.plots.import_corner`; timings: docs/speed_under_load.md#imports).
  Each relies on how the library is written, so
  each is pinned: :data:`CHECKED_VERSIONS` lists the versions it was checked on
  (``tests/test_lazy.py`` fails, naming the installed version, on any other), and every run
  checks the structure it relies on and
  raises :class:`ImportError` naming the library and its version where that changed, never leaving
  a library half-working. ``BAYES_IMU_PLAIN_IMPORTS=1`` turns the trick off (plain imports).
"""

import importlib
import os
import sys
import threading

__all__ = ["LazyModule", "import_without", "CHECKED_VERSIONS", "PLAIN_IMPORTS_ENV", "in_series"]

#: the release series of each library :func:`import_without` was checked on (its tests pass there;
#: setup.cfg pins the same series, so a fresh install gets one of them and a new series is a
#: deliberate bump)
CHECKED_VERSIONS = {"emcee": ("3.1",), "corner": ("2.3",)}


def in_series(installed, series):
    """Whether version ``installed`` belongs to one of the release ``series`` (``"3.1"`` holds
    ``3.1.6``, not ``3.10.0``)."""
    return any(installed == s or installed.startswith(s + ".") for s in series)
#: environment variable that turns :func:`import_without` into a plain import
PLAIN_IMPORTS_ENV = "BAYES_IMU_PLAIN_IMPORTS"


class LazyModule:
    """Stands for the module ``name``; the first attribute access imports it."""

    def __init__(self, name):
        self._name = name
        self._module = None

    def __getattr__(self, attr):
        if attr.startswith("__"):
            raise AttributeError(attr)
        if self._module is None:
            self._module = importlib.import_module(self._name)
        return getattr(self._module, attr)


def import_without(name, absent, *, owner, attribute, stand_in, prepare=None):
    """The module ``name``, imported with the module ``absent`` marked missing where that is safe.

    ``name`` must handle ``absent`` being missing by leaving ``owner.attribute`` (a module of
    ``name`` and one of its names) ``None``; that attribute is then set to ``stand_in``, which
    imports ``absent`` when called, so that the library works for every input as before.

    ``name`` loaded already is returned as it is. Where ``absent`` is loaded already, another
    thread runs (it could be importing ``absent`` at that moment), or :data:`PLAIN_IMPORTS_ENV` is
    ``1``, ``prepare()`` (if given) and a plain import run instead.

    Raises
    ------
    ImportError
        ``name`` no longer imports without ``absent``, or no longer leaves ``owner.attribute``
        ``None``: the message names the library, its version and the checked versions.
    """
    if name in sys.modules:
        return sys.modules[name]
    if (
        absent in sys.modules
        or threading.active_count() > 1
        or os.environ.get(PLAIN_IMPORTS_ENV) == "1"
    ):
        if prepare is not None:
            prepare()
        return importlib.import_module(name)
    sys.modules[absent] = None  # "import of <absent> halted": the library takes its path without it
    try:
        module = importlib.import_module(name)
    except ImportError as exc:
        for loaded in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            del sys.modules[loaded]  # nothing half-imported stays behind
        raise ImportError(
            _changed(name, absent, f"it no longer imports without {absent} ({exc})")
        ) from None
    finally:
        del sys.modules[absent]
    holder = sys.modules.get(owner)
    if holder is None or getattr(holder, attribute, False) is not None:
        raise ImportError(
            _changed(name, absent, f"{owner}.{attribute} is not None without {absent}")
        )
    setattr(holder, attribute, stand_in)
    return module


def _changed(name, absent, what):
    from importlib.metadata import PackageNotFoundError, version

    try:
        installed = version(name)
    except PackageNotFoundError:
        installed = "(version unknown)"
    checked = ", ".join(CHECKED_VERSIONS.get(name, ()))
    return (
        f"{name} {installed}: {what}; bayes_imu imports {name} without {absent} to save import "
        f"time, which was checked on {name} {checked} (bayes_imu/_lazy.py): set "
        f"{PLAIN_IMPORTS_ENV}=1 to import it plainly, and please report it"
    )
