"""Writing a :class:`~bayes_imu.report.scene.Report`: ``report.json`` and a self-contained
``report.html``.

The HTML page embeds every figure as a base64 PNG (the comparison chart is also written
as ``comparison.png``) (no external files, no scripts) so it
can be mailed or archived as one file. Sections: the scene, the comparison chart of
bounds versus outage, the table of bounds, the ranking and its reason, per sensor the
model it needed (and the evidence of the runner-up), diagnostics, its Allan fit and drift
bands, and a plain statement of what the bound means and assumes.
"""

import base64
import html
import io
import json

import numpy as np

from ..drift.bands import SENSOR_QUANTITIES
from ..drift.display import display_unit, display_parameters, rate_display
from ..io.readers import SI_UNITS as UNITS_SI
from ..noise.model import PARAMETER_UNITS, REGISTRY
from .scene import MAX_SEARCH_S, OUTPUT_UNITS
from .text import as_given, outage_text, p_text, spread_prior_note
from .scene_nav import navigation_section


__all__ = ["write_report", "report_html"]

ASSUMPTIONS = (
    "Each bound is the {cred:.0%} posterior quantile of the 1-sigma drift sigma(t) of the "
    "integrated sensor noise: given the static log, the sensor's true 1-sigma drift is below it "
    "with {cred:.0%} probability. It is a bound on a standard deviation, not on the error itself; "
    "a 3-sigma error budget multiplies it by three.",
    "Noise terms modelled: {terms}, each only when the data support it "
    "(Bayesian evidence). Bounds average over the candidate models, weighted by their posterior "
    "probabilities. A fit that fails its goodness-of-fit check is flagged and its intervals are "
    "widened by a fitted model discrepancy.",
    "Bias at the start of the outage: {start} ('calibrated', the default: the bias is estimated as "
    "the mean of the samples over the calibration window just before GPS drops, and its estimation "
    "error is included; 'zero' is the paper's convention, the bias known exactly; 'stationary' "
    "draws it from its stationary distribution).",
    "Not modelled: temperature dependence, scale-factor and misalignment errors, vibration "
    "rectification and g-sensitivity, "
    "turn-on bias repeatability, {filter}. The log must be static and representative of the "
    "operating conditions.",
    "Unit-to-unit spread: a sensor given by one log (or fit folder) is bounded for that unit only; "
    "a sensor given by several units' logs is bounded for a new unit of the model (hierarchical "
    "fit, each section says which).",
    "A bound at an outage longer than the sensor's log extrapolates its fitted model: noise slower "
    "than the record (a long bias time constant, a random walk) is not identified there, so such "
    "bounds (marked * in the table) can be optimistic; record logs several times longer than the "
    "longest outage.",
)


def navigation_filter_assumption(has_imus):
    """What the report says of the navigation filter: the per-sensor bounds leave it out, and the
    IMUs' navigation section (``has_imus``: the scene has a ``[navigation]`` table) adds it."""
    if has_imus:
        return ("and, in the per-sensor bounds, the navigation filter (gravity, Schuler and "
                "attitude coupling enter the IMUs' navigation section below only)")
    return ("and the navigation filter itself (no gravity, Schuler or attitude coupling: a "
            "scene's [navigation] table adds them for each IMU)")


def _png(fig_function, *args, failures=None, name="picture", **kwargs):
    """``fig_function(*args, buffer, **kwargs)``'s PNG as a data URI; where ``failures`` (a list)
    is given, a picture that cannot be drawn is ``""`` and its
    :class:`~bayes_imu.report.worker.PictureFailure` (called ``name``) is appended: the numbers of
    the page are kept (issue 37)."""
    from .worker import draw_picture

    buffer = io.BytesIO()
    if failures is None:
        fig_function(*args, buffer, **kwargs)
    else:
        failure = draw_picture(fig_function, *args, buffer, **kwargs)
        if failure is not None:
            failure.name = "".join(c if c.isprintable() else "?" for c in name)
            failures.append(failure)
            return ""
    return _data_uri(buffer.getvalue())


def _img(alt, uri):
    """An ``<img>`` of a data URI, or a line saying the picture could not be drawn (``uri`` "")."""
    if not uri:
        return f'<p class="no-picture">{html.escape(alt)}: the picture could not be drawn.</p>'
    return f'<img alt="{html.escape(alt)}" src="{uri}">'


