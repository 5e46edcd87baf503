"""Figures (matplotlib imported inside each function, Agg backend)."""

import numpy as np

__all__ = ["plot_allan"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_allan(result, path, *, label=""):
    """Log-log Allan deviation with its interval bars and the -1/2, 0, +1/2 slope guides.

    The guides pass through the curve's first point (-1/2: angle / velocity random
    walk), its minimum (0: bias instability) and its last point (+1/2: rate random walk);
    they are reading aids, not fits.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 5))
    tau, adev = result.tau, result.adev
    err = np.vstack([adev - result.adev_low, result.adev_high - adev])
    ax.errorbar(tau, adev, yerr=err, fmt="o-", ms=3, capsize=2, label=label or "overlapping ADEV")
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
        ax.annotate(text, (span[end], line[end]), textcoords="offset points", xytext=offset, fontsize=8, color="dimgray")
    ax.set_ylim(adev.min() / 4, adev.max() * 2)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (input units)")
    ax.set_title(f"Overlapping Allan deviation, {result.confidence:.1%} intervals")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
