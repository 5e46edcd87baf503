import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))  # the exact-reference helpers
# the commands write their figures in this process (each worker process would import matplotlib and
# ArviZ again, seconds per test); tests/test_worker.py checks the worker writes the same files
os.environ.setdefault("BAYES_IMU_OUTPUT_PROCESS", "0")

#: the shared, read-only real data (licensed separately; never copied into the project)
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data_real"


@pytest.fixture
def rng():
    """A fresh, seeded generator for each test (SPEC 7: no global random state)."""
    return np.random.default_rng(20261121)


def shared_file(*parts):
    """Path into ``../shared/data_real``; skip the test cleanly when it is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path}")
    return path


@pytest.fixture
def figures(monkeypatch):
    """The figures the plot functions of :mod:`bayes_imu.report.plots` close, kept for inspection
    (closed at the end of the test)."""
    import matplotlib.pyplot as real

    from bayes_imu.report import plots

    kept = []

    class Shim:
        def __getattr__(self, name):
            return getattr(real, name)

        @staticmethod
        def close(fig):
            kept.append(fig)

    monkeypatch.setattr(plots, "pyplot", lambda: Shim())
    yield kept
    for fig in kept:
        real.close(fig)
