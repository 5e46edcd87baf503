"""The output worker process (bayes_imu.report.worker) and the command's fast exit."""

import io
import json
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.report.worker import WORKERS_ENV, OutputWriter, background_default


def _append(path, text):
    with open(path, "a", encoding="utf-8") as f:
        f.write(f"{text} {os.getpid()}\n")


def _fail(message):
    raise InputError(message)


def _children():
    return [p for p in multiprocessing.active_children() if p.name == "bayes_imu-outputs"]


@pytest.mark.parametrize("background", [True, False])
def test_every_call_runs_once_in_the_worker_or_here(tmp_path, background):
    out = tmp_path / "log.txt"
    with OutputWriter(background=background) as writer:
        for i in range(5):
            writer.submit(_append, out, f"call{i}")
    lines = [line.split() for line in out.read_text().splitlines()]
    assert sorted(text for text, _ in lines) == [f"call{i}" for i in range(5)]
    pids = {int(pid) for _, pid in lines}
    assert (os.getpid() not in pids) if background else (pids == {os.getpid()})
    assert not _children()


def _interval(path, seconds):
    start = time.time()
    time.sleep(seconds)
    with open(path, "a", encoding="utf-8") as f:
        f.write(f"{start} {time.time()}\n")


def test_calls_run_side_by_side_once_the_caller_waits(tmp_path):
    """Two 1.5 s calls sent, then the caller waits: with two or more usable CPUs the worker runs
    them at once (their intervals overlap), with one it runs them one after the other."""
    from bayes_imu.report.worker import usable_cpus

    out = tmp_path / "times.txt"
    with OutputWriter(background=True) as writer:
        writer.submit(_interval, out, 1.5)
        writer.submit(_interval, out, 1.5)
    (a0, a1), (b0, b1) = sorted(
        tuple(map(float, line.split())) for line in out.read_text().splitlines()
    )
    assert (b0 < a1) == (usable_cpus() >= 2)


def _pid_then_sleep(path, seconds):
    path.write_text(str(os.getpid()))
    time.sleep(seconds)
    path.write_text("finished")


def _fail_after(message, seconds):
    time.sleep(seconds)
    raise InputError(message)


def test_an_error_in_the_worker_is_raised_here_with_its_type_and_stops_it(tmp_path):
    """The error comes back with its type and nothing else runs to its end: with two or more usable
    CPUs (Linux) the next call started beside the failing one and is stopped (its process gone, its
    file never finished); with one it never starts; a call sent after the error never runs."""
    from bayes_imu.report.worker import _can_fork, usable_cpus

    running = tmp_path / "running.txt"
    start = time.perf_counter()
    with pytest.raises(InputError, match="bad figure"):
        with OutputWriter(background=True) as writer:
            writer.submit(_fail_after, "bad figure", 1.0)
            writer.submit(_pid_then_sleep, running, 30)
            writer.wait()
            writer.submit(_append, tmp_path / "after.txt", "never")
    assert time.perf_counter() - start < 15
    assert not (tmp_path / "after.txt").exists()
    side_by_side = _can_fork() and usable_cpus() >= 2
    assert running.exists() == side_by_side
    if side_by_side:
        pid = running.read_text()
        assert pid != "finished"
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)
    assert not _children()


def _square(x):
    return x * x, os.getpid()


@pytest.mark.parametrize("background", [True, False])
def test_computed_calls_come_back_with_their_values_or_errors_and_stop_nothing(
    tmp_path, background
):
    """compute(): each call's value comes back (from the worker, or at once here); a call that fails
    comes back with its exception (exception(), and result() raises it) and the outputs sent after
    it are still written; done() never waits."""
    out = tmp_path / "log.txt"
    with OutputWriter(background=background) as writer:
        futures = [writer.compute(_square, i) for i in range(4)]
        failed = writer.compute(_fail, "no mode")
        writer.submit(_append, out, "written")
        while not futures[-1].done():
            time.sleep(0.01)
        assert [f.result()[0] for f in futures] == [0, 1, 4, 9]
        assert {f.result()[1] != os.getpid() for f in futures} == {background}
        assert isinstance(failed.exception(), InputError) and "no mode" in str(failed.exception())
        with pytest.raises(InputError, match="no mode"):
            failed.result()
    assert out.read_text().split()[0] == "written"
    assert not _children()


