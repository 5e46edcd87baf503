"""Navigation bands: the posterior of a free-inertial navigator's error from a gyro's and an
accelerometer's fits (the loop and the exact variances: :mod:`bayes_imu.drift.navigation`).

Each posterior draw of the gyro (rad/s) is paired with one of the accelerometer (m/s^2), both
model-averaged as drift bands are (:func:`bayes_imu.drift.bands.model_draws`); a pair gives the
1-sigma error ``sigma(t)`` of tilt, velocity and position of one horizontal channel (the sum of
every term's exact variance, both sensors; their noises are independent). Two numbers are
reported per time, and they answer different questions:

``sigma`` (``q05, q50, q95``)
    the credible band of the 1-sigma error: what the data say about the navigator's spread;
``bound`` (default 95 %)
    the posterior predictive bound of the error itself, ``P(|error| <= bound) = 0.95`` under
    the mixture of zero-mean normals over the draws: what a navigation engineer calls "the
    95 % error" (about 1.96 sigma, wider when the draws disagree).

Three-axis fits (gyro x, y, z and accelerometer x, y, z) give two channels: along x (the
accelerometer x and the tilt about y, gyro y) and along y (accelerometer y, gyro x). Their
``radial`` rows are the horizontal radius: ``sigma`` is the rms radius
``sqrt(sigma_x^2 + sigma_y^2)`` and ``bound`` the predictive quantile of the radius of the
two-dimensional normal mixture. ``speed`` adds the cross-track error of a vehicle moving at
that speed from the heading error (the vertical gyro z, no Schuler coupling): ``V`` times the
double integral of the gyro z error.

What the record measures (``honest=True``, the default): a fit of a log read in memory keeps the
calibrated order-1 drift its own record shows (:mod:`bayes_imu.drift.direct`): a gyro's tilt, an
accelerometer's velocity, model-free, for outages up to about half the record. Where that
interval reaches outside the model's band, the drift bands are widened to contain it; the
navigation bands inherit the same widening, sensor by sensor: each quantile's factor
``f_s(t) = honest / model`` of sensor ``s`` (``<= 1`` below the median, ``>= 1`` above) is
carried forward in time as its running extreme over the measured outages up to ``t`` (a
navigation error at ``t`` integrates the sensor's error over the whole outage, so a misfit the
record shows at a shorter horizon bears on it; interpolated in log time between the record's
outages), and the band of a quantity is scaled by
``sqrt(sum_s share_s f_s^2)``, ``share_s`` the sensor's share of the median variance. The
predictive bound is scaled by the largest upper factor. Beyond what the record measures the
last factor is kept (the model's extrapolation, widened as it was at the record's end).
"""

from dataclasses import dataclass, field, replace

import numpy as np

from .bands import DEFAULT_CALIBRATION_S, MODEL_CHOICES, default_times, drift_bands, model_draws
from .direct import direct_contrasts
from .navigation import EARTH_RADIUS, GRAVITY, QUANTITIES, QUANTITY_UNITS, NavLoop
from ..errors import InputError
from ..noise import BIAS_STARTS, TERMS

__all__ = [
    "NavQuantity",
    "NavigationBands",
    "navigation_bands",
    "nav_times",
    "predictive_bound",
    "longest_outage",
    "STATISTICS",
]

#: what a requirement bounds: the predictive error bound, or the credible bound on the 1-sigma error
STATISTICS = ("bound", "sigma")
_BISECTIONS = 60
_ANGLES = 64  # trapezoid points over the half period of the radial CDF's angle integral


