"""Fit the six ADIS16405 static logs (three gyro axes each) and compare with the datasheet.

Reads ``../shared/data_real/smac_imudata/adis_16405_imu{1..6}.csv.gz`` (SMAC-Group imudata,
CC BY-NC-SA 4.0: read in place, never copied; the script exits cleanly when absent),
fits each gyro column (deg/s, 100 Hz) with model selection, and prints the selected
model and, in deg/s/sqrt(Hz) (median and 90% interval): the white term's density alone, the
noise density of the short-term terms together (``noise_density``: white + filtered white +
fast correlated + quantization, what sets the Allan deviation at the shortest tau), and the
angle random walk as IEEE Std 952 reads it off the Allan deviation (the model-averaged
posterior's sigma(1 s) sqrt(1 s), :mod:`bayes_imu.inference.allan_readout`); then whether the
six replicates' 90% intervals of each share a common value per axis. Datasheet (REFERENCE_VALUES.md):
0.05 deg/s/sqrt(Hz) (ARW 2 deg/sqrt(h)).

    python scripts/fit_adis.py [--axes x,y,z]
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
DATASHEET_DENSITY = 0.05


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--axes", default="x,y,z")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not SHARED.exists():
        print(f"shared data not found at {SHARED}; nothing to do")
        return 0
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.allan_readout import allan_readout
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.io.readers import read_log

    print(f"{'log':6s} {'axis':4s} {'model':58s} {'white alone':>24s} {'short-term density':>24s} "
          f"{'ARW at 1 s (IEEE)':>24s} {'conv':>5s}")
    intervals = {}
    for axis in args.axes.split(","):
        for imu in range(1, 7):
            values = read_log(SHARED / f"adis_16405_imu{imu}.csv.gz", column=f"gyro_{axis}_dps").values
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ConvergenceWarning)
                result = fit_allan(allan_variance(values, rate_hz=100.0), rng=args.seed)
            reading = allan_readout(result, None, unit="deg/s")
            white, arw = reading["white_noise_density"], reading["random_walk"]
            lo, med, hi = np.quantile(result.draws("noise_density"), [0.05, 0.5, 0.95])
            for name, (a, b) in (("short-term", (lo, hi)), ("ARW", (arw["q05"], arw["q95"])),
                                 ("white", (white["q05"], white["q95"]))):
                intervals.setdefault((axis, name), []).append((a, b))
            cells = [(white["median"], white["q05"], white["q95"]), (med, lo, hi),
                     (arw["median"], arw["q05"], arw["q95"])]
            text = " ".join(f"{c:.5f} [{a:.5f},{b:.5f}]" for c, a, b in cells)
            print(f"imu{imu:<3d} {axis:4s} {'+'.join(result.model.terms):58s} {text} "
                  f"{str(result.diagnostics['converged']):>5s}")
    print(f"\ndatasheet noise density {DATASHEET_DENSITY} deg/s/sqrt(Hz)")
    for (axis, name), iv in intervals.items():
        lo, hi = max(a for a, _ in iv), min(b for _, b in iv)
        verdict = "overlap (replicates agree)" if lo <= hi else f"do not all overlap (gap {lo - hi:.5f})"
        print(f"axis {axis} {name}: six 90% intervals {verdict}; intervals span "
              f"{min(a for a, _ in iv):.5f}-{max(b for _, b in iv):.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
