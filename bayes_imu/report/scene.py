"""Component-selection reports: conservative drift bounds for several IMUs in one scene.

A *scene* (TOML, :func:`read_scene`) lists GPS-outage durations, a credibility, an
optional requirement on one quantity, and the sensors with their static logs. For each
sensor :func:`build_report` converts the log to SI (rad/s, m/s^2), fits it with model
selection (each sensor carries only the terms its data support), and computes:

* ``bounds``: for every outage and quantity, the posterior quantile at ``credibility`` of
  the 1-sigma drift ``sigma(t)`` (``bound``), widened where the record measures the drift as
  drift.csv's bands are (:class:`_Bound`), and its median; SI output units (rad, m/s, m);
* ``max_outage_s``: the longest outage whose bound on the required quantity stays within
  ``max_error``, found by bisection on a continuous time (the bound increases with t).

Paths (``log``, ``logs``, ``fit``, ``fits``) are relative to the scene's folder and confined to it
(after resolving ``..`` and links): a scene is a file a user may be handed, and ``log =
"/etc/shadow"``
must not make the report read it. ``allow_outside = true`` in ``[scene]`` (or
``allow_outside=True``,
the command's ``--allow-outside``) lifts the rule. The units of one sensor (``logs``, ``fits``) must
be distinct: the same file or folder twice, or two files with the same content, would count one
unit twice in the unit-to-unit spread (refused by name). A log may be a ``.npy`` file (one channel;
``column = "0"``), and text logs may give ``time_column`` (and ``time_unit``) instead of, or
besides, ``rate_hz``, as the command line does.

Ranking: longest ``max_outage_s`` first, ties (and scenes without a requirement) by the
bound at the longest outage; sensors that cannot provide the required quantity (a gyro
for a position requirement) rank last.
"""

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..allan.pipeline import LogSource, allan_from_source, check_source, with_article
from ..drift.bands import (DEFAULT_CALIBRATION_S, SENSOR_QUANTITIES, direct_part, drift_bands,
                           drift_draws)
from ..drift.direct import direct_contrasts
from ..noise import BIAS_STARTS
from ..noise.contrast_covariance import reused_sums
from ..noise.quantities import SENSORS
from ..drift.display import DISPLAY_CHOICES, parse_amount
from ..errors import InputError
from ..inference.fit import fit_allan
from ..drift.closed_forms import SI_OUTPUT_UNITS
from ..io.limits import RANGES, check_range
from ..io.readers import INCREMENT_UNITS, SI_UNITS, UNITS, read_text
from ..io.timebase import GAP_POLICIES, TIME_UNITS, check_rate

__all__ = [
    "Scene",
    "SensorSpec",
    "SensorReport",
    "Report",
    "read_scene",
    "build_report",
    "distinct_units",
    "check_logs",
    "OUTPUT_UNITS",
]

OUTPUT_UNITS = SI_OUTPUT_UNITS
MAX_SEARCH_S = 1e6


@dataclass(frozen=True)
class SensorSpec:
    """One ``[[sensor]]`` of a scene.

    Attributes
    ----------
    name, kind, units : str
    paths : tuple of Path
        The log (``log``), the logs of several units (``logs``), or fit folders (``fit`` /
        ``fits``).
    columns : tuple of str
        Axes to bound (the worst one counts); empty for fit folders (their axes are used).
    rate_hz : float or None
        Sample rate (Hz); ``None`` where the time stamps give it (``time_column``, a ROS bag).
    source : {"log", "logs", "fit", "fits"}
    reading : LogSource or None
        How each log is read (everything ``bayes-imu fit`` reads: time column and gaps, a ROS
        bag's topic, increments, out-of-core reading); its ``log`` is left empty. ``None``
        for fit folders.
    datasheet : tuple or None
        ``(path, kind, values)`` of the sensor's ``datasheet`` file
        (:mod:`bayes_imu.noise.datasheet_check`).
    """

    name: str
    paths: tuple
    columns: tuple
    rate_hz: float
    kind: str
    units: str
    source: str = "log"
    reading: LogSource = None
    datasheet: tuple = None

    @property
    def log(self):
        return self.paths[0]

    @property
    def column(self):
        return ",".join(self.columns) if self.columns else "(from the fit)"

    @property
    def population(self):
        """Several units: bounds are for a new unit of the model."""
        return len(self.paths) > 1


@dataclass(frozen=True)
class Scene:
    """A parsed scene file (see the module docstring and the README for the format)."""

    name: str
    outages_s: tuple
    credibility: float
    sensors: tuple
    requirement: dict | None = None
    bias_start: str = "calibrated"
    path: str = ""
    calibration_s: float = DEFAULT_CALIBRATION_S
    navigation: dict | None = None
    imus: tuple = ()
    #: ``"si"`` or ``"deg"`` (``[scene] display_units``, ``bayes-imu report --display-units``):
    #: report.html, comparison.png and report.json's ``*_display`` values; SI values are kept
    display_units: str = "si"


