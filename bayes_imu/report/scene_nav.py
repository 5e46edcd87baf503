"""Scenes with a navigation requirement: IMUs (a gyro + an accelerometer) ranked by the longest
GPS outage whose horizontal navigation error stays within it.

A scene's ``[navigation]`` table states the requirement and its ``[[imu]]`` entries pair sensors
of the scene by name (format: docs/cli.md, "Scenes: navigation requirements"):

.. code-block:: toml

    [navigation]
    quantity = "position"   # position (default), velocity or tilt
    max_error = "5 m"       # the requirement ...
    after_s = 60            # ... for outages of at least this long (optional: pass or fail)
    credibility = 0.95      # default: the scene's
    statistic = "bound"     # the predictive error bound (default) or "sigma"
    schuler = true

    [[imu]]
    name = "tactical gyro + budget accelerometer"
    gyro = "tactical gyro"  # the name of a [[sensor]] of kind gyro
    accel = "budget accel"  # ... of kind accel

Each IMU's bands are :func:`bayes_imu.drift.nav_bands.navigation_bands` of its sensors'
posteriors (the fit of one unit, or a new unit of the population when a sensor lists several
units: the unit-to-unit spread is then included), with the scene's bias start and calibration
window. One axis each gives one horizontal channel (the accelerometer along it, the gyro about
the perpendicular horizontal axis); three axes each (columns or fit axes x, y, z) the horizontal
radius. The ranking: longest outage within the requirement first
(:func:`~bayes_imu.drift.nav_bands.longest_outage`), ties by the bound at the scene's longest
outage.
"""

from dataclasses import dataclass

import numpy as np

from ..drift.display import parse_amount
from ..drift.nav_bands import STATISTICS, longest_outage, nav_times, navigation_bands
from ..drift.navigation import QUANTITIES, QUANTITY_UNITS
from ..errors import InputError
from .scene import _excerpt, _known

__all__ = [
    "ImuSpec",
    "ImuReport",
    "read_navigation",
    "imu_reports",
    "rank_imus",
    "nav_horizon",
    "navigation_json",
    "requirement_text",
]

#: navigation-requirement quantities and the units their ``max_error`` is given in
_AMOUNT_QUANTITY = {"tilt": "attitude", "velocity": "velocity", "position": "position"}
_NAV_KEYS = ("quantity", "max_error", "after_s", "credibility", "statistic", "schuler")
_IMU_KEYS = ("name", "gyro", "accel")


@dataclass(frozen=True)
class ImuSpec:
    """One ``[[imu]]``: a name and the names of its gyro and accelerometer ``[[sensor]]``."""

    name: str
    gyro: str
    accel: str


@dataclass(frozen=True)
class ImuReport:
    """Navigation error of one IMU.

    Attributes
    ----------
    spec : ImuSpec
    bands : NavigationBands
        On :func:`nav_times` up to :func:`nav_horizon`, the scene's outages included.
    rows : tuple of dict
        Per scene outage and quantity: ``bound`` (what the requirement bounds), ``sigma_low``,
        ``sigma_median``, ``sigma_high`` (the 1-sigma band), ``predictive_bound``, ``gyro_share``
        (the gyro's share of the median variance), ``dominant``, ``term_shares`` (each term's
        median variance times the probability that its sensor has it, as a share of their sum;
        shares below 0.5 % left out).
    longest_outage_s : float
        Longest outage within the requirement [s] (``0``: not even one sample; the search
        horizon: never exceeded there).
    meets : bool or None
        Within the requirement for ``after_s`` (``None`` without ``after_s``).
    unit_to_unit : bool
        A sensor of the IMU is a population's new unit (the spread between units included).
    record_s : float
        The shorter sensor log [s].
    """

    spec: ImuSpec
    bands: object
    rows: tuple
    longest_outage_s: float
    meets: bool
    unit_to_unit: bool
    record_s: float

    @property
    def name(self):
        return self.spec.name