def _data_uri(png):
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _shown(report, quantity):
    """``(unit, factor from SI)`` of ``quantity``'s drift in the report's display units."""
    return display_unit(OUTPUT_UNITS[quantity], report.scene.display_units)


def _comparison_figure(report, target):
    from .plots import plain_text, pyplot, save_png, series_colours

    plt = pyplot()
    # one colour per series of the whole figure: the sensors', then the IMUs' (bottom row)
    colours = series_colours(len(report.sensors) + len(report.imus))
    quantities = [
        q for q in OUTPUT_UNITS if any(q in SENSOR_QUANTITIES[s.spec.kind] for s in report.sensors)
    ]
    rows, cols = (2, max(len(quantities), 3)) if report.imus else (1, len(quantities))
    height = 4.3 * rows + (1.2 if report.imus else 0)
    fig, axes = plt.subplots(rows, cols, figsize=(6 * cols, height), squeeze=False)
    if report.imus:
        from .scene_nav import draw_imu_panels

        for ax in axes[0][len(quantities):]:
            ax.set_visible(False)
        for ax in axes[1][3:]:
            ax.set_visible(False)
        draw_imu_panels(report, *axes[1][:3], colours=colours[len(report.sensors):])
    for ax, quantity in zip(axes[0], quantities):
        unit, factor = _shown(report, quantity)
        for i, s in enumerate(report.sensors):
            band = next((b for b in s.bands if b.quantity == quantity), None)
            if band is None:
                continue
            band = band.scaled(factor) if factor != 1.0 else band
            keep = band.total[-1] > 0
            ax.plot(
                band.t_s[keep],
                band.total[-1][keep],
                color=colours[i],
                label=f"{plain_text(s.spec.name)} ({band.quantiles[-1]:.0%} bound)",
            )
            ax.plot(band.t_s[keep], band.total[1][keep], color=colours[i], ls=":", lw=1)
        for t in report.scene.outages_s:
            ax.axvline(t, color="gray", lw=0.8, ls="--")
            ax.annotate(
                f"outage {t:g} s",
                (t, 0.02),
                xycoords=("data", "axes fraction"),
                rotation=90,
                fontsize=7,
                color="dimgray",
                ha="right",
                va="bottom",
            )
        req = report.scene.requirement
        if req and req["quantity"] == quantity:
            limit = req["max_error"] * factor
            shown = f"{limit:.4g} {unit}"
            ax.axhline(limit, color="red", lw=1,
                       label=f"requirement {shown}{as_given(req.get('given'), shown)}")
            for i, s in enumerate(report.sensors):
                t_max = s.max_outage_s
                if t_max is not None and 0 < t_max < MAX_SEARCH_S:
                    ax.plot([t_max], [limit], marker="v", ms=8, color=colours[i], ls="none",
                            label=f"{plain_text(s.spec.name)}: longest acceptable outage "
                                  f"{t_max:.3g} s")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("outage duration (s)")
        ax.set_ylabel(f"1-sigma {quantity} drift ({unit})")
        ax.set_title(f"{quantity}: bound (solid) and median (dotted)")
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.tight_layout()
    save_png(fig, target, dpi=100)
    plt.close(fig)


def _source_text(s):
    spec = s.spec
    if spec.source in ("fit", "fits"):
        where = (
            "fit folder"
            + ("s " if spec.population else " ")
            + ", ".join(p.name for p in spec.paths)
        )
    else:
        where = ("logs " if spec.population else "log ") + ", ".join(p.name for p in spec.paths)
        axis = s.axes[s.worst]
        fitted = axis.fit if axis.fit is not None else axis.population.unit_fits[0]
        rate = spec.rate_hz if spec.rate_hz is not None else fitted.allan.rate_hz  # from stamps
        where += f", column {spec.column}, input {spec.units}, {rate:g} Hz"
    axes = (
        f"; worst of axes {', '.join(a.axis for a in s.axes)}: {s.axes[s.worst].axis}"
        if len(s.axes) > 1
        else ""
    )
    return f"{spec.kind}, {where}{axes}"