@dataclass(frozen=True)
class AxisResult:
    """One axis of a sensor: the posterior its bounds come from.

    Attributes
    ----------
    axis : str
    posterior : FitResult or UnitPosterior
        What the bounds use (a population's new-unit predictive for several units).
    fit : FitResult or None
        The single-unit fit (one log or fit folder).
    population : PopulationResult or None
    """

    axis: str
    posterior: object
    fit: object = None
    population: object = None

    @property
    def unit_fits(self):
        """``((label, FitResult), ...)``: the single-unit fits behind this axis, the fit alone
        (label ``None``) or each unit of the population (its label)."""
        if self.population is not None:
            return tuple(zip(self.population.labels, self.population.unit_fits))
        return () if self.fit is None else ((None, self.fit),)


@dataclass(frozen=True)
class SensorReport:
    """Bounds of one sensor: the worst axis at each outage and quantity (``bounds[i]["axis"]``).

    ``fit`` is the single-unit fit of the worst axis, or ``None`` for a population.
    """

    spec: SensorSpec
    axes: tuple
    bounds: tuple
    max_outage_s: float | None
    bands: tuple
    worst: int = 0

    @property
    def fit(self):
        return self.axes[self.worst].fit

    @property
    def posterior(self):
        return self.axes[self.worst].posterior

    @property
    def record_s(self):
        return self.posterior.record_s

    @property
    def datasheet_check(self):
        """``{"file", "axis", "values", "verdict"}``: the worst axis's probability of each
        datasheet value being within spec
        (:func:`~bayes_imu.noise.datasheet_check.check_datasheet`), or ``None`` without a
        datasheet."""
        if self.spec.datasheet is None:
            return None
        from ..noise.datasheet_check import check_datasheet, verdict

        path, kind, values = self.spec.datasheet
        checked = check_datasheet(self.posterior, kind, values)
        return {"file": str(path), "axis": self.axes[self.worst].axis, "values": checked,
                "verdict": verdict(checked)}


@dataclass(frozen=True)
class Report:
    scene: Scene
    sensors: tuple
    ranking: tuple
    reason: str
    imus: tuple = ()
    imu_ranking: tuple = ()
    imu_reason: str = ""

    def to_json(self):
        """JSON-ready dict (``report.json``)."""
        from .._version import __version__

        out = []
        for s in self.sensors:
            unit = _si_unit(s.spec.kind)
            entry = {
                "name": s.spec.name,
                "kind": s.spec.kind,
                "source": s.spec.source,
                "log": str(s.spec.log),
                "paths": [str(p) for p in s.spec.paths],
                "column": s.spec.column,
                "input_units": s.spec.units,
                "axes": [a.axis for a in s.axes],
                "worst_axis": s.axes[s.worst].axis,
            }
            if s.fit is not None:
                summary = s.fit.summary(unit=unit)
                entry.update(
                    {
                        k: summary[k]
                        for k in (
                            "model",
                            "parameters",
                            "diagnostics",
                            "candidates",
                            "adequacy",
                            "model_averaging",
                        )
                    }
                )
                entry["unit_to_unit"] = (
                    f"NOT included: the bounds are for the tested unit ({s.spec.log.name}); "
                    "another unit of this model may be worse (give several logs to include it)"
                )
            else:
                summary = s.axes[s.worst].population.summary(unit=unit)
                entry.update(
                    model=summary["model"],
                    parameters=summary["new_unit"],
                    population=summary["population"],
                    units=summary["units"],
                    structures=summary["structures"],
                    diagnostics=summary["diagnostics"],
                )
                n_units = len(s.axes[s.worst].population.labels)
                entry["unit_to_unit"] = (
                    f"included: the bounds are for a NEW unit of this model (posterior "
                    f"predictive of a hierarchical fit of {n_units} units)"
                )
            entry.update(bounds=list(s.bounds), max_outage_s=s.max_outage_s)
            if s.spec.datasheet is not None:
                entry["datasheet_check"] = s.datasheet_check
            out.append(entry)
        scene = self.scene
        doc = {"scene": scene.name, "credibility": scene.credibility,
               "outages_s": list(scene.outages_s), "requirement": scene.requirement,
               "bias_start": scene.bias_start,
               "calibration_s": scene.calibration_s if scene.bias_start == "calibrated" else None,
               "models": "averaged over the candidate models by posterior probability",
               "sensors": out, "ranking": list(self.ranking), "ranking_reason": self.reason,
               "bayes_imu_version": __version__}
        if self.scene.navigation is not None:
            from .scene_nav import navigation_json

            doc["navigation"] = navigation_json(self)
        if scene.display_units != "si":  # display values beside the SI ones, which stay
            _add_display(doc, self)
        return doc


def _add_display(doc, report):
    """``report.json`` under ``display_units = "deg"``: ``display_units``, the requirement's
    ``requirement_display``, and each sensor's ``parameters_display`` (a gyro's) and
    ``bounds_display`` (attitude in deg), beside the SI values."""
    from ..drift.display import display_parameters, display_unit

    display = report.scene.display_units
    doc["display_units"] = display
    req = doc["requirement"]
    if req is not None:
        unit, factor = display_unit(req["unit"], display)
        doc["requirement_display"] = {"quantity": req["quantity"],
                                      "max_error": req["max_error"] * factor, "unit": unit}
    for entry, s in zip(doc["sensors"], report.sensors):
        shown = display_parameters(entry["parameters"], _si_unit(s.spec.kind), display)
        if shown is not None:
            entry["parameters_display"] = shown
        rows = []
        for b in entry["bounds"]:
            unit, factor = display_unit(b["unit"], display)
            rows.append(dict(b, bound=b["bound"] * factor, median=b["median"] * factor, unit=unit))
        entry["bounds_display"] = rows