def test_a_worker_that_dies_is_reported_in_one_line_by_a_computed_call(tmp_path):
    """The output process killed while the caller waits for a computed value (say, by the kernel's
    out-of-memory killer): the caller gets the same RuntimeError as when it waits for its outputs,
    not a bare EOFError."""
    import signal

    writer = OutputWriter(background=True)
    try:
        pending = writer.compute(time.sleep, 30)
        time.sleep(0.5)
        os.kill(writer._process.pid, signal.SIGKILL)
        with pytest.raises(RuntimeError, match="output process stopped"):
            pending.result()
    finally:
        writer.stop()
    assert not _children()


def test_a_computed_value_not_waited_for_does_not_hold_the_caller(tmp_path):
    """Leaving the writer waits for the outputs only: a computed call still running (a speculative
    search that was not needed) is stopped with the worker."""
    start = time.perf_counter()
    with OutputWriter(background=True) as writer:
        writer.submit(_append, tmp_path / "out.txt", "written")
        writer.wait()
        pending = writer.compute(time.sleep, 30)
    assert time.perf_counter() - start < 15
    assert not pending.done() and (tmp_path / "out.txt").exists() and not _children()


def test_leaving_by_an_exception_stops_the_worker_at_once(tmp_path):
    start = time.perf_counter()
    with pytest.raises(RuntimeError, match="caller failed"):
        with OutputWriter(background=True) as writer:
            writer.submit(time.sleep, 30)
            writer.submit(_append, tmp_path / "late.txt", "never")
            raise RuntimeError("caller failed")
    assert time.perf_counter() - start < 10
    assert not (tmp_path / "late.txt").exists() and not _children()


def test_environment_variable_chooses_and_is_checked(monkeypatch):
    monkeypatch.setenv(WORKERS_ENV, "0")
    assert background_default() is False
    monkeypatch.setenv(WORKERS_ENV, "1")
    assert background_default() is True and background_default(automatic=False) is True
    monkeypatch.delenv(WORKERS_ENV)
    assert background_default(automatic=False) is False  # not asked for: only the variable decides
    monkeypatch.setenv(WORKERS_ENV, "yes")
    with pytest.raises(InputError, match=f"{WORKERS_ENV}='yes': expected 0 or 1"):
        background_default()


def test_no_output_process_on_a_busy_machine(monkeypatch):
    """Automatic choice: a worker process only where the processes running now leave a CPU free
    (issue 39); a one-minute load average left by a job that has ended does not decline it (the
    average lags: after a busy minute an idle machine declined the process that saves it 0.4 s);
    without /proc the load average decides."""
    from bayes_imu.report import worker

    monkeypatch.delenv(WORKERS_ENV, raising=False)
    monkeypatch.setattr(worker, "usable_cpus", lambda: 2)
    monkeypatch.setattr(worker.os, "getloadavg", lambda: (0.3, 0.3, 0.3))
    monkeypatch.setattr("builtins.open", lambda *a, **k: io.StringIO("0.30 0.30 0.30 1/200 999\n"))
    assert background_default() is True and worker.spare_cpus() == 2  # nothing else running
    monkeypatch.setattr("builtins.open", lambda *a, **k: io.StringIO("0.30 0.30 0.30 3/200 999\n"))
    assert background_default() is False  # two other processes running now: the average lags them
    monkeypatch.setattr("builtins.open", lambda *a, **k: io.StringIO("0.30 0.30 0.30 1/200 999\n"))
    monkeypatch.setattr(worker.os, "getloadavg", lambda: (2.1, 0.3, 0.3))
    assert background_default() is True  # a past load, nothing else running now
    monkeypatch.setattr("builtins.open", lambda *a, **k: io.StringIO("2.10 0.30 0.30 3/200 999\n"))
    assert background_default() is False  # a load that goes on

    def no_proc(*a, **k):
        raise OSError("no /proc")

    monkeypatch.setattr("builtins.open", no_proc)
    assert background_default() is False and worker.spare_cpus() == pytest.approx(-0.1)
    monkeypatch.setattr(worker.os, "getloadavg", lambda: (0.3, 0.3, 0.3))
    assert background_default() is True
    monkeypatch.setenv(WORKERS_ENV, "1")  # the variable still decides
    monkeypatch.setattr(worker.os, "getloadavg", lambda: (2.1, 0.3, 0.3))
    assert background_default() is True


