"""End-to-end speed of ``bayes-imu fit`` on a 1e6-sample single-column CSV, beside the fastest peer.

Writes a white + Gauss-Markov log (100 Hz, 1e6 samples, ``bayes_imu.noise.simulate``) to a
temporary folder and times, each in a fresh process as a user runs it:

* ``bayes-imu fit`` (imports, reading the CSV, Allan variance, model selection, sampling,
  writing summary.json, posterior.nc, fit.npz and both figures);
* the peer: allan-variance (PyPI) ``compute_avar`` + ``estimate_parameters`` on the same CSV
  read with pandas (its point estimate by NNLS on its own 100-point grid), when installed.

Prints one row per run, the median ratio, and the stages of the last run (Python API, same
process). The issue's goal is a ratio of at most 2.

    python scripts/bench_fit.py [--runs 3] [--samples 1000000]
    python scripts/bench_fit.py --real [--runs 1] # the six ADIS16405 gyro x logs (../shared), one
    run each python scripts/bench_fit.py --load 2 [--runs 3] # 2 CPU-bound processes run meanwhile

``--load N`` starts N busy processes (a pure-Python loop each, one per core on a 2-core machine)
before the first run and stops them after the last: both tools are timed on a machine as busy as a
user's often is (issue 39: fit and peer side by side under the same load). The load average at the
start and end is printed; the goals are a median ratio <= 1.6 idle and <= 2.5 under load. Each row
also gives the CPU time (user + system) of each tool's process tree, ``cpu_ratio`` their ratio: on a
machine loaded by others, a fair proxy of the idle wall-time ratio (where neither waits for the
other core).
"""

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # validate_real's DATA for --real


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--runs",
        type=int,
        default=None,
        help="runs of each tool on each log (default 3; 1 with --real)",
    )
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument(
        "--real",
        action="store_true",
        help="instead, the real ADIS16405 logs' gyro x axes (../shared, read as given: gzip CSV, "
        "deg/s, 100 Hz), one run each unless --runs says otherwise",
    )
    parser.add_argument(
        "--real-units",
        default="1,2,3,4,5,6",
        help="with --real: which ADIS16405 units (comma-separated, default all six)",
    )
    parser.add_argument("--load", type=int, default=0,
                        help="busy processes to run meanwhile (default 0: idle)")
    args = parser.parse_args(argv)
    with _busy(args.load):
        _run(args)


BUSY = "while True: pass"


@contextlib.contextmanager
def _busy(n):
    """``n`` CPU-bound child processes for the duration of the block (killed after it)."""
    procs = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(n)]
    try:
        if n:
            time.sleep(2.0)
        print(f"background load: {n} busy processes; load average {os.getloadavg()[0]:.1f} "
              f"({os.cpu_count()} cores)")
        yield
    finally:
        print(f"load average at the end: {os.getloadavg()[0]:.1f}")
        for p in procs:
            p.kill()
            p.wait()


def _run(args):
    if args.real:
        from validate_real import DATA

        if not DATA.exists():
            print(f"skipped: {DATA} not found")
            return
        logs = [
            (DATA / f"adis_16405_imu{int(i)}.csv.gz", "gyro_x_dps", 100.0)
            for i in args.real_units.split(",")
        ]
        _compare(logs, args.runs or 1)
        return
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    truth = {"noise_variance": 0.25, "bias_variance": 1e-4, "time_constant": 100.0}
    y = simulate_log(NoiseModel(("white", "gauss_markov"), 0.01), truth, args.samples, rng=1)
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "gyro.csv"
        np.savetxt(log, y, fmt="%.9g", header="gyro_x_dps", comments="")
        _compare([(log, "gyro_x_dps", 100.0)], args.runs or 3)
        stages(log)


