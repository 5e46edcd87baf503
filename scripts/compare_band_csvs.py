"""Two runs of ``scripts/validate_independent.py --csv`` on the same scenes, compared row by row.

For a change that should leave the bands' coverage as it was (a sampler that samples the same
posterior, for instance), prints for each band edge and the median the share of points that are
identical, the median, 95th percentile and largest relative difference, and on how many points
the coverage verdict agrees.

    python scripts/compare_band_csvs.py OLD.csv NEW.csv
"""

import argparse
import csv
import sys

import numpy as np


def _rows(path):
    with open(path, newline="") as f:
        return {(r["family"], r["seed"], r["quantity"], r["t_s"]): r for r in csv.DictReader(f)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old")
    parser.add_argument("new")
    args = parser.parse_args(argv)
    old, new = _rows(args.old), _rows(args.new)
    keys = sorted(set(old) & set(new))
    if not keys:
        print(f"no common (family, seed, quantity, t_s) rows in {args.old} and {args.new}",
              file=sys.stderr)
        return 2
    print(f"{len(keys)} common points ({len(old)} and {len(new)} rows)")
    print(f"{'column':>7} {'identical':>9} {'median':>9} {'95%':>9} {'max':>9}"
          "  (relative difference)")
    for column in ("q05", "q50", "q95"):
        d = np.abs([float(new[k][column]) / float(old[k][column]) - 1.0 for k in keys])
        print(f"{column:>7} {np.mean(d == 0):9.1%} {np.median(d):9.2e} {np.quantile(d, 0.95):9.2e} "
              f"{d.max():9.2e}")
    same = sum(old[k]["covered"] == new[k]["covered"] for k in keys)
    print(f"coverage verdict the same on {same} of {len(keys)} points")
    return 0


if __name__ == "__main__":
    sys.exit(main())