def _fit(tmp_path, name, workers, monkeypatch, log):
    monkeypatch.setenv(WORKERS_ENV, workers)
    out = tmp_path / name
    args = [
        "fit",
        str(log),
        "--column",
        "gyro",
        "--rate",
        "100",
        "--terms",
        "white,gauss_markov",
        "--sensor",
        "gyro",
        "--horizon",
        "30",
        "--out",
        str(out),
        "--seed",
        "3",
        "--quiet",
    ]
    assert main(args) == 0
    return out


def test_fit_outputs_are_the_same_from_the_worker_and_in_process(tmp_path, rng, monkeypatch):
    """Every file of a fit (figures byte for byte, the ArviZ file's arrays) is the same whether the
    worker process or the command itself writes it."""
    from bayes_imu.inference.fit import import_arviz

    log = tmp_path / "log.csv"
    y = 0.05 * rng.standard_normal(30_000) + 0.002 * np.convolve(
        rng.standard_normal(30_000), np.ones(500) / 500, "same"
    )
    log.write_text("gyro\n" + "\n".join(f"{v:.9g}" for v in y) + "\n")
    here = _fit(tmp_path, "here", "0", monkeypatch, log)
    there = _fit(tmp_path, "there", "1", monkeypatch, log)
    names = sorted(p.name for p in here.iterdir())
    assert names == sorted(p.name for p in there.iterdir())
    assert {
        "allan_fit.png",
        "corner.png",
        "drift.png",
        "posterior.nc",
        "summary.json",
        "drift.csv",
        "fit.npz",
    } <= set(names)
    for name in ("allan_fit.png", "corner.png", "drift.png", "drift.csv"):
        assert (here / name).read_bytes() == (there / name).read_bytes(), name
    assert json.loads((here / "summary.json").read_text()) == json.loads(
        (there / "summary.json").read_text()
    )
    az = import_arviz()
    a, b = az.from_netcdf(here / "posterior.nc"), az.from_netcdf(there / "posterior.nc")
    assert a.groups() == b.groups()
    for group in a.groups():
        for var in a[group].data_vars:
            np.testing.assert_array_equal(a[group][var].values, b[group][var].values)
    assert not _children()


