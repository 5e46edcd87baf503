"""Every figure: it decodes as a PNG of the expected size, and carries its labels, units and legend
entries."""

import numpy as np
import pytest

from bayes_imu import NoiseModel, allan_variance, fit_allan, simulate_log
from bayes_imu.report import plots
from bayes_imu.drift.bands import drift_bands


@pytest.fixture(scope="module")
def fit():
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    y = simulate_log(
        model, {"noise_variance": 1e-4, "bias_variance": 1e-7, "time_constant": 20.0}, 60_000, rng=3
    )
    return fit_allan(allan_variance(y, rate_hz=100.0), terms=("white", "gauss_markov"), rng=0)


def _texts(fig):
    out = []
    for ax in fig.axes:
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        legend = ax.get_legend()
        if legend is not None:
            out += [t.get_text() for t in legend.get_texts()]
        out += [t.get_text() for t in ax.texts]
    return " | ".join(out)


def _png(path, min_size=(300, 200)):
    import matplotlib.image

    image = matplotlib.image.imread(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert image.shape[1] >= min_size[0] and image.shape[0] >= min_size[1]
    assert image[..., :3].std() > 0.05  # not blank
    return image


def test_allan_plot_labels_its_unit(tmp_path, figures, fit):
    plots.plot_allan(fit.allan, tmp_path / "a.png", label="log: gx", unit="rad/s")
    _png(tmp_path / "a.png")
    text = _texts(figures[-1])
    assert (
        "Allan deviation (rad/s)" in text and "averaging time tau (s)" in text and "log: gx" in text
    )


def test_allan_fit_has_band_terms_and_residuals(tmp_path, figures, fit):
    plots.plot_allan_fit(fit, tmp_path / "f.png", unit="rad/s", rng=0)
    _png(tmp_path / "f.png")
    text = _texts(figures[-1])
    for word in (
        "posterior 90% band",
        "white noise",
        "Gauss-Markov bias",
        "whitened",
        "goodness of fit",
        "(rad/s)",
    ):
        assert word in text, word


@pytest.mark.parametrize("largest", [1.7, 58.2])
def test_residual_panel_keeps_the_band_readable_beside_large_residuals(largest):
    """Residuals of tens (a real accelerometer log's short taus) beside the +-2 band: the panel is
    linear within +-2 and logarithmic beyond, its ticks at 0, +-2, +-10 and +-50 (up to 1.5 times
    the largest residual), every residual inside the axis, and the title says so; residuals within
    10 keep a linear axis and the plain title."""
    from types import SimpleNamespace

    import matplotlib.figure

    tau = 0.01 * 2.0 ** np.arange(6)
    r = np.array([0.5, -1.2, largest, -largest / 2, 0.3, 1.1])
    fit = SimpleNamespace(adequacy=SimpleNamespace(residuals=r, adequate=largest < 2,
                                                   p_value=0.3 if largest < 2 else 1e-40),
                          allan=SimpleNamespace(tau=tau), widened=largest >= 2)
    ax = matplotlib.figure.Figure().subplots()
    plots._residual_panel(ax, fit)
    low, high = ax.get_ylim()
    assert low <= r.min() and high >= r.max()
    if largest < 10:
        assert ax.get_yscale() == "linear" and "log scale" not in ax.get_title()
        return
    assert ax.get_yscale() == "symlog" and ax.get_title().endswith("log scale beyond +-2")
    assert list(ax.get_yticks()) == [-50, -10, -2, 0, 2, 10, 50]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["-50", "-10", "-2", "0", "2", "10",
                                                            "50"]


def test_allan_fit_keeps_every_label_inside_the_figure_and_its_legend_off_the_data(
    tmp_path, figures, fit
):
    """The fixed layout (no tight_layout pass): every visible text (title, axis and tick labels,
    legend entries, a long log name wrapped) lies inside the saved figure, and the legend stands
    beside the data panel, not on it (inside, its entries hid observed points on real logs)."""
    name = "a_long_name_of_a_real_recording_from_the_test_bench_2026-11-24.csv.gz: gyro_x_dps"
    plots.plot_allan_fit(fit, tmp_path / "f.png", label=name, unit="rad/s", rng=0)
    fig = figures[-1]
    fig.canvas.draw()  # at the figure's own dpi, the units of fig.bbox
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    legend = ax.get_legend()
    texts = list(legend.get_texts())
    for each in fig.axes:
        texts += [each.title, each.xaxis.label, each.yaxis.label]
        for axis, (low, high) in ((each.xaxis, each.get_xlim()), (each.yaxis, each.get_ylim())):
            texts += [t.label1 for t in axis.get_major_ticks() + axis.get_minor_ticks()
                      if t.label1.get_visible() and min(low, high) <= t.get_loc() <= max(low, high)]
    page = fig.bbox
    for text in texts:
        if not text.get_text():
            continue
        box = text.get_window_extent(renderer)
        assert (
            page.x0 - 1 <= box.x0
            and box.x1 <= page.x1 + 1
            and page.y0 - 1 <= box.y0
            and box.y1 <= page.y1 + 1
        ), text.get_text()
    assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    assert any(name.split(":")[0][:20] in t.get_text() for t in legend.get_texts())
    assert max(len(line) for t in legend.get_texts() for line in t.get_text().split("\n")) <= 34


def test_corner_has_units_and_no_offset_ticks(tmp_path, figures, fit):
    plots.plot_corner(fit, tmp_path / "c.png", unit="rad/s")
    _png(tmp_path / "c.png")
    fig = figures[-1]
    text = _texts(fig)
    assert "noise_variance\n[(rad/s)^2]" in text and "time_constant\n[s]" in text
    fig.canvas.draw()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            assert axis.get_offset_text().get_text() == ""


def test_corner_tick_labels_are_plain_text_giving_each_tick_value(tmp_path, figures, fit):
    """The corner plot's edge tick labels are plain text (no mathtext to parse), and each non-empty
    one reads back, Unicode superscripts included, as its tick's value to the precision the label
    shows (what matplotlib's mathtext label gives); some minor ticks are labelled
    (minor_thresholds)."""
    import re

    plots.plot_corner(fit, tmp_path / "c.png", unit="rad/s")
    fig = figures[-1]
    fig.canvas.draw()
    digits = str.maketrans(
        "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079", "-0123456789"
    )
    labelled = 0
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                text = tick.label1.get_text()
                if not text:
                    continue
                assert "$" not in text
                match = re.fullmatch(
                    r"(?:([0-9.]+)\u00d7)?10([\u207b\u2070-\u2079\u00b9\u00b2\u00b3]+)", text
                )
                assert match, text
                coefficient = float(match.group(1) or 1.0)
                value = coefficient * 10.0 ** int(match.group(2).translate(digits))
                decimals = (
                    len(match.group(1).split(".")[1])
                    if match.group(1) and "." in match.group(1)
                    else 0
                )
                exponent = np.floor(np.log10(tick.get_loc()))
                assert value == pytest.approx(
                    tick.get_loc(), abs=0.51 * 10.0 ** (exponent - decimals)
                ), text
                labelled += 1
    assert labelled >= 2 * len(fit.parameter_names)


def test_drift_plot_labels_terms_with_probability(tmp_path, figures, fit):
    bands = drift_bands(fit, quantity="attitude", bias_start="calibrated", horizon_s=1000.0)
    plots.plot_drift([bands.scaled(180 / np.pi)], tmp_path / "d.png", units=["deg"])
    _png(tmp_path / "d.png")
    text = _texts(figures[-1])
    assert "1-sigma attitude error (deg)" in text and "time since GPS loss (s)" in text
    assert "white noise" in text and "credible band" in text
    assert "bias calibrated over 60 s" in text
    for name, p in bands.term_probability.items():
        label = plots.term_label(name)
        assert (label in text) == (p >= 0.1), name


def test_drift_plot_minor_ticks_are_2_and_5_of_time_and_the_skipped_decades(tmp_path, figures,
                                                                            fit):
    """drift.png's log axes (plots.sparse_log_minor_ticks, also nav.png's): the time axis's
    unlabelled minor ticks at 2 and 5 of each decade, the error axis's at whole decades only, none
    labelled; the major (labelled) ticks are matplotlib's decades."""
    bands = drift_bands(fit, quantity="attitude", bias_start="calibrated", horizon_s=1000.0)
    plots.plot_drift([bands], tmp_path / "d.png", units=["rad"])
    ax = figures[-1].axes[0]
    x_lo, x_hi = ax.get_xlim()
    x_minor = [v for v in ax.xaxis.get_minorticklocs() if x_lo <= v <= x_hi]
    mantissa = {round(v / 10.0 ** np.floor(np.log10(v) + 1e-9), 6) for v in x_minor}
    assert len(x_minor) >= 4 and mantissa == {2.0, 5.0}, x_minor
    y_minor = ax.yaxis.get_minorticklocs()
    np.testing.assert_allclose(np.log10(y_minor), np.round(np.log10(y_minor)), atol=1e-9)
    for axis in (ax.xaxis, ax.yaxis):
        assert all(t.label1.get_text() == "" for t in axis.get_minor_ticks())
        majors = axis.get_majorticklocs()
        np.testing.assert_allclose(np.log10(majors), np.round(np.log10(majors)), atol=1e-9)


def test_sparse_minor_ticks_leave_a_narrow_log_axis_its_labelled_minor_ticks():
    """An axis spanning under two decades keeps matplotlib's minor ticks (2..9, labelled where no
    decade falls inside); a wide one is thinned (plots.sparse_log_minor_ticks)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.loglog([0.01, 3600.0], [2e-3, 8e-3])
    plots.sparse_log_minor_ticks(ax)
    assert isinstance(ax.xaxis.get_minor_formatter(), NullFormatter)
    assert not isinstance(ax.yaxis.get_minor_formatter(), NullFormatter)
    fig.canvas.draw()  # the tick labels laid out
    y_labels = [t.get_text() for t in ax.yaxis.get_minorticklabels() if t.get_text()]
    assert len(y_labels) >= 2, y_labels


def test_population_plot(tmp_path, figures):
    from bayes_imu.inference.population import fit_population

    rng = np.random.default_rng(5)
    model = NoiseModel(("white",), 0.01)
    allans = [
        allan_variance(simulate_log(model, {"noise_variance": v}, 5000, rng=rng), rate_hz=100.0)
        for v in (1e-4, 1.2e-4, 0.9e-4)
    ]
    pop = fit_population(allans, labels=["a", "b", "c"], terms=("white",), rng=0)
    bands = drift_bands(pop.new_unit, quantity="attitude", bias_start="zero", horizon_s=10.0)
    plots.plot_population(
        pop, tmp_path / "p.png", unit="rad/s", bands=bands, unit_bands=[bands] * 3, drift_unit="rad"
    )
    _png(tmp_path / "p.png")
    text = _texts(figures[-1])
    for word in ("new unit, 90% predictive band", "a", "b", "c", "Allan deviation (rad/s)",
                 "1-sigma attitude error (rad)", "a alone, median"):
        assert word in text, word
    # --display-units deg (issue 38): the Allan panel in deg/s, each value times 180/pi
    plots.plot_population(pop, tmp_path / "d.png", unit="deg/s", rng=0, scale=180 / np.pi)
    plots.plot_population(pop, tmp_path / "r.png", unit="rad/s", rng=0)
    rad, deg = figures[-1].axes[0], figures[-2].axes[0]
    assert deg.get_ylabel() == "Allan deviation (deg/s)" and len(deg.lines) == len(rad.lines) == 4
    for r, d in zip(rad.lines, deg.lines):
        assert np.array_equal(d.get_xdata(), r.get_xdata())
        assert d.get_ydata() == pytest.approx(r.get_ydata() * 180 / np.pi, rel=1e-14)


def test_corner_without_arviz_draws_the_same_figure_and_keeps_its_arviz_entry_point(tmp_path, fit):
    """The plotting warm-up imports corner without ArviZ (a slow import) in a process that has not
    loaded it: the corner plot is the same PNG, byte for byte, as the one drawn once ArviZ is
    loaded, and corner's ArviZ entry point still works (a dict of draws, which only that path
    accepts, imports ArviZ when it is first needed)."""
    import json
    import subprocess
    import sys

    from bayes_imu.inference.archive import save_fit

    save_fit(fit, tmp_path / "fit.npz")
    code = """
