"""The executable's speed trick, leaving through ``os._exit`` without the interpreter's teardown
(``bayes_imu.cli:command``, docs/architecture.md "Speed tricks"): what it guards is that every
printed line and file is out, and the status is the command's, although nothing is flushed by
the teardown it skips."""

import json
import os
import subprocess
import sys

CODE = """
import sys
from bayes_imu.cli import command
command(sys.argv[1:])
print("not reached")
"""


def _run(*args):
    # standard output is a pipe, so block-buffered (not where PYTHONUNBUFFERED is set): a line
    # left in the buffer would be lost
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    return subprocess.run([sys.executable, "-c", CODE, *args], capture_output=True, text=True,
                          timeout=120, env=env)


def test_the_executable_leaves_with_its_status_and_every_line_written(tmp_path):
    spec = tmp_path / "imu.json"
    spec.write_text(json.dumps({"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3}))
    done = _run("drift", str(spec), "--horizon", "10", "--out", str(tmp_path / "o"))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == f"wrote {tmp_path / 'o' / 'drift.csv'}" and "not reached" not in done.stdout
    rows = (tmp_path / "o" / "drift.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,quantity") and rows[-1].startswith("10,attitude")


ALLOCATOR = """
import os, resource, sys
import numpy as np
if sys.argv[1] == "steady":
    from bayes_imu.cli.main import _steady_allocator
    print("set", _steady_allocator(), os.environ.get("MALLOC_MMAP_THRESHOLD_"),
          os.environ.get("MALLOC_TRIM_THRESHOLD_"))
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for k in range(64):  # arrays growing from 256 KiB to 2020 KiB (no 2 MiB huge page fits), freed
    a = np.ones((2**18 + k * 28 * 2**10) // 8)
    del a
print("faults", resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _allocator(mode, **env):
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")} | env
    done = subprocess.run([sys.executable, "-c", ALLOCATOR, mode], capture_output=True,
                          text=True, timeout=120, env=env, check=True)
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    return lines.get("set"), int(lines["faults"])


def test_the_executable_fixes_the_allocators_thresholds():
    """glibc maps each block above its moving threshold afresh and unmaps it when freed: arrays of
    growing size, each above the last freed one, written and freed, fault in every page (64
    arrays of 256-2020 KiB, each too small for a transparent huge page: 18 500 pages). ``command``
    fixes the thresholds (``_steady_allocator``): blocks below 32 MiB come from the heap, which
    grows once to the largest (2 MiB: about 500 pages) and is reused; the output process gets
    them through glibc's variables. A user's own setting of either variable is left alone."""
    if not sys.platform.startswith("linux") or os.confstr("CS_GNU_LIBC_VERSION") is None:
        import pytest

        pytest.skip("glibc's malloc only")
    said, steady = _allocator("steady")
    assert said == f"True {32 * 2**20} {64 * 2**20}"
    _, moving = _allocator("default")
    assert moving > 10_000 and steady < 3_000, (moving, steady)
    said, own = _allocator("steady", MALLOC_MMAP_THRESHOLD_="131072")
    assert said == "False 131072 None" and own > 10_000, own


BLAS = """
import json, multiprocessing, os, sys
import numpy as np
from threadpoolctl import threadpool_info


def blas_threads():
    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def child(queue):
    import scipy.linalg  # noqa: F401
    queue.put(blas_threads())


if __name__ == "__main__":
    from bayes_imu.cli.main import _one_blas_thread
    before = blas_threads()
    set_ = _one_blas_thread()
    import scipy.linalg  # noqa: F401
    later = {k: v for k, v in blas_threads().items() if k not in before}
    queue = multiprocessing.get_context("spawn").Queue()
    p = multiprocessing.get_context("spawn").Process(target=child, args=(queue,))
    p.start()
    print(json.dumps({"set": list(set_), "env": os.environ.get("OPENBLAS_NUM_THREADS"),
                      "later": later, "child": queue.get(timeout=60)}))
    p.join()
"""


def _blas(tmp_path, **env):
    script = tmp_path / "blas.py"
    script.write_text(BLAS)
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")} | env
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=120, env=env, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def test_the_executable_runs_blas_on_one_thread_in_the_libraries_it_loads(tmp_path):
    """``command`` sets OPENBLAS_NUM_THREADS and MKL_NUM_THREADS (``_one_blas_thread``): a BLAS
    library loaded afterwards (scipy's, where it bundles its own) and every library of a process it
    starts (spawned, as the output process is) runs one thread, as threadpoolctl reads them. A
    user's own setting is left alone."""
    seen = _blas(tmp_path)
    assert seen["set"] == ["OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"] and seen["env"] == "1"
    assert seen["child"] and set(seen["child"].values()) == {1}, seen["child"]
    assert set(seen["later"].values()) <= {1}, seen["later"]
    own = _blas(tmp_path, OPENBLAS_NUM_THREADS="2")
    assert own["set"] == [] and own["env"] == "2"
