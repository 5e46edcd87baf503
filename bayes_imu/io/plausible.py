"""Plausibility of a static log: its declared units, and steps in its level.

The noise model is fitted to whatever numbers it is given: a gyro log in deg/s declared as rad/s
gives an angle random walk 57x too large, an accelerometer column in g declared as mg a velocity
random walk 1000x too small, and a step in the middle of a log is fitted as noise. These checks
look at what a *static* log must show, in SI after the declared conversion:

* **gyro**: the mean of each axis at most :data:`MAX_GYRO_MEAN` (Earth rate, 7.3e-5 rad/s, plus
  the largest plausible bias of a consumer MEMS gyro, about 30 deg/s); the white-noise density
  (the spread of first differences, ``sd(diff) / sqrt(2 rate)``) within :data:`GYRO_DENSITY`;
* **accelerometer**: each axis's mean at most :data:`MAX_ACCEL_MEAN` (gravity and a bias), the
  norm of three axes' means near 1 g (:data:`GRAVITY_NORM`), the density within
  :data:`ACCEL_DENSITY`.

:func:`check_units` returns ``None`` when the declared unit passes, else a one-line message
naming what is implausible and the units of the same kind under which the log would pass (the
likely right one), with ``fatal`` true where no unit passes (the command refuses such a log
unless told to trust the units). :func:`find_step` flags a level shift of at least
:data:`STEP_SIGMAS` times the per-sample noise between two adjacent windows (a 20-sigma step is
never white noise: the difference of two 64-sample means has a standard deviation of 0.18 sigma).
"""

import math

import numpy as np

from .readers import UNITS

__all__ = [
    "check_units",
    "find_step",
    "Plausibility",
    "PlausibilityWarning",
    "MAX_GYRO_MEAN",
    "MAX_ACCEL_MEAN",
    "GRAVITY_NORM",
    "GYRO_DENSITY",
    "ACCEL_DENSITY",
    "STEP_SIGMAS",
    "STEP_WINDOW",
]

G = 9.80665
EARTH_RATE = 7.292115e-5
#: largest |mean| of a static gyro axis (rad/s): Earth rate and a bias of about 30 deg/s
MAX_GYRO_MEAN = 0.5
#: largest |mean| of a static accelerometer axis (m/s^2): gravity plus a large bias (1.5 g)
MAX_ACCEL_MEAN = 1.5 * G
#: range of the norm of three static accelerometer axes' means (m/s^2)
GRAVITY_NORM = (0.7 * G, 1.3 * G)
#: plausible white-noise density of a gyro (rad/s/sqrt(Hz)): 0.01 deg/sqrt(h) .. 34 deg/sqrt(h)
#: (0.57 deg/s/sqrt(Hz), ten times the noisiest MEMS datasheets; a deg/s log declared rad/s, such as
#: the ADIS16405's 0.04 deg/s/sqrt(Hz), reads 0.04 rad/s/sqrt(Hz) and is caught here even where its
#: bias is small enough to pass the mean check)
GYRO_DENSITY = (5e-8, 0.01)
#: plausible white-noise density of an accelerometer (m/s^2/sqrt(Hz)): 1 ug/sqrt(Hz) .. 5
#: mg/sqrt(Hz)
ACCEL_DENSITY = (9.8e-6, 0.05)
#: a level shift of this many per-sample sigmas between adjacent windows is a step
STEP_SIGMAS = 10.0
#: samples in each of the two windows compared by :func:`find_step`
STEP_WINDOW = 64


class PlausibilityWarning(UserWarning):
    """A log that does not look like a static log in its declared units, or that has a step."""


class Plausibility:
    """What :func:`check_units` found: ``message`` (one line), ``likely`` (units under which the
    log would pass)
    and ``fatal`` (no unit passes)."""

    def __init__(self, message, likely, fatal):
        self.message, self.likely, self.fatal = message, tuple(likely), bool(fatal)

    def __str__(self):
        return self.message


