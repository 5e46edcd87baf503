"""Kalibr IMU noise file (``imu.yaml``) from ``bayes-imu fit`` output folders.

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

Units: the fit folder's ``summary.json`` records the unit of the fitted values (SI when
``bayes-imu fit`` ran with ``--units``; rad/s, deg/s, deg/h, m/s^2, g, mg are accepted and
converted to SI here). A folder of a several-column fit stands for all its axes.
``update_rate`` is the log's rate [Hz]. Nominal values are posterior medians; with
``credibility`` the upper posterior quantile (conservative). Several axes of one sensor
combine to the worst axis (largest value). A fit that failed its adequacy check is flagged
in the file (``# WARNING`` line) and in the returned ``_adequate``.
"""

import json
import math

import numpy as np

from .errors import InputError
from .io import UNITS, read_text

__all__ = ["kalibr_values", "write_kalibr_yaml", "axis_densities"]


def _summary(folder):
    summary_path = folder / "summary.json"
    if not summary_path.exists():
        raise InputError(f"{summary_path}: no such file; expected a bayes-imu fit output folder")
    try:
        summary = json.loads(read_text(summary_path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{summary_path}: invalid JSON ({exc})") from None
    if not isinstance(summary, dict):
        raise InputError(f"{summary_path}: expected a JSON object (a bayes-imu fit summary)")
    return summary


def _axis_folders(folders):
    """``(folder, summary)`` of each fitted axis: a several-column fit (``axes``) expands to its axes."""
    out = []
    for folder in folders:
        summary = _summary(folder)
        if "axes" in summary:
            out += [(folder / axis["folder"], _summary(folder / axis["folder"])) for axis in summary["axes"].values()]
        else:
            out.append((folder, summary))
    return out


def _load(folder, summary):
    summary_path = folder / "summary.json"
    unit = summary.get("unit")
    if unit not in UNITS:
        raise InputError(f"{summary_path}: unit {unit!r}: expected one of {', '.join(UNITS)} (rerun fit with --units)")
    from .fit import _arviz

    try:
        posterior = _arviz().from_netcdf(str(folder / "posterior.nc")).posterior
    except (OSError, ValueError) as exc:
        raise InputError(f"{folder / 'posterior.nc'}: cannot read ({exc})") from None
    draws = {name: posterior[name].values.reshape(-1) for name in summary["parameters"] if name in posterior}
    return draws, UNITS[unit]


def axis_densities(summary, draws, factor):
    """Per-draw SI noise density and random-walk density of one fitted axis."""
    from .noise import NoiseModel

    dt = 1.0 / summary["rate_hz"]
    if "noise_variance" not in draws:
        raise InputError("fit has no white term: Kalibr needs a noise density")
    density = np.sqrt(NoiseModel(tuple(summary["model"]), dt).short_term_variance(draws) * dt) * factor
    rw2 = np.zeros_like(density)
    if "rate_random_walk" in draws:
        rw2 += draws["rate_random_walk"] ** 2
    for variance, time_constant in (("bias_variance", "time_constant"), ("bias_variance_2", "time_constant_2")):
        if variance in draws:
            rw2 += 2.0 * draws[variance] / draws[time_constant]
    if "bias_instability" in draws:
        tau_max = 2.0 ** math.floor(math.log2(summary["n_samples"] / 4.0)) * dt
        rw2 += draws["bias_instability"] ** 2 * 6.0 * math.log(2.0) / (math.pi * tau_max)
    return density, np.sqrt(rw2) * factor


def kalibr_values(gyro_dirs, accel_dirs, *, credibility=None):
    """Kalibr fields from the fit folders of each sensor's axes (worst axis)."""
    if credibility is not None and not 0.5 <= credibility < 1:
        raise InputError(f"--credibility={credibility!r}: expected a number in [0.5, 1)")
    q = 0.5 if credibility is None else credibility
    out, rates, inadequate = {}, set(), []
    for kind, dirs, want in (("gyroscope", gyro_dirs, "gyro"), ("accelerometer", accel_dirs, "accel")):
        dens, walk = [], []
        for folder, summary in _axis_folders(dirs):
            draws, (unit_kind, factor) = _load(folder, summary)
            if unit_kind != want:
                raise InputError(f"{folder}: unit {summary['unit']!r} is not a {want} unit")
            d, w = axis_densities(summary, draws, factor)
            if not (summary.get("adequacy") or {}).get("adequate", True):
                inadequate.append(str(folder))
            dens.append(float(np.quantile(d, q)))
            walk.append(float(np.quantile(w, q)))
            rates.add(float(summary["rate_hz"]))
        out[f"{kind}_noise_density"] = max(dens)
        out[f"{kind}_random_walk"] = max(walk)
    if len(rates) != 1:
        raise InputError(f"fit folders have different rates {sorted(rates)} Hz: expected one IMU rate")
    out["update_rate"] = rates.pop()
    out["_mode"] = "posterior medians" if credibility is None else f"upper {credibility:.0%} posterior quantiles"
    out["_adequate"] = not inadequate
    out["_inadequate"] = inadequate
    return out


def write_kalibr_yaml(values, path):
    """Write the Kalibr ``imu.yaml`` (no YAML library needed: flat keys)."""
    lines = [f"# bayes_imu Kalibr IMU noise model: {values['_mode']}, worst axis, SI units"]
    if not values.get("_adequate", True):
        lines.append("# WARNING: the noise model failed its goodness-of-fit check for "
                     + ", ".join(values["_inadequate"]) + " (intervals widened; values less certain than stated)")
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk"):
        lines.append(f"{key}: {values[key]:.6e}")
    lines.append("rostopic: /imu0")
    lines.append(f"update_rate: {values['update_rate']:g}")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