def read_navigation(doc, path, sensors, credibility):
    """``(requirement dict or None, tuple of ImuSpec)`` from a parsed scene ``doc``.

    ``sensors``: ``{name: kind}`` of the scene's ``[[sensor]]`` entries; ``credibility`` the
    scene's (the default of the requirement's). Every bad value is one line naming the file,
    the table and the key.
    """
    nav, imus = doc.get("navigation"), doc.get("imu")
    if nav is None and imus is None:
        return None, ()
    where = f"{path}: [navigation]"
    if nav is None:
        raise InputError(f"{path}: [[imu]] entries need a [navigation] table (the requirement)")
    if not isinstance(nav, dict):
        raise InputError(f"{where}: expected a table")
    _known(nav, _NAV_KEYS, where)
    quantity = nav.get("quantity", "position")
    if quantity not in QUANTITIES:
        raise InputError(
            f"{where}: quantity={_excerpt(quantity)}: expected one of {', '.join(QUANTITIES)}"
        )
    if "max_error" not in nav:
        raise InputError(f"{where}: missing key 'max_error' (for example \"5 m\")")
    given = nav["max_error"]
    max_error = parse_amount(given, _AMOUNT_QUANTITY[quantity], f"{where} max_error")
    after = nav.get("after_s")
    if after is not None and (
        isinstance(after, bool)
        or not isinstance(after, (int, float))
        or not (np.isfinite(after) and 0 < after <= 1e6)
    ):
        raise InputError(f"{where}: after_s={_excerpt(after)}: expected seconds in (0, 1e6]")
    cred = nav.get("credibility", credibility)
    if isinstance(cred, bool) or not isinstance(cred, (int, float)) or not 0.5 <= cred < 1:
        raise InputError(f"{where}: credibility={_excerpt(cred)}: expected a number in [0.5, 1)")
    statistic = nav.get("statistic", "bound")
    if statistic not in STATISTICS:
        raise InputError(
            f"{where}: statistic={_excerpt(statistic)}: expected 'bound' (the predictive error "
            "bound) or 'sigma' (the credible bound on the 1-sigma error)"
        )
    schuler = nav.get("schuler", True)
    if not isinstance(schuler, bool):
        raise InputError(f"{where}: schuler={_excerpt(schuler)}: expected true or false")
    requirement = {
        "quantity": quantity,
        "max_error": float(max_error),
        "unit": QUANTITY_UNITS[quantity],
        "given": given if isinstance(given, str) else None,
        "after_s": None if after is None else float(after),
        "credibility": float(cred),
        "statistic": statistic,
        "schuler": schuler,
    }
    if not isinstance(imus, list) or not imus:
        raise InputError(
            f"{path}: [navigation] needs at least one [[imu]] entry (name, gyro, accel)"
        )
    specs = []
    for i, entry in enumerate(imus, start=1):
        at = f"{path}: [[imu]] #{i}"
        if not isinstance(entry, dict):
            raise InputError(f"{at}: expected a table")
        _known(entry, _IMU_KEYS, at)
        values = {}
        for key in _IMU_KEYS:
            value = entry.get(key)
            if not isinstance(value, str) or not value:
                raise InputError(f"{at}: {key}={_excerpt(value)}: expected a non-empty string")
            values[key] = value
        for key in ("gyro", "accel"):
            kind = sensors.get(values[key])
            if kind is None:
                raise InputError(
                    f"{at}: {key}={_excerpt(values[key])}: no [[sensor]] of that name; "
                    f"expected one of {', '.join(map(repr, sensors))}"
                )
            if kind != key:
                raise InputError(
                    f"{at}: {key}={_excerpt(values[key])} is "
                    f"{'an' if kind == 'accel' else 'a'} {kind} sensor; expected "
                    f"{'an' if key == 'accel' else 'a'} {key}"
                )
        specs.append(ImuSpec(values["name"], values["gyro"], values["accel"]))
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: [[imu]] names must be unique, got {names}")
    return requirement, tuple(specs)