def _parameter_rows(quantiles, kind, display, digits=".4g"):
    """Table rows ``name, 5%, median, 95%`` (SI) of ``quantiles`` (name -> three values), with
    the same three in display units and their unit beside them where those differ from SI."""
    blocks = {n: {"q05": q[0], "median": q[1], "q95": q[2], "unit": ""}
              for n, q in quantiles.items()}
    shown = display_parameters(blocks, UNITS_SI[kind], display)
    rows = []
    for n, q in quantiles.items():
        cells = "".join(f"<td>{v:{digits}}</td>" for v in q)
        cells += f"<td>{html.escape(_si_unit(n, kind))}</td>"
        if shown is not None:
            d = shown[n]
            cells += "".join(f"<td>{d[k]:{digits}}</td>" for k in ("q05", "median", "q95"))
            cells += f"<td>{html.escape(d['unit'])}</td>"
        rows.append(f"<tr><td>{html.escape(n)}</td>{cells}</tr>")
    if shown is not None and "noise_density" in quantiles:  # as a datasheet gives it
        arw = "".join(f"<td>{v:{digits}}</td>" for v in quantiles["noise_density"])
        arw += f"<td>{html.escape(_si_unit('noise_density', kind))}</td>"
        arw += "".join(f"<td>{shown['noise_density'][k] * _PER_SQRT_HOUR:{digits}}</td>"
                       for k in ("q05", "median", "q95"))
        rows.append(
            f"<tr><td>angle random walk (noise_density)</td>{arw}"
            f"<td>{html.escape(shown['noise_density']['unit'].split('/')[0])}/sqrt(h)</td></tr>"
        )
    return "".join(rows)


#: a density per sqrt(s) (e.g. deg/s/sqrt(Hz) = deg/sqrt(s)) per sqrt(h): sqrt(3600 s/h)
_PER_SQRT_HOUR = 60.0


def _parameter_head(title, kind, display, sep=""):
    """The header row of :func:`_parameter_rows`."""
    extra = ""
    if rate_display(UNITS_SI[kind], display)[1] != 1.0:
        extra = "<th>5% (shown)</th><th>median (shown)</th><th>95% (shown)</th><th>unit shown</th>"
    return (f"<tr><th>{title}</th>{sep}<th>5%</th><th>median</th><th>95%</th><th>unit</th>"
            f"{extra}</tr>")


def _si_unit(name, kind):
    """The SI unit of parameter ``name`` of a ``kind`` sensor (``(rad/s)^2``, ``s``, ...)."""
    return PARAMETER_UNITS.get(name, "1").format(u=UNITS_SI[kind])


def _sensor_section(s, cred, failures=None, display="si"):
    if s.fit is None:
        return _population_section(s, failures, display)
    from .plots import plot_allan_fit, plot_drift

    fit = s.fit
    cands = sorted(fit.candidates, key=lambda c: -c.log_evidence)
    chosen = fit.candidates[fit.selected]
    runner = next((c for c in cands if c.terms != chosen.terms), None)
    why = f"log evidence {chosen.log_evidence:.2f}"
    if runner is not None:
        margin = chosen.log_evidence - runner.log_evidence
        why += (
            f"; the most probable other model, {' + '.join(runner.terms)}, "
            f"{runner.log_evidence:.2f}: "
            + (f"{margin:.2f} nats less" if margin >= 0 else
               f"{-margin:.2f} nats more, within the selection margin, so the model with fewer "
               "terms is kept (the drift bands average both by their probabilities)")
        )
    d = fit.diagnostics
    # what summary.json parameters prints
    rows = _parameter_rows(fit.repeatability_quantiles(), s.spec.kind, display)
    head = _parameter_head("parameter (SI; 90% including the repeatability between the log's "
                           "parts)", s.spec.kind, display, "\n")
    sheet = _datasheet_table(s)
    rate_unit, scale = rate_display(UNITS_SI[s.spec.kind], display)
    allan_png = _png(lambda target: plot_allan_fit(fit, target, label=s.spec.name,
                                                   unit=rate_unit, rng=0, scale=scale),
                     failures=failures, name=f"report.html: the Allan fit of {s.spec.name[:40]}")
    bands, units = _shown_bands(s.bands, display)
    drift_png = _png(lambda target: plot_drift(bands, target, units=units, title=s.spec.name),
                     failures=failures, name=f"report.html: the drift bands of {s.spec.name[:40]}")
    conv = "converged" if d["converged"] else "NOT CONVERGED: treat with caution"
    a = fit.adequacy
    fit_check = (
        "adequate"
        if a.adequate
        else "INADEQUATE: the model does not describe this log"
        + ("; intervals widened by a fitted model discrepancy" if fit.widened else "")
        + (f"; at a prior bound: {', '.join(a.at_prior_bound)}" if a.at_prior_bound else "")
    )
    rhat = (f"R-hat max {d['rhat_max']:.4f}, bulk ESS min {d['ess_bulk_min']:.0f}, tail ESS min "
            f"{d['ess_tail_min']:.0f}, " if "rhat_max" in d else "")
    return f"""
<section class="sensor" id="sensor-{html.escape(s.spec.name)}">
<h3>{html.escape(s.spec.name)} ({html.escape(_source_text(s))})</h3>
<p class="spread">Unit-to-unit spread: NOT included. These bounds are for the tested unit; another \
unit of the same
model may be worse (list several units' logs to bound a new unit).</p>
<p class="model">Model needed: <b>{html.escape(' + '.join(fit.model.terms))}</b> ({why}).</p>
<p class="adequacy">Goodness of fit: p {html.escape(p_text(a.p_value))}, worst at tau = \
{a.worst_tau_s:g} s: {html.escape(fit_check)}.</p>
{_stationarity_text(fit)}
{_drift_check_text(s.bands)}
<p class="diagnostics">Sampler: {conv}; {rhat}{d['n_steps']} steps x {d['n_walkers']} walkers.</p>
<table>{head}{rows}</table>{sheet}
{_img(f"Allan fit of {s.spec.name}", allan_png)}
{_img(f"drift bands of {s.spec.name}", drift_png)}
</section>"""