def _si_unit(kind):
    return SI_UNITS[kind]


def _excerpt(value, limit=80):
    """``repr(value)``, control characters as ``?``, at most ``limit`` characters: a value quoted
    in an error."""
    text = "".join(c if c.isprintable() else "?" for c in repr(value))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _get(table, key, kind, where, default=None, required=True):
    if key not in table:
        if required:
            raise InputError(f"{where}: missing key {_excerpt(key)}")
        return default
    value = table[key]
    if kind is float:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not np.isfinite(value)
            or value <= 0
        ):
            raise InputError(f"{where}: {key}={_excerpt(value)}: expected a positive number")
        return float(value)
    if not isinstance(value, str) or not value:
        raise InputError(f"{where}: {key}={_excerpt(value)}: expected a non-empty string")
    return value


def _known(table, keys, where):
    """Reject the first key of ``table`` not in ``keys``, by name, with the nearest key as a hint
    (``unit``: did you mean 'units'?)."""
    import difflib

    unknown = [k for k in table if k not in keys]
    if unknown:
        near = difflib.get_close_matches(str(unknown[0]), keys, n=1, cutoff=0.75)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise InputError(f"{where}: unknown key {_excerpt(unknown[0])}{hint}; expected keys: "
                         f"{', '.join(keys)}")


def read_scene(path, *, allow_outside=False):
    """Parse and validate a scene TOML file; paths are relative to the file and confined to its
    folder unless
    ``allow_outside`` (or ``allow_outside = true`` in ``[scene]``); the units of a sensor must be
    distinct."""
    path = Path(path)
    try:
        doc = tomllib.loads(read_text(path))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML "
                         f"({_excerpt(str(exc).splitlines()[0] if str(exc) else exc)})") from None
    except RecursionError:
        raise InputError(f"{path}: TOML nested too deeply; expected a scene file") from None
    _known(doc, ("scene", "requirement", "sensor", "navigation", "imu"), f"{path}: top level")
    scene = doc.get("scene")
    if not isinstance(scene, dict):
        raise InputError(f"{path}: missing [scene] table")
    _known(
        scene,
        (
            "name",
            "outages_s",
            "credibility",
            "bias_start",
            "calibration_s",
            "allow_outside",
            "display_units",
        ),
        f"{path}: [scene]",
    )
    display = scene.get("display_units", "si")
    if display not in DISPLAY_CHOICES:
        raise InputError(f"{path}: [scene] display_units={_excerpt(display)}: expected one of "
                         f"{', '.join(DISPLAY_CHOICES)}")
    outside = scene.get("allow_outside", False)
    if not isinstance(outside, bool):
        raise InputError(f"{path}: [scene] allow_outside={_excerpt(outside)}: expected true or "
                         "false")
    allow_outside = allow_outside or outside
    outages = scene.get("outages_s")
    low, high, _ = RANGES["time_s"]
    if (
        not isinstance(outages, list)
        or not outages
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and low <= v <= high
            for v in outages
        )
    ):
        raise InputError(f"{path}: [scene] outages_s={_excerpt(outages)}: expected a non-empty "
                         "list of seconds, each "
                         f"from {low:g} to {high:g}")
    cred = scene.get("credibility", 0.95)
    if isinstance(cred, bool) or not isinstance(cred, (int, float)) or not 0.5 <= cred < 1:
        raise InputError(f"{path}: [scene] credibility={_excerpt(cred)}: expected a number in "
                         "[0.5, 1)")
    bias_start = scene.get("bias_start", "calibrated")
    if bias_start not in BIAS_STARTS:
        raise InputError(f"{path}: [scene] bias_start={_excerpt(bias_start)}: expected one of "
                         f"{', '.join(BIAS_STARTS)}")
    calibration = scene.get("calibration_s", DEFAULT_CALIBRATION_S)
    if isinstance(calibration, bool) or not isinstance(calibration, (int, float)):
        raise InputError(f"{path}: [scene] calibration_s={_excerpt(calibration)}: expected a "
                         "number of seconds")
    check_range("calibration_s", calibration, f"{path}: [scene] calibration_s")
    requirement = doc.get("requirement")
    if requirement is not None:
        where = f"{path}: [requirement]"
        if not isinstance(requirement, dict):
            raise InputError(f"{where}: expected a table")
        _known(requirement, ("quantity", "max_error"), where)
        quantity = _get(requirement, "quantity", str, where)
        if quantity not in OUTPUT_UNITS:
            raise InputError(f"{where} quantity={_excerpt(quantity)}: expected one of "
                             f"{', '.join(OUTPUT_UNITS)}")
        if "max_error" not in requirement:
            raise InputError(f"{where}: missing key 'max_error'")
        given = requirement["max_error"]
        requirement = {
            "quantity": quantity,
            "max_error": parse_amount(given, quantity, f"{where} max_error"),
            "unit": OUTPUT_UNITS[quantity],
            "given": given if isinstance(given, str) else None,
        }
    sensors = doc.get("sensor")
    if not isinstance(sensors, list) or not sensors:
        raise InputError(f"{path}: no [[sensor]] entries")
    specs = []
    for i, entry in enumerate(sensors, start=1):
        where = f"{path}: [[sensor]] #{i}"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: expected a table")
        keys = (
            "name",
            "log",
            "logs",
            "fit",
            "fits",
            "column",
            "rate_hz",
            "kind",
            "units",
            "datasheet",
        )
        _known(entry, keys + _READING, where)
        kind = _get(entry, "kind", str, where)
        if kind not in SENSOR_QUANTITIES:
            raise InputError(f"{where}: kind={_excerpt(kind)}: expected 'gyro' or 'accel'")
        sheet = _datasheet(entry, path, kind, where, allow_outside)
        sources = [k for k in ("log", "logs", "fit", "fits") if k in entry]
        if len(sources) != 1:
            raise InputError(
                f"{where}: expected exactly one of log, logs (several units), fit or fits (fit "
                f"folders); got {', '.join(sources) or 'none'}"
            )
        source = sources[0]
        paths = tuple(
            _confined(path, p, source, where, allow_outside) for p in _paths(entry, source, where)
        )
        if len(paths) > 1:
            distinct_units(paths, where=where)
        name = _get(entry, "name", str, where)
        if source in ("fit", "fits"):
            for key in ("column", "rate_hz", "units") + _READING:
                if key in entry:
                    raise InputError(
                        f"{where}: {key} is taken from the fit folder; leave it out with {source}"
                    )
            specs.append(
                SensorSpec(name, paths, (), None, kind, SI_UNITS[kind], source, datasheet=sheet)
            )
            continue
        reading = _reading(entry, kind, where)
        columns = _columns(entry, where)
        specs.append(SensorSpec(name, paths, columns, reading.rate, kind, reading.units, source,
                                dataclasses.replace(reading, column=",".join(columns),
                                                    calibration=float(calibration)), sheet))
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: sensor names must be unique, got {names}")
    from .scene_nav import read_navigation

    navigation, imus = read_navigation(doc, path, {s.name: s.kind for s in specs}, float(cred))
    return Scene(
        str(scene.get("name", path.stem)),
        tuple(float(v) for v in outages),
        float(cred),
        tuple(specs),
        requirement,
        bias_start,
        str(path),
        float(calibration),
        navigation,
        imus,
        display,
    )


