"""ROS bags without ROS: ``sensor_msgs/Imu`` topics of ROS1 ``.bag`` files and ROS2 bag folders.

Reading uses the pure-Python `rosbags` library (an optional dependency, ``pip install
bayes_imu[bags]``; imported only here, when a bag is read). Columns are the fields of
``sensor_msgs/Imu``: ``gyro_x``, ``gyro_y``, ``gyro_z`` (``angular_velocity``, rad/s) and
``accel_x``, ``accel_y``, ``accel_z`` (``linear_acceleration``, m/s^2). The time of each
sample is its header stamp (integer nanoseconds since the first message, so epoch times
lose no precision), checked as a CSV time column
(:func:`bayes_imu.io.timebase.check_time`, messages numbered from 1 in bag order).
"""

from pathlib import Path

import numpy as np

from ..errors import InputError
from .readers import LogData, check_signal

__all__ = ["IMU_FIELDS", "is_bag", "read_imu_bag"]

#: column name -> (message field, vector component)
IMU_FIELDS = {
    "gyro_x": ("angular_velocity", "x"),
    "gyro_y": ("angular_velocity", "y"),
    "gyro_z": ("angular_velocity", "z"),
    "accel_x": ("linear_acceleration", "x"),
    "accel_y": ("linear_acceleration", "y"),
    "accel_z": ("linear_acceleration", "z"),
}
_IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")


def is_bag(path):
    """A ROS1 ``.bag`` file, a ROS2 bag folder (with ``metadata.yaml``), or a ROS2
    ``.db3``/``.mcap`` file."""
    path = Path(path)
    return path.suffix in (".bag", ".db3", ".mcap") or (
        path.is_dir() and (path / "metadata.yaml").exists()
    )


def read_imu_bag(path, *, topic, columns):
    """Samples of ``sensor_msgs/Imu`` fields on ``topic``, with their header stamps.

    Parameters
    ----------
    path : str or Path
        ROS1 ``.bag`` file or ROS2 bag folder.
    topic : str
        e.g. ``"/imu0"``.
    columns : sequence of str
        Keys of :data:`IMU_FIELDS`.

    Returns
    -------
    LogData
        ``values`` of shape ``(n_messages, len(columns))`` (rad/s, m/s^2), ``time_s`` the header
        stamps (s since the first message) and ``lines`` the message numbers (1-based, bag order).
    """
    path = Path(path)
    unknown = [c for c in columns if c not in IMU_FIELDS]
    if unknown:
        raise InputError(
            f"columns={unknown[0]!r}: expected sensor_msgs/Imu fields {', '.join(IMU_FIELDS)}"
        )
    if not path.exists():
        raise InputError(f"{path}: no such file or bag folder")
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(
            "reading ROS bags needs the rosbags package: pip install 'bayes_imu[bags]'"
        ) from None
    source = path.parent if path.suffix in (".db3", ".mcap") else path
    try:
        with AnyReader([source], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                imu_topics = sorted(
                    {c.topic for c in reader.connections if c.msgtype in _IMU_TYPES}
                )
                raise InputError(f"{path}: no topic {topic!r}; sensor_msgs/Imu topics in the bag: "
                                 f"{', '.join(imu_topics) or 'none'}")
            if connections[0].msgtype not in _IMU_TYPES:
                raise InputError(
                    f"{path}: topic {topic!r} carries {connections[0].msgtype}; expected "
                    "sensor_msgs/Imu"
                )
            rows, stamps = [], []
            for connection, _, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                rows.append(
                    [getattr(getattr(msg, IMU_FIELDS[c][0]), IMU_FIELDS[c][1]) for c in columns]
                )
                stamps.append(
                    int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
                )
    except InputError:
        raise
    except Exception as exc:  # rosbags raises its own family for unreadable bags
        text = str(exc).strip().splitlines()
        raise InputError(
            f"{path}: cannot read as a ROS bag ({type(exc).__name__}: {text[0] if text else ''})"
        ) from None
    if not rows:
        raise InputError(f"{path}: topic {topic!r} has no messages")
    values = np.asarray(rows, dtype=np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(
            f"{path}: message {i + 1}, {columns[j]}: got {values[i, j]!r}; expected a finite number"
        )
    for j, column in enumerate(columns):
        check_signal(values[:, j], where=f"{path}: {topic} {column}")
    # integer nanoseconds relative to the first stamp: epoch seconds in float64 keep only ~0.2 us
    time_s = (np.asarray(stamps, dtype=np.int64) - stamps[0]) * 1e-9
    return LogData(
        values, tuple(columns), str(path), time_s, np.arange(1, len(rows) + 1), "ros bag", True
    )
