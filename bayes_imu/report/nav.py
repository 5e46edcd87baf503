"""The ``nav`` outputs: fit folders in (units checked); nav.csv, nav.png, summary.json out.

The computation is :func:`bayes_imu.drift.nav_bands.navigation_bands`; this module reads the
fit folders (``bayes-imu fit --units`` writes their unit into ``summary.json``), writes the files
through :func:`bayes_imu.report.output.staged_folder` and draws the figure.
"""

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..drift.nav_bands import longest_outage, nav_times, navigation_bands
from ..drift.navigation import schuler_period_s
from ..errors import InputError
from .._version import __version__
from .output import staged_folder

__all__ = [
    "NavRequest",
    "load_nav_fits",
    "run_nav",
    "plot_nav",
    "plot_horizon",
    "format_length",
    "CSV_COLUMNS",
]

#: nav.csv: the 90 % band of the 1-sigma error, its unit, then the predictive 95 % error bound
CSV_COLUMNS = ("t_s", "quantity", "q05", "q50", "q95", "unit", "bound95")
_KIND = {"gyro": ("rad/s", "a gyro"), "accel": ("m/s^2", "an accelerometer")}
_UNIT_KIND = {"rad/s": "gyro", "m/s^2": "accel"}


@dataclass(frozen=True)
class NavRequest:
    """What ``bayes-imu nav`` was asked (the library options, paths and output folder)."""

    gyro: Path
    accel: Path
    out: Path
    times: tuple = (10.0, 60.0, 300.0)
    bias_start: str = "calibrated"
    calibration_s: float = 60.0
    schuler: bool = True
    models: str = "averaged"
    speed: float = None
    horizon_s: float = None
    seed: int = 0
    force: bool = False
    max_position_m: float = None


def load_nav_fits(folder, kind):
    """Fits of one sensor from a fit folder (one axis, or three of a several-column fit).

    Raises
    ------
    InputError
        Not a fit folder, a fit in another unit (a gyro given as ``--accel``, a fit without
        ``--units``), or neither one nor three axes.
    """
    from ..inference.archive import fit_axes, load_fit

    unit, name = _KIND[kind]
    flag = f"{kind}={folder}:"
    try:
        axes = fit_axes(folder)
    except InputError as exc:
        raise _named(kind, folder, exc) from None
    fits = []
    for axis, place, summary in axes:
        got = summary.get("unit")
        if got != unit:
            other = _UNIT_KIND.get(got)
            hint = (
                f"it is {_KIND[other][1]} fit; gyro and accel swapped?"
                if other and other != kind
                else "run bayes-imu fit with --units to convert it"
            )
            raise InputError(
                f"{kind}={place}: fitted in {got!r}; expected {name} fit in {unit} ({hint})"
            )
        try:
            fits.append(load_fit(place))
        except InputError as exc:
            raise _named(kind, place, exc) from None
    if len(fits) not in (1, 3):
        raise InputError(f"{flag} {len(fits)} axes; expected one axis or three (x, y, z)")
    return fits


def _named(kind, path, exc):
    text = str(exc)
    return InputError(f"{kind}={text}" if text.startswith(str(path)) else f"{kind}={path}: {text}")


def run_nav(request, *, failures=None, background=False):
    """Compute the bands of ``request``, write its folder; return ``(NavigationBands, summary)``.

    ``failures``: a list collecting the :class:`~bayes_imu.report.worker.PictureFailure` of
    ``nav.png`` where it cannot be drawn (the numbers are written all the same); without it such
    an error is raised. ``background``: draw ``nav.png`` in a second process
    (:class:`~bayes_imu.report.worker.OutputWriter`), which imports matplotlib while this one
    computes the bands (the command's choice, :func:`~bayes_imu.report.worker.background_default`);
    otherwise here, matplotlib imported on a second thread meanwhile."""
    from .plots import pyplot
    from .worker import OutputWriter

    # started first: the worker's imports (pyplot, as plot_nav imports it) overlap the fits'
    # loading as well as the bands
    with OutputWriter(background=background, warm=(pyplot,)) as writer:
        bands, summary = _run_nav(request, writer, failures is None)
    if failures is not None:
        failures.extend(f for f in writer.picture_failures if f is not None)
    return bands, summary


