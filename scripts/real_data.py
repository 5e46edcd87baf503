"""Real logs: every channel of the six ADIS16405 recordings and the Xsens MTi-G gyro, fitted.

Reads ``../shared/data_real/smac_imudata/`` (SMAC-Group imudata, CC BY-NC-SA 4.0: read in
place, never copied; the script exits cleanly with a message when the folder is absent).
ADIS16405: 6 channels (gyro deg/s, accel g) x 6 recordings of 1e6 samples at 100 Hz;
MTi-G: gyro X (rad/s), 5e5 samples at 100 Hz. Each channel is converted to SI and fitted
with model selection (``bayes_imu.inference.fit``). The script prints per channel and recording
the selected model and, in the datasheet's unit, the noise density of the short-term terms
(``noise_density``: median and 90% interval as ``summary.json`` prints it, with the
repeatability between the log's parts), the white term's density alone, and the random walk
as IEEE Std 952 reads it off the Allan deviation (sigma(1 s) sqrt(1 s) of the model-averaged
posterior, :mod:`bayes_imu.inference.allan_readout`; the number a datasheet's ARW / VRW means),
compares with the datasheet values of ``REFERENCE_VALUES.md``, says whether the six
replicates' 90% intervals share a common value, and plots the six posteriors side by
side (``--out``/real_data_posteriors.png).

    python scripts/real_data.py [--out docs/real_data] [--quick]

``--quick`` fits imu1's gyro X and the MTi-G on their first 2**17 samples (a smoke run).
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
RATE = 100.0
# (channel, input unit, datasheet density, its unit, factor from SI to that unit)
DEG = 180.0 / np.pi
ADIS = [
    ("gyro_x_dps", "deg/s", 0.0333, "deg/s/sqrt(Hz)", DEG),
    ("gyro_y_dps", "deg/s", 0.0333, "deg/s/sqrt(Hz)", DEG),
    ("gyro_z_dps", "deg/s", 0.0333, "deg/s/sqrt(Hz)", DEG),
    ("accel_x_g", "g", 3.33e-3, "m/s^2/sqrt(Hz)", 1.0),
    ("accel_y_g", "g", 3.33e-3, "m/s^2/sqrt(Hz)", 1.0),
    ("accel_z_g", "g", 3.33e-3, "m/s^2/sqrt(Hz)", 1.0),
]
MTIG = ("gyro_x_rad_s", "rad/s", 0.05, "deg/s/sqrt(Hz)", DEG)


def fit_channel(path, column, unit, n_max, seed):
    from bayes_imu import allan_variance, fit_allan
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.io.readers import read_log, to_si

    values = to_si(read_log(path, column=column).values[:n_max], unit)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return fit_allan(allan_variance(values, rate_hz=RATE), rng=seed)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "real_data"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--quick", action="store_true", help="imu1 gyro X and the MTi-G, 2**17 samples each"
    )
    args = parser.parse_args(argv)
    if not SHARED.exists():
        print(f"shared data not found at {SHARED}; nothing to do")
        return 0
    n_max = 2**17 if args.quick else None
    channels = ADIS[:1] if args.quick else ADIS
    imus = [1] if args.quick else list(range(1, 7))
    print(
        f"{'log':9s} {'channel':13s} {'model':58s} {'density q05':>11s} {'median':>9s} {'q95':>9s} "
        f"{'white':>9s} {'IEEE 1 s':>9s} {'datasheet':>9s} {'unit':15s} conv"
    )
    densities, readings = {}, {}
    for column, unit, sheet, sheet_unit, factor in channels:
        for imu in imus:
            res = fit_channel(
                SHARED / f"adis_16405_imu{imu}.csv.gz", column, unit, n_max, args.seed
            )
            q = np.quantile(res.repeatable_draws("noise_density"), [0.05, 0.5, 0.95]) * factor
            densities.setdefault(column, []).append(q)
            white, ieee = _readings(res, factor)
            readings.setdefault(column, []).append((white, ieee))
            print(
                f"imu{imu:<6d} {column:13s} {'+'.join(res.model.terms):58s} {q[0]:11.5g} "
                f"{q[1]:9.5g} {q[2]:9.5g} {white:9.5g} {ieee:9.5g} {sheet:9.4g} {sheet_unit:15s} "
                f"{res.diagnostics['converged']}"
            )
    column, unit, sheet, sheet_unit, factor = MTIG
    res = fit_channel(SHARED / "cont_imu1.csv.gz", column, unit, n_max, args.seed)
    q = np.quantile(res.repeatable_draws("noise_density"), [0.05, 0.5, 0.95]) * factor
    white, ieee = _readings(res, factor)
    print(
        f"{'MTi-G':9s} {column:13s} {'+'.join(res.model.terms):58s} {q[0]:11.5g} {q[1]:9.5g} "
        f"{q[2]:9.5g} {white:9.5g} {ieee:9.5g} {sheet:9.4g} {sheet_unit:15s} "
        f"{res.diagnostics['converged']}"
    )
    print(
        "\nADIS16405 datasheet: ARW 2 deg/sqrt(h) = 0.0333 deg/s/sqrt(Hz) (the ADI note also "
        "quotes 0.05), VRW 0.2 m/s/sqrt(h) = 3.33e-3 m/s^2/sqrt(Hz); MTi-G: 0.05 deg/s/sqrt(Hz)"
    )
    for column, qs in densities.items():
        qs = np.array(qs)
        lo, hi = qs[:, 0].max(), qs[:, 2].min()
        verdict = "share a common value" if lo <= hi else f"do not all overlap (gap {lo - hi:.3g})"
        spread = qs[:, 1].max() / qs[:, 1].min() - 1.0
        print(
            f"{column}: the {len(qs)} replicates' 90% intervals {verdict}; medians "
            f"{qs[:, 1].min():.4g} to {qs[:, 1].max():.4g} ({spread:.1%} apart)"
        )
        white, ieee = np.array(readings[column]).T
        print(f"{column}: white alone {white.min():.4g} to {white.max():.4g}; IEEE reading at 1 s "
              f"{ieee.min():.4g} to {ieee.max():.4g}")
    args.out.mkdir(parents=True, exist_ok=True)
    plot(densities, args.out / "real_data_posteriors.png")
    print(f"wrote {args.out / 'real_data_posteriors.png'}")
    return 0


def _readings(res, factor):
    """Medians of the white term's density alone and of the IEEE Std 952 reading at 1 s."""
    from bayes_imu.inference.allan_readout import allan_readout

    out = allan_readout(res, None, unit="SI")
    return out["white_noise_density"]["median"] * factor, out["random_walk"]["median"] * factor


def plot(densities, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(densities), figsize=(3.0 * len(densities), 3.6), squeeze=False)
    for ax, (column, qs) in zip(axes[0], densities.items()):
        qs = np.array(qs)
        x = np.arange(1, len(qs) + 1)
        ax.errorbar(
            x, qs[:, 1], yerr=[qs[:, 1] - qs[:, 0], qs[:, 2] - qs[:, 1]], fmt="o", capsize=3
        )
        ax.set(title=column, xlabel="ADIS16405 recording", xticks=x)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    axes[0][0].set_ylabel("noise density (90% interval)")
    fig.suptitle("ADIS16405: six recordings, posterior noise density per channel")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