def _stationarity_text(fit):
    """The stationarity check's paragraph: whether the log's parts share one noise (empty where the
    fit was not checked)."""
    steady = getattr(fit, "stationarity", None)
    if steady is None:
        return ""
    if steady.stationary:
        return (f'<p class="stationarity">Stationarity: the log\'s {steady.n_segments} parts share '
                f"one noise (p {html.escape(p_text(steady.p_value))}).</p>")
    return (
        f'<p class="stationarity">Stationarity: <b>NOT STATIONARY</b>: the noise changes during '
        f"the log: its {steady.n_segments} parts differ in Allan deviation at tau = "
        f"{steady.worst_tau_s:g} s (p {html.escape(p_text(steady.p_value))}; a warm-up?); the "
        "drift bands include that spread.</p>"
    )


def _shown_bands(bands, display):
    """``(bands, units)``: a sensor's drift bands and their units in display units."""
    shown = [display_unit(OUTPUT_UNITS[b.quantity], display) for b in bands]
    return ([b.scaled(f) if f != 1.0 else b for b, (_, f) in zip(bands, shown)],
            [u for u, _ in shown])


def _drift_check_text(bands):
    """The drift-space check (drift.direct): the drift the log itself shows against the bands."""
    band = next((b for b in bands if getattr(b, "check", None) is not None), None)
    check = None if band is None else band.check
    if check is None:
        return (
            '<p class="drift-check">Drift measured on the log itself: not available for these '
            "bands.</p>"
        )
    verdict = (
        "agrees with the model"
        if check.adequate
        else f"DISAGREES with the model (worst at {check.worst_t_s:g} s): the bands include the "
             "log's own interval"
    )
    return (
        f'<p class="drift-check">Drift measured on the log itself, checked at the report\'s '
        f"times up to {check.t_s[-1]:g} s ({html.escape(_measured_range(band))}): "
        f"p {html.escape(p_text(check.p_combined))}, {html.escape(verdict)}.</p>"
    )
def _measured_range(band):
    """Where the log measures the band's drift itself (:attr:`DriftBands.measured_s`), beyond which
    the band extrapolates the model."""
    if np.isfinite(band.measured_s):
        return (f"the log measures drift up to {band.measured_s:g} s; beyond, the bands "
                "extrapolate the model")
    return "beyond the log, the bands extrapolate the model"


def _datasheet_table(s):
    """A sensor's datasheet check (scene ``datasheet``): spec, posterior median, P(within spec)."""
    check = s.datasheet_check
    if check is None:
        return ""
    rows = []
    for n, v in check["values"].items():
        cells = (f"<td>{v['median']:.4g}</td><td>{v['probability']:.2f}</td>"
                 if v["probability"] is not None else "<td>not in the model</td><td></td>")
        rows.append(
            f"<tr><td>{html.escape(n)}</td><td>{v['spec']:.4g} {html.escape(v['unit'])}</td>"
            f"{cells}</tr>"
        )
    head = ("<tr><th>datasheet value</th><th>spec</th><th>posterior median</th>"
            "<th>P(within spec)</th></tr>")
    verdict = html.escape(check["verdict"])
    return (f'\n<table class="datasheet">{head}{"".join(rows)}</table>\n'
            f'<p class="datasheet">{verdict}</p>')


