"""``bayes-imu fit`` of two versions of the code, alternately, on the real ADIS16405 logs.

A change to the fit's speed moves it by a few percent, and this 2-core machine's own speed moves as
much from hour to hour (docs/speed_under_load.md). This script times two versions side by side: for
each log and seed, a fresh ``python -m bayes_imu.cli fit`` of version A, then of version B (the
command as a user runs it: output process, bytecode written), and prints each pair, the totals and
their ratio B / A.

A version is a git revision of this repository, optionally with a patch applied on top
(``REV+PATCH``: the experiments of docs/speed_under_load.md are kept as patches in
docs/benchmarks/patches/). Each is checked out in a temporary worktree; the compiled extension
(``bayes_imu._compiled``, built by ``pip install``) is copied from this tree into both, which is
what they would build where ``setup.py`` and the kernel sources it compiles are the same in all
three (checked: the script stops otherwise; rebuild with ``python setup.py build_ext --inplace``
in each worktree then). One warm-up run of each (numba's cache, bytecode) is not timed.

    python scripts/bench_fit_ab.py --a HEAD --b HEAD+docs/benchmarks/patches/X.patch \
        [--units 1,3] [--seeds 0-4] [--column gyro_x_dps]
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # validate_real's DATA
#: what the compiled extension is built from (setup.py's KERNELS)
BUILD_INPUTS = ("setup.py", "bayes_imu/allan/_sources.py", "bayes_imu/noise/_sources.py",
                "bayes_imu/io/_sources.py", "bayes_imu/noise/euler_sums.py")


def _git(*args, cwd=ROOT):
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True,
                          text=True).stdout


def _checkout(spec, where):
    """A worktree of ``spec`` (``REV`` or ``REV+PATCH``) at ``where``, the extension copied in."""
    rev, _, patch = spec.partition("+")
    _git("worktree", "add", "--detach", "-q", str(where), rev)
    if patch:
        _git("apply", str(Path(patch).resolve()), cwd=where)
    for inputs in BUILD_INPUTS:
        if (where / inputs).read_bytes() != (ROOT / inputs).read_bytes():
            raise SystemExit(f"{spec}: {inputs} differs from this tree's: the extension copied "
                             "from here would not be its build (rebuild it in the worktree)")
    for built in (ROOT / "bayes_imu").glob("_compiled*"):
        shutil.copy2(built, where / "bayes_imu" / built.name)


def _fit(tree, log, column, seed, out):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = str(tree)
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "bayes_imu.cli", "fit", str(log), "--column", column, "--rate",
         "100", "--out", str(out), "--seed", str(seed)],
        env=env, cwd=out.parent, capture_output=True, text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"fit of {log} failed in {tree}:\n{done.stderr}")
    return time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", required=True, help="version A: REV or REV+PATCH")
    parser.add_argument("--b", required=True, help="version B: REV or REV+PATCH")
    parser.add_argument("--units", default="1,3", help="ADIS16405 units (default 1,3)")
    parser.add_argument("--seeds", default="0-4", help="seeds, FIRST-LAST (default 0-4)")
    parser.add_argument("--column", default="gyro_x_dps")
    args = parser.parse_args(argv)
    from validate_real import DATA

    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return
    first, _, last = args.seeds.partition("-")
    seeds = range(int(first), int(last or first) + 1)
    logs = [DATA / f"adis_16405_imu{int(u)}.csv.gz" for u in args.units.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        trees = {"A": tmp / "a", "B": tmp / "b"}
        try:
            _checkout(args.a, trees["A"])
            _checkout(args.b, trees["B"])
            load = os.getloadavg()
            print(f"A = {args.a}, B = {args.b}; load average before: {load[0]:.2f}; "
                  f"{os.cpu_count()} cores")
            for name, tree in trees.items():  # warm-up: numba's cache, bytecode
                _fit(tree, logs[0], args.column, 0, tmp / f"warm_{name}")
            totals = {"A": 0.0, "B": 0.0}
            print(f"{'log':>24s} {'seed':>4s} {'A_s':>6s} {'B_s':>6s} {'B/A':>5s}")
            for log in logs:
                for seed in seeds:
                    t = {name: _fit(tree, log, args.column, seed, tmp / f"out_{name}")
                         for name, tree in trees.items()}
                    for name in t:
                        totals[name] += t[name]
                    print(f"{log.name:>24s} {seed:4d} {t['A']:6.2f} {t['B']:6.2f} "
                          f"{t['B'] / t['A']:5.3f}")
            print(f"total: A {totals['A']:.2f} s, B {totals['B']:.2f} s, B/A "
                  f"{totals['B'] / totals['A']:.3f}; load average after: {os.getloadavg()[0]:.2f}")
        finally:
            for tree in trees.values():
                if tree.exists():
                    _git("worktree", "remove", "--force", str(tree))
            _git("worktree", "prune")


if __name__ == "__main__":
    main()