def nav_horizon(outages_s, requirement):
    """Longest outage searched [s]: two hours (past the Schuler period), or twice the longest
    outage or ``after_s`` of the scene."""
    longest = max(list(outages_s) + [requirement.get("after_s") or 0.0])
    return max(2.0 * 3600.0, 2.0 * longest)


def _rows(bands, outages, requirement):
    rows = []
    for t in outages:
        i = int(np.argmin(np.abs(bands.t_s - t)))
        for name in QUANTITIES:
            q = bands.quantities[name]
            g, a = q.sensors["gyro"][i] ** 2, q.sensors["accel"][i] ** 2
            source = bands.quantities.get(f"{name}_x", q)  # three axes: the shares of channel x
            # each term's median variance, weighted by the probability that the sensor has it
            parts = {
                label: float(v[i]) ** 2 * source.term_probability.get(label, 1.0)
                for label, v in source.terms.items()
                if np.isfinite(v[i])
            }
            total = sum(parts.values()) or 1.0
            parts = {k: v for k, v in parts.items() if v >= 0.005 * total}
            rows.append(
                {
                    "outage_s": float(t),
                    "quantity": name,
                    "unit": q.unit,
                    "bound": float(bands.statistic(name, requirement["statistic"])[i]),
                    "predictive_bound": float(q.bound[i]),
                    "sigma_low": float(q.sigma[0][i]),
                    "sigma_median": float(q.sigma[1][i]),
                    "sigma_high": float(q.sigma[-1][i]),
                    "gyro_share": float(g / (g + a)) if g + a > 0 else 0.5,
                    "dominant": "gyro" if g >= a else "accel",
                    "term_shares": {k: v / total for k, v in parts.items()},
                }
            )
    return tuple(rows)


def _pair(imu, by_name):
    """The two sensors' posteriors as :func:`navigation_bands` takes them."""
    where = f"[[imu]] {_excerpt(imu.name)}"
    gyro = [a.posterior for a in by_name[imu.gyro].axes]
    accel = [a.posterior for a in by_name[imu.accel].axes]
    if len(gyro) != len(accel) or len(gyro) not in (1, 3):
        raise InputError(
            f"{where}: gyro {imu.gyro!r} has {len(gyro)} axes and accel {imu.accel!r} "
            f"{len(accel)}; expected one axis each (one channel) or three each (x, y, z)"
        )
    return (gyro[0], accel[0]) if len(gyro) == 1 else (gyro, accel)


def imu_reports(scene, sensor_reports, rng):
    """:class:`ImuReport` of every ``[[imu]]`` of ``scene`` from the sensors' reports, one stream
    each spawned from ``rng`` (a :class:`numpy.random.Generator`)."""
    req = scene.navigation
    if req is None:
        return ()
    by_name = {s.spec.name: s for s in sensor_reports}
    out = []
    for imu, child in zip(scene.imus, rng.spawn(len(scene.imus))):
        pair = _pair(imu, by_name)
        c = req["credibility"]
        options = {
            "bias_start": scene.bias_start,
            "calibration_s": scene.calibration_s,
            "schuler": req["schuler"],
            "credibility": c,
            "quantiles": (1.0 - c, 0.5, c) if req["statistic"] == "sigma" else (0.05, 0.5, 0.95),
            "rng": int(child.integers(2**63)),
        }
        horizon = nav_horizon(scene.outages_s, req)
        sensors = (by_name[imu.gyro], by_name[imu.accel])
        dt = sensors[0].posterior.model.dt
        marks = list(scene.outages_s) + ([req["after_s"]] if req["after_s"] else [])
        try:
            bands = navigation_bands(*pair, nav_times(dt, marks, horizon), **options)
            longest = longest_outage(
                *pair,
                req["max_error"],
                quantity=req["quantity"],
                horizon_s=horizon,
                statistic=req["statistic"],
                coarse=bands,
                **options,
            )
        except InputError as exc:
            raise InputError(f"[[imu]] {_excerpt(imu.name)}: {exc}") from None
        meets = None if req["after_s"] is None else bool(longest >= req["after_s"])
        out.append(
            ImuReport(
                imu,
                bands,
                _rows(bands, scene.outages_s, req),
                float(longest),
                meets,
                any(s.fit is None for s in sensors),
                float(min(s.record_s for s in sensors)),
            )
        )
    return tuple(out)


