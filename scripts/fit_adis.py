"""Fit the six ADIS16405 static logs (three gyro axes each) and compare with the datasheet.

Reads ``../shared/data_real/smac_imudata/adis_16405_imu{1..6}.csv.gz`` (SMAC-Group imudata,
CC BY-NC-SA 4.0: read in place, never copied; the script exits cleanly when absent),
fits each gyro column (deg/s, 100 Hz) with model selection, and prints the selected
model and, in deg/s/sqrt(Hz) (median and 90% interval): the white term's density alone, the
noise density of the short-term terms together (``noise_density``: white + filtered white +
fast correlated + quantization, what sets the Allan deviation at the shortest tau), and the
angle random walk as IEEE Std 952 reads it off the Allan deviation (the model-averaged
posterior's sigma(1 s) sqrt(1 s), :mod:`bayes_imu.inference.allan_readout`), each as
``summary.json`` prints it (intervals with the repeatability between the log's parts); then whether
the six replicates' 90% intervals of each share a common value per axis, and the markdown tables of
docs/reference.md (medians; the noise density's half-width printed and for the record alone).
Datasheet (REFERENCE_VALUES.md): 0.05 deg/s/sqrt(Hz) (ARW 2 deg/sqrt(h)).

    python scripts/fit_adis.py [--axes x,y,z] [--data DIR]
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"
DATASHEET_DENSITY = 0.05


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--axes", default="x,y,z")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--data", type=Path, default=SHARED, help="the smac_imudata folder")
    args = parser.parse_args(argv)
    if not args.data.exists():
        print(f"shared data not found at {args.data}; nothing to do")
        return 0
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.io.readers import read_log

    print(f"{'log':6s} {'axis':4s} {'model':58s} {'white alone':>24s} {'short-term density':>24s} "
          f"{'ARW at 1 s (IEEE)':>24s} {'conv':>5s}")
    intervals, tables = {}, {}
    axes = args.axes.split(",")
    for axis in axes:
        for imu in range(1, 7):
            path = args.data / f"adis_16405_imu{imu}.csv.gz"
            values = read_log(path, column=f"gyro_{axis}_dps").values
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ConvergenceWarning)
                result = fit_allan(allan_variance(values, rate_hz=100.0), rng=args.seed)
            summary = result.summary(unit="deg/s")  # the intervals a user copies
            reading = summary["allan_datasheet"]
            params, alone = summary["parameters"], summary["parameters_this_record"]
            cells = {"white": reading["white_noise_density"],
                     "short-term": params["noise_density"], "ARW": reading["random_walk"]}
            for name, e in cells.items():
                intervals.setdefault((axis, name), []).append((e["q05"], e["q95"]))
                tables.setdefault(name, {})[(axis, imu)] = e
            tables.setdefault("record", {})[(axis, imu)] = alone["noise_density"]
            text = " ".join(f"{e['median']:.5f} [{e['q05']:.5f},{e['q95']:.5f}]"
                            for e in cells.values())
            print(f"imu{imu:<3d} {axis:4s} {'+'.join(result.model.terms):58s} {text} "
                  f"{str(result.diagnostics['converged']):>5s}")
    print(f"\ndatasheet noise density {DATASHEET_DENSITY} deg/s/sqrt(Hz)")
    for (axis, name), iv in intervals.items():
        lo, hi = max(a for a, _ in iv), min(b for _, b in iv)
        verdict = (
            "overlap (replicates agree)" if lo <= hi else f"do not all overlap (gap {lo - hi:.5f})"
        )
        print(f"axis {axis} {name}: six 90% intervals {verdict}; intervals span "
              f"{min(a for a, _ in iv):.5f}-{max(b for _, b in iv):.5f}")
    _print_tables(tables, axes)
    return 0


def _print_tables(tables, axes):
    """The markdown tables of docs/reference.md: medians per axis and unit, then half-widths."""
    head = "| axis | " + " | ".join(f"imu{i}" for i in range(1, 7)) + " |\n|---|" + "---|" * 6
    titles = {"ARW": "ARW as IEEE Std 952 reads it (allan_datasheet.random_walk), deg/s/sqrt(Hz)",
              "short-term": "short-term noise density (parameters.noise_density), deg/s/sqrt(Hz)",
              "white": "white term alone, model-averaged (allan_datasheet.white_noise_density), "
                       "deg/s/sqrt(Hz)"}
    for name, title in titles.items():
        print(f"\n{title}\n\n{head}")
        for axis in axes:
            row = [f"{tables[name][(axis, i)]['median']:.4f}" for i in range(1, 7)]
            print(f"| {axis} | " + " | ".join(row) + " |")
    print("\nnoise_density 90% half-width (% of the median): printed (with repeatability) / "
          f"this record alone\n\n{head}")
    for axis in axes:
        cells = []
        for i in range(1, 7):
            pair = (tables["short-term"][(axis, i)], tables["record"][(axis, i)])
            widths = [50 * (e["q95"] - e["q05"]) / e["median"] for e in pair]
            cells.append(f"{widths[0]:.2f} / {widths[1]:.2f}")
        print(f"| {axis} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    sys.exit(main())