def _run_nav(request, writer, strict):
    """:func:`run_nav` with its output writer; ``strict``: an error drawing the picture is
    raised."""
    gyro = load_nav_fits(request.gyro, "gyro")
    accel = load_nav_fits(request.accel, "accel")
    if len(gyro) != len(accel):
        raise InputError(
            f"gyro and accelerometer fits: {len(gyro)} and {len(accel)} axes; expected the same "
            "number (1 or 3)"
        )
    times = np.asarray(request.times, float)
    if times.size == 0 or not np.all(np.isfinite(times) & (times > 0)):
        raise InputError(
            f"times={list(request.times)!r}: expected positive outage lengths in seconds"
        )
    # the output folder claimed first: a folder that would be refused (not ours, or ours without
    # --force) is refused before the bands are computed, not after
    with staged_folder(
        request.out, force=request.force, inputs=[request.gyro, request.accel]
    ) as tmp:
        if not writer.background:
            _import_pyplot_meanwhile()
        dt = gyro[0].model.dt
        grid = nav_times(dt, times, request.horizon_s)
        pair = (gyro if len(gyro) == 3 else gyro[0], accel if len(accel) == 3 else accel[0])
        options = {
            "bias_start": request.bias_start,
            "calibration_s": request.calibration_s,
            "schuler": request.schuler,
            "models": request.models,
            "speed": request.speed,
            "rng": request.seed,
        }
        bands = navigation_bands(*pair, grid, **options)
        picked = np.searchsorted(bands.t_s, np.round(times / dt) * dt - 0.25 * dt)
        rows = _rows(bands, picked)
        summary = _summary(bands, request, rows, gyro, accel)
        if request.max_position_m is not None:
            longest = longest_outage(
                *pair, request.max_position_m, horizon_s=request.horizon_s, coarse=bands, **options
            )
            summary["requirement"] = {
                "quantity": "position",
                "max_error_m": request.max_position_m,
                "credibility": 0.95,
                # a whole number of samples: 15.53, not 15.530000000000001
                "longest_outage_s": None if longest is None else float(f"{longest:.12g}"),
                "meaning": "longest outage whose predictive 95 % bound of the "
                + ("horizontal position error (radius)" if len(gyro) == 3 else
                   "position error in this one horizontal channel")
                + " stays within max_error_m (to the refined grid of longest_outage)",
            }
        lines = [",".join(CSV_COLUMNS)]
        lines += [
            f"{r['t_s']:.9g},{r['quantity']},{r['q05']:.9g},{r['q50']:.9g},{r['q95']:.9g},"
            f"{r['unit']},"
            f"{r['bound95']:.9g}"
            for r in rows
        ]
        (tmp / "nav.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        picture = {
            "marks": bands.t_s[picked],
            "title": f"{Path(request.gyro).name} + {Path(request.accel).name}",
            "record_s": min(f.record_s for f in gyro + accel),
            "t_max": plot_horizon(times, request.horizon_s),
        }
        draw = writer.submit if strict else writer.picture
        draw(plot_nav, bands, tmp / "nav.png", **picture)
        writer.wait()  # nav.png in the staging folder before it is moved into place
    return bands, summary


def _import_pyplot_meanwhile():
    """Import matplotlib's pyplot (the picture's) on a second thread while the bands are computed,
    where the process may use two CPUs or more: the bands' transforms and matrix products leave the
    interpreter free most of the time, and the picture then starts without the import (about 0.15 s
    of the command; timings: docs/speed_under_load.md, thirteenth session). A later ``pyplot()``
    waits for the import to finish (Python's per-module import lock); on one CPU nothing is
    started."""
    from .._system import usable_cpus

    if usable_cpus() < 2:
        return
    import threading

    from .plots import pyplot

    def target():
        try:
            pyplot()
        except Exception:  # noqa: BLE001 - the picture's own import reports it (draw_picture)
            pass

    threading.Thread(target=target, name="bayes-imu pyplot import", daemon=True).start()


