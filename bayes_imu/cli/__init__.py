"""Stage 7, the command line: argv in, library calls, files and exit status out.

Owns argument parsing into frozen request objects (the log a command names is a
:class:`~bayes_imu.allan.pipeline.LogSource`), printing, and mapping library errors to one-line
messages and exit status 2 (:mod:`~bayes_imu.cli.main`). The library never imports it.
"""

from .main import command, main

__all__ = ["main", "command"]
