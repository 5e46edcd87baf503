"""Outputs written by a second process while the command goes on fitting.

A fit's figures cost imports (matplotlib and corner, without ArviZ: see
:func:`bayes_imu.report.plots.import_corner`) and rendering, all in Python (timings:
docs/speed_under_load.md#imports). :class:`OutputWriter` starts one worker
process (``spawn``: no fork of a threaded process) as the command starts; the worker imports
those libraries while the command reads the log and fits it on another core, then writes
each output it is sent. On Linux each output is written by a child forked from the warmed-up
worker: one at a time while the command is still fitting, side by side (one per usable CPU)
once it waits, so the figures of a fit cost about the longest of them
instead of their sum. With one usable CPU, or ``background=False``, the same calls run in
the calling process instead; the files are the same either way (tested).

The worker only writes where it is told (the command's staging folder,
:mod:`bayes_imu.report.output`); the caller waits for it (:meth:`OutputWriter.wait`) before the
outputs are moved into place, and stops it when anything fails, so a failed run leaves
nothing half-written. An error in the worker is raised again in the caller, with its type.

The worker may also compute for the caller (:meth:`OutputWriter.compute`, a future as
:mod:`concurrent.futures` gives): work the caller could do itself, sent ahead so that it runs on the
other core while the caller goes on (a fit's speculative mode searches: the ``pool`` of
:func:`bayes_imu.inference.fit.fit_allan`). Such a call comes back with its value or its exception
and stops nothing.

The environment variable :data:`WORKERS_ENV` (``0`` or ``1``) overrides the automatic choice.

**Numbers before pictures.** A picture is drawn through :meth:`OutputWriter.picture` (or
:func:`draw_picture`): any ``Exception`` while drawing it (a label matplotlib rejects, a missing
font, a library bug) removes the partial file and is recorded as a :class:`PictureFailure`
(:attr:`OutputWriter.picture_failures`) instead of stopping the run, so the numbers
(summary.json, fit.npz, CSV files) are written and kept; the command then warns in one line
per picture and exits with :data:`PICTURE_FAILED_STATUS`.
"""

import os

from .._system import usable_cpus  # noqa: F401 (part of this module's API; tests patch it here)
from ..errors import InputError

__all__ = [
    "OutputWriter",
    "Computed",
    "PictureFailure",
    "draw_picture",
    "usable_cpus",
    "spare_cpus",
    "background_default",
    "WORKERS_ENV",
    "PICTURE_FAILED_STATUS",
]

#: environment variable: "0" writes outputs in the calling process, "1" in a worker process
WORKERS_ENV = "BAYES_IMU_OUTPUT_PROCESS"
#: exit status of a command whose numbers were written but one or more pictures failed
PICTURE_FAILED_STATUS = 3


class PictureFailure:
    """A picture that could not be drawn: its file name and the error, in one sanitised line."""

    def __init__(self, path, error, name=None):
        self.path = str(path)
        text = str(error).strip().splitlines()
        line = f"{type(error).__name__}: {text[0] if text else ''}"
        line = "".join(c if c.isprintable() else "?" for c in line)
        self.message = line if len(line) <= 160 else line[:157] + "..."
        #: what the picture is, where it has no file of its own (one embedded in report.html)
        self.name = None if name is None else "".join(c if c.isprintable() else "?" for c in name)

    def __str__(self):
        import os.path

        shown = self.name or os.path.basename(self.path)
        return f"{shown} was not drawn ({self.message}); the numbers were written"