def rank_imus(scene, imus):
    """``(names in order, reason)``: longest outage within the requirement first, ties by the
    bound at the scene's longest outage (smallest first)."""
    if not imus:
        return (), ""
    req = scene.navigation
    t_max = max(scene.outages_s)

    def last(r):
        return next(
            row["bound"]
            for row in r.rows
            if row["outage_s"] == t_max and row["quantity"] == req["quantity"]
        )

    order = sorted(imus, key=lambda r: (-r.longest_outage_s, last(r)))
    what = (
        "predictive error bound"
        if req["statistic"] == "bound"
        else "credible bound on the 1-sigma error"
    )
    reason = (
        f"IMUs ranked by the longest outage whose {req['credibility']:.0%} {what} of the "
        f"{'horizontal ' if req['quantity'] != 'tilt' else ''}{req['quantity']} error stays "
        f"within {req['max_error']:g} {req['unit']} (gyro and accelerometer through the Schuler "
        f"loop{'' if req['schuler'] else ', here off'}); ties by the bound at {t_max:g} s"
    )
    return tuple(r.name for r in order), reason


def requirement_text(req):
    """One line: what the navigation requirement asks."""
    from .text import as_given

    limit = f"{req['max_error']:.4g} {req['unit']}"
    given = as_given(req.get("given"), limit, "(given as {})")
    after = f" for outages of at least {req['after_s']:g} s" if req.get("after_s") else ""
    what = "error" if req["statistic"] == "bound" else "1-sigma error"
    return f"{req['quantity']} {what} at most {limit}{given}{after} at {req['credibility']:.0%}"


def navigation_json(report):
    """The ``navigation`` part of ``report.json``."""
    req = report.scene.navigation
    imus = []
    for r in report.imus:
        imus.append(
            {
                "name": r.name,
                "gyro": r.spec.gyro,
                "accel": r.spec.accel,
                "channels": "horizontal radius (x, y)"
                if "position_x" in r.bands.quantities
                else "one horizontal channel",
                "longest_outage_s": r.longest_outage_s,
                "meets_requirement": r.meets,
                "unit_to_unit": (
                    "included: a sensor is a new unit of its population"
                    if r.unit_to_unit
                    else "NOT included: the bounds are for the tested units"
                ),
                "record_s": r.record_s if np.isfinite(r.record_s) else None,
                "measured_to_s": None if not np.isfinite(r.bands.measured_s)
                else r.bands.measured_s,
                "rows": list(r.rows),
            }
        )
    return {
        "requirement": req,
        "requirement_text": requirement_text(req),
        "search_horizon_s": nav_horizon(report.scene.outages_s, req),
        "imus": imus,
        "ranking": list(report.imu_ranking),
        "ranking_reason": report.imu_reason,
    }


def _plot_span(report):
    """Longest time drawn [s]: twice the scene's longest outage (or ``after_s``)."""
    req = report.scene.navigation
    return 2.0 * max(list(report.scene.outages_s) + [req.get("after_s") or 0.0])


