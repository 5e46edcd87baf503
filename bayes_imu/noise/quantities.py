"""Sensor kinds and the drift quantities they integrate to: one home for both.

A *sensor kind* (:data:`SENSORS`) is what the rate samples measure: a gyro (angular rate, SI
unit rad/s) or an accelerometer (specific force, m/s^2). A *drift quantity*
(:data:`QUANTITIES`) is what the navigation integrates a sensor's error to: attitude (a gyro,
integration order 1, rad), velocity (an accelerometer, order 1, m/s) and position (an
accelerometer, order 2, m). Sensors, outputs, datasheets and Kalibr files look kinds and
quantities up here instead of re-deriving them from unit strings.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, ModelError
from ..io.readers import SI_UNITS, UNITS

__all__ = ["Sensor", "Quantity", "SENSORS", "QUANTITIES", "G", "DEG", "UG", "sensor", "quantity",
           "sensor_of_unit", "sensor_of_si_unit", "si_sensor",
           "order_of"]

#: standard gravity [m/s^2]
G = 9.80665
#: one rad in degrees
DEG = 180.0 / np.pi
#: one m/s^2 in micro-g
UG = 1.0 / (G * 1e-6)


@dataclass(frozen=True)
class Sensor:
    """A sensor kind.

    Attributes
    ----------
    name : str
        ``"gyro"`` or ``"accel"`` (the names the command line and scene files use).
    si_unit : str
        SI unit of its rate samples.
    quantities : tuple of str
        The drift quantities it integrates to, in increasing order.
    long_name : str
        What Kalibr and datasheets call it.
    """

    name: str
    si_unit: str
    quantities: tuple
    long_name: str


@dataclass(frozen=True)
class Quantity:
    """A drift quantity: the Euler integral of a sensor's error of one order.

    Attributes
    ----------
    name : str
    sensor : str
        The sensor kind it is integrated from.
    order : int
        Integration order (1 or 2).
    si_unit : str
        SI unit of the quantity.
    """

    name: str
    sensor: str
    order: int
    si_unit: str


SENSORS = {
    "gyro": Sensor("gyro", SI_UNITS["gyro"], ("attitude",), "gyroscope"),
    "accel": Sensor("accel", SI_UNITS["accel"], ("velocity", "position"), "accelerometer"),
}
QUANTITIES = {
    "attitude": Quantity("attitude", "gyro", 1, "rad"),
    "velocity": Quantity("velocity", "accel", 1, "m/s"),
    "position": Quantity("position", "accel", 2, "m"),
}


def sensor(name):
    """The :class:`Sensor` called ``name``; :class:`InputError` for any other name."""
    if name not in SENSORS:
        raise InputError(f"sensor kind {name!r}: expected one of {', '.join(SENSORS)}")
    return SENSORS[name]


def quantity(name):
    """The :class:`Quantity` called ``name``; :class:`InputError` for any other name."""
    if name not in QUANTITIES:
        raise InputError(f"quantity={name!r}: expected one of {', '.join(QUANTITIES)}")
    return QUANTITIES[name]


def sensor_of_si_unit(unit):
    """Sensor kind name of an SI rate unit (``"rad/s"`` -> ``"gyro"``, ``"m/s^2"`` -> ``"accel"``),
    else ``None``: what a result fitted in ``unit`` is, when it does not carry its sensor kind."""
    return next((name for name, s in SENSORS.items() if s.si_unit == unit), None)


def si_sensor(sensor, unit):
    """The sensor kind of a result in ``unit`` whose own kind is ``sensor`` (or ``None``), when
    ``unit`` is that kind's SI unit (what datasheet units are converted from), else ``None``.

    Raises
    ------
    InputError
        When ``unit`` is the SI unit of another kind than ``sensor``.
    """
    kind = sensor_of_si_unit(unit)
    if sensor is None or kind is None:
        return kind
    if kind != sensor:
        raise InputError(f"unit {unit!r} is an {SENSORS[kind].long_name}'s, but the result is a "
                         f"{SENSORS[sensor].long_name}'s ({SENSORS[sensor].si_unit})")
    return kind


def sensor_of_unit(unit):
    """Sensor kind name of a rate unit (``"deg/s"`` -> ``"gyro"``), or ``None`` for a unit of no
    known kind."""
    entry = UNITS.get(unit)
    return None if entry is None else entry[0]


def order_of(name):
    """Integration order of a quantity; :class:`ModelError` if the order is not a supported one."""
    order = quantity(name).order
    if order not in (1, 2):  # pragma: no cover - the table above holds only supported orders
        raise ModelError(f"quantity {name!r} has order {order}: expected 1 or 2")
    return order
