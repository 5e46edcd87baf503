"""Imports on demand: ``import bayes_imu`` loads none of the heavy optional libraries."""

import subprocess
import sys

HEAVY = (
    "scipy",
    "arviz",
    "matplotlib",
    "corner",
    "emcee",
    "numba",
    "pandas",
    "xarray",
    "dask",
    "rosbags",
)


def test_import_loads_no_heavy_library():
    code = "import sys, bayes_imu; print(' '.join(m for m in %r if m in sys.modules))" % (HEAVY,)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"imported at 'import bayes_imu': {done.stdout.strip()}"


def test_second_process_compiles_nothing():
    """numba kernels come from the on-disk cache: a second process saves no new compiled code (the
    JIT kernels of a record of 2**21 samples or more among them: its fused fill and sums, its
    residue sums)."""
    code = """
import numpy as np
import bayes_imu as bi
from bayes_imu.noise.avar_covariance import avar_covariance
y = np.random.default_rng(0).standard_normal(4096)
a = bi.allan_variance(y, rate_hz=100.0)
bi.allan_variance(np.random.default_rng(1).standard_normal((1 << 21) + 1), rate_hz=100.0)
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
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
        )
    saved = [line for line in (done.stdout + done.stderr).splitlines() if "saved" in line]
    assert not saved, "compiled again in a second process:\n" + "\n".join(saved)


def test_a_fit_does_not_import_scipy_stats():
    """scipy.stats (slow to import) stays out of a fit command's process: emcee is imported without
    it (its KDE move imports it on first use, and still works), the intervals and tests use
    scipy.special. The output process, which needs ArviZ, imports it there."""
    code = """
import sys, json
import numpy as np
from bayes_imu.cli.main import main
rng = np.random.default_rng(1)
y = rng.standard_normal(20000) + 0.01 * np.cumsum(rng.standard_normal(20000))
np.savetxt(sys.argv[1] + "/g.csv", y, header="g", comments="")
assert main(["fit", sys.argv[1] + "/g.csv", "--column", "g", "--rate", "100", "--out", sys.argv[1] \
+ "/o", "--quiet"]) == 0
loaded = "scipy.stats" in sys.modules
import emcee
s = emcee.EnsembleSampler(8, 1, lambda x: -0.5 * float(x[0]) ** 2, moves=emcee.moves.KDEMove())
s.run_mcmc(np.linspace(-1, 1, 8)[:, None], 5)
print(json.dumps([loaded, "scipy.stats" in sys.modules]))
"""
    import json
    import os
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "BAYES_IMU_OUTPUT_PROCESS": "1"}
        done = subprocess.run(
            [sys.executable, "-c", code, folder],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1]) == [False, True]


def test_a_fit_writes_every_output_without_numba_arviz_or_pandas():
    """A fit command with drift bands, writing its outputs in its own process (as Python callers
    do), loads neither numba (the precompiled kernels sum a log this short and draw the drift grid;
    numba and its compiled-code machinery: docs/speed_under_load.md#imports;
    where numba has no AOT compiler the package is built without them, and numba is then expected)
    nor ArviZ or xarray (posterior.nc through h5netcdf, corner without ArviZ) nor pandas (a plain
    table of numbers, here four columns of which one is fitted, is read by numpy's reader), and
    writes every file."""
    code = """
import sys, json, os
import numpy as np
from bayes_imu.cli.main import main
rng = np.random.default_rng(2)
y = rng.standard_normal(20000) + 0.01 * np.cumsum(rng.standard_normal(20000))
np.savetxt(sys.argv[1] + "/g.csv", np.column_stack([np.arange(y.size) / 100.0, y, -y, 2.0 * y]), \
header="t,g,h,k",
           delimiter=",", comments="")
assert main(["fit", sys.argv[1] + "/g.csv", "--column", "g", "--rate", "100", "--units", "rad/s", \
"--sensor", "gyro",
             "--out", sys.argv[1] + "/o", "--quiet"]) == 0
print(json.dumps([[m for m in ("numba", "arviz", "xarray", "scipy.stats", "pandas") if m in \
sys.modules],
                  sorted(os.listdir(sys.argv[1] + "/o"))]))
"""
    import json
    import os
    import tempfile

    from bayes_imu.allan.kernels import precompiled

    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "BAYES_IMU_OUTPUT_PROCESS": "0"}
        done = subprocess.run(
            [sys.executable, "-c", code, folder],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
    assert done.returncode == 0, done.stderr
    loaded, files = json.loads(done.stdout.splitlines()[-1])
    assert loaded == ([] if precompiled() is not None else ["numba"])
    assert {
        "summary.json",
        "fit.npz",
        "posterior.nc",
        "allan_fit.png",
        "corner.png",
        "drift.png",
    } <= set(files)


def test_nav_from_the_executable_imports_neither_matplotlib_nor_scipy_fft():
    """``bayes-imu nav`` as the executable runs it (the output process on), in a fresh process:
    nav.png is drawn by the second process, so the command's own process imports no matplotlib,
    and the flicker's transforms are numpy's (scipy.fft cost about 0.25 s of a 1.4 s command:
    docs/speed_under_load.md, seventeenth session). Every file is written."""
    fits = """
import sys, json, os
import numpy as np
from bayes_imu.inference.archive import save_fit
from bayes_imu.inference.fit import fit
rng = np.random.default_rng(3)
for name, scale, unit in (("g", 3e-3, "rad/s"), ("a", 2e-2, "m/s^2")):
    os.mkdir(sys.argv[1] + "/" + name)
    y = scale * rng.standard_normal(20000) + 1e-5 * np.cumsum(rng.standard_normal(20000))
    terms = ("white", "gauss_markov", "bias_instability")  # the flicker: its FFT quadratic form
    save_fit(fit(y, rate_hz=100.0, terms=terms, rng=0, progress=False),
             sys.argv[1] + f"/{name}/fit.npz")
    with open(sys.argv[1] + f"/{name}/summary.json", "w") as f:
        json.dump({"unit": unit, "column": name}, f)
"""
    nav = """
import sys, json, os, importlib
from bayes_imu.cli.main import main
importlib.import_module("bayes_imu.cli.main")._EXECUTABLE = True  # as command() sets it
assert main(["nav", "--gyro", sys.argv[1] + "/g", "--accel", sys.argv[1] + "/a", "--quiet",
             "--out", sys.argv[1] + "/n"]) == 0
print(json.dumps([[m for m in ("matplotlib", "scipy.fft") if m in sys.modules],
                  sorted(os.listdir(sys.argv[1] + "/n"))]))
"""
    import json
    import os
    import tempfile

    env = {**os.environ, "BAYES_IMU_OUTPUT_PROCESS": "1"}
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([sys.executable, "-c", fits, folder], check=True, timeout=300)
        done = subprocess.run([sys.executable, "-c", nav, folder], capture_output=True,
                              text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    imported, files = json.loads(done.stdout.splitlines()[-1])
    assert imported == [], f"imported by the nav command's process: {imported}"
    assert files == [".bayes_imu.json", "nav.csv", "nav.png", "summary.json"]
