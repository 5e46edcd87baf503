"""Imports on demand: ``import bayes_imu`` loads none of the heavy optional libraries."""

import subprocess
import sys

HEAVY = ("scipy", "arviz", "matplotlib", "corner", "emcee", "numba", "pandas", "xarray", "dask", "rosbags")


def test_import_loads_no_heavy_library():
    code = "import sys, bayes_imu; print(' '.join(m for m in %r if m in sys.modules))" % (HEAVY,)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"imported at 'import bayes_imu': {done.stdout.strip()}"