#: keys of a ``[[sensor]]`` with logs that say how to read them, beyond column, rate_hz and units
_READING = ("time_column", "time_unit", "gaps", "topic", "input", "stream", "where")


def _reading(entry, kind, where):
    """How the logs of a ``[[sensor]]`` are read: a :class:`LogSource` without its log."""
    time_column = _get(entry, "time_column", str, where, required=False)
    time_unit = _get(entry, "time_unit", str, where, required=False)
    if time_unit is not None and (time_column is None or time_unit not in TIME_UNITS):
        raise InputError(f"{where}: time_unit={_excerpt(time_unit)}: expected one of "
                         f"{', '.join(TIME_UNITS)}, with time_column")
    topic = _get(entry, "topic", str, where, required=False)
    rate = _get(entry, "rate_hz", float, where, required=time_column is None and topic is None)
    if rate is not None:
        check_rate(rate, source="rate_hz", where=where)
    gaps = _get(entry, "gaps", str, where, default="error", required=False)
    if gaps not in GAP_POLICIES:
        raise InputError(f"{where}: gaps={gaps!r}: expected one of {', '.join(GAP_POLICIES)}")
    kind_of_input = _get(entry, "input", str, where, default="rate", required=False)
    if kind_of_input not in ("rate", "increments"):
        raise InputError(f"{where}: input={kind_of_input!r}: expected 'rate' or 'increments'")
    stream = entry.get("stream", False)
    if not isinstance(stream, bool):
        raise InputError(f"{where}: stream={stream!r}: expected true or false")
    table = UNITS if kind_of_input == "rate" else INCREMENT_UNITS
    units = _get(entry, "units", str, where)
    if units not in table or table[units][0] != kind:
        allowed = [u for u, (k, _) in table.items() if k == kind]
        what = f"a {kind}" + (" (increments)" if kind_of_input == "increments" else "")
        raise InputError(f"{where}: units={_excerpt(units)}: expected one of {', '.join(allowed)} "
                         f"for {what}")
    rows = _get(entry, "where", str, where, required=False)
    if rows is not None:
        from ..io.rows import parse_where

        try:
            parse_where(rows)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
    return LogSource(topic=topic, stream=stream, rate=rate, time_column=time_column,
                     time_unit=time_unit, gaps=gaps, input=kind_of_input, units=units, sensor=kind,
                     where=rows)