def test_a_widened_fit_command_is_the_same_with_modes_sought_ahead(tmp_path, monkeypatch):
    """A fit command whose candidates all fail the adequacy check (white noise plus a 3 s square
    wave, which a vibration line does not describe either: every candidate
    scored again with the discrepancy term) writes the same summary.json and fit.npz whether its
    output process seeks the widened modes ahead (fit_allan's pool) or the command seeks them all
    itself."""
    t = np.arange(30_000) / 100.0
    y = 0.05 * np.random.default_rng(3).standard_normal(t.size)
    y += 0.02 * np.sign(np.sin(2.0 * np.pi * t / 3.0))
    log = tmp_path / "log.csv"
    log.write_text("gyro\n" + "\n".join(f"{v:.9g}" for v in y) + "\n")
    outs = {}
    for workers in ("1", "0"):
        monkeypatch.setenv(WORKERS_ENV, workers)
        outs[workers] = tmp_path / f"out{workers}"
        assert (
            main(
                [
                    "fit",
                    str(log),
                    "--column",
                    "gyro",
                    "--rate",
                    "100",
                    "--out",
                    str(outs[workers]),
                    "--seed",
                    "1",
                    "--quiet",
                ]
            )
            == 0
        )
    ahead, alone = (json.loads((outs[w] / "summary.json").read_text()) for w in ("1", "0"))
    assert ahead["adequacy"]["widened"] and ahead == alone
    with np.load(outs["1"] / "fit.npz") as a, np.load(outs["0"] / "fit.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for name in a.files:
            assert a[name].tobytes() == b[name].tobytes(), name
    assert not _children()


def test_command_exits_with_its_status_and_flushed_output(tmp_path):
    """The executable leaves without the interpreter's teardown: its status and every line it
    printed arrive (a user error: one line, status 2; a run: its summary lines, status 0)."""
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "bayes_imu.cli",
            "fit",
            str(tmp_path / "missing.csv"),
            "--rate",
            "100",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "missing.csv" in bad.stderr
    sensor = tmp_path / "s.json"
    sensor.write_text(json.dumps({"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3}))
    good = subprocess.run(
        [sys.executable, "-m", "bayes_imu.cli", "drift", str(sensor), "--out", str(tmp_path / "d")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert good.returncode == 0 and good.stderr == ""
    assert good.stdout.splitlines()[0].startswith("attitude: 1-sigma drift after 3600 s")
    assert good.stdout.splitlines()[-1] == f"wrote {tmp_path / 'd' / 'drift.csv'}"
    assert (tmp_path / "d" / "drift.csv").read_text().startswith("t_s,")


def test_a_reader_that_leaves_early_does_not_stop_the_run(tmp_path):
    """``bayes-imu ... | head -1``: standard output closed before the command prints. The run goes
    on quietly and writes its outputs (status 0, nothing on standard error), as with a reader that
    stays."""
    sensor = tmp_path / "s.json"
    sensor.write_text(json.dumps({"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3}))
    proc = subprocess.Popen(
        [sys.executable, "-m", "bayes_imu.cli", "drift", str(sensor), "--out", str(tmp_path / "d")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    proc.stdout.close()  # the reader is gone before the first line
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and err == ""
    assert (tmp_path / "d" / "drift.csv").read_text().startswith("t_s,")


def test_plotting_imports_are_quiet(tmp_path):
    """ArviZ announces a refactor on standard error once a day (a stamp file in the user's cache
    folder, written when it announces). The plotting warm-up no longer imports it (corner without
    ArviZ), and where corner's ArviZ entry point imports it later, it does so without a word: on a
    day with no stamp yet, nothing is printed and the stamp shows that ArviZ did reach its
    announcement."""
    code = (
        "import sys; from bayes_imu.report.plots import import_plotting; import_plotting(); "
        "assert 'arviz' not in sys.modules; import corner, numpy as np; "
        "corner.corner({'x': np.random.default_rng(0).normal(size=(2, 100))}); assert 'arviz' in "
        "sys.modules"
    )
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}  # no stamp: ArviZ announces today
    quiet = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == ""
    assert any(tmp_path.rglob("daily_warning"))


def test_warm_ups_leave_nothing_behind(tmp_path, monkeypatch):
    """The worker's warm-ups write only inside a temporary folder they remove, and close their
    figure."""
    import tempfile

    from bayes_imu.report.plots import import_plotting, pyplot

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    import_plotting()
    assert list(tmp_path.iterdir()) == []
    assert pyplot().get_fignums() == []


def _report_default(conn):
    conn.send(background_default())


def test_no_output_process_from_a_daemonic_process(monkeypatch):
    """A daemonic process (a Dask or multiprocessing pool worker) may not start children: there the
    outputs are written in-process, whatever the environment variable asks."""
    monkeypatch.setenv(WORKERS_ENV, "1")
    context = multiprocessing.get_context("spawn")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_report_default, args=(send,), daemon=True)
    child.start()
    assert receive.recv() is False
    child.join()
    assert background_default() is True  # the same setting, not daemonic


def test_python_callers_of_main_write_in_process_unless_asked(tmp_path, rng, monkeypatch):
    """main() from Python (no environment setting) writes a fit's outputs in the calling process: a
    spawned output process re-runs the caller's script, which without a __main__ guard ran the
    command again there (an 'internal error' printed by the child). The executable and an explicit
    setting use the worker."""
    import sys as _sys

    import bayes_imu.report.runs as runs

    cli = _sys.modules["bayes_imu.cli.main"]
    chosen = []

    class Recording(OutputWriter):
        def __init__(self, background=None, warm=()):
            chosen.append(background_default() if background is None else background)
            super().__init__(False, ())

    monkeypatch.setattr(runs, "OutputWriter", Recording)  # the fit's run (report.runs)
    log = tmp_path / "log.csv"
    log.write_text(
        "gyro\n" + "\n".join(f"{v:.9g}" for v in 0.05 * rng.standard_normal(4096)) + "\n"
    )
    monkeypatch.delenv(WORKERS_ENV, raising=False)
    # a machine with spare cores, fixed for the test: the real running count changes between calls
    # (other tests run beside this one), so comparing with a later background_default() raced
    import bayes_imu.report.worker as worker

    monkeypatch.setattr(worker, "usable_cpus", lambda: 4)
    monkeypatch.setattr(worker, "spare_cpus", lambda: 3.0)
    args = [
        "fit",
        str(log),
        "--column",
        "gyro",
        "--rate",
        "100",
        "--terms",
        "white",
        "--quiet",
        "--out",
    ]
    assert main(args + [str(tmp_path / "a")]) == 0
    monkeypatch.setattr(cli, "_EXECUTABLE", True)  # as bayes_imu.cli:command sets it
    assert main(args + [str(tmp_path / "b")]) == 0
    assert chosen == [False, True]  # the Python caller in process despite spare cores
    assert not _children()


def _slow_warm_up(folder):
    import tempfile

    with tempfile.TemporaryDirectory(dir=folder):
        (Path(folder) / "started").touch()
        time.sleep(30)


def test_stopped_during_its_warm_up_the_worker_leaves_no_temporary_folder(tmp_path):
    """The caller can finish (or fail) while the worker still warms up (a warm-up that writes into a
    temporary folder): stopped then, the worker removes that folder on its way out."""
    import functools

    writer = OutputWriter(background=True, warm=(functools.partial(_slow_warm_up, str(tmp_path)),))
    deadline = time.perf_counter() + 60
    while not (tmp_path / "started").exists() and time.perf_counter() < deadline:
        time.sleep(0.05)
    writer.stop()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["started"]
    assert not _children()


def _write_value(path, holder, ballast=None):
    Path(path).write_text(json.dumps(holder), encoding="utf-8")


def test_a_call_sends_its_arguments_as_they_were_when_submitted(tmp_path):
    """The arguments are pickled as the call is submitted: a caller that changes them afterwards
    (a fit result's cached properties, filled while the figures were queued) neither changes what
    the worker gets nor breaks its pickling ("dictionary changed size during iteration" stopped
    the worker about one run in six). The worker starts slowly and a first call fills the pipe,
    so a sender that pickled later would see the change."""
    import functools

    holder = {"value": 1}
    with OutputWriter(background=True, warm=(functools.partial(time.sleep, 1.0),)) as writer:
        writer.submit(_write_value, tmp_path / "first.json", {"value": 0},
                      ballast=np.zeros(1 << 20))  # 8 MB: more than a pipe holds
        writer.submit(_write_value, tmp_path / "second.json", holder)
        for k in range(200):  # the dictionary changes size after the call was submitted
            holder[f"late{k}"] = k
        holder["value"] = 2
    assert json.loads((tmp_path / "second.json").read_text()) == {"value": 1}
    assert not _children()


def test_this_process_running_threads_are_not_other_work(monkeypatch):
    """/proc/loadavg's running count includes this process's own running threads (numpy's BLAS
    pool spins a while after work): they are not other work, so two of them running beside one
    other task still leave a CPU of two free; unreadable thread states count this thread alone."""
    from bayes_imu.report import worker

    def proc(states, running):
        def fake_open(path, *a, **k):
            if str(path) == "/proc/loadavg":
                return io.StringIO(f"0.30 0.30 0.30 {running}/200 999\n")
            task = str(path).split("/")[-2]
            return io.StringIO(f"{task} (python3 (x)) {states[int(task)]} 1 2 3\n")
        return fake_open

    monkeypatch.delenv(WORKERS_ENV, raising=False)
    monkeypatch.setattr(worker, "usable_cpus", lambda: 2)
    monkeypatch.setattr(worker.os, "listdir", lambda path: ["0", "1"])
    monkeypatch.setattr("builtins.open", proc({0: "R", 1: "R"}, 3))
    assert worker._own_running() == 2
    assert worker.spare_cpus() == 1 and background_default() is True  # one other task
    monkeypatch.setattr("builtins.open", proc({0: "R", 1: "S"}, 3))
    assert worker.spare_cpus() == 0 and background_default() is False  # two other tasks
    monkeypatch.setattr("builtins.open", proc({0: "S", 1: "S"}, 1))
    assert worker._own_running() == 1  # the asking thread runs, whatever its stat said
    monkeypatch.setattr(worker.os, "listdir", lambda path: ["0", "1", "2"])
    monkeypatch.setattr("builtins.open", proc({0: "R", 1: "R", 2: "R"}, 4))
    assert worker.spare_cpus() == 1
    monkeypatch.setattr("builtins.open", lambda *a, **k: io.StringIO("no parenthesis\n"))
    assert worker._own_running() == 1