import json, sys
import numpy as np
from bayes_imu.inference.archive import load_fit
from bayes_imu.report.plots import import_plotting, plot_corner
import_plotting()
fit = load_fit(sys.argv[1])
plot_corner(fit, sys.argv[2] + "/without.png")
before = [m for m in ("arviz", "xarray") if m in sys.modules]
import corner
fig = corner.corner({"x": np.random.default_rng(0).normal(size=(2, 200))})
after = "arviz" in sys.modules
plot_corner(fit, sys.argv[2] + "/with.png")
print(json.dumps([before, after, len(fig.axes)]))
"""
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "fit.npz"), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    before, after, n_axes = json.loads(done.stdout.strip().splitlines()[-1])
    assert before == [] and after and n_axes == 1
    assert (tmp_path / "without.png").read_bytes() == (tmp_path / "with.png").read_bytes()


def test_corner_notices_stay_out_of_the_output(tmp_path, fit, caplog, monkeypatch):
    """Draws too concentrated for contours make corner log "Too few points to create valid contours"
    on the root logger (a command printed it as WARNING:root: lines); plot_corner leaves those
    notices out and still draws the figure. Without the filter the same call logs them (the test can
    fail)."""
    import contextlib
    import dataclasses
    import logging

    samples = fit.samples.copy()
    # one value, and a few draws far from it: the mass sits in one histogram bin
    samples[:, 2] = samples[0, 2]
    samples[:5, 2] *= 1e3
    pinned = dataclasses.replace(fit, samples=samples)
    with caplog.at_level(logging.WARNING):
        plots.plot_corner(pinned, tmp_path / "corner.png")
    assert not [r for r in caplog.records if "contours" in r.getMessage()]
    _png(tmp_path / "corner.png")
    monkeypatch.setattr(plots, "_without_corner_notices", contextlib.nullcontext)
    with caplog.at_level(logging.WARNING):
        plots.plot_corner(pinned, tmp_path / "corner2.png")
    assert [r for r in caplog.records if "contours" in r.getMessage()]


@pytest.mark.parametrize(
    "low, high",
    [
        (0.0748, 0.0762),
        (0.0795, 0.09),
        (3e-5, 2.4e-4),
        (20.0, 310.0),
        (1e-6, 3e-4),
        (4e-6, 7e-4),
        (0.1, 5e3),
        (1e-12, 1e3),
        (0.999, 1.001),
        (7.5e-5, 4.2e-4),
        (60.0, 450.0),
        (1.1e-3, 2.8e-2),
        (0.9, 1.2),
    ],
)
def test_corner_ticks_lie_inside_with_few_labels_apart_and_decades_labelled_when_there_are_two(
    low, high
):
    """Each axis's ticks (plots._log_ticks): inside its range, sorted and distinct, labelled and
    unlabelled apart; 1 to 4 labelled, and those two or more powers of ten wherever two or more lie
    inside; over two or more decades the unlabelled ones only 1, 2 or 5 times a power of ten; where
    two or more of those that may be labelled lie farther than 10% of the axis from its ends, no
    label within 10% of them (else 5%, where two lie farther than that); labels at least 15% of the
    axis apart (45-degree labels of 7 points on a 1.9-inch panel; the rule before put 9e-5 and 1e-4
    6% apart on (7.5e-5, 4.2e-4), a real fit's axis)."""
    labelled, other = plots._log_ticks(low, high)
    ticks = np.concatenate([labelled, other])
    assert np.all((ticks >= low * (1 - 1e-9)) & (ticks <= high * (1 + 1e-9)))
    assert np.unique(ticks).size == ticks.size and np.all(np.diff(labelled) > 0)
    assert 1 <= labelled.size <= 4
    powers = [10.0**e for e in range(int(np.floor(np.log10(low))), int(np.ceil(np.log10(high))) + 1)
              if low <= 10.0**e <= high]
    if len(powers) >= 2:
        assert (
            set(np.log10(labelled).round(9)) <= set(np.log10(powers).round(9))
            and len(labelled) >= 2
        )
        coefficient = other / 10.0 ** np.floor(np.log10(other) + 1e-9)
        assert np.all(np.isin(np.round(coefficient, 6), (1.0, 2.0, 5.0)))
    else:
        assert labelled.size >= 2 or ticks.size == 1
    labellable = np.array(powers) if len(powers) >= 2 else ticks
    where = (np.log10(labellable) - np.log10(low)) / np.log10(high / low)
    labelled_where = (np.log10(labelled) - np.log10(low)) / np.log10(high / low)
    for edge in (0.1, 0.05):
        if np.count_nonzero((where > edge) & (where < 1.0 - edge)) >= 2:
            assert np.all((labelled_where > edge) & (labelled_where < 1.0 - edge))
            break
    assert np.all(np.diff(labelled_where) >= 0.15 - 1e-12)


def test_corner_grid_is_the_lower_triangle_with_labels_on_its_edges_only(tmp_path, figures):
    """k (k + 1) / 2 panels in a k x k grid; every visible tick label on the bottom row (x) or the
    left column (y, below the first row), with each edge's axis label; a parameter pinned to one
    value still draws."""
    import dataclasses

    model = NoiseModel(("white", "gauss_markov", "random_walk"), 0.01)
    y = simulate_log(model, {"noise_variance": 1e-4, "bias_variance": 1e-7, "time_constant": 20.0,
                             "rate_random_walk": 1e-6}, 40_000, rng=4)
    fit = fit_allan(allan_variance(y, rate_hz=100.0), terms=model.terms, rng=0)
    k = fit.samples.shape[1]
    samples = fit.samples.copy()
    samples[:, 1] = samples[0, 1]  # one parameter pinned
    plots.plot_corner(dataclasses.replace(fit, samples=samples), tmp_path / "c.png")
    _png(tmp_path / "c.png", min_size=(k * 150, k * 150))
    fig = figures[-1]
    fig.canvas.draw()
    assert len(fig.axes) == k * (k + 1) // 2
    grid = {
        (ax.get_subplotspec().rowspan.start, ax.get_subplotspec().colspan.start): ax
        for ax in fig.axes
    }
    assert set(grid) == {(i, j) for i in range(k) for j in range(i + 1)}
    for (i, j), ax in grid.items():
        shown_x = [t for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
        shown_y = [t for t in ax.get_yticklabels() if t.get_visible() and t.get_text()]
        assert bool(shown_x) == (i == k - 1) and bool(ax.get_xlabel()) == (i == k - 1), (i, j)
        assert bool(shown_y) == (j == 0 and i > 0) and bool(ax.get_ylabel()) == (
            j == 0 and i > 0
        ), (i, j)


def test_a_one_parameter_corner_plot_labels_few_ticks_apart_and_its_interval_digits(tmp_path,
                                                                                   figures):
    """A one-parameter model's corner.png is a histogram on a log axis: over a narrow range
    matplotlib labelled every minor tick, one over the other (2.46x10^-3 ... 2.52x10^-3 on a
    white-noise log). It takes the grid's ticks (at most four labelled, apart) and its title the
    digits the interval resolves (report.text.interval_text, at most 4)."""
    from bayes_imu.report.text import interval_text

    y = 0.05 * np.random.default_rng(1).standard_normal(50_000)
    fit = fit_allan(allan_variance(y, rate_hz=100.0), terms=("white",), rng=0)
    assert fit.samples.shape[1] == 1
    plots.plot_corner(fit, tmp_path / "c.png")
    fig = figures[-1]
    fig.canvas.draw()
    ax = fig.axes[0]
    low, high = ax.get_xlim()
    shown = [t for t in ax.get_xticklabels(which="both")
             if t.get_visible() and t.get_text() and low <= t.get_position()[0] <= high]
    assert 2 <= len(shown) <= 4, [t.get_text() for t in shown]
    boxes = sorted((t.get_window_extent() for t in shown), key=lambda b: b.x0)
    assert all(a.x1 <= b.x0 for a, b in zip(boxes, boxes[1:]))
    q = np.quantile(fit.samples[:, 0], [0.05, 0.5, 0.95])
    assert ax.get_title().startswith(interval_text(q[1], q[0], q[2], most=4) + " (")


def test_an_accelerometers_rate_terms_are_named_for_acceleration():
    """The figures of an accelerometer say "acceleration random walk" / "acceleration ramp" (a new
    user read "rate random walk" on an accelerometer's allan_fit.png and drift.png); a gyro's
    stay."""
    from bayes_imu.report.plots import term_label

    assert term_label("random_walk", True) == "acceleration random walk"
    assert term_label("ramp", True) == "acceleration ramp"
    assert term_label("random_walk") == "rate random walk"
    assert term_label("gauss_markov", True) == term_label("gauss_markov")


def test_corner_panel_titles_print_three_digits_without_an_exponent(figures):
    """A corner plot's diagonal title printed a time constant of 192 s (90% 59 to 661 s) as
    "1.9e+02 [59, 6.6e+02]": two digits, exponents for numbers people read plainly. The titles now
    take :func:`~bayes_imu.report.text.interval_numbers` (at least three digits, one precision for
    the three numbers, plain from 1e-3 to 1e5)."""
    from bayes_imu.report.text import interval_numbers

    rng = np.random.default_rng(4)
    x = np.exp(rng.normal(np.log(192.0), 0.74, 40_000))  # 90% about 57 to 650 s
    fig = plots.pyplot().figure()
    ax = fig.add_subplot()
    plots._diagonal_panel(ax, x, (x.min(), x.max()), 20)
    q = np.quantile(x, [0.05, 0.5, 0.95])
    median, low, high = interval_numbers(q[1], q[0], q[2], most=4)
    assert ax.get_title() == f"{median}\n[{low}, {high}]"
    assert "e" not in ax.get_title() and len(median) == 3 and len(high) == 3, ax.get_title()
    plots.pyplot().close(fig)


def test_series_colours_are_all_different_and_none_is_reserved():
    """One colour per series of a figure (comparison.png gave sensor #2 and IMU #2 the same "C1";
    nav.png's terms repeated the tab10 colours past ten): every colour different, none near the
    red of a requirement line, the grey of the outage marks or black; the cycle's own first."""
    from matplotlib.colors import to_rgb

    for n in (1, 6, 12, 45, 80):
        colours = plots.series_colours(n)
        assert len(colours) == n == len(set(colours))
        for colour in colours:
            for reserved, radius in plots.RESERVED_COLOURS.items():
                distance = np.linalg.norm(np.subtract(to_rgb(colour), to_rgb(reserved)))
                assert distance > radius, (colour, reserved)
    assert plots.series_colours(3) == ["#1f77b4", "#ff7f0e", "#2ca02c"]  # C0, C1, C2


def test_corner_pair_panels_shade_corners_density_as_one_mesh(tmp_path, figures, fit):
    """plots._pair_panel draws corner.hist2d's density shading with ``pcolormesh`` instead of its
    polygon-per-bin ``pcolor``: each pair panel holds one mesh whose bin edges, values, colours and
    place among the panel's artists are those of corner's own ``pcolor`` on a fresh axes (the
    reference: corner itself), and the Axes method is restored."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PolyQuadMesh, QuadMesh
    from matplotlib.figure import Figure

    plots.plot_corner(fit, tmp_path / "c.png")
    _png(tmp_path / "c.png")
    fig = figures[-1]
    pair = next(ax for ax in fig.axes if ax.get_subplotspec().rowspan.start
                != ax.get_subplotspec().colspan.start)
    assert "pcolor" not in vars(pair)
    meshes = [c for c in pair.collections if isinstance(c, QuadMesh)]
    assert len(meshes) == 1 and not any(isinstance(c, PolyQuadMesh) for c in pair.collections)
    corner = plots.import_corner()
    ref_fig = Figure()
    FigureCanvasAgg(ref_fig)
    ref = ref_fig.add_subplot()
    x, y = fit.samples[:, 0], fit.samples[:, 1]
    ranges = [plots._draw_range(x), plots._draw_range(y)]
    corner.hist2d(x, y, ax=ref, range=ranges, axes_scale=["log", "log"], bins=20, color="k")
    polys = [c for c in ref.collections if isinstance(c, PolyQuadMesh)]
    assert len(polys) == 1
    mesh, poly = meshes[0], polys[0]
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).ravel(),
                                  np.asarray(poly.get_array()).ravel())
    np.testing.assert_array_equal(mesh.get_coordinates(), poly._coordinates)
    assert mesh.get_cmap() == poly.get_cmap() and mesh.norm.vmax == poly.norm.vmax
    order = [type(c).__name__ for c in pair.collections]
    ref_order = [type(c).__name__ for c in ref.collections]
    assert order == [n.replace("PolyQuadMesh", "QuadMesh") for n in ref_order], (order, ref_order)


def test_allan_deviation_plots_thin_wide_log_axes_minor_ticks_to_2_and_5(tmp_path, figures, fit):
    """allan_fit.png and allan.png (plots.thin_log_minor_ticks): a log axis spanning two decades or
    more has its unlabelled minor ticks at 2 and 5 of each decade, and one spanning less keeps
    matplotlib's 2..9."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    def mantissas(axis):
        lo, hi = sorted(axis.get_view_interval())
        locs = [v for v in axis.get_minorticklocs() if lo <= v <= hi]
        return {round(v / 10.0 ** np.floor(np.log10(v) + 1e-9), 6) for v in locs}

    plots.plot_allan_fit(fit, tmp_path / "f.png", rng=0)
    plots.plot_allan(fit.allan, tmp_path / "a.png")
    for fig in figures[-2:]:
        ax = fig.axes[0]
        lo, hi = ax.get_xlim()
        assert np.log10(hi / lo) >= 2 and mantissas(ax.xaxis) == {2.0, 5.0}
        assert all(t.label1.get_text() == "" for t in ax.xaxis.get_minor_ticks())
    narrow = Figure()
    FigureCanvasAgg(narrow)
    ax = narrow.add_subplot()
    ax.loglog([1.0, 3.0, 20.0], [0.2, 0.3, 0.5])
    plots.thin_log_minor_ticks(ax.yaxis)  # 0.2-0.5: under two decades
    plots.thin_log_minor_ticks(ax.xaxis)  # 1-20: under two decades
    assert mantissas(ax.yaxis) >= {2.0, 3.0, 4.0} and mantissas(ax.xaxis) >= {2.0, 3.0, 4.0}


def test_pngs_are_written_at_the_fast_zlib_level(tmp_path, fit):
    """plots.save_png writes at zlib level 3 (PNG_COMPRESSION): the image data's zlib header says a
    fast level (FLEVEL 1: levels 2-5; Pillow's default 6 says 2), and the pixels are those of
    matplotlib's default PNG."""
    import struct
    import zlib

    import matplotlib.image

    plots.plot_allan(fit.allan, tmp_path / "a.png")
    data = (tmp_path / "a.png").read_bytes()
    i = data.index(b"IDAT")
    (length,) = struct.unpack(">I", data[i - 4:i])
    head = data[i + 4:i + 6]
    assert (head[0] * 256 + head[1]) % 31 == 0 and head[1] >> 6 == 1, head
    zlib.decompressobj().decompress(data[i + 4:i + 4 + length])  # a valid stream
    fig = plots.pyplot().figure()
    ax = fig.add_subplot()
    ax.plot([1, 2, 3], [3, 1, 2])
    plots.save_png(fig, tmp_path / "ours.png", dpi=50)
    fig.savefig(tmp_path / "default.png", dpi=50)
    plots.pyplot().close(fig)
    np.testing.assert_array_equal(matplotlib.image.imread(tmp_path / "ours.png"),
                                  matplotlib.image.imread(tmp_path / "default.png"))
    default = (tmp_path / "default.png").read_bytes()
    j = default.index(b"IDAT")
    assert default[j + 5] >> 6 == 2  # the reference: Pillow's default level says FLEVEL 2


def test_a_few_far_draws_fall_outside_the_corner_axes_instead_of_squeezing_them(tmp_path, figures,
                                                                               fit):
    """plots._draw_range: each axis runs from the CORNER_TAIL quantile of the draws to the 1 -
    CORNER_TAIL one (widened a little, never past the extremes), so a few draws a thousand times
    away from the rest (a walker's excursion) are left out: the axis spans about the bulk's decade,
    not four; without such draws the axis covers those quantiles and no more than the draws'
    span."""
    import dataclasses

    rng = np.random.default_rng(5)
    samples = fit.samples.copy()
    far = rng.choice(len(samples), 5, replace=False)
    samples[far, 0] *= 1e3
    plots.plot_corner(dataclasses.replace(fit, samples=samples), tmp_path / "c.png")
    _png(tmp_path / "c.png")
    first = next(ax for ax in figures[-1].axes  # the first parameter's histogram
                 if ax.get_subplotspec().rowspan.start == ax.get_subplotspec().colspan.start == 0)
    lo, hi = first.get_xlim()
    bulk = np.delete(samples[:, 0], far)
    assert lo <= np.quantile(bulk, 0.01) and hi >= np.quantile(bulk, 0.99)
    assert np.log10(hi / lo) < np.log10(bulk.max() / bulk.min()) + 0.5  # the far draws left out
    low, high = plots._draw_range(fit.samples[:, 0])  # the fit's own draws
    span = np.log(fit.samples[:, 0].max() / fit.samples[:, 0].min())
    assert low <= np.quantile(fit.samples[:, 0], plots.CORNER_TAIL)
    assert high >= np.quantile(fit.samples[:, 0], 1 - plots.CORNER_TAIL)
    assert np.log(high / low) <= span * (1 + 1e-6)
