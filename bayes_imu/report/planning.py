"""Figure and table of a record-length plan (:func:`bayes_imu.drift.plan.plan_record_length`)."""

import numpy as np

from ..drift.plan import Z90
from ..noise.model import PARAMETER_LABELS

__all__ = ["plot_plan", "plan_csv", "csv_field"]


def _half_width_percent(log_sd):
    """Upper half-width of the 90% interval, % of the value: ``100 (exp(1.645 sd) - 1)``."""
    return 100.0 * np.expm1(Z90 * np.asarray(log_sd))


def plot_plan(plans, path, *, title="", pilot_s=None):
    """``plan.png``: the 90% interval's half-width (percent) versus record length.

    ``plans``: ``[(label, PlanResult), ...]`` (one per axis); left panel the parameters, right
    panel the drift at each horizon (when planned).
    """
    from matplotlib.ticker import FixedLocator, FuncFormatter, LogLocator, NullFormatter

    from .plots import plain_text, pyplot, save_png

    plt = pyplot()
    with_drift = any(p.horizons_s.size for _, p in plans)
    fig, axes = plt.subplots(
        1, 2 if with_drift else 1, figsize=(11 if with_drift else 6.5, 4.6), squeeze=False
    )
    styles = ["-", "--", ":"]
    for a, (label, plan) in enumerate(plans):
        hours = plan.lengths_s / 3600.0
        prefix = f"{plain_text(label)}: " if len(plans) > 1 else ""
        for j, name in enumerate(plan.names):
            axes[0, 0].plot(
                hours,
                _half_width_percent(plan.log_sd[:, j]),
                styles[a % 3],
                marker="o",
                ms=3,
                color=f"C{j}",
                label=prefix + PARAMETER_LABELS.get(name, name),
            )
        if with_drift:
            for j, t in enumerate(plan.horizons_s):
                axes[0, 1].plot(
                    hours,
                    _half_width_percent(plan.drift_log_sd[:, j]),
                    styles[a % 3],
                    marker="o",
                    ms=3,
                    color=f"C{j}",
                    label=f"{prefix}{plan.quantity} drift at {t:g} s",
                )
    titles = ["parameters", "1-sigma drift (bias calibrated before the outage)"]
    for ax, sub in zip(axes[0], titles):
        ax.set_xscale("log")
        ax.set_yscale("log")
        lengths = plans[0][1].lengths_s
        ax.xaxis.set_major_locator(FixedLocator(lengths / 3600.0))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: _length_label(v * 3600.0)))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.tick_params(axis="x", labelsize=8)
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}%"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("record length")
        ax.set_ylabel("90% interval: upper half-width (% of value)")
        ax.set_title(sub, fontsize=10)
        ax.axhline(10.0, color="0.6", lw=0.8, zorder=0)
        if pilot_s:
            ax.axvline(pilot_s / 3600.0, color="0.4", lw=0.8, ls="--", zorder=0)
            ax.text(
                pilot_s / 3600.0,
                0.02,
                " pilot",
                transform=ax.get_xaxis_transform(),
                fontsize=8,
                color="0.3",
            )
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7.5, loc="upper right")
    fig.suptitle(
        plain_text(title) or "Predicted 90% intervals versus record length (Fisher information)",
        fontsize=11,
    )
    fig.tight_layout()
    save_png(fig, path, dpi=110)
    plt.close(fig)


def _length_label(seconds):
    if seconds < 3600:
        return f"{seconds / 60:.3g} min"
    return (
        f"{seconds / 3600:.3g} h"
        if seconds < 172800 or seconds % 86400
        else f"{seconds / 86400:.3g} d"
    )


def plan_csv(plans):
    """CSV text of the plan rows (``axis,length_s,what,value,q05,q95,width90``)."""
    lines = ["axis,length_s,what,value,q05,q95,width90"]
    for label, plan in plans:
        for r in plan.rows():
            lines.append(
                f"{csv_field(label)},{r['length_s']:.9g},{r['what']},{r['value']:.9g},"
                f"{r['q05']:.9g},"
                f"{r['q95']:.9g},{r['width90']:.6g}"
            )
    return "\n".join(lines) + "\n"


def csv_field(text):
    """``text`` as one CSV field (RFC 4180): quoted, its quotes doubled, where it holds a comma, a
    quote, a line break or another unprintable character, or starts or ends with a space (a column
    named ``a,b``, or one with a newline, stays one field of one row)."""
    text = str(text)
    if any(c in ',"' or not c.isprintable() for c in text) or text != text.strip():
        return '"' + text.replace('"', '""') + '"'
    return text