def draw_imu_panels(report, ax_bands, ax_share, ax_terms=None, *, colours=None):
    """The IMUs on the bottom row of ``comparison.png``: the required quantity's bound, median and
    1-sigma band per IMU with the requirement and each IMU's longest outage within it; the gyro's
    share of its median variance (which sensor dominates when); and each term's share at the
    scene's outages (``ax_terms``, stacked bars). ``colours``: one per IMU in ranking order
    (default :func:`~bayes_imu.report.plots.series_colours`), none of the figure's other series'."""
    from .plots import plain_text, series_colours

    req = report.scene.navigation
    name = req["quantity"]
    span = _plot_span(report)
    styles = ("-", "--", "-.", ":")
    ranked = ranked_imus(report)
    colours = series_colours(len(ranked)) if colours is None else colours
    for i, r in enumerate(ranked):
        b = r.bands
        q = b.quantities[name]
        keep = (b.t_s >= 0.1) & (b.t_s <= span) & (q.sigma[0] > 0)
        t = b.t_s[keep]
        colour, style = colours[i], styles[i % len(styles)]
        label = f"#{i + 1} {plain_text(r.name)}"
        ax_bands.fill_between(t, q.sigma[0][keep], q.sigma[-1][keep], color=colour, alpha=0.15,
                              lw=0)
        ax_bands.plot(t, b.statistic(name, req["statistic"])[keep], color=colour, lw=1.8, ls=style,
                      label=label)
        ax_bands.plot(t, q.sigma[1][keep], color=colour, lw=0.8, ls=":")
        if 0 < r.longest_outage_s <= span:
            ax_bands.plot([r.longest_outage_s], [req["max_error"]], marker="v", ms=9, color=colour,
                          ls="none")
        g, a = q.sensors["gyro"][keep] ** 2, q.sensors["accel"][keep] ** 2
        ax_share.plot(t, g / np.maximum(g + a, 1e-300), color=colour, lw=2.2 - 0.4 * (i % 3),
                      ls=style, label=label)
    ax_bands.axhline(req["max_error"], color="red", lw=1,
                     label=f"requirement {req['max_error']:.4g} {req['unit']}")
    if req.get("after_s"):
        for ax in (ax_bands, ax_share):
            ax.axvline(req["after_s"], color="black", lw=1, ls="--")
        ax_bands.annotate(f"required outage {req['after_s']:g} s", (req["after_s"], 0.97),
                          xycoords=("data", "axes fraction"), rotation=90, fontsize=8,
                          ha="right", va="top",
                          bbox=dict(facecolor="white", edgecolor="none", alpha=0.8, pad=1))
    what = "predictive bound" if req["statistic"] == "bound" else "bound on the 1-sigma error"
    where = "horizontal " if name != "tilt" else ""
    ax_bands.set_title(f"IMUs: {where}{name} error, gyro + accelerometer", fontsize=11)
    ax_bands.set_ylabel(f"{where}{name} error ({req['unit']}); lines: {req['credibility']:.0%} "
                        f"{what}", fontsize=9)
    ax_bands.plot([], [], color="gray", lw=0.8, ls=":", label="1-sigma median (band shaded)")
    ax_bands.plot([], [], "v", color="gray",
                  label="longest outage within the requirement (in each IMU's colour)")
    ax_share.axhline(0.5, color="gray", lw=1, ls=":")
    ax_share.text(0.02, 0.97, "gyro dominates", transform=ax_share.transAxes, va="top",
                  fontsize=9, color="dimgray")
    ax_share.text(0.02, 0.03, "accelerometer dominates", transform=ax_share.transAxes,
                  va="bottom", fontsize=9, color="dimgray")
    ax_share.set_ylim(-0.02, 1.02)
    ax_share.set_ylabel(f"gyro's share of the {name} error variance")
    ax_share.set_title("which sensor dominates when", fontsize=11)
    for ax in (ax_bands, ax_share):
        ax.set_xscale("log")
        ax.set_xlim(0.1, span)
        ax.set_xlabel("outage duration (s)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="lower right" if ax is ax_bands else "center right")
    ax_bands.set_yscale("log")
    if ax_terms is not None:
        _draw_term_shares(report, ax_terms)


def ranked_imus(report):
    """The scene's IMU reports in ranking order (``report.imu_ranking``; any it leaves out follow in
    scene order): the figure's ``#n`` is the IMU's place in the ranking."""
    ranking = list(getattr(report, "imu_ranking", ()) or ())
    placed = [r for name in ranking for r in report.imus if r.name == name]
    return placed + [r for r in report.imus if r.name not in ranking]


def _draw_term_shares(report, ax):
    """Stacked bars: each term's share of the required quantity's variance, per IMU and outage."""
    from .plots import sensor_term_label

    name = report.scene.navigation["quantity"]
    labels = sorted({k for r in report.imus for row in r.rows if row["quantity"] == name
                     for k in row["term_shares"]})
    gyro = [k for k in labels if k.startswith("gyro:")]
    accel = [k for k in labels if k.startswith("accel:")]
    colours = {k: c for k, c in zip(gyro, _shades("Blues", len(gyro)))}
    colours.update({k: c for k, c in zip(accel, _shades("Oranges", len(accel)))})
    # neighbouring shades of one colour map are hard to tell apart: every other term hatched too
    hatches = {k: ("", "///", "...", "xxx")[i % 4] for group in (gyro, accel)
               for i, k in enumerate(group)}
    ticks, texts = [], []
    x = 0.0
    for t in report.scene.outages_s:
        for i, r in enumerate(ranked_imus(report)):
            row = next(w for w in r.rows if w["outage_s"] == t and w["quantity"] == name)
            bottom = 0.0
            for k in gyro + accel:
                share = row["term_shares"].get(k, 0.0)
                ax.bar(x, share, bottom=bottom, color=colours[k], width=0.8, edgecolor="white",
                       lw=0.5, hatch=hatches[k])
                bottom += share
            ticks.append(x)
            texts.append(f"#{i + 1}")
            x += 1.0
        ax.annotate(f"{t:g} s", (x - 0.5 - len(report.imus) / 2.0, 1.02),
                    xycoords=("data", "axes fraction"), ha="center", fontsize=9)
        x += 0.6
    ax.set_xticks(ticks, texts, fontsize=8)
    ax.set_ylim(0, 1)
    ax.set_ylabel(f"share of the {name} error variance")
    ax.set_xlabel("IMU (# in the ranking) at each scene outage")
    ax.set_title("each term's share (gyro blue, accelerometer orange)", fontsize=11, pad=16)
    for k in gyro + accel:
        ax.bar(0, 0, color=colours[k], hatch=hatches[k], edgecolor="white", lw=0.5,
               label=sensor_term_label(k))
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)