def _datasheet(entry, path, kind, where, allow_outside=False):
    """``(path, kind, values)`` of a sensor's ``datasheet = "FILE"`` (relative to the scene)."""
    if "datasheet" not in entry:
        return None
    from ..noise.datasheet_check import read_datasheet_spec

    value = entry["datasheet"]
    if not isinstance(value, str) or not value:
        raise InputError(f"{where}: datasheet={value!r}: expected the path of a JSON or TOML "
                         "datasheet file")
    sheet_kind, values = read_datasheet_spec(
        _confined(path, value, "datasheet", where, allow_outside)
    )
    if sheet_kind != kind:
        raise InputError(f"{where}: datasheet {value}: a {sheet_kind} datasheet for a {kind}")
    return path.parent / value, kind, values



def _confined(scene_path, given, key, where, allow_outside):
    """``given`` (relative to the scene's folder), refused where it resolves outside that folder;
    the message says so when a symbolic link takes a path that reads as inside out of it."""
    folder = scene_path.parent
    candidate = folder / given
    if allow_outside:
        return candidate
    rule = ("paths are confined to it unless allow_outside = true in [scene] (or "
            "allow_outside=True)")
    try:
        inside = candidate.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError):  # a symlink loop
        raise InputError(f"{where}: {key} path {_excerpt(given)} cannot be resolved (a symbolic "
                         "link loop); expected a path inside the scene's folder") from None
    if not inside:
        link = _outside_link(folder, given)
        why = "" if link is None else f": {link}"
        raise InputError(f"{where}: {key} path {_excerpt(given)} lies outside the scene's "
                         f"folder{why}; {rule}")
    return candidate


def _outside_link(folder, given):
    """Where ``given`` reads as a path inside ``folder`` (absolute or leaving it by ``..``: no) but
    a symbolic link on it leads out, what that link is (``"it is a symbolic link that resolves to
    '/x/a.csv'"``, or the same of a folder on its way), else ``None``."""
    import os

    relative = Path(os.path.normpath(given))
    if relative.is_absolute() or relative.parts[:1] == ("..",):
        return None
    try:
        home = folder.resolve()
        for k in range(1, len(relative.parts) + 1):
            part = folder.joinpath(*relative.parts[:k])
            if not part.is_symlink():
                continue
            target = part.resolve()
            if not target.is_relative_to(home):
                what = ("it is" if k == len(relative.parts)
                        else f"its folder {_excerpt(str(Path(*relative.parts[:k])))} is")
                return f"{what} a symbolic link that resolves to {_tail(target)}"
    except (OSError, RuntimeError):
        return None
    return None


def _tail(path, limit=80):
    """A path for a message: its last ``limit`` characters (the file's name is what tells two
    apart), sanitised."""
    text = "".join(c if c.isprintable() else "?" for c in str(path))
    return repr(text if len(text) <= limit else "..." + text[3 - limit:])


def distinct_units(paths, *, where):
    """Refuse two units of one sensor that are the same: the same file or folder (after resolving
    links and
    ``..``), or files with the same content (SHA-256; a folder by its ``fit.npz``). Each would be
    counted as a
    separate unit in the unit-to-unit spread."""
    import hashlib

    seen = {}
    for p in paths:
        target = Path(p)
        keys = []
        try:
            keys.append(("path", str(target.resolve())))
            file = target / "fit.npz" if target.is_dir() else target
            if file.is_file():
                digest = hashlib.sha256()
                with open(file, "rb") as f:
                    while chunk := f.read(1 << 20):
                        digest.update(chunk)
                keys.append(("content", digest.hexdigest()))
        except (OSError, RuntimeError):
            continue  # reported when it is read
        for key in keys:
            if key in seen:
                same = (
                    "the same file or folder" if key[0] == "path" else "files with the same content"
                )
                raise InputError(f"{where}: {_tail(seen[key])} and {_tail(p)} are "
                                 f"{same}: one unit "
                                 "counted twice would make the unit-to-unit spread wrong; give "
                                 "each unit once")
            seen[key] = p


def _paths(entry, key, where):
    value = entry[key]
    many = key in ("logs", "fits")
    if many and (
        not isinstance(value, list)
        or len(value) < 2
        or not all(isinstance(v, str) and v for v in value)
    ):
        raise InputError(f"{where}: {key}={_excerpt(value)}: expected a list of at least 2 paths "
                         "(one per unit)")
    if not many and (not isinstance(value, str) or not value):
        raise InputError(f"{where}: {key}={_excerpt(value)}: expected a path")
    return value if many else [value]


def _columns(entry, where):
    value = entry.get("column")
    if isinstance(value, str) and value:
        return (value,)
    if isinstance(value, list) and value and all(isinstance(v, str) and v for v in value):
        return tuple(value)
    raise InputError(f"{where}: column={_excerpt(value)}: expected a column name or a list of "
                     "names (several axes: "
                     "the worst one is bounded)")


def _bound(
    fit, t, quantity, credibility, bias_start, calibration_s=DEFAULT_CALIBRATION_S, rng=None
):
    """``(bound, median)`` at outages ``t`` (s): :class:`_Bound` for one set of times."""
    return _Bound(fit, quantity, credibility, bias_start, calibration_s, rng)(t)