@dataclass(frozen=True)
class NavQuantity:
    """One row group of :class:`NavigationBands`.

    Attributes
    ----------
    name : str
        ``tilt``, ``velocity``, ``position`` (one channel, or the horizontal radius of two),
        ``<q>_x`` / ``<q>_y`` (each channel of a three-axis set), ``cross_track``.
    unit : str
        ``rad``, ``m/s`` or ``m``.
    sigma : (n_q, n_t) ndarray
        Posterior quantiles of the 1-sigma error (rms radius for the radial rows).
    bound : (n_t,) ndarray
        Posterior predictive bound of the error at :attr:`NavigationBands.credibility`.
    terms : dict
        ``"gyro:<term>"`` / ``"accel:<term>"`` -> ``(n_t,)`` posterior median of that term's
        1-sigma contribution, over the draws whose model has it.
    sensors : dict
        ``"gyro"``, ``"accel"`` -> ``(n_t,)`` posterior median of each sensor's 1-sigma part.
    term_probability : dict
        Same keys as ``terms`` -> posterior probability that the sensor has the term (share of
        the draws whose model has it).
    """

    name: str
    unit: str
    sigma: np.ndarray
    bound: np.ndarray
    terms: dict = field(default_factory=dict)
    sensors: dict = field(default_factory=dict)
    term_probability: dict = field(default_factory=dict)


@dataclass(frozen=True)
class NavigationBands:
    """Posterior of the navigation error of a gyro + accelerometer (module docstring).

    Attributes
    ----------
    t_s : (n_t,) outage lengths [s] (whole samples).
    quantiles : (n_q,) probabilities of ``sigma``.
    quantities : dict
        Name -> :class:`NavQuantity`, in order.
    credibility : float
        Probability of every ``bound``.
    bias_start, calibration_s, schuler, models : the options used (``calibration_s`` is
        ``nan`` unless ``bias_start="calibrated"``).
    g, radius : float
        Gravity [m/s^2] and Earth radius [m] of the loop.
    speed : float
        Vehicle speed of the cross-track rows [m/s] (``nan`` if none).
    n_draws : int
        Posterior draw pairs used.
    """

    t_s: np.ndarray
    quantiles: np.ndarray
    quantities: dict
    credibility: float
    bias_start: str
    calibration_s: float
    schuler: bool
    models: str
    g: float = GRAVITY
    radius: float = EARTH_RADIUS
    speed: float = float("nan")
    n_draws: int = 0
    measured_s: float = float("nan")

    def within(self, name, max_error, statistic="bound"):
        """Longest listed outage [s] whose ``bound`` of ``name`` is <= ``max_error`` (0: none);
        ``statistic="sigma"``: its highest 1-sigma quantile instead (the credible bound on the
        1-sigma error)."""
        bound = self.statistic(name, statistic)
        bad = np.flatnonzero(bound > max_error)
        ok = self.t_s[: bad[0]] if bad.size else self.t_s
        return float(ok[-1]) if ok.size else 0.0

    def statistic(self, name, statistic="bound"):
        """``(n_t,)``: the predictive error bound of ``name`` (``"bound"``) or the highest
        quantile of its 1-sigma band (``"sigma"``)."""
        if statistic not in STATISTICS:
            raise InputError(f"statistic={statistic!r}: expected one of {', '.join(STATISTICS)}")
        q = self.quantities[name]
        return q.bound if statistic == "bound" else q.sigma[-1]


def nav_times(dt, times=(), horizon_s=None, n=30):
    """Log-spaced whole-sample times from one sample to the horizon (default 2 h, past the Schuler
    period, or twice the longest of ``times``), with ``times`` added."""
    times = np.asarray(times, float).ravel()
    horizon = float(
        horizon_s if horizon_s is not None else max(np.max(times, initial=0.0) * 2.0, 2.0 * 3600.0)
    )
    grid = default_times(dt, horizon, n)
    return np.unique(np.concatenate([grid, np.round(times / dt) * dt]))