def draw_picture(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, a function drawing a picture into ``args[1]`` (its path, or
    ``path=``): ``None``,
    or a :class:`PictureFailure` (the partial file removed) where it raised an ``Exception``.
    Ctrl-C, SIGTERM,
    exits and a full disk still stop the run."""
    import errno

    path = kwargs.get("path", args[1] if len(args) > 1 else None)  # or a buffer: nothing to remove
    try:
        fn(*args, **kwargs)
    except Exception as exc:
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise  # a full disk stops the run: the previous results are kept (report.output)
        if isinstance(path, (str, os.PathLike)):
            try:
                os.unlink(path)
            except OSError:
                pass
        return PictureFailure("picture" if path is None else path, exc)
    return None


def background_default(automatic=True):
    """Whether outputs go to a worker process: :data:`WORKERS_ENV` if set, else (``automatic``) a
    spare CPU (:func:`spare_cpus` at least 1); never from a daemonic process (a Dask or
    multiprocessing worker), which may not start one. ``automatic=False``: only where the variable
    asks (a Python caller of the command, whose script a spawned process would run again)."""
    import multiprocessing

    value = os.environ.get(WORKERS_ENV, "").strip()
    if value and value not in ("0", "1"):
        raise InputError(f"environment variable {WORKERS_ENV}={value!r}: expected 0 or 1")
    if multiprocessing.current_process().daemon:
        return False
    if value:
        return value == "1"
    return automatic and usable_cpus() >= 2 and spare_cpus() >= 1.0


def spare_cpus():
    """Usable CPUs less the tasks running now other than this process's threads
    (``/proc/loadavg``'s running count less :func:`_own_running`, Linux; elsewhere the one-minute
    load average): the cores other work leaves free for the next seconds, the fit's length.

    The output process pays where it has a core of its own: on a busy machine it only adds its
    imports (measured on 2 cores under a load of 19 from other jobs, 1e6-sample ``bayes-imu fit``,
    two runs each: 17.7 and 19.4 s wall, 3.5 and 3.8 s CPU with it; 15.2 and 15.3 s, 2.4 and 2.5 s
    without; issue 39). The load average is not used where the running count is known: it lags
    by about a minute both ways, and after a job that has just ended it declined the process on
    an idle machine, where it saves 0.4-0.5 s of a 2.5-3 s fit (``BAYES_IMU_OUTPUT_PROCESS`` 1
    against 0, two runs each of the synthetic 1e6-sample log and two ADIS16405 logs: 2.48-2.72 s
    against 2.86-3.20 s; docs/speed_under_load.md)."""
    try:
        with open("/proc/loadavg") as f:
            # "running/total": less this process's own running threads
            return usable_cpus() - (int(f.read().split()[3].split("/")[0]) - _own_running())
    except (OSError, ValueError, IndexError):
        pass
    try:
        load = os.getloadavg()[0]
    except OSError:  # not available on this platform: as if idle
        load = 0.0
    return usable_cpus() - load


def _own_running():
    """Threads of this process running now (Linux: state ``R`` in ``/proc/self/task/*/stat``), at
    least the one asking; 1 where they cannot be read. /proc/loadavg's running count includes them:
    on an idle 2-core machine a fit command's second thread (numpy's BLAS pool, which spins a
    while after work) was running in about half the checks, and with one more task that happened
    to run at that instant the check declined the output process: 1 check in 8 after the peer's
    run here, and 3-4 of the 18 real-log fits of each benchmark run of the seventeenth session
    (their CPU time about their wall time), each 0.25-0.3 s slower (docs/speed_under_load.md)."""
    try:
        count = 0
        for task in os.listdir("/proc/self/task"):
            with open(f"/proc/self/task/{task}/stat") as f:
                # the state follows the command name's closing parenthesis
                count += f.read().rsplit(")", 1)[1].split()[0] == "R"
        return max(count, 1)
    except (OSError, IndexError):
        return 1


#: seconds stop() waits for the worker to end on SIGTERM before it kills it
_TERM_WAIT_S = 3.0


class OutputWriter:
    """Run independent output-writing calls in a worker process (or here).

    In the worker, calls may run side by side and finish in any order (:func:`_serve`): a
    call must not need another's file. Once a call fails, no other starts, and those still
    running are stopped.

    Parameters
    ----------
    background : bool or None
        ``True``: a worker process; ``False``: each call runs at once in this process;
        ``None``: :func:`background_default`.
    warm : sequence of callables
        Called (without arguments) by the worker as it starts, typically functions that
        import the plotting libraries, so that the imports overlap the caller's work.

    Use as a context manager: leaving it normally waits for every call (raising the first
    error); leaving it by an exception stops the worker at once. Calls travel through pipes
    (no semaphores, nothing for multiprocessing's resource tracker to clean up); a thread
    sends them, so the caller never waits for the worker to read.
    """

    def __init__(self, background=None, warm=()):
        self.background = background_default() if background is None else bool(background)
        self._pending = 0
        self._process = None
        self._values, self._calls = {}, 0  # compute(): the values come back by call number
        self.picture_failures = []  # PictureFailure of each picture not drawn (picture())
        if self.background:
            import multiprocessing
            import queue
            import threading

            context = multiprocessing.get_context("spawn")
            job_out, job_in = context.Pipe(duplex=False)
            self._results, result_in = context.Pipe(duplex=False)
            self._process = context.Process(
                target=_serve,
                args=(job_out, result_in, tuple(warm)),
                daemon=True,
                name="bayes_imu-outputs",
            )
            self._process.start()
            job_out.close()
            result_in.close()
            self._outbox = queue.SimpleQueue()
            self._sender = threading.Thread(
                target=_send_all,
                args=(self._outbox, job_in),
                daemon=True,
                name="bayes_imu-outputs-sender",
            )
            self._sender.start()

    def submit(self, fn, *args, **kwargs):
        """Call ``fn(*args, **kwargs)``: at once here, or queued for the worker (arguments
        pickled)."""
        if not self.background:
            fn(*args, **kwargs)
            return
        self._outbox.put(_pickled((fn, args, kwargs)))
        self._pending += 1

    def picture(self, fn, *args, **kwargs):
        """:meth:`submit` of a picture: a failure to draw it is recorded in
        :attr:`picture_failures`, not raised
        (:func:`draw_picture`)."""
        if not self.background:
            failure = draw_picture(fn, *args, **kwargs)
            if failure is not None:
                self.picture_failures.append(failure)
            return
        self.submit(draw_picture, fn, *args, **kwargs)

    def compute(self, fn, *args, **kwargs):
        """``fn(*args, **kwargs)`` in the worker: a :class:`Computed` future. The worker runs such a
        call as it arrives, ahead of the outputs queued and in its own process (no fork: it is meant
        to be short, a few milliseconds, and the outputs wait for it); :meth:`wait` does not wait
        for it, and a call whose value is not needed in the end is stopped with the worker. Here (no
        worker) the call runs at once."""
        if not self.background:
            call = _Call(0, fn, args, kwargs)
            return Computed(None, 0, call())
        self._calls += 1
        self._outbox.put(_pickled((_Call(self._calls, fn, args, kwargs), (), {})))
        return Computed(self, self._calls)

    def pool(self):
        """This writer as an executor for :func:`~bayes_imu.inference.fit.fit_allan`'s ``pool``
        (``submit`` is
        :meth:`compute`)."""
        return _Pool(self)

    def _receive(self, block):
        """Take one message from the worker (``block``: wait for it); False where none has come. A
        finished output counts down :meth:`wait`'s calls, a computed value is kept, an output's
        error is raised."""
        if self._process is None or (not block and not self._results.poll(0)):
            return False
        outcome = self._next_result()
        if isinstance(outcome, _Value):
            self._values[outcome.number] = outcome
            return True
        self._pending -= 1
        if isinstance(outcome, PictureFailure):
            self.picture_failures.append(outcome)
        elif outcome is not None:
            self.stop()
            raise outcome
        return True

    def wait(self):
        """Block until every queued output is done; raise the first error one of them raised."""
        if self._pending:
            # this process now waits: the worker may use every CPU
            self._outbox.put(_pickled(_DRAIN))
        while self._pending:
            self._receive(block=True)

    def _next_result(self):
        while not self._results.poll(0.5):
            if not self._process.is_alive() and not self._results.poll():
                self._stopped_early()
        try:
            return self._results.recv()
        # the worker died (its end of the pipe closed): poll saw the end, not a result
        except (EOFError, OSError):
            self._process.join(5.0)
            self._stopped_early()

    def _stopped_early(self):
        code = self._process.exitcode
        self.stop()
        raise RuntimeError(
            f"the output process stopped (exit code {code}) before writing its outputs"
        )

    def stop(self):
        """Stop the worker at once (calls not yet done are dropped); it writes nothing more."""
        if self._process is not None:
            self._outbox.put(None)  # ends the sender thread
            if self._process.is_alive():
                self._process.terminate()
                # SIGTERM ends it at once (its handler stops its children and exits); one run of
                # the suite in many saw it finish a 30 s computed call first: then SIGKILL
                self._process.join(_TERM_WAIT_S)
                if self._process.is_alive():
                    self._process.kill()
            self._process.join()
            self._results.close()
            self._process = None
        self._pending = 0

    def close(self):
        """Wait for every queued call, then stop the worker (it has nothing left to write)."""
        try:
            self.wait()
        finally:
            self.stop()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.stop()
        return False


class Computed:
    """The future of :meth:`OutputWriter.compute`: ``done()`` (without waiting), ``exception()`` and
    ``result()`` (waiting), as :class:`concurrent.futures.Future` has them. A call whose worker was
    stopped before it finished is never done."""

    def __init__(self, writer, number, value=None):
        self._writer, self._number, self._value = writer, number, value

    def done(self):
        if self._value is None:
            while self._writer._receive(block=False):
                pass
            self._value = self._writer._values.pop(self._number, None)
        return self._value is not None

    def exception(self):
        self._wait()
        return self._value.error

    def result(self):
        self._wait()
        if self._value.error is not None:
            raise self._value.error
        return self._value.value

    def _wait(self):
        while not self.done():
            if not self._writer._receive(block=True):
                raise RuntimeError("the output process was stopped before it computed this value")


class _Pool:
    """An :class:`OutputWriter` seen as an executor: ``submit(fn, *args, **kwargs)`` is its
    ``compute``."""

    def __init__(self, writer):
        self.submit = writer.compute


class _Value:
    """What a computed call sends back: its number, and its value or its exception."""

    def __init__(self, number, value, error):
        self.number, self.value, self.error = number, value, error


class _Call:
    """A computed call as the worker runs it: its value or its exception, returned (never raised: a
    computation the caller can do itself stops no output)."""

    def __init__(self, number, fn, args, kwargs):
        self.number, self.fn, self.args, self.kwargs = number, fn, args, kwargs

    def __call__(self):
        try:
            return _Value(self.number, self.fn(*self.args, **self.kwargs), None)
        except Exception as exc:
            return _Value(self.number, None, _picklable(exc))


def _pickled(job):
    """A call pickled now, in the caller's thread, as the worker's ``recv`` reads it: pickled in the
    sender thread instead, a call's arguments could change while they were being pickled (a fit
    result's cached properties filled by the caller: "dictionary changed size during iteration",
    which stopped the worker about one run in six on an ADIS16405 log)."""
    from multiprocessing.reduction import ForkingPickler

    return bytes(ForkingPickler.dumps(job))


def _send_all(outbox, conn):
    """The sender thread: send each queued call (pickled by :func:`_pickled`), in order, until
    ``None``; the caller never waits for the worker to read."""
    try:
        while True:
            job = outbox.get()
            if job is None:
                return
            conn.send_bytes(job)
    except OSError:  # the worker was stopped
        return
    finally:
        conn.close()


def _serve(jobs, results, warm):
    """The worker: warm up, then run each call and send back ``None`` or its exception.

    Where the system forks (Linux), each call runs in a child forked from this warmed-up
    process (imports shared, nothing loaded again): one at a time while the caller is busy,
    as many as there are usable CPUs once it waits (:data:`_DRAIN`), so a fit's figures and
    ArviZ file (when sent) are written side by side. Elsewhere the calls run here, one after the
    other.
    """
    import signal
    import sys

    # Ctrl-C reaches the caller, which stops this process
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # stopped (OutputWriter.stop) while warming up or writing: leave through SystemExit, so that
    # temporary folders and open files are cleaned up as their `with` blocks end
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(1))
    for fn in warm:
        try:
            fn()
        except Exception:  # a failed warm-up import is reported by the call that needs it
            pass
    if _can_fork():
        import gc

        # the warmed-up objects: never collected, so children don't copy their pages to scan them
        gc.freeze()
        _serve_forking(jobs, results)
        return
    while True:
        try:
            job = jobs.recv()
        except EOFError:  # the caller is gone
            return
        if job == _DRAIN:
            continue
        outcome = _call(job)
        results.send(outcome)
        # sent back, raised again by the caller; nothing more is run
        if isinstance(outcome, BaseException):
            return


#: sent by the caller as it starts waiting: every usable CPU may write from then on
_DRAIN = "drain"


def _call(job):
    """Run one ``(fn, args, kwargs)``: ``None``, the exception it raised (picklable), or a computed
    call's
    :class:`_Value`."""
    fn, args, kwargs = job
    try:
        value = fn(*args, **kwargs)
    except BaseException as exc:
        return _picklable(exc)
    return value if isinstance(value, (_Value, PictureFailure)) else None


def _can_fork():
    """Whether calls run in forked children: Linux only (macOS's system libraries are not fork-safe
    once loaded; Windows has no fork)."""
    import sys

    return hasattr(os, "fork") and sys.platform.startswith("linux")


def _serve_forking(jobs, results):
    """:func:`_serve`'s loop with each output in a forked child (at most one while the caller is
    busy); a computed call (:meth:`OutputWriter.compute`) runs here at once, ahead of the outputs
    queued (it is short, and the caller may be waiting for it)."""
    import collections
    import signal
    from multiprocessing.connection import wait

    queued, running = collections.deque(), {}  # running: the child's result connection -> its pid

    def stop_children(*_):
        for pid in running.values():
            try:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            except OSError:
                pass
        running.clear()

    # OutputWriter.stop terminates this process: its children go with it
    def stopped(signum, frame):
        stop_children()
        os._exit(1)

    signal.signal(signal.SIGTERM, stopped)
    cpus, caller_waits = usable_cpus(), False
    while True:
        for conn in wait([*running, jobs]):
            if conn is jobs:
                try:
                    job = jobs.recv()
                except EOFError:  # the caller is gone: nothing more to send results to
                    stop_children()
                    return
                # the caller may be waiting for it
                if isinstance(job, tuple) and isinstance(job[0], _Call):
                    results.send(_call(job))
                    continue
                caller_waits = job == _DRAIN
                if not caller_waits:
                    queued.append(job)
                continue
            try:
                outcome = conn.recv()
            except EOFError:
                outcome = RuntimeError("an output-writing process stopped before it finished")
            os.waitpid(running.pop(conn), 0)
            conn.close()
            results.send(outcome)
            # raised again by the caller; nothing more is run
            if isinstance(outcome, BaseException):
                stop_children()
                return
        while queued and len(running) < (cpus if caller_waits else max(1, cpus - 1)):
            conn, pid = _fork_call(queued.popleft())
            running[conn] = pid


def _fork_call(job):
    """Run ``job`` in a forked child; returns (the connection its outcome arrives on, its pid)."""
    import multiprocessing
    import signal

    receive, send = multiprocessing.Pipe(duplex=False)
    pid = os.fork()
    if pid == 0:  # the child: run the call, send its outcome, leave without any teardown
        status = 1
        try:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            receive.close()
            send.send(_call(job))
            status = 0
        finally:
            os._exit(status)
    send.close()
    return receive, pid


def _picklable(exc):
    import pickle

    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return RuntimeError(f"{type(exc).__name__}: {exc}")