def format_length(metres):
    """A length for people: ``"17.4 km"``, ``"156 m"``, ``"1.30 m"``, ``"0.197 m"``, ``"4.2 mm"``
    (three significant digits, no exponent from a millimetre to 1e6 km)."""
    m = float(metres)
    if not np.isfinite(m):
        return f"{m} m"
    size = abs(m)
    if float(f"{size:.3g}") >= 1000.0:
        km = m / 1000.0
        return f"{km:,.0f} km" if abs(km) >= 999.5 else f"{_three(km)} km"
    if size >= 0.01 or size == 0.0:
        return f"{_three(m)} m"
    return f"{_three(m * 1000.0)} mm" if size >= 1e-6 else f"{m:.3g} m"


def _three(x):
    """``x`` to three significant digits in fixed notation (``x`` from 1e-3 to 999.5)."""
    x = float(f"{x:.3g}")  # rounded first: 999.6 is 1000, three digits "1.00e3"
    digits = max(0, 2 - int(np.floor(np.log10(abs(x))))) if x else 2
    return f"{x:.{digits}f}"


def plot_horizon(times, horizon_s=None):
    """Longest time of nav.png [s]: ``horizon_s``, else twice the longest of ``times`` and at
    least 1200 s (the command's ``--horizon``)."""
    return float(horizon_s) if horizon_s is not None else max(2.0 * float(np.max(times)), 1200.0)


def _rows(bands, picked):
    rows = []
    for i in picked:
        for name, q in bands.quantities.items():
            dominant = max(q.sensors, key=lambda s: q.sensors[s][i]) if q.sensors else None
            rows.append(
                {
                    "t_s": float(bands.t_s[i]),
                    "quantity": name,
                    "q05": float(q.sigma[0][i]),
                    "q50": float(q.sigma[1][i]),
                    "q95": float(q.sigma[-1][i]),
                    "unit": q.unit,
                    "bound95": float(q.bound[i]),
                    "dominant_sensor": dominant,
                    "terms": {t: float(v[i]) for t, v in q.terms.items()},
                }
            )
    return rows


def _summary(bands, request, rows, gyro, accel):
    return {
        "command": "nav",
        "gyro": str(request.gyro),
        "accel": str(request.accel),
        "axes": len(gyro),
        "rate_hz": 1.0 / gyro[0].model.dt,
        "loop": {
            "schuler": bands.schuler,
            "g_m_s2": bands.g,
            "earth_radius_m": bands.radius,
            "schuler_period_s": schuler_period_s(bands.g, bands.radius),
            "model": "one horizontal channel, local-level frame, small angles, stationary or "
            "constant-velocity vehicle: p' = v, v' = -g phi + a_err, phi' = v/R + w_err; samples "
            "held over each period",
        },
        "bias_start": bands.bias_start,
        "calibration_s": bands.calibration_s if bands.bias_start == "calibrated" else None,
        "models": bands.models,
        "speed_m_s": None if request.speed is None else bands.speed,
        "n_draws": bands.n_draws,
        "seed": request.seed,
        "columns": {
            "q05, q50, q95": "posterior 5/50/95 % quantiles of the 1-sigma error "
            "(90 % credible band)",
            "bound95": "posterior predictive 95 % bound of the error itself: "
            "P(|error| <= bound95) = 0.95 "
            "(for the horizontal radius of three-axis sets: P(radius <= bound95))",
        },
        "small_angle_valid_to_s": small_angle_limit(bands),
        "inputs": input_checks(gyro, accel),
        "rows": rows,
        "bayes_imu_version": __version__,
    }


def input_checks(gyro, accel):
    """The checks of each input fit, as its ``summary.json`` records them: ``sensor``, ``axis``
    (0-based), ``adequate`` and ``p_value`` (does the noise model describe the log), ``stationary``
    and ``stationarity_p`` (does the noise stay the same through the log; ``None`` where not
    checked). The navigation bounds inherit what a failed check says of a fit's bands."""
    out = []
    for sensor, fits in (("gyro", gyro), ("accel", accel)):
        for axis, fit in enumerate(fits):
            steady = getattr(fit, "stationarity", None)
            out.append({
                "sensor": sensor,
                "axis": axis,
                "adequate": bool(fit.adequacy.adequate),
                "p_value": float(fit.adequacy.p_value),
                "stationary": None if steady is None else bool(steady.stationary),
                "stationarity_p": None if steady is None else float(steady.p_value),
            })
    return out


