"""Kalibr IMU noise file (``imu.yaml``) from fit results (or ``bayes-imu fit`` folders read through
:func:`bayes_imu.inference.archive.load_fit`).

Kalibr (and most VIO / VINS packages) take four continuous-time noise densities, in SI:

* ``gyroscope_noise_density`` [rad/s/sqrt(Hz)] and ``accelerometer_noise_density``
  [m/s^2/sqrt(Hz)]: the short-term noise as white noise, ``sqrt(q_eff dt)`` with ``q_eff``
  the white variance plus the white equivalents of filtered white noise (``4 c``) and of a
  high-frequency correlated term (``s^2 (1 + phi)/(1 - phi)``): what a filter running at
  ``update_rate`` sees beyond a few samples;
* ``gyroscope_random_walk`` [rad/s^2/sqrt(Hz)] and ``accelerometer_random_walk``
  [m/s^3/sqrt(Hz)]: the density of the bias random walk. Our terms map to it as
  ``rate_random_walk`` K directly; a Gauss-Markov bias as its driving-noise density
  ``sqrt(2 sigma_b^2 / T)`` (the random walk it behaves like for t << T, an upper bound on
  its drift; both Gauss-Markov biases, never the fast correlated term, which is short-term
  noise); bias instability B as the random walk with the same Allan variance at the
  longest averaging time of the log, ``B sqrt(6 ln2 / (pi tau_max))``. Present terms add in
  quadrature, per posterior draw.

Units: each fit's unit is given (a fit folder's ``summary.json`` records it: SI when
``bayes-imu fit`` ran with ``--units``; rad/s, deg/s, deg/h, m/s^2, g, mg are accepted and
converted to SI here). A folder of a several-column fit stands for all its axes. Either
sensor may be given alone (only its two keys are written). ``update_rate`` is the log's
rate [Hz]. Nominal values are posterior medians; with ``credibility`` the upper posterior
quantile (conservative). Several axes of one sensor combine to the worst axis (largest
value, the file says so), and every axis's own value is listed in comment lines. A fit that
failed its adequacy check is flagged in the file (``# WARNING`` line) and in ``adequate``.
Both densities' draws are widened by the repeatability between the record's parts
(:mod:`bayes_imu.inference.repeatability`), as ``summary.json``'s ``parameters``: the noise
density read by its short-term terms, the random walk by the bias and slow terms.
"""

from dataclasses import dataclass, field
from pathlib import Path
import math
import re

import numpy as np

from ..errors import InputError
from ..inference.repeatability import kalibr_group, widen
from ..io.readers import UNITS, read_json_object
from ..noise.quantities import SENSORS

__all__ = [
    "KalibrAxis",
    "KalibrValues",
    "kalibr_values",
    "kalibr_values_from_folders",
    "write_kalibr_yaml",
    "axis_densities",
    "fit_folders",
    "comment_text",
    "rate_of",
]

_KINDS = {name: s.long_name for name, s in SENSORS.items()}


@dataclass(frozen=True)
class KalibrAxis:
    """One fitted axis: its label, fit result and the factor from the fit's unit to SI."""

    label: str
    fit: object
    factor: float = 1.0


@dataclass(frozen=True)
class KalibrValues:
    """Kalibr fields (SI), worst axis per sensor, and each axis's own values.

    ``values``: ``{gyroscope,accelerometer}_{noise_density,random_walk}`` (only the sensors
    given) and ``update_rate``; ``per_axis``: key -> list of ``(label, value)``.
    """

    values: dict
    per_axis: dict
    mode: str
    inadequate: tuple = ()
    extra: dict = field(default_factory=dict)

    @property
    def adequate(self):
        return not self.inadequate


def axis_densities(fit, factor=1.0):
    """Per-draw SI noise density and random-walk density of one fitted axis (module docstring).

    ``fit``: a FitResult (or anything with ``model``, ``draws``, ``parameter_names`` and
    ``allan``); ``factor``: its unit in SI.
    """
    model = fit.model
    dt = model.dt
    if "noise_variance" not in model.parameter_names:
        raise InputError("fit has no white term: Kalibr needs a noise density")
    draws = {n: fit.draws(n) for n in model.parameter_names}
    density = np.sqrt(model.short_term_variance(draws) * dt) * factor
    rw2 = np.zeros_like(density)
    allan = getattr(fit, "allan", None)  # the longest averaging time of the log, where it is known
    octave = None if allan is None else 2.0 ** math.floor(math.log2(allan.n_samples / 4.0))
    tau_max = math.nan if octave is None else octave * dt
    for term in model.components:  # each term's Kalibr role (:attr:`bayes_imu.noise.Term.kalibr`)
        if term.kalibr == "random_walk":
            rw2 += term.kalibr_random_walk2(draws, tau_max)
    # repeatability between parts (inference.repeatability), each density read by its own terms
    reads, steady = getattr(fit, "part_reads", None), getattr(fit, "stationarity", None)
    groups = [kalibr_group(model, role) for role in ("noise_density", "random_walk")]
    if hasattr(fit, "repeatable_draws"):  # the draws of summary.json's parameters.noise_density
        density = np.asarray(fit.repeatable_draws("noise_density"), float) * factor
    else:
        density = widen(density, groups[0], 0.5, reads, steady, 0, short=True)
    return density, widen(np.sqrt(rw2) * factor, groups[1], 0.5, reads, steady, 1)


