"""Allan deviation of the six ADIS16405 static logs (../shared/data_real/smac_imudata), gyro X/Y/Z.

Writes docs/adis16405_allan.png. Data: SMAC-Group imudata, CC BY-NC-SA 4.0 (S. Guerrier,
R. Molinari; University of Calgary); read from ../shared, never copied into this project.
The figure is a derived work under the same licence.
"""

import argparse
from pathlib import Path

import numpy as np

from bayes_imu.allan.estimator import allan_variance
from bayes_imu.io.readers import read_log

DATA = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "docs" / "adis16405_allan.png",
    )
    args = parser.parse_args(argv)
    if not DATA.exists():
        print(f"skipped: {DATA} not available")
        return 0
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), sharey=True)
    for axis, ax in zip("xyz", axes):
        for unit in range(1, 7):
            log = read_log(DATA / f"adis_16405_imu{unit}.csv.gz", column=f"gyro_{axis}_dps")
            r = allan_variance(log.values, rate_hz=100.0)
            ax.errorbar(
                r.tau,
                r.adev,
                yerr=[r.adev - r.adev_low, r.adev_high - r.adev],
                lw=1,
                capsize=1.5,
                label=f"imu{unit}",
            )
        tau = np.array([0.01, 10.0])
        ax.loglog(tau, 0.05 / np.sqrt(tau), "k--", lw=1, label="datasheet 0.05 deg/s/sqrt(Hz)")
        ax.axhline(0.007 * 0.664, color="k", ls=":", lw=1, label="0.664 x datasheet bias stability")
        ax.set_title(f"ADIS16405 gyro {axis.upper()} (6 logs, 2.8 h, 100 Hz)")
        ax.set_xlabel("tau (s)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("overlapping Allan deviation (deg/s), 68.3% intervals")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    main()