class _Bound:
    """The conservative bound of one fit and quantity as a function of outage time.

    At each outage, the posterior quantile at ``credibility`` of the 1-sigma drift (and its
    median), model-averaged, with the given bias semantics. Where the record measures the drift
    itself (calibrated attitude, velocity or position of a log read in memory:
    :mod:`bayes_imu.drift.direct`), the bound is widened to contain the record's own interval,
    as the bands of drift.csv are (:func:`~bayes_imu.drift.bands.drift_bands`, ``honest=True``),
    and each widened value at the horizons the record measures is carried forward to longer
    outages (:func:`~bayes_imu.drift.direct.upper_envelope`; computed once): a report's bound is
    never narrower than the band the same fit writes, at any outage. The draws (one seed from
    ``rng``) are the same at every time asked, so the bound is one deterministic function of
    time, non-decreasing wherever the model's drift is (what :func:`max_outage`'s bisection
    needs).
    """

    def __init__(self, fit, quantity, credibility, bias_start, calibration_s, rng):
        self.fit, self.quantity, self.credibility = fit, quantity, float(credibility)
        self.bias_start, self.calibration_s = bias_start, calibration_s
        self.seed = (int(rng) if isinstance(rng, (int, np.integer))
                     else int(np.random.default_rng(rng).integers(2**63)))
        self.floor_t = self.floor = np.empty(0)
        contrasts = direct_contrasts(fit, quantity, bias_start, calibration_s)
        if contrasts is None or self.credibility <= 0.5:
            return
        draws = self._draws(np.unique(contrasts.t_s))
        q = np.array([self.credibility, 0.5])
        total = np.quantile(draws["total"], q, axis=0)
        part = direct_part(fit, draws, quantity, bias_start, calibration_s, q, total)
        if part is not None:
            # the horizons in increasing order (np.unique), the band already their upper envelope
            # (direct_part: upper_envelope)
            self.floor_t, self.floor = draws["t_s"], part[0][0]

    def _draws(self, t):
        return drift_draws(
            self.fit,
            np.atleast_1d(t),
            quantity=self.quantity,
            bias_start=self.bias_start,
            calibration_s=self.calibration_s,
            rng=self.seed,
        )

    def __call__(self, t):
        """``(bound, median)``, each ``(n_t,)``, at outages ``t`` (s)."""
        draws = self._draws(t)
        d = draws["total"]
        bound, median = np.quantile(d, self.credibility, axis=0), np.median(d, axis=0)
        if self.floor.size:
            # widened where the record measures these outages (its interval at each, as
            # drift_bands widens them), then carried forward from the horizons it measures
            q = np.array([self.credibility, 0.5])
            part = direct_part(self.fit, draws, self.quantity, self.bias_start,
                               self.calibration_s, q, np.vstack([bound, median]))
            if part is not None:
                bound = part[0][0]
            # the largest widened bound at a measured horizon not longer than each outage
            at = np.searchsorted(self.floor_t, draws["t_s"] * (1.0 + 1e-12), side="right") - 1
            bound = np.where(at >= 0, np.maximum(bound, self.floor[np.maximum(at, 0)]), bound)
        return bound, median


def max_outage(
    fit,
    quantity,
    max_error,
    credibility,
    bias_start="calibrated",
    calibration_s=DEFAULT_CALIBRATION_S,
    *,
    rng=None,
):
    """Longest time (s) whose ``credibility`` bound on ``quantity`` stays within ``max_error``.

    The bound is model-averaged, with the given bias semantics (default: the bias calibrated
    over ``calibration_s`` seconds before the outage), and widened where the record measures the
    drift, as drift.csv's bands are (:class:`_Bound`).

    Bisection on log time between one sample and :data:`MAX_SEARCH_S` (relative precision 1e-4);
    ``0.0`` if even two samples exceed it, :data:`MAX_SEARCH_S` if the search limit does not.
    The bound of a log flagged non-stationary includes random draws of the spread between its
    parts (:func:`bayes_imu.drift.bands.drift_draws`): every time the bisection tries uses the
    same draws (one seed from ``rng``), so the bound it searches is one deterministic, increasing
    function of time and the same ``rng`` gives the same answer.
    """
    dt = fit.model.dt
    lo, hi = 2.0 * dt, MAX_SEARCH_S  # position needs two samples to be non-zero
    seed = int(np.random.default_rng(rng).integers(2**63))
    bounds = _Bound(fit, quantity, credibility, bias_start, calibration_s, seed)

    def bound(t):
        return bounds(t)[0][0]

    if bound(lo) > max_error:
        return 0.0
    if bound(hi) <= max_error:
        return float(MAX_SEARCH_S)
    while hi / lo > 1.0 + 1e-4:
        mid = np.sqrt(lo * hi)
        if bound(mid) <= max_error:
            lo = mid
        else:
            hi = mid
    return float(lo)


