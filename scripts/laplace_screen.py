"""How far the Laplace estimate of a candidate's evidence is from its importance-sampled one.

``fit_allan`` leaves a candidate with its Laplace estimate when that estimate is more than
``LAPLACE_SCREEN`` nats below the best importance-sampled evidence (``bayes_imu.inference.selection``).
That is safe if the Laplace estimate never overstates the evidence by much. This script fits the
shipped synthetic logs and every real channel (``../shared``; skipped when absent) with the screen
off, records both estimates for every candidate scored (widened ones included), and prints the
range of ``Laplace - importance`` overall and per source, with the candidates at the extremes.
Run: ``python scripts/laplace_screen.py [--quick]`` (a few minutes; sampling is cut short, only
the model selection matters here).
"""

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))


def synthetic():
    """(name, values, rate) of the shipped single-sensor synthetic logs (truth.json)."""
    from bayes_imu.io.readers import read_log

    truth = json.loads((ROOT / "data_synthetic" / "truth.json").read_text())
    for name in ("gyro_lowgrade", "gyro_highgrade", "gyro_rrw", "accel_gravity"):
        entry = truth[name]
        log = read_log(ROOT / "data_synthetic" / f"{name}.csv.gz", column=entry["column"])
        yield f"synthetic:{name}", log.values, float(entry["rate_hz"])  # the units do not change the evidences


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="synthetic logs and three real channels")
    args = parser.parse_args(argv)
    import importlib

    from bayes_imu import allan_variance
    from validate_real import DATA, RATE, channels

    fit_module = importlib.import_module("bayes_imu.inference.fit")  # the module (the package exports a function)
    fit_module.LAPLACE_SCREEN = np.inf  # every candidate importance-sampled
    laplace, sampled = {}, {}
    laplace_fn, evidence_fn = fit_module.laplace_log_evidence, fit_module.log_evidence

    def record_laplace(post, u):
        out = laplace_fn(post, u)
        laplace[id(post)] = (post, out[0])
        return out

    def record_evidence(post, u, **kw):
        out = evidence_fn(post, u, **kw)
        sampled[id(post)] = out.log_z
        return out

    fit_module.laplace_log_evidence, fit_module.log_evidence = record_laplace, record_evidence
    sources = list(synthetic())
    if DATA.exists():
        real = [(name, y, RATE) for name, _, y in channels()]
        sources += real[:3] if args.quick else real
    else:
        print(f"real data not found ({DATA}): synthetic logs only")
    rows = []
    for name, y, rate in sources:
        laplace.clear()
        sampled.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit_module.fit_allan(allan_variance(y, rate_hz=rate), rng=0, max_steps=250)
        best = max(sampled.values())
        for key, (post, lz) in laplace.items():
            widened = "+discrepancy" if post.discrepancy else ""
            rows.append((name, "+".join(post.model.terms) + widened, lz - sampled[key], sampled[key] - best))
        diffs = [r[2] for r in rows if r[0] == name]
        print(f"{name:28s} {len(diffs):3d} candidates  Laplace - importance: {min(diffs):+7.2f} to {max(diffs):+6.2f} nats")
    diffs = np.array([r[2] for r in rows])
    low, high = rows[int(np.argmin(diffs))], rows[int(np.argmax(diffs))]
    print(f"\nall {len(rows)} candidates of {len(sources)} logs: Laplace - importance from {diffs.min():+.2f} to "
          f"{diffs.max():+.2f} nats (median {np.median(diffs):+.2f})")
    print(f"  lowest:  {low[0]} {low[1]} ({low[3]:+.1f} nats from the best)")
    print(f"  highest: {high[0]} {high[1]} ({high[3]:+.1f} nats from the best)")
    print(f"a screen of S nats keeps every candidate whose evidence is within S - {diffs.max():.2f} nats of the best")
    return 0


if __name__ == "__main__":
    sys.exit(main())