def small_angle_limit(bands):
    """Time [s] at which the median 1-sigma tilt reaches :data:`SMALL_ANGLE_RAD`, interpolated
    log-log between the two band times around it (the tilt grows as a power of time between
    them); the first band time where it is already above at the first; ``None`` where it stays
    below. ``summary.json``'s ``small_angle_valid_to_s`` and where ``nav.png`` hatches."""
    return small_angle_time(bands.t_s, bands.quantities["tilt"].sigma[1])


def small_angle_time(t, tilt):
    """:func:`small_angle_limit` of a median 1-sigma tilt (or attitude error) ``tilt`` [rad] at
    times ``t`` [s]."""
    t, tilt = np.asarray(t, float), np.asarray(tilt, float)
    over = np.flatnonzero(tilt > SMALL_ANGLE_RAD)
    if not over.size:
        return None
    i = over[0]
    if i == 0 or not (tilt[i - 1] > 0 and t[i - 1] > 0):
        return float(t[i])
    x0, x1 = np.log(t[i - 1]), np.log(t[i])
    y0, y1 = np.log(tilt[i - 1]), np.log(tilt[i])
    return float(np.exp(x0 + (np.log(SMALL_ANGLE_RAD) - y0) * (x1 - x0) / (y1 - y0)))


_TERM_STYLE = {"gyro": "-", "accel": "--"}
#: legend entries of every panel, explained once above them
_COMMON = ("1-sigma error", "95 % error bound", ": all its terms", "median tilt >", "beyond the")


def _common(label):
    return any(label.startswith(c) or c in label for c in _COMMON)

#: tilt beyond which the small-angle error model is marked as no longer valid [rad]
SMALL_ANGLE_RAD = 0.1