def _population_section(s, failures=None, display="si"):
    from .plots import plot_drift, plot_population

    pop = s.axes[s.worst].population
    rows = _parameter_rows(pop.new_unit.quantiles(), s.spec.kind, display)
    head = _parameter_head("new unit (SI)", s.spec.kind, display)
    spread = "".join(
        f"<tr><td>{html.escape(n)}</td><td>{q[0]:.3g}</td><td>{q[1]:.3g}</td><td>{q[2]:.3g}</td></"
        "tr>"
        for n, q in pop.spread_quantiles().items()
    )
    inadequate = [label for label, f in zip(pop.labels, pop.unit_fits) if not f.adequacy.adequate]
    check = (
        "every unit's fit adequate"
        if not inadequate
        else "INADEQUATE fits (intervals widened where a discrepancy was fitted): "
        + ", ".join(inadequate)
    )
    sheet = _datasheet_table(s)
    note = spread_prior_note(pop)
    weak = "" if note is None else f'\n<p class="spread-prior">Note: {html.escape(note)}.</p>'
    rate_unit, scale = rate_display(UNITS_SI[s.spec.kind], display)
    pop_png = _png(lambda target: plot_population(pop, target, unit=rate_unit, rng=0, scale=scale),
                   failures=failures, name=f"report.html: the population of {s.spec.name[:40]}")
    bands, units = _shown_bands(s.bands, display)
    drift_png = _png(lambda target: plot_drift(bands, target, units=units,
                                               title=f"{s.spec.name}: a new unit"),
                     failures=failures, name=f"report.html: the drift bands of {s.spec.name[:40]}")
    return f"""
<section class="sensor" id="sensor-{html.escape(s.spec.name)}">
<h3>{html.escape(s.spec.name)} ({html.escape(_source_text(s))})</h3>
<p class="spread">Unit-to-unit spread: included. These bounds are for a NEW unit of this model: \
the posterior
predictive of a hierarchical fit of {len(pop.labels)} units.</p>
<p class="model">Common model: <b>{html.escape(' + '.join(pop.model.terms))}</b> (summed evidence \
over the units);
{html.escape(check)}; population sampler \
{'converged' if pop.diagnostics['converged'] else 'NOT CONVERGED'}.</p>{weak}
<table>{head}{rows}</table>{sheet}
<table><tr><th>unit-to-unit spread (ln \
units)</th><th>5%</th><th>median</th><th>95%</th></tr>{spread}</table>
{_img(f"population of {s.spec.name}", pop_png)}
{_img(f"drift bands of {s.spec.name}", drift_png)}
</section>"""


