"""Imports on demand: ``import bayes_imu`` loads none of the heavy optional libraries."""

import subprocess
import sys

HEAVY = ("scipy", "arviz", "matplotlib", "corner", "emcee", "numba", "pandas", "xarray", "dask", "rosbags")


def test_import_loads_no_heavy_library():
    code = "import sys, bayes_imu; print(' '.join(m for m in %r if m in sys.modules))" % (HEAVY,)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"imported at 'import bayes_imu': {done.stdout.strip()}"


def test_second_process_compiles_nothing():
    """numba kernels come from the on-disk cache: a second process saves no new compiled code."""
    code = """
import numpy as np
import bayes_imu as bi
from bayes_imu.noise.avar_covariance import avar_covariance
y = np.random.default_rng(0).standard_normal(4096)
a = bi.allan_variance(y, rate_hz=100.0)
model = bi.NoiseModel(("white", "gauss_markov"), 0.01)
params = {"noise_variance": 1.0, "bias_variance": 0.1, "time_constant": 5.0}
avar_covariance(model, params, a.m, a.n_samples)
model.avar(a.m, params)  # the compiled Gauss-Markov AVAR
post = bi.UnitPosterior(model, np.array([[1.0, 0.1, 5.0]]), 40.0)
bi.drift_bands(post, [0.1, 1.0], quantity="attitude", bias_start="zero")
from bayes_imu.allan.outofcore import allan_variance_file
"""
    import os

    env = {**os.environ, "NUMBA_DEBUG_CACHE": "1"}
    for attempt in range(2):
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    saved = [line for line in (done.stdout + done.stderr).splitlines() if "saved" in line]
    assert not saved, "compiled again in a second process:\n" + "\n".join(saved)
