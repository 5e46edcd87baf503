"""Fleets of sensors: many ``bayes-imu fit`` runs in parallel on Dask distributed.

Each log is one task that runs exactly the ``bayes-imu fit`` command it would run alone
(same options, same seed), in a worker process, into ``OUT/<log name>/``; so the results
are identical to serial runs. A failed log is reported with its exit status and its
one-line error and does not stop the others. :func:`run_batch` uses a ``LocalCluster``
(one single-threaded worker process per core) unless given the address of a running
Dask scheduler (``tcp://host:8786``), or runs serially in-process with ``scheduler="serial"``.
Dask is an optional dependency (``pip install 'bayes_imu[fleet]'``), imported only here.
"""

import contextlib
import io
import time
from dataclasses import asdict, dataclass

from ._output import safe_folder_name
from .errors import InputError

__all__ = ["BatchJob", "JobResult", "run_batch", "job_name"]


@dataclass(frozen=True)
class BatchJob:
    """One log of a batch: its name (the output sub-folder) and its ``bayes-imu fit`` arguments."""

    name: str
    argv: tuple


@dataclass(frozen=True)
class JobResult:
    """Outcome of one log: exit status (0, 2 user error, 1 internal error), the error line, wall time (s)."""

    name: str
    status: int
    error: str
    seconds: float
    worker: str

    def to_json(self):
        return asdict(self)


def job_name(path, taken):
    """Output sub-folder name for a log path (unique within ``taken``)."""
    stem = path.name
    for suffix in (".gz", ".csv", ".tsv", ".txt", ".npy", ".bag", ".f64", ".f32", ".bin", ".raw"):
        stem = stem.removesuffix(suffix)
    return safe_folder_name(stem, taken)


def run_job(job):
    """Run one ``bayes-imu fit`` in this process; never raises (a failure is a result)."""
    import os
    import socket

    from .cli import main

    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            status = main(list(job.argv))
        except BaseException as exc:  # noqa: BLE001 - a worker must report, not die
            status, err = 1, io.StringIO(f"bayes-imu: internal error: {type(exc).__name__}: {exc}")
    lines = [line for line in err.getvalue().splitlines() if "error" in line]
    return JobResult(job.name, int(status), lines[-1] if (status and lines) else "", time.perf_counter() - start,
                     f"{socket.gethostname()}:{os.getpid()}")


def run_batch(jobs, *, scheduler=None, n_workers=None, progress=False):
    """Run ``jobs`` (sequence of :class:`BatchJob`) and return their :class:`JobResult` in job order.

    Parameters
    ----------
    scheduler : None, "serial" or str
        ``None``: a new ``LocalCluster``; ``"serial"``: one after another in this process;
        otherwise the address of a running Dask scheduler.
    n_workers : int, optional
        Worker processes of the ``LocalCluster`` (default: one per core).
    progress : bool
        A progress bar over finished logs on standard error.
    """
    from ._progress import progress_bar

    jobs = list(jobs)
    if scheduler == "serial":
        with progress_bar(total=len(jobs), desc="logs", unit="log", enabled=progress) as bar:
            out = []
            for job in jobs:
                out.append(run_job(job))
                bar.update()
            return out
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError("parallel batches need Dask: pip install 'bayes_imu[fleet]' (or use --serial)") from None
    import logging

    for name in ("distributed", "tornado"):  # Dask's INFO chatter would drown the command's own lines
        logging.getLogger(name).setLevel(logging.ERROR)
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            cluster = stack.enter_context(LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                                       dashboard_address=None, silence_logs=logging.ERROR))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout="10s"))
            except (OSError, TimeoutError) as exc:
                raise InputError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        futures = client.map(run_job, jobs, pure=False, key=[f"bayes-imu-fit-{j.name}" for j in jobs])
        results = {}
        with progress_bar(total=len(jobs), desc="logs", unit="log", enabled=progress) as bar:
            for future in as_completed(futures):
                index = futures.index(future)
                try:
                    results[index] = future.result()
                except Exception as exc:  # the worker itself died (memory, killed)
                    results[index] = JobResult(jobs[index].name, 1, f"bayes-imu: worker failed: {exc}", 0.0, "")
                bar.update()
    return [results[i] for i in range(len(jobs))]
