"""Datasheet numbers read off the posterior Allan deviation, as IEEE Std 952 / 1293 read them.

A datasheet's angle (velocity) random walk, bias instability and rate random walk are
readings of the Allan deviation curve, not parameters of one noise model. They are computed
here from the model-averaged posterior (every draw of every candidate the drift bands use,
:attr:`~bayes_imu.inference.fit.FitResult.mixture`), whatever terms were selected, from each
draw's exact sampled-data Allan deviation ``sigma(tau)`` on a log grid of averaging times:

``angle_random_walk`` / ``velocity_random_walk`` (``N``)
    the -1/2-slope line read at ``tau = 1 s``: ``N = sigma(1 s) sqrt(1 s)`` (whatever dominates
    the curve at 1 s: a 10 Hz low-pass filter or a short Gauss-Markov bias moves it).
``bias_instability`` (``B``)
    the flat minimum of ``sigma`` over the fitted averaging times divided by
    ``sqrt(2 ln 2 / pi) = 0.664`` (flicker's floor); ``tau_s`` is where the minimum lies, and
    ``at_edge`` the share of draws whose minimum is the longest fitted ``tau`` (the curve still
    falling there: then the value is an upper bound).
``rate_random_walk`` (``K``)
    the +1/2-slope line ``K sqrt(tau / 3)`` read at ``tau = 3 s``, drawn through the Allan
    deviation at the longest fitted ``tau`` (``tau_s``): ``K = sigma(tau) sqrt(3 / tau)``. Where the
    curve does not rise there yet (``rising`` is the share of draws whose slope exceeds 1/4) it
    is an upper bound on the random walk.
``white_noise_density``
    the white term alone, ``sqrt(noise_variance dt)``: the -1/2 line the short-term white noise
    would give without the other terms.

Each interval includes the repeatability between the record's parts, as ``summary.json``
``parameters`` does (:func:`bayes_imu.inference.repeatability.widen`): the random-walk reading and
the white density read by the short-term terms (those of a Kalibr noise density) and the white
term, the bias instability and rate random walk readings by the bias and slow terms.

Each number is a posterior median with its 5-95% interval, in datasheet units (deg/sqrt(h),
deg/h, deg/h/sqrt(h) for a gyro fitted in rad/s; m/s/sqrt(h), ug, m/s/h/sqrt(h) for an
accelerometer in m/s^2; the fit's own unit ``u`` otherwise).
"""

import numpy as np

from ..noise.avar_forms import NoiseModel
from .repeatability import kalibr_group, widen

__all__ = ["allan_readout", "BI_FLOOR"]

#: Allan-deviation floor of flicker noise per unit bias instability, sqrt(2 ln 2 / pi)
BI_FLOOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))
_DEG = 180.0 / np.pi
_UG = 1.0 / (9.80665 * 1e-6)
#: name -> (gyro factor, unit, accel factor, unit, generic unit)
_UNITS = {
    "random_walk": (_DEG * 60.0, "deg/sqrt(h)", 60.0, "m/s/sqrt(h)", "{u}/sqrt(Hz)"),
    "bias_instability": (_DEG * 3600.0, "deg/h", _UG, "ug", "{u}"),
    "rate_random_walk": (
        _DEG * 3600.0**1.5,
        "deg/h/sqrt(h)",
        3600.0**1.5,
        "m/s/h/sqrt(h)",
        "{u}/sqrt(s)",
    ),
}
_NAMES = {"gyro": ("angle_random_walk", "bias_instability", "rate_random_walk"),
          "accel": ("velocity_random_walk", "bias_instability", "acceleration_random_walk"),
          None: ("random_walk", "bias_instability", "rate_random_walk")}
_MAX_DRAWS = 2000


def _draw_parts(fit, rng):
    comps = [(NoiseModel(c.terms, fit.model.dt), c.samples) for c in fit.mixture]
    if not comps:
        comps = [(fit.model, fit.samples[:, :len(fit.model.parameter_names)])]
    total = sum(s.shape[0] for _, s in comps)
    if total > _MAX_DRAWS:  # an even thinning keeps each component's share
        step = int(np.ceil(total / _MAX_DRAWS))
        comps = [(m, s[::step]) for m, s in comps]
    return comps