def build_report(scene, *, rng=None, progress=None):
    """Fit (or read) every sensor of ``scene`` and compute its bounds (module docstring).

    A sensor with several logs or fit folders is a population of units: its bounds are for a
    new unit of the model (:func:`bayes_imu.inference.population.fit_population`). Several axes:
    each outage's bound is the worst axis's. Each sensor draws from its own stream spawned from
    ``rng`` (:meth:`numpy.random.Generator.spawn`): its numbers are the same whichever sensors are
    listed beside it (tested). With an integer ``rng`` (``bayes-imu report --seed``), a log the
    report fits is fitted with that seed, as ``bayes-imu fit --seed`` fits it: the same chains and
    the same numbers as the fit command's (tested; the bounds and bands draw from the sensor's
    stream). ``progress``, if given, is called as ``progress(done, total, name)``
    after each sensor (``done`` of ``total`` sensors finished, the last one's name).

    Every sensor's logs are checked from their headers first (:func:`check_logs`): a wrong column
    in the last sensor is refused before the first one is fitted.
    """
    for spec in scene.sensors:
        check_logs(spec)
    fit_seed = int(rng) if isinstance(rng, (int, np.integer)) else None
    rng = np.random.default_rng(rng)
    reports = []
    # each sensor its own stream, spawned from the report's: a sensor's fits and bounds do not
    # depend on the sensors listed before it (one stream through all of them made them depend on the
    # order and the company)
    for spec, sensor_rng in zip(scene.sensors, rng.spawn(len(scene.sensors))):
        axes = _axes(spec, sensor_rng, fit_seed)
        # the record's own position contrasts at every outage tried reuse one parameter point's
        # structure-function sums (the same numbers), dropped after the sensor
        with reused_sums():
            reports.append(_sensor_report(scene, spec, axes, sensor_rng))
        if progress is not None:
            progress(len(reports), len(scene.sensors), spec.name)
    ranking, reason = _rank(scene, reports)
    from .scene_nav import imu_reports, rank_imus

    imus = imu_reports(scene, reports, rng)  # after the sensors' streams: theirs stay the same
    return Report(scene, tuple(reports), ranking, reason, imus, *rank_imus(scene, imus))


def _sensor_report(scene, spec, axes, sensor_rng):
    """The :class:`SensorReport` of one sensor's fitted ``axes``: its bounds at the scene's
    outages, bands and longest acceptable outage (draws from ``sensor_rng``)."""
    per_axis = []
    for a in axes:
        rows = []
        for quantity in SENSOR_QUANTITIES[spec.kind]:
            bound, median = _bound(
                a.posterior,
                np.array(scene.outages_s),
                quantity,
                scene.credibility,
                scene.bias_start,
                scene.calibration_s,
                rng=sensor_rng,
            )
            rows += [
                {
                    "outage_s": t,
                    "quantity": quantity,
                    "bound": float(b),
                    "median": float(m),
                    "unit": OUTPUT_UNITS[quantity],
                    "extrapolated": bool(t > a.posterior.record_s),
                    "axis": a.axis,
                }
                for t, b, m in zip(scene.outages_s, bound, median)
            ]
        per_axis.append(rows)
    bounds = tuple(
        max((rows[i] for rows in per_axis), key=lambda r: r["bound"])
        for i in range(len(per_axis[0]))
    )
    last = [i for i, b in enumerate(bounds) if b["outage_s"] == max(scene.outages_s)][-1]
    worst = next(i for i, a in enumerate(axes) if a.axis == bounds[last]["axis"])
    bands = tuple(
        drift_bands(
            axes[worst].posterior,
            quantity=quantity,
            bias_start=scene.bias_start,
            horizon_s=max(scene.outages_s) * 2.0,
            calibration_s=scene.calibration_s,
            quantiles=(1.0 - scene.credibility, 0.5, scene.credibility),
            rng=sensor_rng,
        )
        for quantity in SENSOR_QUANTITIES[spec.kind]
    )
    req = scene.requirement
    longest = None
    if req is not None and req["quantity"] in SENSOR_QUANTITIES[spec.kind]:
        longest = min(
            max_outage(
                a.posterior,
                req["quantity"],
                req["max_error"],
                scene.credibility,
                scene.bias_start,
                scene.calibration_s,
                rng=sensor_rng,
            )
            for a in axes
        )
    return SensorReport(spec, tuple(axes), bounds, longest, bands, worst)


def check_logs(spec):
    """Check a sensor's logs from their headers alone, before any is read: each text log's columns
    (time column and ``where`` columns included) against its header, with the "did you mean" hint
    of ``bayes-imu fit --column`` (:func:`~bayes_imu.allan.pipeline.check_source`). Fit folders
    and logs whose checks need their content are left to :func:`build_report`'s reading.

    Raises
    ------
    InputError
        ``sensor 'name': FILE: no column ...``, as the reading would say it.
    """
    if spec.reading is None:
        return
    try:
        for p in spec.paths:
            check_source(dataclasses.replace(spec.reading, log=p))
    except InputError as exc:
        raise InputError(f"sensor {_excerpt(spec.name)}: {exc}") from None