def predictive_bound(sigma, credibility=0.95, *, sigma2=None):
    """Quantile of ``|e|`` (or the radius) under the mixture of zero-mean normals over axis 0.

    ``sigma`` ``(n_draws, n_t)``: per-draw standard deviations. With ``sigma2`` (the second
    channel's), the bound is on the radius of the 2-D normal of standard deviations
    ``(sigma, sigma2)``, whose CDF is the trapezoid sum (exponentially convergent, periodic
    integrand) of ``P(r <= x) = (1/pi) int_0^pi (1 - exp(-x^2 q/2)) / (q a b) d theta``,
    ``q = cos^2/a^2 + sin^2/b^2``. Bisection to 2^-60 of the bracket.
    """
    from scipy.special import erf

    a = np.maximum(np.asarray(sigma, float), 1e-300)
    if sigma2 is None:

        def cdf(x):
            return np.mean(erf(x / (np.sqrt(2.0) * a)), axis=0)

        hi = 8.0 * a.max(axis=0)
    else:
        b = np.maximum(np.asarray(sigma2, float), 1e-300)
        theta = (np.arange(_ANGLES) + 0.5) * np.pi / _ANGLES
        q = np.cos(theta) ** 2 / a[..., None] ** 2 + np.sin(theta) ** 2 / b[..., None] ** 2
        norm = q * (a * b)[..., None]

        def cdf(x):
            return np.mean(
                np.mean(-np.expm1(-0.5 * x[None, :, None] ** 2 * q) / norm, axis=-1), axis=0
            )

        hi = 8.0 * np.hypot(a, b).max(axis=0)
    lo = np.zeros_like(hi)
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        below = cdf(mid) < credibility
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _as_axes(fits, what):
    fits = list(fits) if isinstance(fits, (list, tuple)) else [fits]
    if len(fits) not in (1, 3):
        raise InputError(f"{what}: expected one fit or three (axes x, y, z), got {len(fits)}")
    return fits


def _pick(fit, models, n, rng):
    """``[(model, samples)]`` restricted to ``n`` draws chosen at random (``rng``)."""
    parts = model_draws(fit, models)
    sizes = [s.shape[0] for _, s in parts]
    keep = np.sort(rng.choice(sum(sizes), size=n, replace=False))
    bounds = np.cumsum([0] + sizes)
    return [
        (m, s[keep[(keep >= lo) & (keep < hi)] - lo])
        for (m, s), lo, hi in zip(parts, bounds[:-1], bounds[1:])
    ]


def _segment_spread(fit, variance, t, rng):
    """A fit flagged non-stationary: each draw's variance times ``exp(2 z s(t))``, ``z ~ N(0, 1)``
    per    draw (the between-segment spread of :func:`bayes_imu.drift.bands.drift_draws`)."""
    steady = getattr(fit, "stationarity", None)
    if steady is None or steady.stationary:
        return variance
    z = rng.standard_normal((variance.shape[0], 1, 1))
    return variance * np.exp(2.0 * z * np.asarray(steady.drift_log_sd(t), float)[None, :, None])


def _sensor_variance(parts, loop, k, bias_start, n_cal, factor=1.0):
    """``(total (n, n_t, 3), terms {name: (n, n_t, 3) with nan where absent})`` for one sensor."""
    n = sum(s.shape[0] for _, s in parts)
    total = np.zeros((n, k.size, 3))
    terms = {}
    start = 0
    for model, samples in parts:
        stop = start + samples.shape[0]
        if stop > start:
            params = model.unpack(samples)
            for term in model.components:
                v = factor * term.nav_variance(
                    loop, k, params, model.dt, bias_start=bias_start, n_cal=n_cal
                )
                total[start:stop] += v
                terms.setdefault(term.name, np.full((n, k.size, 3), np.nan))[start:stop] = v
        start = stop
    return total, {t: terms[t] for t in TERMS if t in terms}


