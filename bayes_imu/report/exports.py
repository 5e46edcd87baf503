"""Filter noise files from fits: Kalibr, OpenVINS, VINS-Fusion, GTSAM and MATLAB, one code path.

Every format here takes the same two-term model (white noise + bias random walk) of each
sensor; they differ in names, units and time convention. The values are computed once, as
SI continuous-time densities (:class:`ImuNoise`), and each format is a conversion of those
four numbers (``to_fields``) with its exact inverse (``from_fields``, what the tests use to
round-trip published values):

* ``kalibr``: ``{gyroscope,accelerometer}_noise_density`` [rad/s/sqrt(Hz), m/s^2/sqrt(Hz)]
  and ``..._random_walk`` [rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)], continuous-time densities
  (Kalibr wiki "IMU Noise Model"; the EuRoC and TUM-VI ``imu0`` / ``imu_config.yaml`` files);
* ``openvins``: the Kalibr keys under ``imu0:`` (``kalibr_imu_chain.yaml``), continuous-time
  as Kalibr (OpenVINS discretises them itself: ``sigma/sqrt(dt)``, ``sigma_b sqrt(dt)``);
* ``vins``: ``gyr_n``, ``acc_n`` (noise), ``gyr_w``, ``acc_w`` (bias random walk), the same
  continuous-time densities in Kalibr's units (what VINS-Fusion users enter; its config
  comments call them "standard deviations");
* ``gtsam`` (JSON) and ``gtsam-py`` (a Python snippet): ``gyroscopeCovariance``,
  ``accelerometerCovariance``, ``biasOmegaCovariance``, ``biasAccCovariance`` of
  ``PreintegrationCombinedParams``: continuous-time covariances, the squared densities
  [(rad/s)^2/Hz, ...] times I3;
* ``matlab``: ``gyroparams`` / ``accelparams`` NoiseDensity [(rad/s)/sqrt(Hz), (m/s^2)/sqrt(Hz)]
  and RandomWalk [(rad/s)*sqrt(Hz), (m/s^2)*sqrt(Hz)]: the IEEE Std 952 N and K (the
  MathWorks example "Inertial Sensor Noise Analysis Using Allan Variance" sets them from the
  Allan deviation at tau = 1 s and 3 s), numerically the Kalibr densities.

Values: the point values are the posterior medians of
:func:`bayes_imu.report.kalibr.axis_densities` (the Kalibr conversion: the noise density
with the white equivalents of the short-term terms,
the bias terms as a random-walk density). With ``overbound=True`` the written values are
:func:`bayes_imu.drift.overbound.overbound`'s pair (a white + random-walk model whose
calibrated drift bounds the posterior's upper credible drift over ``[t_min, t_max]``), and
the point values, the factor over them and the horizons where the bound is tight are
listed in comments (JSON: in fields of their own).

Several axes of one sensor: one number per field, the largest over the axes (of each axis's
own point value, or of its own overbound), every axis's value listed beside it.
"""

from dataclasses import dataclass, field
import json
import math

import numpy as np

from .._version import __version__
from ..drift.overbound import overbound as overbound_pair
from ..errors import InputError
from .kalibr import axis_densities, comment_text, fit_folders, rate_of

__all__ = [
    "ImuNoise",
    "ExportValues",
    "FORMATS",
    "export_values",
    "export_values_from_folders",
    "to_fields",
    "from_fields",
    "render_export",
    "write_export",
]

