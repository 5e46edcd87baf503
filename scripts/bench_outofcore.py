"""Out-of-core Allan variance: time and peak memory on logs up to 1e9 samples.

For each size, writes a raw little-endian float64 log (white noise plus a random walk,
written in chunks, never held whole) into ``--dir``, then runs, each in a fresh process
so that peak memory (``ru_maxrss`` of the child) is its own:

* ``bayes_imu.allan.outofcore.allan_variance_file`` (octave grid, default 4M-sample chunks);
* for sizes up to ``--in-memory-max``, the in-memory ``allan_variance`` on ``np.fromfile``
  of the same log, and the largest relative difference between the two results.

Needs 16 bytes of free disk per sample (the log and the temporary phase file).

    python scripts/bench_outofcore.py [--sizes 1e8,1e9] [--dir /tmp] [--in-memory-max 1e8]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CHILD = (r"""
import json, resource, sys, time
import numpy as np
mode, path, rate = sys.argv[1], sys.argv[2], float(sys.argv[3])
start = time.perf_counter()
if mode == "outofcore":
    from bayes_imu.allan.outofcore import allan_variance_file
    result = allan_variance_file(path, rate_hz=rate)
else:
    from bayes_imu.allan.estimator import allan_variance
    result = allan_variance(np.fromfile(path, dtype="<f8"), rate_hz=rate)
seconds = time.perf_counter() - start
np.save(path + "." + mode + ".avar.npy", result.avar)
print(json.dumps({"seconds": seconds, "peak_mb": """
r"""resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                  "n_tau": int(result.m.size)}))
""")


def write_log(path, n, rng, chunk=1 << 24):
    """White noise (sigma 1e-2) plus a random walk, float64, written chunk by chunk."""
    level = 0.0
    with open(path, "wb") as handle:
        for lo in range(0, n, chunk):
            k = min(chunk, n - lo)
            walk = level + 1e-5 * np.cumsum(rng.standard_normal(k))
            level = float(walk[-1])
            (1e-2 * rng.standard_normal(k) + walk).astype("<f8").tofile(handle)


def run(mode, path, rate):
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(path), str(rate)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", default="1e8,1e9")
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()))
    parser.add_argument("--in-memory-max", type=float, default=1e8)
    parser.add_argument("--rate", type=float, default=1000.0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(3)
    print(
        f"{'samples':>8s} {'log GB':>7s} {'mode':10s} {'time_s':>7s} {'Msamples/s':>10s} "
        f"{'peak MB':>8s} {'peak/log':>8s} {'max rel diff':>12s}"
    )
    for n in (int(float(v)) for v in args.sizes.split(",")):
        with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
            path = Path(tmp) / "log.f64"
            start = time.perf_counter()
            write_log(path, n, rng)
            written = time.perf_counter() - start
            size_gb = path.stat().st_size / 1e9
            modes = ["outofcore"] + (["in_memory"] if n <= args.in_memory_max else [])
            results = {m: run(m, path, args.rate) for m in modes}
            diff = ""
            if "in_memory" in results:
                a = np.load(str(path) + ".outofcore.avar.npy")
                b = np.load(str(path) + ".in_memory.avar.npy")
                diff = f"{np.max(np.abs(a / b - 1.0)):.1e}"
            for mode, r in results.items():
                print(
                    f"{n:8.0e} {size_gb:7.2f} {mode:10s} {r['seconds']:7.1f} "
                    f"{n / 1e6 / r['seconds']:10.1f} {r['peak_mb']:8.0f} "
                    f"{r['peak_mb'] / 1e3 / size_gb:8.3f} {diff:>12s}"
                )
            print(f"         (writing the {size_gb:.1f} GB log took {written:.0f} s; "
                  f"{os.cpu_count()} cores, {results['outofcore']['n_tau']} cluster sizes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