def _quantity(name, unit, var_g, var_a, terms_g, terms_a, q, credibility, column):
    sd = np.sqrt(var_g[..., column] + var_a[..., column])
    terms = {f"gyro:{t}": _median(v[..., column]) for t, v in terms_g.items()}
    terms.update({f"accel:{t}": _median(v[..., column]) for t, v in terms_a.items()})
    sensors = {
        "gyro": np.median(np.sqrt(var_g[..., column]), axis=0),
        "accel": np.median(np.sqrt(var_a[..., column]), axis=0),
    }
    probability = {
        f"{s}:{t}": float(np.mean(np.isfinite(v[:, 0, 0])))
        for s, part in (("gyro", terms_g), ("accel", terms_a))
        for t, v in part.items()
    }
    return NavQuantity(
        name,
        unit,
        np.quantile(sd, q, axis=0),
        predictive_bound(sd, credibility),
        terms,
        sensors,
        probability,
    )


def _median(v):
    has = np.isfinite(v[:, 0])
    return np.median(np.sqrt(v[has]), axis=0)


#: the order-1 drift each sensor's record measures (the gyro's tilt, the accelerometer's velocity)
_MEASURED = {"gyro": "attitude", "accel": "velocity"}


def record_factors(fit, kind, t, q, *, bias_start, calibration_s, models="averaged",
                   max_draws=1000):
    """``((n_q, n_t) factors, measured_s)``: how far the record's own interval widens one sensor's
    band (module docstring); ones, and ``nan``, where the record measures nothing.

    ``fit`` a gyro (``kind="gyro"``, its tilt) or an accelerometer (``"accel"``, its velocity).
    The factors ``honest / model`` of :func:`bayes_imu.drift.bands.drift_bands` (``max_draws``
    draws, a fixed seed: the same fit gets the same factors in every call) are taken on the
    record's own outage grid, ``<= 1`` for ``q < 1/2``, ``>= 1`` above, 1 at the median, as running
    extremes over the grid; at ``t`` they are interpolated in log time (1 before the grid's first
    outage, the last value beyond it). The grid's factors are memoised per fit.
    """
    q = np.asarray(q, float)
    t = np.asarray(t, float)
    key = (id(fit), kind, tuple(q), bias_start, float(calibration_s), models, max_draws)
    hit = _FACTORS.get(key)
    if hit is None or hit[0] is not fit:
        hit = (fit, *_grid_factors(fit, kind, q, bias_start, calibration_s, models, max_draws))
        _FACTORS[key] = hit
        while len(_FACTORS) > _FACTORS_KEPT:
            _FACTORS.pop(next(iter(_FACTORS)))
    _, grid, ratio, measured = hit
    if grid is None:
        return np.ones((q.size, t.size)), float("nan")
    inside = t >= grid[0]
    log_t = np.log(np.where(inside, t, grid[0]))
    out = np.array([np.interp(log_t, np.log(grid), r) for r in ratio])
    return np.where(inside[None, :], out, 1.0), measured


#: memo of :func:`record_factors`: key -> (fit, grid, factors, measured_s); the newest kept
_FACTORS = {}
_FACTORS_KEPT = 16


def _grid_factors(fit, kind, q, bias_start, calibration_s, models, max_draws):
    """``(grid [s], (n_q, n_grid) running-extreme factors, measured_s)``, or ``(None, None,
    nan)``."""
    contrasts = direct_contrasts(fit, _MEASURED[kind], bias_start, calibration_s)
    if contrasts is None:
        return None, None, float("nan")
    bands = drift_bands(fit, contrasts.t_s, quantity=_MEASURED[kind], bias_start=bias_start,
                        calibration_s=calibration_s, models=models, quantiles=q, rng=0,
                        max_draws=max_draws)
    if bands.model_total is None:
        return None, None, float("nan")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bands.model_total > 0, bands.total / bands.model_total, 1.0)
    low, high = (q < 0.5)[:, None], (q > 0.5)[:, None]
    ratio = np.where(low, np.minimum(ratio, 1.0), np.where(high, np.maximum(ratio, 1.0), 1.0))
    ratio = np.where(
        low, np.minimum.accumulate(ratio, axis=1), np.maximum.accumulate(ratio, axis=1)
    )
    return bands.t_s, ratio, float(bands.measured_s)