def _compare(logs, runs):
    """``bayes-imu fit`` and the peer, each in a fresh process, ``runs`` times on each (log, column,
    rate)."""
    peer = _peer_available()
    print(
        f"{'run':>3s} {'log':>24s} {'fit_s':>7s} {'peer_s':>7s} {'ratio':>6s} {'fit_cpu':>7s} "
        f"{'peer_cpu':>8s} {'cpu_ratio':>9s}  model"
    )
    ours, theirs, our_cpu, their_cpu = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for log, column, rate in logs:
            for run in range(runs):
                out = Path(tmp) / f"out{len(ours)}"
                cpu = _children_cpu()
                start = time.perf_counter()
                proc = subprocess.run(
                    [
                        sys.executable,
                        "-m",
                        "bayes_imu.cli",
                        "fit",
                        str(log),
                        "--column",
                        column,
                        "--rate",
                        f"{rate:g}",
                        "--out",
                        str(out),
                        "--seed",
                        str(run),
                    ],
                    capture_output=True,
                    text=True,
                )
                if proc.returncode != 0:
                    raise SystemExit(f"bayes-imu fit {log} {column} failed (exit "
                                     f"{proc.returncode}):\n{proc.stderr}")
                ours.append(time.perf_counter() - start)
                our_cpu.append(_children_cpu() - cpu)
                cpu = _children_cpu()
                theirs.append(_time_peer(log, column, rate) if peer else float("nan"))
                their_cpu.append(_children_cpu() - cpu if peer else float("nan"))
                print(
                    f"{run:3d} {Path(log).name:>24s} {ours[-1]:7.2f} {theirs[-1]:7.2f} "
                    f"{ours[-1] / theirs[-1]:6.2f} {our_cpu[-1]:7.2f} {their_cpu[-1]:8.2f} "
                    f"{our_cpu[-1] / their_cpu[-1]:9.2f}  {proc.stdout.splitlines()[0]}"
                )
    if peer:
        print(
            f"\nmedian: bayes-imu fit {np.median(ours):.2f} s, allan-variance "
            f"{np.median(theirs):.2f} s, ratio {np.median(ours) / np.median(theirs):.2f} "
            "(goals: <= 1.6 idle, <= 2.5 under load); CPU time (user + system, the command's "
            f"processes and threads): {np.median(our_cpu):.2f} s and {np.median(their_cpu):.2f} s, "
            f"ratio {np.median(our_cpu) / np.median(their_cpu):.2f}"
        )
    else:
        print("\nallan-variance not installed (pip install allan-variance): no peer timing")


PEER = """
import sys
import pandas as pd
from allan_variance import compute_avar, estimate_parameters
x = pd.read_csv(sys.argv[1])[sys.argv[2]].to_numpy()
tau, avar = compute_avar(x, dt=1.0 / float(sys.argv[3]))
params, prediction = estimate_parameters(tau, avar)
"""


def _children_cpu():
    """CPU time (user + system, s) of this process's finished children so far (their own children
    and threads included where they were waited for)."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _peer_available():
    import importlib.util

    return (
        importlib.util.find_spec("allan_variance") is not None
        and importlib.util.find_spec("pandas") is not None
    )


def _time_peer(log, column, rate):
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", PEER, str(log), column, f"{rate:g}"],
        capture_output=True,
        text=True,
        check=True,
    )
    return time.perf_counter() - start


def stages(log):
    """The stages of one fit in this process (after the timed runs: imports warm), then the outputs
    the command writes, each timed here with the first import of what it needs: posterior.nc (the
    command's own process writes it, with h5netcdf), then the output process's warm-up (matplotlib
    and corner; ArviZ is not imported) and its two figures."""
    import tempfile

    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.inference.archive import write_netcdf
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.io.readers import read_log
    from bayes_imu.report.plots import import_plotting, plot_allan_fit, plot_corner

    t0 = time.perf_counter()
    values = read_log(log, column="gyro_x_dps").values
    t1 = time.perf_counter()
    allan = allan_variance(values, rate_hz=100.0)
    t2 = time.perf_counter()
    result = fit_allan(allan, rng=0)
    t3 = time.perf_counter()
    print(
        f"\nstages (in-process, warm): read {t1 - t0:.2f} s, Allan variance {t2 - t1:.2f} s, "
        f"selection + sampling {t3 - t2:.2f} s ({result.diagnostics['n_steps']} steps x "
        f"{result.diagnostics['n_walkers']} walkers)"
    )
    _honesty_stages(values, result, t3 - t0)
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        times = [time.perf_counter()]
        for step in (lambda: write_netcdf(result, out / "posterior.nc"), import_plotting,
                     lambda: plot_allan_fit(result, out / "allan_fit.png", rng=0),
                     lambda: plot_corner(result, out / "corner.png")):
            step()
            times.append(time.perf_counter())
    d = np.diff(times)
    print(
        f"outputs (timed here): posterior.nc {d[0]:.2f} s (the command's process); the output "
        f"process's matplotlib + corner {d[1]:.2f} s, allan_fit.png {d[2]:.2f} s, corner.png "
        f"{d[3]:.2f} s"
    )



def _honesty_stages(values, result, fit_s):
    """What issue 35 adds to a fit: the record's contrasts (inside allan_variance), the drift-space
    check the command writes without --sensor, and the summary's IEEE readings and repeatability
    intervals."""
    from bayes_imu.allan.contrast import phase_contrasts
    from bayes_imu.drift.bands import default_times
    from bayes_imu.drift.direct import record_drift_check

    times = [time.perf_counter()]
    for step in (lambda: phase_contrasts(values, rate_hz=100.0),
                 lambda: record_drift_check(result, default_times(result.model.dt, 3600.0), rng=0),
                 lambda: result.summary(unit="deg/s")):
        step()
        times.append(time.perf_counter())
    d = np.diff(times)
    print(
        f"issue 35 additions: contrasts {d[0]:.2f} s, drift check {d[1]:.2f} s, summary (readings, "
        f"repeatability included) {d[2]:.2f} s: {100 * d[:2].sum() / fit_s:.1f}% of read + Allan + "
        f"fit ({fit_s:.2f} s) "
        "beside the summary"
    )


if __name__ == "__main__":
    main()