def kalibr_values(gyro=(), accel=(), *, credibility=None):
    """Kalibr fields from the :class:`KalibrAxis` of each sensor's axes (either sensor may be
    empty)."""
    if credibility is not None and not 0.5 <= credibility < 1:
        raise InputError(f"credibility={credibility!r}: expected a number in [0.5, 1)")
    if not gyro and not accel:
        raise InputError("Kalibr export: give the fits of a gyro, an accelerometer, or both")
    q = 0.5 if credibility is None else credibility
    values, per_axis, rates, inadequate = {}, {}, set(), []
    for kind, axes in (("gyro", gyro), ("accel", accel)):
        for axis in axes:
            d, w = axis_densities(axis.fit, axis.factor)
            check = getattr(axis.fit, "adequacy", None)
            if check is not None and not check.adequate:
                inadequate.append(axis.label)
            for key, draws in (("noise_density", d), ("random_walk", w)):
                per_axis.setdefault(f"{_KINDS[kind]}_{key}", []).append(
                    (axis.label, float(np.quantile(draws, q)))
                )
            rates.add(rate_of(axis.fit))
    for key, rows in per_axis.items():
        values[key] = max(v for _, v in rows)
    if len(rates) != 1:
        raise InputError(f"fits have different rates {sorted(rates)} Hz: expected one IMU rate")
    values["update_rate"] = rates.pop()
    mode = (
        "posterior medians"
        if credibility is None
        else f"upper {credibility:.0%} posterior quantiles"
    )
    return KalibrValues(values, per_axis, mode, tuple(inadequate))


def fit_folders(folders, kind):
    """:class:`KalibrAxis` of every axis in ``bayes-imu fit`` folders (several-column fits
    expand)."""
    from ..inference.archive import fit_axes, load_fit
    from ..inference.population_archive import is_population_folder, load_population

    out = []
    for folder in folders:
        population = is_population_folder(folder)  # fit-population: its new-unit predictive
        if population:
            places = [(Path(folder), read_json_object(Path(folder) / "summary.json",
                                                      "a bayes-imu fit-population summary"))]
        else:
            places = [(place, s) for _, place, s in fit_axes(folder)]
        for place, s in places:
            unit = s.get("unit")
            if unit not in UNITS:
                raise InputError(
                    f"{place / 'summary.json'}: unit {unit!r}: expected one of {', '.join(UNITS)} "
                    "(rerun fit with --units)"
                )
            unit_kind, factor = UNITS[unit]
            if unit_kind != kind:
                names = {"gyro": ("a gyro", "--gyro"), "accel": ("an accelerometer", "--accel")}
                raise InputError(f"{place}: fitted in {unit!r}, {names[unit_kind][0]} unit; "
                                 f"expected {names[kind][0]} fit (give this folder with "
                                 f"{names[unit_kind][1]})")
            if population:
                new_unit = load_population(place).new_unit
                out.append(KalibrAxis(f"{place} (new unit)", new_unit, factor))
            else:
                out.append(KalibrAxis(str(place), load_fit(place), factor))
    return out


def rate_of(fit):
    """Sample rate [Hz] of a fit (its Allan variance's), or of a population's new unit (its
    model's)."""
    allan = getattr(fit, "allan", None)
    return float(allan.rate_hz) if allan is not None else 1.0 / fit.model.dt


def kalibr_values_from_folders(gyro_dirs=(), accel_dirs=(), *, credibility=None):
    """:func:`kalibr_values` of fit folders."""
    return kalibr_values(
        fit_folders(gyro_dirs, "gyro"), fit_folders(accel_dirs, "accel"), credibility=credibility
    )


def comment_text(text):
    """A label inside a one-line comment (YAML, Python, MATLAB): every character that could end
    the comment line (newlines, other control and line-separator characters) as ``?``, so that no
    label injects a key or a statement."""
    return "".join(c if c.isprintable() else "?" for c in str(text))


def write_kalibr_yaml(result, path, *, topic="/imu0"):
    """Write the Kalibr ``imu.yaml`` (flat keys: no YAML library needed). Labels (fit folder names)
    appear only
    in comments, sanitised (:func:`_comment`); the topic is checked to be a ROS name."""
    if not isinstance(topic, str) or not re.fullmatch(r"(/[A-Za-z][A-Za-z0-9_]*)+", topic):
        raise InputError(f"topic={comment_text(topic)[:80]!r}: expected a ROS topic name such as "
                         "/imu0 (letters, digits, "
                         "_ between slashes)")
    v = result.values
    several = any(len(rows) > 1 for rows in result.per_axis.values())
    lines = [f"# bayes_imu Kalibr IMU noise model: {result.mode}, SI units"
             + (", worst axis of each sensor" if several else "")]
    if not result.adequate:
        lines.append("# WARNING: the noise model failed its goodness-of-fit check for "
                     + ", ".join(comment_text(a) for a in result.inadequate)
                     + " (intervals widened; values less certain than stated)")
    for key in (
        "accelerometer_noise_density",
        "accelerometer_random_walk",
        "gyroscope_noise_density",
        "gyroscope_random_walk",
    ):
        if key in v:
            if several:
                lines.append(
                    f"# {key} per axis: "
                    + ", ".join(
                        f"{comment_text(label)} {value:.6e}"
                        for label, value in result.per_axis[key]
                    )
                )
            lines.append(f"{key}: {v[key]:.6e}")
    lines.append(f"rostopic: {topic}")
    lines.append(f"update_rate: {v['update_rate']:g}")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
