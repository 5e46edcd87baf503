"""``python -m bayes_imu.cli``: the ``bayes-imu`` command."""

from .main import command

command()