def _adev_draws(fit, m, rng=None):
    """``(n_draws, n_m)`` Allan deviations and ``(n_draws,)`` white densities of the mixture."""
    adev, white = [], []
    for model, samples in _draw_parts(fit, rng):
        params = model.unpack(samples)
        adev.append(np.sqrt(model.avar(m, params)))
        white.append(np.sqrt(params["noise_variance"] * model.dt) if "noise_variance" in params
                     else np.zeros(samples.shape[0]))
    return np.concatenate(adev), np.concatenate(white)


def _entry(values, factor, unit, what, **extra):
    v = np.asarray(values, float) * factor
    return {
        "median": float(np.median(v)),
        "q05": float(np.quantile(v, 0.05)),
        "q95": float(np.quantile(v, 0.95)),
        "unit": unit,
        "what": what,
        **extra,
    }


def allan_readout(fit, kind=None, *, unit="u"):
    """IEEE Std 952 / 1293 readings of the posterior Allan deviation (module docstring).

    Parameters
    ----------
    fit : FitResult
    kind : {"gyro", "accel"} or None
        Sensor kind of an SI fit (datasheet units); ``None`` keeps the fit's unit.
    unit : str
        The fit's rate unit (for ``kind=None``).

    Returns
    -------
    dict
        name -> ``median``, ``q05``, ``q95``, ``unit``, ``what``, ``tau_s`` (the averaging time the
        number describes) and the flags of the module docstring.
    """
    dt = fit.model.dt
    lo, hi = float(fit.allan.tau[0]), float(fit.allan.tau[-1])
    m = np.unique(np.round(np.geomspace(max(1.0, lo / dt), max(1.0, hi / dt), 160))).astype(
        np.int64
    )
    m_extra = np.unique(np.round([1.0 / dt, 3.0 / dt])).clip(1).astype(np.int64)
    adev, white = _adev_draws(fit, np.concatenate((m, m_extra)))
    tau = m * dt
    grid = adev[:, :m.size]
    at1 = adev[:, m.size] * np.sqrt(m_extra[0] * dt)  # sigma(1 s) sqrt(tau): the -1/2 line at 1 s
    idx = np.argmin(grid, axis=1)
    floor = grid[np.arange(grid.shape[0]), idx]
    k_line = grid[:, -1] * np.sqrt(3.0 / tau[-1])
    slope = np.log(grid[:, -1] / grid[:, max(0, m.size - 9)]) / np.log(
        tau[-1] / tau[max(0, m.size - 9)]
    )
    # repeatability between parts: each reading widened by the parts' read of the terms behind it
    reads, steady = getattr(fit, "part_reads", None), getattr(fit, "stationarity", None)
    groups = [kalibr_group(fit.model, role) for role in ("noise_density", "random_walk")]
    at1 = widen(at1, groups[0], 0.5, reads, steady, 0, short=True)
    white = widen(white, ("white",), 0.5, reads, steady, 1, short=True)
    floor = widen(floor, groups[1], 0.5, reads, steady, 2)
    k_line = widen(k_line, groups[1], 0.5, reads, steady, 3)
    names = _NAMES.get(kind, _NAMES[None])
    pick = 0 if kind == "gyro" else 2 if kind == "accel" else None

    def units(key):
        row = _UNITS[key]
        return (1.0, row[4].format(u=unit)) if pick is None else (row[pick], row[pick + 1])

    out = {
        names[0]: _entry(
            at1,
            *units("random_walk"),
            "-1/2-slope line of the Allan deviation read at tau = 1 s",
            tau_s=float(m_extra[0] * dt),
        ),
        names[1]: _entry(
            floor / BI_FLOOR,
            *units("bias_instability"),
            "flat minimum of the Allan deviation / 0.664 over the fitted averaging times",
            tau_s=float(np.median(tau[idx])),
            at_edge=float(np.mean(idx == m.size - 1)),
        ),
        names[2]: _entry(
            k_line,
            *units("rate_random_walk"),
            "+1/2-slope line through the Allan deviation at the longest fitted tau, read at 3 s",
            tau_s=float(tau[-1]),
            rising=float(np.mean(slope > 0.25)),
        ),
        "white_noise_density": _entry(
            white, *units("random_walk"), "white term alone, sqrt(noise_variance dt)"
        ),
    }
    return out