def _shades(cmap, n):
    from .plots import pyplot

    table = pyplot().get_cmap(cmap)
    return [table(0.35 + 0.6 * i / max(n - 1, 1)) for i in range(n)]


def _top_terms(shares, n=3):
    best = sorted(shares.items(), key=lambda kv: -kv[1])[:n]
    return ", ".join(f"{label.replace('_', ' ')} {share:.0%}" for label, share in best)


def _fit_cautions(report, spec):
    """What the fits behind one IMU failed (goodness of fit, stationarity), as the sensors' sections
    say it: ``"gyro g1 z: the model does not describe the log; ..."``, or ``""``."""
    out = []
    for role, name in (("gyro", spec.gyro), ("accelerometer", spec.accel)):
        sensor = next((s for s in report.sensors if s.spec.name == name), None)
        if sensor is None:
            continue
        for ax in sensor.axes:
            flags = set()
            for _, fit in ax.unit_fits:
                if fit.adequacy is not None and not fit.adequacy.adequate:
                    flags.add("the model does not describe the log")
                steady = getattr(fit, "stationarity", None)
                if steady is not None and not steady.stationary:
                    flags.add("the noise changes during the log")
            if flags:
                out.append(f"{role} {name} {ax.axis}: {', '.join(sorted(flags))}")
    return "; ".join(out)


