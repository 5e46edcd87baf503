"""Fleets of sensors: many jobs in parallel on Dask distributed, each failure isolated.

A job is a frozen spec (:class:`BatchJob`: a name, the frozen request of the work and its output
folder) and a task
function runs it: ``task(job)`` returns normally on success and raises on failure
(:class:`~bayes_imu.errors.BayesIMUError` is a user error, status 2; anything else an internal
error, status 1). The task must be a module-level function (Dask pickles it by reference);
``bayes-imu fit-batch`` passes its own fit and one :class:`~bayes_imu.report.writers.FitRequest` per
log (never an argv), so each log runs exactly what ``bayes-imu fit`` would run alone (same options,
same seed), into ``OUT/<log name>/``, and the results are
identical to serial runs. A failed job is reported with its status and its one-line error
and does not stop the others. :func:`run_batch` uses a ``LocalCluster``
(one single-threaded worker process per core) unless given the address of a running
Dask scheduler (``tcp://host:8786``), or runs serially in-process with ``scheduler="serial"``.
Dask is an optional dependency (``pip install 'bayes_imu[fleet]'``), imported only here.
"""

import contextlib
import io
import time
from dataclasses import asdict, dataclass

from .output import safe_folder_name
from .worker import PICTURE_FAILED_STATUS
from ..errors import InputError

__all__ = ["BatchJob", "JobResult", "run_batch", "job_name"]

#: how long to try to reach a given Dask scheduler before the batch fails (a Dask duration)
CONNECT_TIMEOUT = "10s"


@dataclass(frozen=True)
class BatchJob:
    """One job of a batch: its name (the output sub-folder), the frozen request of its work (for
    ``bayes-imu fit-batch``: a :class:`~bayes_imu.report.writers.FitRequest`) and its output
    folder."""

    name: str
    request: object
    out: object = None


@dataclass(frozen=True)
class JobResult:
    """Outcome of one log: exit status (0, 2 user error, 1 internal error, 3 a picture not drawn),
    the error line, wall time (s)."""

    name: str
    status: int
    error: str
    seconds: float
    worker: str

    @property
    def fitted(self):
        """Whether the log's numbers were written (a picture that failed costs only the picture)."""
        return self.status in (0, PICTURE_FAILED_STATUS)

    def to_json(self):
        return asdict(self)


def job_name(path, taken):
    """Output sub-folder name for a log path (unique within ``taken``)."""
    stem = path.name
    for suffix in (".gz", ".csv", ".tsv", ".txt", ".npy", ".bag", ".f64", ".f32", ".bin", ".raw"):
        stem = stem.removesuffix(suffix)
    return safe_folder_name(stem, taken)


def run_job(task, job):
    """Run ``task(job)`` in this process; never raises (a failure is a :class:`JobResult`)."""
    import os
    import socket

    from ..errors import BayesIMUError

    start = time.perf_counter()
    status, error = 0, ""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            returned = task(job)
            # pictures not drawn
            if isinstance(returned, int) and not isinstance(returned, bool) and returned:
                status, error = (
                    returned,
                    "bayes-imu: warning: a picture was not drawn; the numbers were written",
                )
        except BayesIMUError as exc:
            status, error = 2, f"bayes-imu: error: {exc}"
        except BaseException as exc:  # noqa: BLE001 - a worker must report, not die
            text = str(exc).strip().splitlines()
            status, error = (
                1,
                f"bayes-imu: internal error: {type(exc).__name__}: {text[0] if text else ''}",
            )
    return JobResult(
        job.name,
        status,
        error,
        time.perf_counter() - start,
        f"{socket.gethostname()}:{os.getpid()}",
    )


def run_batch(jobs, task, *, scheduler=None, n_workers=None, progress=False):
    """Run ``task`` on every job of ``jobs`` (sequence of :class:`BatchJob`); their
    :class:`JobResult` in job order.

    Parameters
    ----------
    task : callable
        Module-level function ``task(job)``: returns on success, raises on failure.
    scheduler : None, "serial" or str
        ``None``: a new ``LocalCluster``; ``"serial"``: one after another in this process;
        otherwise the address of a running Dask scheduler.
    n_workers : int, optional
        Worker processes of the ``LocalCluster`` (default: one per core).
    progress : bool
        A progress bar over finished logs on standard error.
    """
    from .._progress import progress_bar

    jobs = list(jobs)
    if scheduler == "serial":
        with progress_bar(total=len(jobs), desc="logs", unit="log", enabled=progress) as bar:
            out = []
            for job in jobs:
                out.append(run_job(task, job))
                bar.update()
            return out
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError(
            "parallel batches need Dask: pip install 'bayes_imu[fleet]' (or scheduler='serial')"
        ) from None
    import logging

    # Dask's INFO chatter would drown the command's own lines
    for name in ("distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.ERROR)
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=n_workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            )
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout=CONNECT_TIMEOUT))
            except (OSError, TimeoutError) as exc:
                raise InputError(f"scheduler={scheduler}: cannot connect ({exc})") from None
        futures = client.map(run_job, [task] * len(jobs), jobs, pure=False,
                             key=[f"bayes-imu-job-{j.name}" for j in jobs])
        results = {}
        with progress_bar(total=len(jobs), desc="logs", unit="log", enabled=progress) as bar:
            for future in as_completed(futures):
                index = futures.index(future)
                try:
                    results[index] = future.result()
                except Exception as exc:  # the worker itself died (memory, killed)
                    results[index] = JobResult(
                        jobs[index].name, 1, f"bayes-imu: worker failed: {exc}", 0.0, ""
                    )
                bar.update()
    return [results[i] for i in range(len(jobs))]
