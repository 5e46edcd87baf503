"""Figures (matplotlib imported inside each function, Agg backend)."""

import contextlib
import functools

import numpy as np

from .text import interval_numbers, interval_text, p_text

__all__ = [
    "plot_allan",
    "plot_allan_fit",
    "plot_corner",
    "plot_drift",
    "plot_population",
    "plain_log_formatter",
    "plain_text",
]


def plain_text(text):
    """User text (a file, column, sensor or unit name) as matplotlib draws it literally: every
    ``$`` escaped, so
    that no pair of them starts mathtext (whose parser rejects ``run$1_$2``), control characters as
    ``?``."""
    text = "".join(c if c.isprintable() or c == "\n" else "?" for c in str(text))
    return text.replace("$", r"\$")


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: zlib level of the PNG files written (Pillow's default is 6): at 3 a fit's corner plot is written
#: in 26 ms instead of 40 ms and is 5% smaller (218 against 229 kB; ad hoc, ``PIL.Image.save`` of
#: the ADIS16405 imu1 gyro x fit's corner plot, best of five); the pixels are the same
PNG_COMPRESSION = 3


def save_png(fig, path, **kwargs):
    """``fig.savefig(path, **kwargs)`` as a PNG at :data:`PNG_COMPRESSION` (``path`` a file name or
    a binary buffer)."""
    fig.savefig(path, format="png", pil_kwargs={"compress_level": PNG_COMPRESSION}, **kwargs)


#: dash patterns of the noise terms' lines, in turn: terms whose curves coincide over a range (white
#: and filtered white noise beyond the filter's time constant) stay visible one through the other
TERM_DASHES = ("--", (0, (1, 1.5)), "-.", (0, (6, 2, 1, 2, 1, 2)))


#: colours the figures give a fixed meaning (a requirement's line, outage marks, legend keys), each
#: with the distance in RGB within which a series' colour would be taken for it
#: (:func:`series_colours`): the cycle's red beside a red requirement line, its grey beside the
#: grey outage marks
RESERVED_COLOURS = {"red": 0.3, "gray": 0.15, "black": 0.3}


def series_colours(n):
    """``n`` colours, no two alike (hex strings): one per series of a figure, so that two series
    drawn in different panels (a sensor's band and an IMU's) never share a colour. Matplotlib's
    colour cycle first (``C0``, ``C1``, ...), then tab20b's and tab20c's (each a shade of every
    hue before the next shade), then evenly spaced hues;
    colours near :data:`RESERVED_COLOURS` are left out."""
    import matplotlib as mpl
    from matplotlib.colors import to_hex, to_rgb

    base = mpl.rcParams["axes.prop_cycle"].by_key().get("color", [])
    # tab20b and tab20c hold five hues in four shades each: one shade of every hue first, so that
    # neighbouring series differ in hue, not only in shade
    more = [mpl.colormaps[name].colors[4 * hue + shade] for name in ("tab20b", "tab20c")
            for shade in range(4) for hue in range(5)]
    reserved = np.array([to_rgb(c) for c in RESERVED_COLOURS])
    radius = np.array(list(RESERVED_COLOURS.values()))

    def free(colour):
        return np.all(np.linalg.norm(reserved - np.array(to_rgb(colour)), axis=1) > radius)

    pool = [c for c in dict.fromkeys(to_hex(c) for c in [*base, *more]) if free(c)]
    m = n - len(pool)
    while len(pool) < n:  # more series than named colours: hues, finer until there are enough
        m *= 2
        hues = (to_hex(mpl.colormaps["hsv"]((k + 0.5) / m)) for k in range(m))
        pool = list(dict.fromkeys([*pool, *(c for c in hues if free(c))]))
    return pool[:n]


def term_dashes(i):
    """The dash pattern of the ``i``-th noise term's line (:data:`TERM_DASHES` in turn)."""
    return TERM_DASHES[i % len(TERM_DASHES)]


#: decades an axis must span for :func:`sparse_log_minor_ticks` to thin its minor ticks
SPARSE_FROM_DECADES = 2.0


def sparse_log_minor_ticks(ax):
    """Minor ticks of a log-log time plot, set after its data and limits: 2 and 5 of each decade of
    time (x), and each decade of the y axis its labels skip, unlabelled. matplotlib's default, every
    2..9 of each decade, is a tick object each (five artists, its label laid out at every draw and
    by ``tight_layout``): over the many decades of a drift plot's error axis a third or more of the
    figure's time. An axis spanning fewer than :data:`SPARSE_FROM_DECADES` decades keeps the
    default, whose minor ticks carry the labels there (:func:`thin_log_minor_ticks`)."""
    thin_log_minor_ticks(ax.xaxis)
    thin_log_minor_ticks(ax.yaxis, subs=(1.0,))


def thin_log_minor_ticks(axis, subs=(2.0, 5.0)):
    """The minor ticks (and minor grid lines) of a log ``axis`` spanning
    :data:`SPARSE_FROM_DECADES` or more decades at ``subs`` of each decade only (2 and 5),
    unlabelled, set after its data and limits; a narrower axis keeps matplotlib's 2..9, whose ticks
    carry the labels there. Each tick is an object of five artists created as the figure is drawn:
    thinned, a fit's ``allan_fit.png`` (5-7 decades of averaging time, 2-4 of deviation) is drawn
    in 0.10-0.13 s instead of 0.16-0.19 s (``scripts/study_speed_options.py --figures``), and reads
    the same way (grid lines at 1, 2 and 5 of each decade)."""
    from matplotlib.ticker import LogLocator, NullFormatter

    low, high = sorted(axis.get_view_interval())
    if axis.get_scale() == "log" and low > 0 and np.log10(high / low) >= SPARSE_FROM_DECADES:
        axis.set_minor_locator(LogLocator(base=10.0, subs=subs, numticks=30))
        axis.set_minor_formatter(NullFormatter())


def import_plotting():
    """Import what the figures need (pyplot, corner) and draw a small log-log figure in memory
    (fonts, text layout and the PNG writer loaded): a worker's warm-up
    (:mod:`bayes_imu.report.worker`), so that its first real figure costs what later ones do."""
    import io

    plt = pyplot()
    import_corner()
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.errorbar([1e-2, 1.0, 1e2], [1.0, 0.1, 0.3], yerr=0.01, fmt="o", label="x")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_title("warm-up: 0.1 s")
    ax.legend(fontsize=8)
    save_png(fig, io.BytesIO(), dpi=50)
    plt.close(fig)


def import_corner():
    """``corner``, without importing ArviZ where nothing has loaded it yet.

    corner imports ArviZ as it is imported (for its ``InferenceData`` entry point), and ArviZ with
    xarray cost more to import than drawing every figure of a fit
    (docs/speed_under_load.md#imports);
    the figures here
    pass numpy arrays, which corner draws without ArviZ (its path where ArviZ is not installed).
    So corner is imported with ArviZ marked absent and given back an ``InferenceData`` entry point
    that imports ArviZ when first called (:func:`_arviz_corner`): ``corner.corner`` works for every
    input as before (tested). Where that is not safe, ArviZ is imported first, without its
    import-time announcement. The mechanism and its version pin:
    :func:`bayes_imu._lazy.import_without`.
    """
    from .._lazy import import_without
    from ..inference.fit import import_arviz

    return import_without("corner", "arviz", owner="corner.corner", attribute="arviz_corner",
                          stand_in=_arviz_corner, prepare=import_arviz)


def _arviz_corner(*args, **kwargs):
    """corner's ``InferenceData`` entry point, imported (with ArviZ) on first call:
    :func:`import_corner` imported corner without it."""
    import importlib
    import sys

    from ..inference.fit import import_arviz

    import_arviz()
    real = importlib.import_module("corner.arviz_corner").arviz_corner
    sys.modules["corner.corner"].arviz_corner = real
    return real(*args, **kwargs)


@contextlib.contextmanager
def _without_corner_notices():
    """corner's notices on the root logger left out inside the block ("Too few points to create
    valid contours": a panel whose draws are too concentrated for contours shows them as points),
    which a command printed as ``WARNING:root:...`` lines that a user can do nothing about."""
    import logging

    def keep(record):
        return "corner" not in record.pathname.replace("\\", "/").split("/")

    root = logging.getLogger()
    root.addFilter(keep)
    try:
        yield
    finally:
        root.removeFilter(keep)


def plot_allan(result, path, *, label="", unit="u"):
    """Log-log Allan deviation with its interval bars and the -1/2, 0, +1/2 slope guides.

    The guides pass through the curve's first point (-1/2: angle / velocity random
    walk), its minimum (0: bias instability) and its last point (+1/2: rate random walk);
    they are reading aids, not fits.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 5))
    tau, adev = result.tau, result.adev
    err = np.vstack([adev - result.adev_low, result.adev_high - adev])
    ax.errorbar(
        tau,
        adev,
        yerr=err,
        fmt="o-",
        ms=3,
        capsize=2,
        label=plain_text(label) or "overlapping ADEV",
    )
    i_min = int(np.argmin(adev))
    guides = (  # (label, slope, anchor index, span in decades before/after the anchor)
        ("ARW / VRW, slope -1/2", -0.5, 0, (0.0, 1.5), (8, 6)),
        ("bias instability, slope 0", 0.0, i_min, (1.0, 1.0), (0, -14)),
        ("RRW, slope +1/2", 0.5, tau.size - 1, (1.5, 0.0), (-60, 10)),
    )
    for text, slope, i, (before, after), offset in guides:
        span = tau[i] * np.logspace(-before, after, 20)
        line = adev[i] * (span / tau[i]) ** slope
        ax.plot(span, line, "--", color="gray", lw=1)
        end = -1 if slope < 0 else 0  # label the free end of the guide
        ax.annotate(
            text,
            (span[end], line[end]),
            textcoords="offset points",
            xytext=offset,
            fontsize=8,
            color="dimgray",
        )
    ax.set_ylim(adev.min() / 4, adev.max() * 2)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel(f"Allan deviation ({plain_text(unit)})")
    ax.set_title(f"Overlapping Allan deviation, {result.confidence:.1%} intervals")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    thin_log_minor_ticks(ax.xaxis)
    thin_log_minor_ticks(ax.yaxis)
    fig.tight_layout()
    save_png(fig, path, dpi=110)
    plt.close(fig)


def plot_allan_fit(fit, path, *, label="", unit="u", rng=None, scale=1.0):
    """Observed Allan deviation with intervals, the 90% posterior predictive band, each term,
    and a panel of the whitened residuals of the goodness-of-fit check.

    The panels have fixed sizes (:data:`_FIT_LAYOUT_IN`) and the legend stands beside them, its long
    entries wrapped: no layout pass (``tight_layout`` draws the figure once more; timings:
    docs/speed_under_load.md#figures), and no entry hides an observed point.

    Parameters
    ----------
    fit : FitResult
    path : path-like
    unit : str
        Unit shown: of the rate samples (after any conversion), times ``scale``.
    rng : seed for the posterior draws shown.
    scale : float
        Display factor of the Allan deviations (``--display-units deg``: 180/pi, ``unit`` deg/s).
    """
    plt = pyplot()
    allan = fit.allan
    adev, adev_low, adev_high = (scale * v for v in (allan.adev, allan.adev_low, allan.adev_high))
    tau_f = np.geomspace(allan.tau[0], allan.tau[-1], 80)
    m_f = np.unique(np.maximum(1, np.round(tau_f * allan.rate_hz)).astype(np.int64))
    tau_f = m_f / allan.rate_hz
    fig, (ax, ax_r) = _fixed_panels(plt, _FIT_LAYOUT_IN)
    err = np.vstack([adev - adev_low, adev_high - adev])
    ax.errorbar(allan.tau, adev, yerr=err, fmt="o", ms=3, capsize=2, color="k",
                label=_wrapped(plain_text(label) or "observed ADEV"))
    steady = getattr(fit, "stationarity", None)
    if steady is not None and not steady.stationary:  # the parts of a log whose noise changes
        for j, part in enumerate(steady.segment_adev):
            ax.plot(
                steady.tau_s,
                scale * part,
                "-",
                color="0.45",
                lw=0.8,
                alpha=0.8,
                label=(
                    _wrapped(
                        f"its {steady.n_segments} parts: noise changes (p {p_text(steady.p_value)})"
                    )
                    if j == 0
                    else None
                ),
            )
    pred = scale * np.sqrt(fit.predictive_avar(m_f, rng=rng))
    lo, med, hi = np.quantile(pred, [0.05, 0.5, 0.95], axis=0)
    ax.fill_between(tau_f, lo, hi, color="C0", alpha=0.3, label="posterior 90% band")
    ax.plot(tau_f, med, color="C0", lw=1.5, label=_wrapped("model: " + " + ".join(fit.model.terms)))
    for i, term in enumerate(fit.model.terms):
        part = scale * np.median(np.sqrt(fit.predictive_avar(m_f, rng=rng, term=term)), axis=0)
        ax.plot(
            tau_f,
            part,
            ls=term_dashes(i),
            color=f"C{i + 1}",
            lw=1,
            label=term_label(term, _is_accel(fit, unit)),
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(adev.min() / 5, adev.max() * 2)
    ax.set_ylabel(f"Allan deviation ({plain_text(unit)})")
    ax.set_title("Allan deviation: data and posterior")
    ax.grid(True, which="both", alpha=0.3)
    # beside the panel, not on it: inside, eight entries hid observed points wherever matplotlib put
    # them
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    _residual_panel(ax_r, fit)
    for axis in (ax.xaxis, ax.yaxis, ax_r.xaxis):
        _plain_log_labels(axis)
        thin_log_minor_ticks(axis)
    save_png(fig, path, dpi=110)
    plt.close(fig)


#: plot_allan_fit's layout (inches): the two panels' width and heights, the gap between them (the
#: residual panel's title), and the margins: tick and axis labels (left, bottom), the title (top),
#: the legend (right)
_FIT_LAYOUT_IN = {
    "width": 5.6,
    "heights": (3.9, 1.3),
    "gap": 0.45,
    "left": 0.85,
    "right": 2.75,
    "bottom": 0.6,
    "top": 0.4,
}


def _fixed_panels(plt, layout):
    """A figure of panels stacked with a shared x axis, laid out at fixed sizes in inches
    (``layout``): the same picture as a tight layout, without drawing the figure once more to
    measure it."""
    heights = layout["heights"]
    width = layout["left"] + layout["width"] + layout["right"]
    height = layout["bottom"] + sum(heights) + layout["gap"] * (len(heights) - 1) + layout["top"]
    return plt.subplots(
        len(heights),
        1,
        figsize=(width, height),
        sharex=True,
        gridspec_kw={
            "height_ratios": heights,
            "left": layout["left"] / width,
            "right": 1.0 - layout["right"] / width,
            "bottom": layout["bottom"] / height,
            "top": 1.0 - layout["top"] / height,
            "hspace": layout["gap"] / np.mean(heights),
        },
    )


def _wrapped(text, width=34):
    """``text`` on lines of at most ``width`` characters, broken at spaces (a word longer than that,
    such as a long file name, across lines): a legend entry beside a panel stays inside the
    figure."""
    import textwrap

    return (
        "\n".join(textwrap.wrap(text, width, subsequent_indent="  ", break_on_hyphens=False))
        or text
    )


def _plain_log_labels(axis):
    """The labels matplotlib gives a log axis (:class:`~matplotlib.ticker.LogFormatterSciNotation`,
    major and minor), in plain text (:func:`plain_log_formatter`): no mathtext to parse."""
    axis.set_major_formatter(plain_log_formatter())
    axis.set_minor_formatter(plain_log_formatter(labelOnlyBase=False))


def _residual_panel(ax, fit):
    """Whitened residuals per cluster size (N(0, 1) each when the model is right), +-2 marked."""
    check = fit.adequacy
    ax.set_xscale("log")
    ax.set_xlabel("averaging time tau (s)")
    if check is None:
        return
    r = check.residuals
    bad = np.abs(r) > 2.0
    ax.axhspan(-2, 2, color="C2", alpha=0.12)
    ax.axhline(0, color="gray", lw=0.8)
    ax.vlines(fit.allan.tau, 0, r, color=np.where(bad, "C3", "k"), lw=1)
    ax.plot(fit.allan.tau, r, "o", ms=3, color="k")
    ax.plot(fit.allan.tau[bad], r[bad], "o", ms=4, color="C3")
    ax.set_ylabel("whitened\nresidual")
    # residuals of tens beside the +-2 band (a real log's short taus): linear within +-2,
    # logarithmic beyond, so that the band and the small residuals stay readable
    top = float(np.max(np.abs(r), initial=0.0))
    wide = top > 10.0
    if wide:
        from matplotlib.ticker import NullLocator

        ax.set_yscale("symlog", linthresh=2.0, linscale=1.0)
        marks = [m for m in (2, 10, 50, 100, 500, 1000, 5000, 10000) if m <= 1.5 * top]
        ax.set_yticks([-m for m in marks[::-1]] + [0] + marks,
                      [f"{-m}" for m in marks[::-1]] + ["0"] + [f"{m}" for m in marks])
        ax.yaxis.set_minor_locator(NullLocator())
    verdict = (
        "adequate"
        if check.adequate
        else ("INADEQUATE, intervals widened" if fit.widened else "INADEQUATE")
    )
    scale = "; log scale beyond +-2" if wide else ""
    ax.set_title(f"goodness of fit: p {p_text(check.p_value)} ({verdict}); shaded: +-2{scale}",
                 fontsize=9)
    ax.grid(True, which="both", alpha=0.3)


def plot_corner(fit, path, *, unit="u", scale=1.0):
    """Corner plot of the physical parameters with their units, on log axes (``unit`` the unit
    shown for the rate samples, each parameter times ``scale`` to its power of that unit:
    ``--display-units deg``).

    Each panel's title gives the median and the 5% / 95% quantiles; tick labels are plain
    numbers (no offset notation), so a tightly pinned parameter still reads correctly. The
    pair panels are corner.py's (:func:`corner.hist2d`: points, density, 0.5-2 sigma contours),
    the grid is laid out here (:func:`_corner_grid`).
    """
    plt = pyplot()

    from ..drift.display import unit_power
    from ..noise.avar_forms import PARAMETER_UNITS

    names = fit.parameter_names
    labels = [f"{n}\n[{plain_text(PARAMETER_UNITS.get(n, '1').format(u=unit))}]" for n in names]
    data = fit.samples
    if scale != 1.0:
        data = data * np.array([scale ** unit_power(PARAMETER_UNITS.get(n, "1")) for n in names])
    if data.shape[1] == 1:
        fig, ax = plt.subplots(figsize=(4.5, 3.2))
        limits = _draw_range(data[:, 0])  # as the grid's axes: a few far draws left out
        ax.hist(data[:, 0], bins=np.geomspace(*limits, 41), color="C0")
        ax.set_xscale("log")
        ax.set_xlim(limits)
        # the grid's ticks (at most four labelled): matplotlib's labelled every minor tick of a
        # narrow log axis, one over the other
        _set_ticks(ax.xaxis, _log_ticks(*limits), labelled=True,
                   label=labels[0].replace("\n", " "))
        q = np.quantile(data[:, 0], [0.05, 0.5, 0.95])
        # the digits the interval resolves, as the diagonal panels of a larger model's corner plot
        ax.set_title(f"{interval_text(q[1], q[0], q[2], most=4)} ({CORNER_SCOPE})", fontsize=8)
        fig.tight_layout()
        save_png(fig, path, dpi=90, bbox_inches="tight", pad_inches=0.1)
    else:
        fig = _corner_grid(plt, data, labels)
        _corner_note(fig, fit.model.terms, data.shape[1])
        save_png(fig, path, dpi=90)
    plt.close(fig)


#: what the corner plot's intervals are: the selected model's posterior from this record alone
CORNER_SCOPE = "this record alone"


#: the corner grid's layout (inches): a panel, the gap between panels, and the margins that hold the
#: tick labels and two-line axis labels (left, bottom), the diagonal's two-line titles (top)
_PANEL_IN, _GAP_IN, _MARGINS_IN = 1.9, 0.1, {"left": 1.15, "bottom": 1.1, "right": 0.25, "top": 0.5}


def _corner_grid(plt, data, labels, bins=20):
    """The lower triangle of a corner plot of ``data`` ``(draws, k)`` on log axes: a histogram of
    each parameter on the diagonal (5%, 50%, 95% quantiles dashed, as corner.py draws them) and
    :func:`corner.hist2d` below it; tick labels on the bottom row and left column only.

    corner.py's ``corner`` draws the same panels in a full k x k grid and blanks the tick labels of
    inner panels by giving them empty label lists, which creates a tick object for every minor tick
    of every log axis (about 1300 for seven parameters, half its drawing time); here the inner
    panels' labels are switched off (no tick created), each parameter's ticks are computed once for
    its column and row, the unlabelled ticks are drawn on the edge panels only, and the layout is
    fixed (no tight bounding box, which draws the figure twice): faster than ``corner``'s, the more
    so the more parameters (timings:
    docs/speed_under_load.md#figures).
    """
    corner = import_corner()
    k = data.shape[1]
    ranges = [_draw_range(data[:, j]) for j in range(k)]
    ticks = [_log_ticks(*r) for r in ranges]
    size = k * _PANEL_IN + (k - 1) * _GAP_IN
    width, height = (
        size + _MARGINS_IN["left"] + _MARGINS_IN["right"],
        size + _MARGINS_IN["bottom"] + _MARGINS_IN["top"],
    )
    fig = plt.figure(figsize=(width, height))
    grid = fig.add_gridspec(
        k,
        k,
        left=_MARGINS_IN["left"] / width,
        right=1.0 - _MARGINS_IN["right"] / width,
        bottom=_MARGINS_IN["bottom"] / height,
        top=1.0 - _MARGINS_IN["top"] / height,
        wspace=_GAP_IN / _PANEL_IN,
        hspace=_GAP_IN / _PANEL_IN,
    )
    with _without_corner_notices():
        for i in range(k):
            for j in range(i + 1):
                ax = fig.add_subplot(grid[i, j])
                if i == j:
                    _diagonal_panel(ax, data[:, i], ranges[i], bins)
                else:
                    _pair_panel(corner, ax, data[:, j], data[:, i], (ranges[j], ranges[i]), bins)
                    _set_ticks(ax.yaxis, ticks[i], labelled=j == 0, label=labels[i])
                _set_ticks(ax.xaxis, ticks[j], labelled=i == k - 1, label=labels[j])
                ax.tick_params(which="both", labelsize=CORNER_FONT)
    return fig


def _pair_panel(corner, ax, x, y, ranges, bins):
    """One pair panel: :func:`corner.hist2d` of ``y`` against ``x`` on log axes, its density
    shading drawn as one mesh.

    corner draws the shading with ``ax.pcolor``, a polygon per bin (400 at 20 bins), each carried
    through the log transform one by one when drawn (a third of the drawing, in a profile). Here
    ``ax.pcolor`` is ``ax.pcolormesh`` for the call (the same bins, colours and order among the
    panel's artists; one transform of the whole mesh): the same picture (bin edges differ by a
    pixel's antialiasing), drawn faster: a corner plot of five parameters in 0.28-0.31 s instead of
    0.34 s, of seven in 0.47-0.55 s instead of 0.62-0.92 s (``scripts/study_speed_options.py
    --figures``, three runs)."""
    ax.pcolor = functools.partial(_mesh, ax)
    try:
        corner.hist2d(x, y, ax=ax, range=list(ranges), axes_scale=["log", "log"], bins=bins,
                      color="k")
    finally:
        del ax.pcolor  # the Axes method again


def _mesh(ax, x, y, c, **kwargs):
    """``ax.pcolor(x, y, c, **kwargs)`` of bin edges ``x``, ``y`` as one
    :meth:`~matplotlib.axes.Axes.pcolormesh`."""
    return ax.pcolormesh(x, y, c, shading="flat", **kwargs)


def _corner_note(fig, terms, k):
    """What the corner plot shows, in the empty upper triangle (wrapped to its width, from the
    second column's left edge): the model, and that the titles are this record's posterior alone
    (summary.json's ``parameters`` add the repeatability between the record's parts)."""
    import textwrap

    width_in = (k - 1) * (_PANEL_IN + _GAP_IN) - _GAP_IN
    chars = max(18, int(width_in * 72.0 / (0.62 * CORNER_FONT)))  # ~0.62 em a character
    text = "\n".join(textwrap.fill(part, chars) for part in (
        " + ".join(terms),
        f"titles: median [5%, 95%], {CORNER_SCOPE}; axes: at most {100 * CORNER_TAIL:g}% of the "
        "draws beyond each end",
        "(summary.json: parameters_this_record; its parameters add the repeatability between "
        "the record's parts where it is wider)",
    ))
    w, h = fig.get_figwidth(), fig.get_figheight()
    fig.text((_MARGINS_IN["left"] + _PANEL_IN + _GAP_IN + 0.1) / w, 1.0 - _MARGINS_IN["top"] / h,
             text, ha="left", va="top", fontsize=CORNER_FONT)


#: the share of a parameter's draws beyond each end of its corner-plot axis, at most: a few far
#: draws (a walker's excursion towards the prior box) squeezed the posterior's bulk into a corner
#: of its panels (a time constant's axis from 1 s for a 60-680 s interval; a vibration frequency's
#: from 0.04 Hz for 0.55 Hz, its row and column collapsed onto one edge)
CORNER_TAIL = 0.002


def _draw_range(x):
    """``(low, high)`` of a corner-plot axis of positive draws ``x``: from the :data:`CORNER_TAIL`
    quantile to the ``1 - CORNER_TAIL`` one, each end moved out by 5% of that span (in logarithm)
    but not beyond the draws' own extremes, so a few far draws fall outside the axis instead of
    squeezing the rest; a parameter pinned to one value gets +-10% around it. The ends are widened
    by a relative 1e-9: corner's log-spaced bins (``logspace`` of the ends' logarithms) round the
    first and last edge inwards by an ulp or so, and draws exactly at an end would otherwise fall
    outside every bin (an empty histogram, which corner refuses)."""
    x = np.asarray(x, float)
    lowest, highest = float(np.min(x)), float(np.max(x))
    if not highest > lowest:
        return lowest / 1.1 * (1.0 - 1e-9), highest * 1.1 * (1.0 + 1e-9)
    low, high = np.quantile(x, [CORNER_TAIL, 1.0 - CORNER_TAIL])
    if not high > low:  # most draws at one value, a few elsewhere: every draw shown
        low, high = lowest, highest
    pad = 0.05 * np.log(high / low)
    low, high = max(lowest, low * np.exp(-pad)), min(highest, high * np.exp(pad))
    return low * (1.0 - 1e-9), high * (1.0 + 1e-9)


#: the corner grid's tick labels: none nearer than LABEL_END of the axis's log length to its ends
#: (where two others can be labelled), none nearer than LABEL_GAP to one another (45-degree labels
#: of CORNER_FONT points on a 1.9-inch panel: a label reaches a fifth of the panel beyond its tick)
LABEL_END, LABEL_GAP = 0.1, 0.22
#: the corner grid's font size (points) of tick labels, axis labels and titles: 7 read as tiny
#: at full size (a new user's finding)
CORNER_FONT = 9


def _log_ticks(low, high, max_labels=4):
    """``(labelled, unlabelled)`` tick positions of a log axis from ``low`` to ``high``:
    matplotlib's log tick positions inside the range (its linear ones where the range is narrower
    than those; where two or more powers of ten lie inside, only 1, 2 and 5 times a power of ten),
    at most ``max_labels`` of them labelled (those powers of ten, else ticks spread over the axis,
    the round ones first: :func:`_spaced`; those near the axis's ends left unlabelled where two
    others can be: :func:`_inside_ends`), so that rotated labels do not overlap."""
    from matplotlib.ticker import LogLocator

    powers = 10.0 ** np.arange(np.ceil(np.log10(low) - 1e-9), np.floor(np.log10(high) + 1e-9) + 1)
    both = np.concatenate(
        [
            LogLocator(numticks=3).tick_values(low, high),
            LogLocator(subs="auto").tick_values(low, high),
            # every power of ten inside (over many decades matplotlib skips some)
            powers,
        ]
    )
    ticks = np.unique(both[(both >= low * (1 - 1e-9)) & (both <= high * (1 + 1e-9))])
    if ticks.size == 0:
        return ticks, ticks
    exponent = np.log10(ticks)
    decades = np.isclose(exponent, np.round(exponent), rtol=0.0, atol=1e-9)
    if np.count_nonzero(decades) >= 2:
        # only 1, 2 and 5 times a power of ten between them (every tick drawn costs), the powers
        # labelled
        keep = np.isin(_coefficient(ticks), (1.0, 2.0, 5.0))
        ticks, decades = ticks[keep], decades[keep]
        candidates = _inside_ends(ticks, low, high, np.flatnonzero(decades))
        chosen = candidates[::-(-candidates.size // max_labels)]
    else:
        chosen = _spaced(
            ticks, _inside_ends(ticks, low, high, np.arange(ticks.size)), low, high, max_labels
        )
    labelled = np.zeros(ticks.size, bool)
    labelled[chosen] = True
    return ticks[labelled], ticks[~labelled]


def _spaced(ticks, candidates, low, high, max_labels, gap=LABEL_GAP):
    """At most ``max_labels`` of the ``candidates`` (indices into ``ticks``), at least ``gap`` of
    the axis's log length apart: a power of ten first, then 2 and 5 times one, then the others, each
    group from the axis's middle out, a tick kept where no kept one is nearer. On a log axis the
    ticks are not evenly spaced (8, 9, 10, 20, 30 x 10^-5), so every k-th one could put two labels
    nearly on one another."""
    where, coefficient = _axis_fraction(ticks, low, high), _coefficient(ticks)
    rank = np.where(coefficient == 1.0, 0, np.where(np.isin(coefficient, (2.0, 5.0)), 1, 2))
    kept = []
    for i in sorted(candidates, key=lambda i: (rank[i], abs(where[i] - 0.5))):
        if len(kept) < max_labels and all(abs(where[i] - where[j]) >= gap for j in kept):
            kept.append(i)
    return np.sort(np.array(kept, dtype=np.int64))


def _axis_fraction(ticks, low, high):
    """Where ``ticks`` lie on a log axis from ``low`` to ``high``: 0 at its start, 1 at its end."""
    return (np.log10(ticks) - np.log10(low)) / max(np.log10(high) - np.log10(low), 1e-300)


def _coefficient(ticks):
    """``ticks`` over their power of ten (1 to 9.99...), rounded to 6 decimals: 2 for 2e-5."""
    return np.round(ticks / 10.0 ** np.floor(np.log10(ticks) + 1e-9), 6)


def _inside_ends(ticks, low, high, candidates, margin=LABEL_END):
    """The ``candidates`` (indices into ``ticks``) farther than ``margin`` of the axis's log length
    from both ends, where two or more are (a label at a panel's edge runs into the next panel's),
    else those farther than half that, else all of them."""
    where = _axis_fraction(ticks[candidates], low, high)
    for edge in (margin, margin / 2):
        inside = candidates[(where > edge) & (where < 1.0 - edge)]
        if inside.size >= 2:
            return inside
    return candidates


def _set_ticks(axis, ticks, *, labelled, label):
    """Fixed ticks on ``axis`` (:func:`_log_ticks`: the labelled ones major, the rest minor); on an
    edge (``labelled``) plain tick labels rotated 45 degrees and the axis label, elsewhere no
    labels."""
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    major, minor = ticks
    axis.set_major_locator(FixedLocator(major))
    # the unlabelled ticks on the edges only, where they help read the labelled ones: an inner panel
    # lines up with its edge panels (each tick drawn is an object of five artists)
    axis.set_minor_locator(FixedLocator(minor) if labelled else NullLocator())
    axis.set_minor_formatter(NullFormatter())
    name = axis.axis_name
    if labelled:
        axis.set_major_formatter(
            plain_log_formatter(labelOnlyBase=False, minor_thresholds=(np.inf, np.inf))
        )
        axis.axes.tick_params(axis=name, which="major", labelrotation=45)
        axis.set_label_text(label, fontsize=CORNER_FONT)
    else:
        axis.set_major_formatter(NullFormatter())
        axis.axes.tick_params(
            axis=name, which="both", **{"labelbottom" if name == "x" else "labelleft": False}
        )


def _diagonal_panel(ax, x, limits, bins):
    """One parameter's histogram on log bins, its 5%, 50%, 95% quantiles dashed and given in the
    title (to the digits the interval resolves: :func:`~bayes_imu.report.text.interval_numbers`)."""
    from matplotlib.ticker import NullLocator

    counts, edges = np.histogram(x, bins=np.geomspace(limits[0], limits[1], bins + 1))
    ax.stairs(counts, edges, color="k")
    q = np.quantile(x, [0.05, 0.5, 0.95])
    for value in q:
        ax.axvline(value, ls="dashed", color="k")
    ax.set_xscale("log")
    ax.set_xlim(limits)
    ax.set_ylim(0.0, 1.1 * counts.max())
    ax.yaxis.set_major_locator(NullLocator())
    ax.yaxis.set_minor_locator(NullLocator())
    # the digits the interval resolves, as the console prints them (at most 4 in a panel's title)
    median, low, high = interval_numbers(q[1], q[0], q[2], most=4)
    ax.set_title(f"{median}\n[{low}, {high}]", fontsize=CORNER_FONT)


_SUPERSCRIPT = str.maketrans(
    "-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079"
)


def plain_log_formatter(**kwargs):
    """``matplotlib.ticker.LogFormatterSciNotation(**kwargs)`` whose labels are plain text
    (``2\u00d710\u207b\u00b3``, Unicode superscripts) instead of mathtext
    (``$\\mathdefault{2\\times10^{-3}}$``): the same ticks labelled, the same numbers. Every
    mathtext label is parsed when drawn (matplotlib's cache holds 50), which makes a corner plot
    slower (timings: docs/speed_under_load.md#figures)."""
    import re

    from matplotlib.ticker import LogFormatterSciNotation

    pattern = re.compile(
        r"^\$\\mathdefault\{(-?)(?:([0-9.]+)\\times\s*)?([0-9]+)(?:\^\{(-?[0-9]+)\})?\}\$$"
    )

    class PlainLogFormatter(LogFormatterSciNotation):
        def __call__(self, x, pos=None):
            label = super().__call__(x, pos)
            match = pattern.match(label)
            # anything else (an empty label, another notation) as matplotlib writes it
            if match is None:
                return label
            sign, coefficient, base, exponent = match.groups()
            text = base + (exponent.translate(_SUPERSCRIPT) if exponent is not None else "")
            return sign + (f"{coefficient}\u00d7{text}" if coefficient else text)

    return PlainLogFormatter(**kwargs)


def term_label(name, accel=False):
    """What a figure calls a term (:attr:`bayes_imu.noise.Term.plot_label`; else its name); an
    accelerometer's rate terms are its acceleration's ("acceleration random walk")."""
    from ..noise import REGISTRY

    label = REGISTRY[name].plot_label if name in REGISTRY else name
    return "acceleration " + label[len("rate "):] if accel and label.startswith("rate ") else label


def sensor_term_label(key):
    """A navigation term ``"gyro:gauss_markov"`` as the figures name it: ``"gyro Gauss-Markov
    bias"``, ``"accel acceleration random walk"`` (:func:`term_label`; "accel" short, so that two
    legend columns fit a panel's width)."""
    sensor, term = key.split(":")
    if sensor == "gyro":
        return f"gyro {term_label(term)}"
    return f"accel {term_label(term, accel=True)}"


def _is_accel(fit, unit):
    """Whether a fit is an accelerometer's: its sensor kind, else its unit."""
    sensor = getattr(getattr(fit, "allan", None), "sensor", None) or getattr(fit, "sensor", None)
    return sensor == "accel" or str(unit) in ("m/s^2", "g", "mg", "ug")


_QUANTITY_LABEL = {
    "attitude": "attitude error",
    "velocity": "velocity error",
    "position": "position error",
}


def plot_drift(bands_list, path, *, units, title="", min_probability=0.1):
    """Drift credible bands (log-log), white and bias parts separately, crossover marked (paper Figs
    8, 11).

    Parameters
    ----------
    bands_list : sequence of DriftBands
        One panel per quantity.
    units : sequence of str
        Unit of each panel's quantity (e.g. "deg", "m/s", "m").
    min_probability : float
        Terms whose posterior probability (model averaging) is lower are not drawn (listed).
    """
    plt = pyplot()
    fig, axes = plt.subplots(
        1, len(bands_list), figsize=(6.5 * len(bands_list), 6.6), squeeze=False
    )
    for ax, bands, unit in zip(axes[0], bands_list, units):
        keep = bands.total[0] > 0  # the double integral is exactly 0 after one sample
        t = bands.t_s[keep]
        lo, hi = bands.total[0][keep], bands.total[-1][keep]
        ax.fill_between(
            t,
            lo,
            hi,
            color="C0",
            alpha=0.3,
            label=f"total, {bands.quantiles[0]:.0%}-{bands.quantiles[-1]:.0%} credible band",
        )
        ax.plot(
            t,
            bands.total[len(bands.quantiles) // 2][keep],
            color="C0",
            lw=1.5,
            label="total, median",
        )
        hidden = []
        for i, (name, part) in enumerate(bands.terms.items()):
            positive = part[keep] > 0
            p = bands.term_probability.get(name, 1.0)
            accel = bands.quantity in ("velocity", "position")
            if p < min_probability:
                hidden.append(term_label(name, accel))
                continue
            if np.any(positive):
                where = f", median where modelled, P = {p:.2f}" if p < 0.995 else ", median"
                ax.plot(t[positive], part[keep][positive], ls=term_dashes(i), lw=1,
                        color=f"C{i + 1}", label=f"{term_label(name, accel)}{where}")
        if hidden:
            import textwrap

            ax.plot(
                [],
                [],
                " ",
                label=textwrap.fill(
                    f"not drawn (P < {min_probability:g}): " + ", ".join(hidden), 60
                ),
            )
        if np.isfinite(bands.crossover_s):
            ax.axvline(bands.crossover_s, color="gray", lw=1, ls=":")
            ax.annotate(
                f"biases and slow terms\nexceed short-term noise\nafter {bands.crossover_s:.3g} s",
                (bands.crossover_s, 0.02),
                xycoords=("data", "axes fraction"),
                textcoords="offset points",
                xytext=(4, 4),
                fontsize=7,
                color="dimgray",
                va="bottom",
                ha="left" if bands.crossover_s < np.sqrt(t[0] * t[-1]) else "right",
            )
        _draw_measured(ax, bands, t)
        ax.set_xscale("log")
        ax.set_yscale("log")
        sparse_log_minor_ticks(ax)
        ax.set_xlabel("time since GPS loss (s)")
        ax.set_ylabel(f"1-sigma {_QUANTITY_LABEL[bands.quantity]} ({plain_text(unit)})")
        start = (
            f"bias calibrated over {bands.calibration_s:g} s"
            if bands.bias_start == "calibrated"
            else f"bias start: {bands.bias_start}"
        )
        ax.set_title(f"{bands.quantity} drift, {start}, {bands.models} models", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(
            fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1, frameon=False
        )
    if title:
        fig.suptitle(plain_text(title))
    fig.tight_layout()
    save_png(fig, path, dpi=110)
    plt.close(fig)


def _draw_measured(ax, bands, t):
    """The record's own 1-sigma drift with its 90% interval (drift.direct) and the model's
    extrapolation beyond what the record measures (or beyond the log) shaded."""
    check = getattr(bands, "check", None)
    if check is not None and check.t_s.size:
        i = np.unique(
            np.linspace(0, check.t_s.size - 1, min(check.t_s.size, 16)).round().astype(int)
        )
        ax.errorbar(
            check.t_s[i],
            check.direct[i],
            yerr=[check.direct[i] - check.direct_low[i], check.direct_high[i] - check.direct[i]],
            fmt="o",
            ms=2.5,
            lw=0.8,
            color="black",
            alpha=0.7,
            label=("measured on the log itself, 90% interval (the model "
                   f"{'agrees' if check.adequate else 'DISAGREES'}: p {p_text(check.p_combined)})"),
        )
    measured = getattr(bands, "measured_s", float("nan"))
    edge = measured if np.isfinite(measured) else bands.record_s
    if edge < t[-1]:
        what = (
            f"beyond what the log measures ({edge:.4g} s): model extrapolation"
            if np.isfinite(measured)
            else f"beyond the log ({edge:.4g} s): extrapolation"
        )
        if measured == 0.0:
            what, edge = "the log measured another calibration window: the model's alone", t[0]
        ax.axvspan(
            edge,
            t[-1],
            color="gray",
            alpha=0.12,
            hatch="//" if np.isfinite(measured) else None,
            label=what,
        )


def plot_population(pop, path, *, unit="u", bands=None, unit_bands=(), rng=None, drift_unit=None,
                    scale=1.0):
    """Population fit: every unit's Allan deviation with the new-unit 90% band; optionally the
    new-unit drift band against each unit's own (single-unit) drift median.

    Parameters
    ----------
    pop : PopulationResult
    unit : str
        Unit of the rate samples.
    bands : DriftBands, optional
        New-unit drift bands (one quantity); adds the right-hand panel.
    unit_bands : sequence of DriftBands
        Each unit's single-unit bands of the same quantity (medians drawn).
    drift_unit : str, optional
        Unit of the drift values shown (default: the integrated unit of ``unit``).
    scale : float
        Display factor of the Allan deviations (``--display-units deg``: 180/pi, ``unit`` deg/s).
    """
    plt = pyplot()
    panels = 2 if bands is not None else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.5 * panels, 4.8), squeeze=False)
    ax = axes[0][0]
    first = pop.unit_fits[0].allan
    tau_lo = min(f.allan.tau[0] for f in pop.unit_fits)
    tau_hi = max(f.allan.tau[-1] for f in pop.unit_fits)
    m_f = np.unique(
        np.maximum(1, np.round(np.geomspace(tau_lo, tau_hi, 80) * first.rate_hz)).astype(np.int64)
    )
    tau_f = m_f / first.rate_hz
    pred = scale * np.sqrt(pop.new_unit.predictive_avar(m_f, rng=rng))
    lo, med, hi = np.quantile(pred, [0.05, 0.5, 0.95], axis=0)
    ax.fill_between(tau_f, lo, hi, color="0.6", alpha=0.45, label="new unit, 90% predictive band")
    ax.plot(tau_f, med, color="k", lw=1.5, label="new unit, median")
    for i, (label, f) in enumerate(zip(pop.labels, pop.unit_fits)):
        ax.plot(
            f.allan.tau,
            scale * f.allan.adev,
            "o-",
            ms=3,
            lw=0.8,
            color=f"C{i % 10}",
            label=plain_text(label),
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel(f"Allan deviation ({plain_text(unit)})")
    ax.set_title(f"{len(pop.labels)} units, model {' + '.join(pop.model.terms)}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    if bands is not None:
        ax = axes[0][1]
        keep = bands.total[0] > 0
        t = bands.t_s[keep]
        ax.fill_between(t, bands.total[0][keep], bands.total[-1][keep], color="0.6", alpha=0.45,
                        label=f"new unit, {bands.quantiles[0]:.0%}-{bands.quantiles[-1]:.0%} band")
        ax.plot(
            t,
            bands.total[len(bands.quantiles) // 2][keep],
            color="k",
            lw=1.5,
            label="new unit, median",
        )
        for i, (label, b) in enumerate(zip(pop.labels, unit_bands)):
            ax.plot(
                t,
                b.total[len(b.quantiles) // 2][keep],
                lw=0.9,
                color=f"C{i % 10}",
                label=f"{plain_text(label)} alone, median",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time since GPS loss (s)")
        from ..drift.bands import integrated_unit

        shown = drift_unit or integrated_unit(unit, bands.quantity)
        ax.set_ylabel(f"1-sigma {_QUANTITY_LABEL[bands.quantity]} ({plain_text(shown)})")
        start = (
            f"bias calibrated over {bands.calibration_s:g} s"
            if bands.bias_start == "calibrated"
            else f"bias start: {bands.bias_start}"
        )
        ax.set_title(f"{bands.quantity} drift of a new unit, {start}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    save_png(fig, path, dpi=110)
    plt.close(fig)