_KEYS = (
    "gyroscope_noise_density",
    "gyroscope_random_walk",
    "accelerometer_noise_density",
    "accelerometer_random_walk",
)
_KIND_KEYS = {"gyro": _KEYS[:2], "accel": _KEYS[2:]}
_SI = {
    "gyroscope_noise_density": "rad/s/sqrt(Hz)",
    "gyroscope_random_walk": "rad/s^2/sqrt(Hz)",
    "accelerometer_noise_density": "m/s^2/sqrt(Hz)",
    "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
}


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time two-term noise densities in SI (``None``: that sensor was not given).

    Attributes
    ----------
    gyroscope_noise_density : float [rad/s/sqrt(Hz)]
    gyroscope_random_walk : float [rad/s^2/sqrt(Hz)]
    accelerometer_noise_density : float [m/s^2/sqrt(Hz)]
    accelerometer_random_walk : float [m/s^3/sqrt(Hz)]
    update_rate : float [Hz]
    """

    gyroscope_noise_density: float = None
    gyroscope_random_walk: float = None
    accelerometer_noise_density: float = None
    accelerometer_random_walk: float = None
    update_rate: float = None

    def present(self):
        """``{key: value}`` of the densities given."""
        return {k: getattr(self, k) for k in _KEYS if getattr(self, k) is not None}


@dataclass(frozen=True)
class ExportValues:
    """What an export writes: the values, and what they came from.

    Attributes
    ----------
    noise : ImuNoise
        The written values (the overbound when computed, else the point values).
    point : ImuNoise
        Posterior medians (largest axis).
    bound : ImuNoise or None
        Overbounding values (largest axis), when asked for.
    per_axis : dict
        Key -> list of ``(axis label, point, overbound or None)`` [SI].
    tight : dict
        Key prefix (``gyroscope`` / ``accelerometer``) -> list of ``(axis, quantity, horizon [s])``.
    mode : str
    inadequate : tuple of str
        Axes whose fit failed its goodness-of-fit check.
    """

    noise: ImuNoise
    point: ImuNoise
    bound: ImuNoise = None
    per_axis: dict = field(default_factory=dict)
    tight: dict = field(default_factory=dict)
    mode: str = "posterior medians"
    inadequate: tuple = ()

    def factors(self):
        """Key -> written overbound over the point value (``nan`` without an overbound)."""
        if self.bound is None:
            return {k: float("nan") for k in self.point.present()}
        point = self.point.present()  # a term the point model lacks (0): an infinite factor
        return {k: v / point[k] if point[k] > 0 else math.inf if v > 0 else 1.0
                for k, v in self.bound.present().items()}


def export_values(
    gyro=(),
    accel=(),
    *,
    overbound=False,
    t_min=None,
    t_max=None,
    credibility=0.95,
    calibration_s=60.0,
    rng=None,
):
    """:class:`ExportValues` of the :class:`~bayes_imu.report.kalibr.KalibrAxis` of each sensor.

    ``overbound``: also compute each axis's overbounding pair over ``[t_min, t_max]`` [s] at
    ``credibility`` (:func:`bayes_imu.drift.overbound.overbound`) and write it.
    """
    if not gyro and not accel:
        raise InputError("export: give the fits of a gyro, an accelerometer, or both")
    rng = np.random.default_rng(rng)
    per_axis, tight, rates, inadequate = {}, {}, set(), []
    for kind, axes in (("gyro", gyro), ("accel", accel)):
        density_key, walk_key = _KIND_KEYS[kind]
        for axis in axes:
            density, walk = (float(np.median(d)) for d in axis_densities(axis.fit, axis.factor))
            bound = (None, None)
            if overbound:
                pair = overbound_pair(
                    axis.fit,
                    kind=kind,
                    t_min=t_min,
                    t_max=t_max,
                    credibility=credibility,
                    calibration_s=calibration_s,
                    rng=rng,
                )
                bound = (pair.noise_density * axis.factor, pair.random_walk * axis.factor)
                tight.setdefault(density_key.split("_")[0], []).extend(
                    (axis.label, q, t) for q, t in pair.tight_s
                )
            per_axis.setdefault(density_key, []).append((axis.label, density, bound[0]))
            per_axis.setdefault(walk_key, []).append((axis.label, walk, bound[1]))
            check = getattr(axis.fit, "adequacy", None)
            if check is not None and not check.adequate:
                inadequate.append(axis.label)
            rates.add(rate_of(axis.fit))
    if len(rates) != 1:
        raise InputError(f"fits have different rates {sorted(rates)} Hz: expected one IMU rate")
    rate = rates.pop()
    point = ImuNoise(
        **{k: max(p for _, p, _ in rows) for k, rows in per_axis.items()}, update_rate=rate
    )
    bound = (
        ImuNoise(
            **{k: max(b for _, _, b in rows) for k, rows in per_axis.items()}, update_rate=rate
        )
        if overbound
        else None
    )
    mode = (
        f"overbound of the upper {credibility:.0%} credible drift"
        if overbound
        else "posterior medians"
    )
    return ExportValues(bound or point, point, bound, per_axis, tight, mode, tuple(inadequate))


def export_values_from_folders(gyro_dirs=(), accel_dirs=(), **options):
    """:func:`export_values` of ``bayes-imu fit`` folders (fitted with ``--units``)."""
    return export_values(
        fit_folders(gyro_dirs, "gyro"), fit_folders(accel_dirs, "accel"), **options
    )


# ---------------------------------------------------------------------------- formats


def _square(v):
    return v * v


@dataclass(frozen=True)
class _Format:
    """Field names of one format, per SI key, with the map from SI and its inverse."""

    names: dict
    forward: object = float
    inverse: object = float
    units: dict = field(default_factory=dict)


_KALIBR = _Format({k: k for k in _KEYS}, units=_SI)
_GTSAM_NAMES = {
    "gyroscope_noise_density": "gyroscopeCovariance",
    "gyroscope_random_walk": "biasOmegaCovariance",
    "accelerometer_noise_density": "accelerometerCovariance",
    "accelerometer_random_walk": "biasAccCovariance",
}
#: format name -> its field names and conversion (module docstring)
FORMATS = {
    "kalibr": _KALIBR,
    "openvins": _KALIBR,
    "vins": _Format(
        {
            "gyroscope_noise_density": "gyr_n",
            "gyroscope_random_walk": "gyr_w",
            "accelerometer_noise_density": "acc_n",
            "accelerometer_random_walk": "acc_w",
        },
        units=_SI,
    ),
    "gtsam": _Format(
        _GTSAM_NAMES,
        _square,
        math.sqrt,
        {k: f"({u.replace('/sqrt(Hz)', '')})^2/Hz" for k, u in _SI.items()},
    ),
    "gtsam-py": _Format(
        _GTSAM_NAMES,
        _square,
        math.sqrt,
        {k: f"({u.replace('/sqrt(Hz)', '')})^2/Hz" for k, u in _SI.items()},
    ),
    "matlab": _Format(
        {
            "gyroscope_noise_density": "gyro.NoiseDensity",
            "gyroscope_random_walk": "gyro.RandomWalk",
            "accelerometer_noise_density": "accel.NoiseDensity",
            "accelerometer_random_walk": "accel.RandomWalk",
        },
        units={
            "gyroscope_noise_density": "(rad/s)/sqrt(Hz)",
            "gyroscope_random_walk": "(rad/s)*sqrt(Hz)",
            "accelerometer_noise_density": "(m/s^2)/sqrt(Hz)",
            "accelerometer_random_walk": "(m/s^2)*sqrt(Hz)",
        },
    ),
}


def _format(name):
    if name not in FORMATS:
        raise InputError(f"format={name!r}: expected one of {', '.join(FORMATS)}")
    return FORMATS[name]


def to_fields(noise, fmt):
    """``{field name: value}`` of an :class:`ImuNoise` in format ``fmt`` (its names and units)."""
    spec = _format(fmt)
    return {spec.names[k]: spec.forward(v) for k, v in noise.present().items()}


def from_fields(values, fmt, *, update_rate=None):
    """The :class:`ImuNoise` (SI) of ``{field: value}`` in format ``fmt`` (inverse of to_fields)."""
    spec = _format(fmt)
    back = {name: key for key, name in spec.names.items()}
    unknown = [n for n in values if n not in back]
    if unknown:
        raise InputError(f"{fmt} fields {unknown}: expected some of {', '.join(back)}")
    return ImuNoise(
        **{back[n]: spec.inverse(float(v)) for n, v in values.items()}, update_rate=update_rate
    )


# ---------------------------------------------------------------------------- files


def _comments(values, fmt):
    """Header lines (without the comment mark): provenance, and per-axis and point values."""
    spec = FORMATS[fmt]
    lines = [
        f"bayes_imu {__version__} {fmt} IMU noise: {values.mode}; continuous-time densities"
        + (" squared (covariances)" if fmt.startswith("gtsam") else "")
    ]
    if values.inadequate:
        lines.append(
            "WARNING: the noise model failed its goodness-of-fit check for "
            + ", ".join(values.inadequate)
        )
    several = any(len(rows) > 1 for rows in values.per_axis.values())
    if several:
        lines.append("one number per field: the largest over the axes (each axis below)")
    factors = values.factors()
    for key in _KEYS:
        if key not in values.per_axis:
            continue
        name, unit = spec.names[key], spec.units[key]
        point = spec.forward(values.point.present()[key])
        text = f"{name} [{unit}]: point (posterior median) {point!r}"
        if values.bound is not None:
            bound = spec.forward(values.bound.present()[key])
            text += f"; overbound {bound!r} (x{factors[key]:.3g} on the density)"
        lines.append(text)
        if several:
            for label, p, b in values.per_axis[key]:
                lines.append(
                    f"  {label}: point {spec.forward(p)!r}"
                    + ("" if b is None else f", overbound {spec.forward(b)!r}")
                )
    for sensor, rows in values.tight.items():
        lines.append(
            f"{sensor} bound tight at "
            + ", ".join(f"{q} {t:.4g} s ({label})" for label, q, t in rows)
        )
    return [comment_text(line) for line in lines]  # labels (folder, column names) end no comment


def render_export(values, fmt, *, topic="/imu0"):
    """The text of the export file in format ``fmt`` (every number to full double precision)."""
    if not isinstance(topic, str) or not topic.startswith("/") or any(c.isspace() for c in topic):
        raise InputError(f"topic={topic!r}: expected a ROS topic name such as /imu0")
    written = to_fields(values.noise, fmt)
    notes = _comments(values, fmt)
    rate = values.noise.update_rate
    if fmt == "gtsam":
        doc = {
            "bayes_imu_version": __version__,
            "format": "gtsam.PreintegrationCombinedParams",
            "convention": "continuous-time covariances: each value v means v * I3",
            "units": {FORMATS[fmt].names[k]: FORMATS[fmt].units[k] for k in values.noise.present()},
            "update_rate": rate,
            "notes": notes,
            **written,
        }
        return json.dumps(doc, indent=2) + "\n"
    if fmt == "gtsam-py":
        lines = [f"# {n}" for n in notes] + [
            "import numpy as np",
            "import gtsam",
            "",
            "params = gtsam.PreintegrationCombinedParams.MakeSharedU(9.80665)",
        ]
        lines += [
            f"params.set{name[0].upper()}{name[1:]}(np.eye(3) * {v!r})"
            for name, v in written.items()
        ]
        return "\n".join(lines) + "\n"
    if fmt == "matlab":
        lines = [f"% {n}" for n in notes]
        for sensor, maker in (("gyro", "gyroparams"), ("accel", "accelparams")):
            mine = {n: v for n, v in written.items() if n.startswith(sensor + ".")}
            if mine:
                lines.append(f"{sensor} = {maker};")
                lines += [f"{n} = {v!r};" for n, v in mine.items()]
        return "\n".join(lines) + "\n"
    lines = (["%YAML:1.0"] if fmt in ("openvins", "vins") else []) + [f"# {n}" for n in notes]
    indent = "  " if fmt == "openvins" else ""
    if fmt == "openvins":
        lines += ["imu0:", "  T_i_b:"] + [
            f"    - {row}"
            for row in (
                "[1.0, 0.0, 0.0, 0.0]",
                "[0.0, 1.0, 0.0, 0.0]",
                "[0.0, 0.0, 1.0, 0.0]",
                "[0.0, 0.0, 0.0, 1.0]",
            )
        ]
    lines += [f"{indent}{n}: {v!r}" for n, v in written.items()]
    if fmt in ("kalibr", "openvins"):
        lines += (
            [f"{indent}rostopic: {topic}", f"{indent}time_offset: 0.0"]
            if fmt == "openvins"
            else [f"rostopic: {topic}"]
        )
        lines.append(f"{indent}update_rate: {rate!r}")
    return "\n".join(lines) + "\n"


def write_export(values, path, fmt, *, topic="/imu0"):
    """Write :func:`render_export` to ``path`` (a path from ``report.output.staged_file``)."""
    path.write_text(render_export(values, fmt, topic=topic), encoding="utf-8")