def _widen(quantity, parts):
    """``quantity`` with its band scaled by the share-weighted factors of ``parts`` (``[(median
    variance (n_t,), factors (n_q, n_t))]``) and its bound by the largest upper factor."""
    var = np.array([v for v, _ in parts])
    share = var / np.maximum(var.sum(axis=0), 1e-300)
    factors = np.sqrt(np.einsum("st,sqt->qt", share, np.array([f for _, f in parts]) ** 2))
    upper = np.max(factors, axis=0)
    return replace(quantity, sigma=quantity.sigma * factors, bound=quantity.bound * upper)


def _honest(out, fits, medians, t, q, **options):
    """The quantities of ``out`` widened by what the records measure (:func:`record_factors`);
    ``(out, longest measured outage [s] or nan)``."""
    kinds = ["gyro"] * (len(fits) // 2) + ["accel"] * (len(fits) // 2)
    found = [record_factors(f, kind, t, q, **options) for f, kind in zip(fits, kinds)]
    measured = [m for _, m in found if np.isfinite(m)]
    if not measured:
        return out, float("nan")
    factors = {i: f for i, (f, _) in enumerate(found)}
    factors["heading"] = factors.get(2)
    if len(fits) == 2:
        members = {name: (0, 1) for name in out}
    else:  # channel x: gyro y (1), accelerometer x (3); channel y: gyro x (0), accelerometer y (4)
        channel = {"_x": (1, 3), "_y": (0, 4)}
        members = {name: channel.get(name[-2:], (0, 1, 3, 4)) for name in out}
        members["cross_track"] = ("heading",)
    column = {name: QUANTITIES.index(name.split("_")[0]) for name in out if name != "cross_track"}
    column["cross_track"] = 2
    widened = {
        name: _widen(quantity, [(medians[i][:, column[name]], factors[i]) for i in members[name]])
        for name, quantity in out.items()
    }
    return widened, float(min(measured))


def _check(gyro, accel, bias_start, models, calibration_s, speed):
    if bias_start not in BIAS_STARTS:
        raise InputError(f"bias_start={bias_start!r}: expected one of {', '.join(BIAS_STARTS)}")
    if models not in MODEL_CHOICES:
        raise InputError(f"models={models!r}: expected one of {', '.join(MODEL_CHOICES)}")
    dts = {f.model.dt for f in gyro + accel}
    if max(dts) > min(dts) * (1.0 + 1e-9):
        rates = [
            ", ".join(sorted({f"{1.0 / f.model.dt:g} Hz" for f in fits})) for fits in (gyro, accel)
        ]
        raise InputError(
            f"gyro and accelerometer fits: mismatched sample rates (gyro {rates[0]}, accelerometer "
            f"{rates[1]}); expected one IMU's logs at one rate"
        )
    dt = gyro[0].model.dt
    if not (np.isfinite(calibration_s) and calibration_s >= dt):
        raise InputError(
            f"calibration={calibration_s!r} s: expected at least one sample ({dt:g} s)"
        )
    if speed is not None and not (np.isfinite(speed) and speed >= 0):
        raise InputError(f"speed={speed!r} m/s: expected a finite speed >= 0")
    if speed is not None and len(gyro) != 3:
        raise InputError(
            "speed: the cross-track error needs the vertical gyro (a three-axis gyro fit)"
        )
    return dt


def navigation_bands(
    gyro_fit,
    accel_fit,
    t=None,
    *,
    bias_start="calibrated",
    calibration_s=DEFAULT_CALIBRATION_S,
    schuler=True,
    models="averaged",
    quantiles=(0.05, 0.5, 0.95),
    credibility=0.95,
    horizon_s=None,
    speed=None,
    max_draws=1000,
    g=GRAVITY,
    radius=EARTH_RADIUS,
    rng=None,
    segment_spread=True,
    honest=True,
):
    """Posterior of the horizontal navigation error during an outage (module docstring).

    Parameters
    ----------
    gyro_fit, accel_fit : FitResult or sequence of three
        Fits of the gyro in rad/s and the accelerometer in m/s^2 (SI, as ``bayes-imu fit
        --units`` writes them; the API cannot check units:
        :func:`bayes_imu.report.nav.load_nav_fits`
        does for fit folders). Three fits each (axes x, y, z) give two channels and the radius.
    t : array_like, optional
        Outage lengths [s]; default :func:`nav_times` up to ``horizon_s``.
    bias_start : {"calibrated", "zero", "stationary"}
        As :func:`bayes_imu.drift.drift_bands`; ``"calibrated"`` removes the mean of the
        ``calibration_s`` seconds before the outage from both sensors.
    schuler : bool
        Schuler loop on (default) or off (the uncoupled short-term forms).
    models : {"averaged", "selected"}
    quantiles : sequence of float
        Probabilities of the 1-sigma band.
    credibility : float
        Probability of the predictive error bound.
    speed : float, optional
        Vehicle speed [m/s]: adds ``cross_track`` (three-axis gyro only).
    max_draws : int
        Draw pairs used (a random subset of each posterior, ``rng``).
    g, radius : float
        Gravity [m/s^2] and Earth radius [m].
    segment_spread : bool
        Widen a sensor flagged non-stationary by the spread between the parts of its log, as
        the drift bands do (:func:`bayes_imu.drift.bands.drift_draws`).
    honest : bool
        Widen the bands by what each sensor's record measures of its own drift
        (:func:`record_factors`, module docstring); fits without a record (an Allan table, a
        population's new unit, another calibration window) are the model's alone.

    Returns
    -------
    NavigationBands
    """
    gyro, accel = _as_axes(gyro_fit, "gyro_fit"), _as_axes(accel_fit, "accel_fit")
    if len(gyro) != len(accel):
        raise InputError(
            f"gyro and accelerometer fits: {len(gyro)} and {len(accel)} axes; "
            "expected the same number"
        )
    dt = _check(gyro, accel, bias_start, models, calibration_s, speed)
    if not 0.0 < credibility < 1.0:
        raise InputError(f"credibility={credibility!r}: expected a probability in (0, 1)")
    t = nav_times(dt, (), horizon_s) if t is None else np.atleast_1d(np.asarray(t, float))
    if t.ndim != 1 or not np.all(np.isfinite(t) & (t >= 0)):
        raise InputError("t: expected a 1-D array of finite times >= 0 (s)")
    k = np.round(t / dt)
    n_cal = int(np.round(calibration_s / dt))
    rng = np.random.default_rng(rng)
    fits = gyro + accel
    n = min([max_draws] + [sum(s.shape[0] for _, s in model_draws(f, models)) for f in fits])
    picked = [_pick(f, models, n, rng) for f in fits]

    medians = {}

    def sensor(i, loop, factor=1.0, key=None):
        total, terms = _sensor_variance(picked[i], loop, k, factor=factor, **kw)
        total = _segment_spread(fits[i], total, k * dt, rng) if segment_spread else total
        medians[i if key is None else key] = np.median(total, axis=0)
        return total, terms

    q = np.asarray(quantiles, float)
    kw = {"bias_start": bias_start, "n_cal": n_cal}
    loop_g = NavLoop("gyro", schuler, g, radius)
    loop_a = NavLoop("accel", schuler, g, radius)
    out = {}
    if len(gyro) == 1:
        vg, tg = sensor(0, loop_g)
        va, ta = sensor(1, loop_a)
        for i, name in enumerate(QUANTITIES):
            out[name] = _quantity(name, QUANTITY_UNITS[name], vg, va, tg, ta, q, credibility, i)
    else:
        # channel x: accelerometer x, tilt about y (gyro y); channel y: accelerometer y, gyro x
        chans = {"x": (1, 3), "y": (0, 4)}
        var = {c: (sensor(ig, loop_g), sensor(ia, loop_a)) for c, (ig, ia) in chans.items()}
        for i, name in enumerate(QUANTITIES):
            sd = {c: np.sqrt(vg[..., i] + va[..., i]) for c, ((vg, _), (va, _)) in var.items()}
            rms = np.hypot(sd["x"], sd["y"])
            sensors = {
                s: np.median(np.sqrt(var["x"][j][0][..., i] + var["y"][j][0][..., i]), axis=0)
                for j, s in enumerate(("gyro", "accel"))
            }
            out[name] = NavQuantity(
                name,
                QUANTITY_UNITS[name],
                np.quantile(rms, q, axis=0),
                predictive_bound(sd["x"], credibility, sigma2=sd["y"]),
                {},
                sensors,
            )
            for c, ((vg, tg), (va, ta)) in var.items():
                out[f"{name}_{c}"] = _quantity(
                    f"{name}_{c}", QUANTITY_UNITS[name], vg, va, tg, ta, q, credibility, i
                )
        if speed is not None:
            heading = NavLoop(
                "accel", False, g, radius
            )  # y' = V psi, psi' = w_z: V w_z integrated twice
            vz, tz = sensor(2, heading, float(speed) ** 2, key="heading")
            zero = np.zeros_like(vz)
            out["cross_track"] = _quantity("cross_track", "m", vz, zero, tz, {}, q, credibility, 2)
    measured = float("nan")
    if honest:
        out, measured = _honest(out, fits, medians, k * dt, q, bias_start=bias_start,
                                calibration_s=calibration_s, models=models, max_draws=max_draws)
    cal = float(calibration_s) if bias_start == "calibrated" else float("nan")
    return NavigationBands(
        k * dt,
        q,
        out,
        float(credibility),
        bias_start,
        cal,
        bool(schuler),
        models,
        float(g),
        float(radius),
        float("nan") if speed is None else float(speed),
        int(n),
        measured,
    )


def longest_outage(
    gyro_fit,
    accel_fit,
    max_error,
    *,
    quantity="position",
    horizon_s=None,
    refine=24,
    statistic="bound",
    coarse=None,
    **options,
):
    """Longest outage [s] whose predictive error bound of ``quantity`` stays <= ``max_error``
    (``statistic="sigma"``: the highest quantile of the 1-sigma band,
    :meth:`NavigationBands.within`).

    The bound is evaluated on :func:`nav_times` up to ``horizon_s``, then on ``refine`` whole-sample
    times between the last listed time within the requirement and the first beyond it; ``options``
    go to :func:`navigation_bands` (the same ``rng`` gives the same draws on both grids);
    ``coarse``, bands already computed with the same options on an increasing grid from one sample
    to the horizon (:func:`nav_times` with any times added), replaces the first grid. Returns
    ``0.0`` when even one sample exceeds it and the horizon when it is never exceeded.
    """
    if not (np.isfinite(max_error) and max_error > 0):
        raise InputError(f"max_error={max_error!r}: expected a positive amount in SI units")
    gyro = _as_axes(gyro_fit, "gyro_fit")
    dt = gyro[0].model.dt
    if coarse is None:
        coarse = navigation_bands(gyro_fit, accel_fit, nav_times(dt, (), horizon_s), **options)
    if quantity not in coarse.quantities:
        raise InputError(f"quantity={quantity!r}: expected one of {', '.join(coarse.quantities)}")
    bound = coarse.statistic(quantity, statistic)
    over = np.flatnonzero(bound > max_error)
    if not over.size:
        return float(coarse.t_s[-1])
    if over[0] == 0:
        return 0.0
    lo, hi = coarse.t_s[over[0] - 1], coarse.t_s[over[0]]
    fine = np.unique(np.round(np.linspace(lo, hi, refine + 2) / dt)) * dt
    bands = navigation_bands(gyro_fit, accel_fit, fine, **options)
    return bands.within(quantity, max_error, statistic)