def _axes(spec, rng, fit_seed=None):
    """The :class:`AxisResult` of each axis of a sensor (fitting its logs or reading its fit
    folders); a log fitted with ``fit_seed`` where given (``bayes-imu fit --seed``'s fit of it),
    else from ``rng``."""
    from ..inference.population import fit_population
    from ..inference.population_archive import is_population_folder
    from .runs import column_warnings

    where = f"sensor {_excerpt(spec.name)}: "
    if spec.source == "fit" and is_population_folder(spec.paths[0]):
        return [_saved_population(spec.paths[0], spec, where)]  # read, not fitted again
    if spec.source in ("fit", "fits"):
        per_unit = [_saved_axes(p, spec, where) for p in spec.paths]
        names = [n for n, _ in per_unit[0]]
        if any([n for n, _ in u] != names for u in per_unit[1:]):
            raise InputError(
                f"{where}the fit folders have different axes: "
                + "; ".join(
                    f"{p}: {', '.join(n for n, _ in u)}" for p, u in zip(spec.paths, per_unit)
                )
            )
        fits = {n: [dict(u)[n] for u in per_unit] for n in names}
        allans = {n: [f.allan for f in fs] for n, fs in fits.items()}
    else:
        try:  # every column of a log in one read, as bayes-imu fit reads it
            read = [allan_from_source(dataclasses.replace(spec.reading, log=p)) for p in spec.paths]
        except InputError as exc:
            raise InputError(f"{where}{exc}") from None
        allans = {column: [r.results[j] for r in read] for j, column in enumerate(spec.columns)}
        fits = {}
        for column in spec.columns:
            fits[column] = []
            for i, (a, path) in enumerate(zip(allans[column], spec.paths)):
                # a warning of the fit says whose ("sampler not converged" of which sensor)
                whose = spec.name if len(spec.paths) == 1 else f"{spec.name} {_label(path, i)}"
                with column_warnings(f"{whose} {column}"):
                    fits[column].append(fit_allan(a, rng=rng if fit_seed is None else fit_seed))
    out = []
    for axis in fits:
        if len(fits[axis]) == 1:
            out.append(AxisResult(axis, fits[axis][0], fits[axis][0]))
        else:
            labels = [_label(p, i) for i, p in enumerate(spec.paths)]
            with column_warnings(f"{spec.name} {axis}"):
                pop = fit_population(allans[axis], labels=labels, unit_fits=fits[axis], rng=rng)
            out.append(AxisResult(axis, pop.new_unit, None, pop))
    return out


def _label(path, i):
    return f"{i + 1}: {path.name}"


def _saved_population(folder, spec, where):
    """The :class:`AxisResult` of a ``bayes-imu fit-population`` folder: its new-unit predictive
    and the population as fitted there (:mod:`bayes_imu.inference.population_archive`)."""
    from ..inference.population_archive import load_population
    from ..io.readers import read_json_object

    try:
        summary = read_json_object(Path(folder) / "summary.json",
                                   "a bayes-imu fit-population summary")
        if summary.get("unit") != spec.units:
            raise InputError(f"{folder}: fitted in {_excerpt(summary.get('unit'))}; a {spec.kind} "
                             f"report needs a fit in {spec.units} (a population fitted with "
                             "its units given)")
        pop = load_population(folder)
    except InputError as exc:
        raise InputError(f"{where}{exc}") from None
    return AxisResult(str(summary.get("column", Path(folder).name)), pop.new_unit, None, pop)


def _saved_axes(folder, spec, where):
    """``[(axis, FitResult)]`` of a fit folder (one axis, or each axis of a several-column fit), in
    SI."""
    from ..inference.archive import fit_axes, load_fit

    out = []
    try:
        for axis, place, summary in fit_axes(folder):
            unit = summary.get("unit")
            if unit != spec.units:
                other = {"rad/s": "gyro", "m/s^2": "accel"}.get(unit)
                hint = (f"it is a {other} fit: is kind = {spec.kind!r} right?" if other
                        else "run bayes-imu fit with --units")
                raise InputError(f"{place}: fitted in {_excerpt(unit)}; kind = {spec.kind!r} "
                                 f"needs a fit in {spec.units} ({hint})")
            out.append((axis, load_fit(place)))
    except InputError as exc:
        raise InputError(f"{where}{exc}") from None
    return out


def _rank(scene, reports):
    from .text import as_given

    t_max = max(scene.outages_s)
    req = scene.requirement

    def last_bound(r):
        q = (
            req["quantity"]
            if req and req["quantity"] in SENSOR_QUANTITIES[r.spec.kind]
            else SENSOR_QUANTITIES[r.spec.kind][-1]
        )
        return next(b["bound"] for b in r.bounds if b["outage_s"] == t_max and b["quantity"] == q)

    if req is None:
        order = sorted(reports, key=last_bound)
        reason = (
            f"no requirement: ranked by the {scene.credibility:.0%} bound at the longest outage "
            f"({t_max:g} s), "
            "smallest first (comparable within one sensor kind)"
        )
    else:
        order = sorted(
            reports, key=lambda r: (r.max_outage_s is None, -(r.max_outage_s or 0.0), last_bound(r))
        )
        limit = f"{req['max_error']:g} {req['unit']}"
        # as the scene gave it ("1 deg"), SI beside it, unless that says the same ("10 m")
        if as_given(req.get("given"), limit):
            limit = f"{req['given']} ({limit})"
        reason = (
            f"ranked by the longest outage whose {scene.credibility:.0%} bound on "
            f"{req['quantity']} stays within {limit}; ties by the bound at {t_max:g} s"
        )
        unable = [r for r in order if req["quantity"] not in SENSOR_QUANTITIES[r.spec.kind]]
        if unable:
            names = ", ".join(f"{r.spec.name} ({with_article(SENSORS[r.spec.kind].long_name)})"
                              for r in unable)
            reason += f"; last, as they do not measure {req['quantity']}: {names}"
    return tuple(r.spec.name for r in order), reason