def _density(values, rate_hz):
    """White-noise density from first differences: ``sd(diff) / sqrt(2 rate)`` (robust: MAD, else
    sd)."""
    d = np.diff(values, axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) / 0.6744897501960817
    sd = np.where(mad > 0, mad, np.std(d, axis=0))
    return sd / math.sqrt(2.0 * rate_hz)


def _problems(mean, density, kind):
    """What is implausible about SI axis means and densities of a static ``kind`` log ([] if
    nothing)."""
    out = []
    if kind == "gyro":
        worst = float(np.max(np.abs(mean)))
        if worst > MAX_GYRO_MEAN:
            out.append(
                f"a mean rate of {worst:.3g} rad/s "
                f"(a static gyro reads at most about {MAX_GYRO_MEAN:g})"
            )
        low, high = GYRO_DENSITY
    else:
        worst = float(np.max(np.abs(mean)))
        if worst > MAX_ACCEL_MEAN:
            out.append(
                f"a mean of {worst / G:.3g} g on one axis "
                "(a static accelerometer reads at most about 1 g)"
            )
        if mean.size == 3:
            norm = float(np.linalg.norm(mean))
            if not GRAVITY_NORM[0] <= norm <= GRAVITY_NORM[1]:
                out.append(
                    f"three axes whose means have a norm of {norm / G:.3g} g "
                    "(a static accelerometer: 1 g)"
                )
        low, high = ACCEL_DENSITY
    for d in np.atleast_1d(density):
        if d > 0 and not low <= d <= high:
            out.append(f"a white-noise density of {d:.3g} (expected {low:g} to {high:g} in SI)")
            break
    return out


def check_units(values, units, rate_hz):
    """Whether a static log in ``units`` (a key of :data:`~bayes_imu.io.readers.UNITS`) is
    plausible.

    Parameters
    ----------
    values : ndarray, shape (n_samples,) or (n_samples, n_axes)
        The samples as read, in ``units``.
    units : str
    rate_hz : float

    Returns
    -------
    Plausibility or None
        ``None`` where the declared unit passes.
    """
    kind, factor = UNITS[units]
    x = np.asarray(values, dtype=np.float64)
    x = x[:, None] if x.ndim == 1 else x
    mean, density = np.mean(x, axis=0), _density(x, rate_hz)
    found = _problems(mean * factor, density * factor, kind)
    if not found:
        return None
    likely = [
        u
        for u, (k, f) in UNITS.items()
        if k == kind and u != units and not _problems(mean * f, density * f, kind)
    ]
    if likely:
        advice = (
            f"the log is plausible in {likely[0]}: is that its unit?"
            if len(likely) == 1
            else f"the log is plausible in {' or '.join(likely)}: is its unit one of them?"
        )
    else:
        advice = "no unit makes it plausible (a moving or broken sensor, a wrong column?)"
    return Plausibility(
        f"in {units} the log shows {'; '.join(found)}; {advice}", likely, not likely
    )


def find_step(values, *, sigmas=STEP_SIGMAS, window=STEP_WINDOW):
    """The largest level shift between two adjacent ``window``-sample means, if it is at least
    ``sigmas`` times
    the per-sample noise: ``(index of the first sample after the step, size in sigmas)``, else
    ``None``.

    The per-sample noise is the robust spread of first differences over sqrt(2) (a step is one
    difference,
    it does not inflate it). A log shorter than four windows, or without spread, is not checked.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1 or x.size < 4 * window:
        return None
    d = np.diff(x)
    sigma = float(np.median(np.abs(d - np.median(d)))) / 0.6744897501960817 / math.sqrt(2.0)
    if not sigma > 0:
        sigma = float(np.std(d)) / math.sqrt(2.0)
    if not sigma > 0:
        return None
    c = np.concatenate(([0.0], np.cumsum(x - x[0])))
    # the window sums after and before each i = window .. n - window, as slices of the running sum
    n, w = x.size, window
    here = c[w:n - w + 1]
    shift = (c[2 * w:] - here) / w - (here - c[:n - 2 * w + 1]) / w
    k = int(np.argmax(np.abs(shift)))
    size = abs(float(shift[k])) / sigma
    return (k + w, size) if size >= sigmas else None