def report_html(report, comparison_png=None, *, failures=None):
    """The self-contained HTML page as a string (``comparison_png``: the chart's PNG bytes,
    drawn if None; ``failures``: a list collecting the pictures that could not be drawn, each
    left out of the page, else such an error is raised)."""
    scene = report.scene
    cred = scene.credibility
    req = scene.requirement
    limit = f"{req['max_error']:.4g} {req['unit']}" if req else ""
    req_text = (f"{req['quantity']} error (1-sigma) at most {limit}"
                + as_given(req.get("given"), limit, "(given as {})") if req else "none")
    if req and _shown(report, req["quantity"])[1] != 1.0 and not req.get("given"):
        unit, factor = _shown(report, req["quantity"])
        req_text += f" ({req['max_error'] * factor:.4g} {unit})"
    display = scene.display_units
    shown_head = ""
    if any(_shown(report, b["quantity"])[1] != 1.0 for s in report.sensors for b in s.bounds):
        shown_head = f"<th>median (shown)</th><th>{cred:.0%} bound (shown)</th><th>unit shown</th>"
    if comparison_png is None:
        comparison = _png(_comparison_figure, report, failures=failures,
                          name="report.html: the comparison chart")
    else:
        comparison = _data_uri(comparison_png) if comparison_png else ""
    bound_rows = []
    for s in report.sensors:
        for b in s.bounds:
            star = "*" if b.get("extrapolated") else ""
            shown = ""
            if shown_head:
                unit, factor = _shown(report, b["quantity"])
                shown = (f"<td>{b['median'] * factor:.4g}</td><td>{b['bound'] * factor:.4g}</td>"
                         f"<td>{unit}</td>")
            bound_rows.append(
                f"<tr><td>{html.escape(s.spec.name)}</td><td>{b['quantity']}</td><td>"
                f"{b['outage_s']:g}{star}</td><td>{b['median']:.4g}</td><td>{b['bound']:.4g}</td>"
                f"<td>{b['unit']}</td>"
                f"{shown}</tr>"
            )
    rank_rows = "".join(
        f"<li>{html.escape(name)}"
        + (
            f": longest outage within the requirement {outage_text(s.max_outage_s)}"
            + _beyond_log(s)
            if s.max_outage_s is not None
            else (": cannot provide the required quantity" if req else "")
        )
        + "</li>"
        for name in report.ranking
        for s in report.sensors
        if s.spec.name == name
    )
    bound_rows = "".join(bound_rows)
    start = (
        f"calibrated over {scene.calibration_s:g} s"
        if scene.bias_start == "calibrated"
        else scene.bias_start
    )
    terms = ", ".join(t.plot_label for t in REGISTRY.values())  # each term's own name (noise.model)
    nav_filter = navigation_filter_assumption(bool(report.imus))
    assumptions = "".join(
        f"<li>{html.escape(a.format(cred=cred, start=start, terms=terms, filter=nav_filter))}</li>"
        for a in ASSUMPTIONS
    )
    sections = "".join(_sensor_section(s, cred, failures, display) for s in report.sensors)
    from .._version import __version__

    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>IMU selection: {html.escape(scene.name)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}}table{{border-\
collapse:collapse}}
td,th{{border:1px solid #bbb;padding:2px 8px;text-align:right}}img{{max-width:100%}}</style></head>
<body>
<h1>IMU selection report: {html.escape(scene.name)}</h1>
<section id="scene"><h2>Scene</h2><p>GPS outages: \
{', '.join(f'{t:g} s' for t in scene.outages_s)}; credibility {cred:.0%};
requirement: {html.escape(req_text)}; bias start: {scene.bias_start}; sensors: \
{len(report.sensors)}.</p></section>
<section id="ranking"><h2>Ranking</h2><ol>{rank_rows}</ol><p \
class="reason">{html.escape(report.reason)}.</p></section>
<section id="comparison"><h2>Bounds versus outage</h2>
{_img("comparison chart", comparison)}</section>
{navigation_section(report)}
<section id="bounds"><h2>Table of bounds</h2><table><tr><th>sensor</th><th>quantity</th><th>outage \
(s)</th>
<th>median</th><th>{cred:.0%} bound</th><th>unit</th>{shown_head}</tr>{bound_rows}</table></section>
<section id="meaning"><h2>What the bound means and assumes</h2><ul>{assumptions}</ul></section>
<section id="sensors"><h2>Sensors</h2>{sections}</section>
<footer><p>bayes_imu {__version__}; scene file {html.escape(scene.path)}.</p></footer>
</body></html>
"""


def _beyond_log(sensor):
    record = sensor.record_s
    return (
        f" (beyond its {outage_text(record)} log: extrapolated)"
        if sensor.max_outage_s > record
        else ""
    )


def write_report(report, out_dir):
    """Write ``report.json``, ``report.html`` and ``comparison.png`` into ``out_dir`` (created if
    needed).

    The numbers first: ``report.json`` is written before any picture is drawn. Returns the list of
    :class:`~bayes_imu.report.worker.PictureFailure` of the pictures that could not be drawn (the
    comparison chart: ``comparison.png`` then absent; a picture of the page: left out of it, a line
    saying so in its place); empty where every picture was drawn."""
    from .worker import draw_picture

    out_dir.mkdir(parents=True, exist_ok=True)
    doc = report.to_json()
    text = json.dumps(doc, indent=2, default=_json_default, allow_nan=False)
    (out_dir / "report.json").write_text(text + "\n", encoding="utf-8")
    failure = draw_picture(_comparison_figure, report, out_dir / "comparison.png")
    png = b"" if failure is not None else (out_dir / "comparison.png").read_bytes()
    failures = [] if failure is None else [failure]
    page = report_html(report, png, failures=failures)
    (out_dir / "report.html").write_text(page, encoding="utf-8")
    return failures


def _json_default(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