def plot_nav(
    bands,
    path,
    *,
    marks=(),
    title="",
    record_s=None,
    min_probability=0.1,
    min_share=0.1,
    t_min=0.1,
    t_max=None,
):
    """Log-log navigation error: 90 % band of the 1-sigma error, median, 95 % bound, each sensor's
    and each term's median contribution (gyro solid, accelerometer dashed), the Schuler period and
    the logs' length marked. Terms with posterior probability below ``min_probability``, or below
    ``min_share`` of the median total at every time, are listed, not drawn; times from ``t_min``
    to ``t_max`` [s] (default: every time of ``bands``). The lines common to the three panels
    are explained once, above them; each panel's legend lists its terms."""
    from .plots import (plain_text, pyplot, save_png, sensor_term_label, series_colours,
                        sparse_log_minor_ticks)

    plt = pyplot()
    names = ("tilt", "velocity", "position")
    fig, axes = plt.subplots(1, 3, figsize=(19, 8.5), squeeze=False)
    t_max = bands.t_s[-1] if t_max is None else float(t_max)
    common = {}
    period = schuler_period_s(bands.g, bands.radius)
    radial = "position_x" in bands.quantities
    # each term its own colour, the same in every panel (the band's first colour of the cycle, the
    # bound's red, the grey and the sensors' black left out: series_colours); the tab10 cycle
    # repeated its colours past ten terms
    labels = list(dict.fromkeys(k for b in bands.quantities.values() for k in b.terms))
    colours = dict(zip(labels, series_colours(len(labels) + 1)[1:]))
    tilted = small_angle_limit(bands)
    for ax, name in zip(axes[0], names):
        q = bands.quantities[name]
        keep = (q.sigma[0] > 0) & (bands.t_s >= min(t_min, bands.t_s[-1]))
        keep &= bands.t_s <= max(t_max, bands.t_s[keep][0] if keep.any() else t_max)
        t, median = bands.t_s[keep], q.sigma[1][keep]
        ax.fill_between(
            t,
            q.sigma[0][keep],
            q.sigma[-1][keep],
            color="C0",
            alpha=0.3,
            label="1-sigma error, 90 % credible band" + (" (rms radius)" if radial else ""),
        )
        ax.plot(t, median, color="C0", lw=1.8, label="1-sigma error, median")
        ax.plot(
            t, q.bound[keep], color="C3", lw=1.8, ls="-.", label="95 % error bound (predictive)"
        )
        marked = np.isin(bands.t_s, marks) & keep
        ax.plot(bands.t_s[marked], q.bound[marked], "o", color="C3", ms=4)
        for sensor, style in _TERM_STYLE.items():
            ax.plot(
                t,
                q.sensors[sensor][keep],
                style,
                color="black",
                lw=1.2,
                alpha=0.7,
                label=f"{'gyro' if sensor == 'gyro' else 'accelerometer'}: all its terms, median",
            )
        source = bands.quantities[f"{name}_x"] if radial else q
        hidden, improbable, drawn = [], 0, 0
        for label, part in source.terms.items():
            share = np.max(part[keep] / median) if median.size else 0.0
            if source.term_probability.get(label, 1.0) < min_probability:
                improbable += 1
                continue
            sensor = label.split(":")[0]
            shown = sensor_term_label(label)  # as the other figures name the term
            if not share >= min_share:
                hidden.append(shown)
                continue
            ax.plot(
                t,
                part[keep],
                _TERM_STYLE[sensor],
                lw=1,
                color=colours[label],
                label=shown + (" (channel x)" if radial else ""),
            )
            drawn += 1
        if hidden or improbable:
            import textwrap

            text = (
                f"not drawn, below {min_share:.0%} of the total: {', '.join(hidden)}; "
                if hidden
                else ""
            )
            if improbable:
                text += (f"{improbable} term{'s' if improbable != 1 else ''} of posterior "
                         f"probability < {min_probability:g}")
            ax.plot([], [], " ", label=textwrap.fill(text.rstrip("; "), 36))
        if tilted is not None and tilted < t[-1]:
            ax.axvspan(
                tilted,
                t[-1],
                facecolor="none",
                edgecolor="gray",
                hatch="//",
                lw=0,
                alpha=0.5,
                label=f"median tilt > {SMALL_ANGLE_RAD:g} rad: beyond the small-angle model",
            )
        if record_s is not None and record_s < t[-1]:
            ax.axvspan(
                record_s,
                t[-1],
                color="gray",
                alpha=0.12,
                label=f"beyond the shorter log ({record_s:.4g} s): extrapolation",
            )
        if bands.schuler and period < t[-1]:
            ax.axvline(period, color="gray", lw=1, ls=":")
            ax.annotate(
                "Schuler period\n84.4 min",
                (period, 0.02),
                xycoords=("data", "axes fraction"),
                textcoords="offset points",
                xytext=(-4, 4),
                fontsize=7,
                color="dimgray",
                ha="right",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(max(median.min() * 0.05, 1e-300), q.bound[keep].max() * 3.0)
        ax.set_xlabel("time since GPS loss (s)")
        what = {
            "tilt": "tilt error",
            "velocity": "horizontal velocity error",
            "position": "horizontal position error",
        }
        if "position_x" not in bands.quantities:  # one channel: along the accelerometer's axis
            # "velocity error, one channel (m/s)": one pair of parentheses, the unit's
            what = {k: v.replace("horizontal ", "") + ", one channel" if k != "tilt" else v
                    for k, v in what.items()}
        ax.set_ylabel(f"{what[name]} ({q.unit})")
        start = (
            f"biases calibrated over {bands.calibration_s:g} s"
            if bands.bias_start == "calibrated"
            else f"bias start: {bands.bias_start}"
        )
        loop = "Schuler loop on" if bands.schuler else "Schuler loop off"
        ax.set_title(
            f"{name}{' (horizontal radius)' if radial else ''}: {start}, {loop}", fontsize=10
        )
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xlim(t[0], t[-1])
        sparse_log_minor_ticks(ax)
        handles, labels = ax.get_legend_handles_labels()
        own = [(h, lab) for h, lab in zip(handles, labels) if not _common(lab)]
        common.update((lab, h) for h, lab in zip(handles, labels) if _common(lab))
        if own:
            ax.legend(*zip(*own), fontsize=9, loc="upper center", bbox_to_anchor=(0.5, -0.11),
                      ncol=2, frameon=False)
    fig.legend(list(common.values()), list(common), loc="upper center", ncol=4, fontsize=10,
               frameon=False, bbox_to_anchor=(0.5, 0.955))
    if title:
        fig.suptitle(f"free-inertial navigation error: {plain_text(title)}", y=0.995)
    # fixed margins (the legends hang below the axes): tight_layout measures every tick label of
    # the many-decade log axes, a third of the figure's time
    fig.subplots_adjust(left=0.045, right=0.99, top=0.84, bottom=0.3, wspace=0.2)
    save_png(fig, path, dpi=110)
    plt.close(fig)