def navigation_section(report):
    """The HTML section of the IMUs (empty without a ``[navigation]`` table)."""
    import html

    from .nav import plot_nav

    if not report.imus:
        return ""
    req = report.scene.navigation
    # the list, the table and the pictures in the ranking's order
    items, ranked = [], ranked_imus(report)
    for r in ranked:
        meets = ("" if r.meets is None else
                 f"; {'MEETS' if r.meets else 'does NOT meet'} the {req['after_s']:g} s "
                 "requirement")
        spread = "unit-to-unit spread included" if r.unit_to_unit else "tested units only"
        caution = _fit_cautions(report, r.spec)
        caution = f" <b>Caution</b>: {html.escape(caution)}." if caution else ""
        items.append(f"<li>{html.escape(r.name)}: within the requirement for "
                     f"{_time_text(r.longest_outage_s, report)}{meets} ({spread}){caution}</li>")
    rows, starred = [], False
    for r in ranked:
        for row in r.rows:
            if row["quantity"] != req["quantity"]:
                continue
            star = "*" if row["outage_s"] > r.record_s else ""
            starred = starred or bool(star)
            rows.append(
                f"<tr><td>{html.escape(r.name)}</td><td>{row['outage_s']:g}{star}</td>"
                f"<td>{_amount(row['bound'], row['unit'])}</td>"
                f"<td>{_amount(row['sigma_median'], row['unit'])} "
                f"[{_amount(row['sigma_low'], row['unit'])}, "
                f"{_amount(row['sigma_high'], row['unit'])}]</td>"
                f"<td>{row['gyro_share']:.0%}</td><td>{row['dominant']}</td>"
                f"<td>{html.escape(_top_terms(row['term_shares']))}</td></tr>")
    figures = []
    span = _plot_span(report)
    for r in ranked:
        buffer = _figure(plot_nav, r.bands, marks=r.bands.t_s[np.isin(r.bands.t_s,
                                                                       report.scene.outages_s)],
                         title=r.name, record_s=r.record_s, t_max=span)
        figures.append(f'<h3>{html.escape(r.name)}</h3><img alt="navigation error of '
                       f'{html.escape(r.name)}" src="{buffer}">')
    # the footnote only where a row carries its mark
    footnote = "<p>* beyond the shorter log: the model's extrapolation.</p>\n" if starred else ""
    stat = ("predictive bound of the error itself" if req["statistic"] == "bound"
            else "credible bound on the 1-sigma error")
    return f"""<section id="navigation"><h2>Navigation: IMUs ranked by the requirement</h2>
<p>Requirement: {html.escape(requirement_text(req))}. Each IMU pairs a gyro and an accelerometer of
the scene; their noise drives one horizontal channel of a free-inertial navigator (tilt projects
gravity into the horizontal channel; Schuler loop {'on' if req['schuler'] else 'off'}; three axes
each give the horizontal radius); the bound is the {req['credibility']:.0%} {stat}. Unlike the
accelerometer-only position drift above, the gyro's tilt is included, which dominates a MEMS IMU
after a few seconds.</p>
<ol>{''.join(items)}</ol><p class="reason">{html.escape(report.imu_reason)}.</p>
<table><tr><th>IMU</th><th>outage (s)</th><th>{req['credibility']:.0%} bound</th>
<th>1-sigma median [band]</th><th>gyro share</th><th>dominant</th><th>largest terms (share of the
variance)</th></tr>{''.join(rows)}</table>
{footnote}{''.join(figures)}
</section>"""


def _amount(value, unit):
    """A table cell: lengths as km / m / mm (:func:`~bayes_imu.report.nav.format_length`), other
    amounts to four digits with their unit."""
    from .nav import format_length

    return format_length(value) if unit == "m" else f"{value:.4g} {unit}"


def _figure(function, *args, **kwargs):
    import base64
    import io

    buffer = io.BytesIO()
    function(*args, buffer, **kwargs)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _time_text(t, report):
    horizon = nav_horizon(report.scene.outages_s, report.scene.navigation)
    if t >= horizon:
        return f"{horizon:g} s or more (the search horizon)"
    return f"{t:.4g} s"
