"""Modules imported on first use: ``import bayes_imu`` stays fast, SciPy loads when a computation needs it."""

import importlib

__all__ = ["LazyModule"]


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
