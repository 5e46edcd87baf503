"""What the machine lends this process: the one place that counts its CPUs (the output process,
:mod:`bayes_imu.report.worker`, and the picture's import thread of the navigation command,
:mod:`bayes_imu.report.nav`, ask it)."""

import os

__all__ = ["usable_cpus"]


def usable_cpus():
    """CPUs this process may run on (its affinity mask where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1
