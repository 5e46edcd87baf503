"""Stage 1, input: logs in, checked samples out.

Owns reading text logs (:mod:`~bayes_imu.io.readers`: CSV/whitespace, compressed, columns,
units and their conversion to SI, JSON objects), the time base (:mod:`~bayes_imu.io.timebase`:
rates from time stamps, gaps) and ROS bags (:mod:`~bayes_imu.io.bags`). Nothing here knows
about Allan variances or noise models.
"""

from .readers import (
    LogData,
    read_log,
    read_columns,
    read_text,
    check_signal,
    SignalExtent,
    positive_number,
    UNITS,
    to_si,
    MAX_MAGNITUDE,
)

__all__ = [
    "LogData",
    "read_log",
    "read_columns",
    "read_text",
    "check_signal",
    "SignalExtent",
    "positive_number",
    "UNITS",
    "to_si",
    "MAX_MAGNITUDE",
]
