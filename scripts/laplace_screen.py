"""Check the Laplace screen of model selection: does it skip only candidates that cannot matter?

``fit_allan`` leaves a candidate with its Laplace estimate when ``selection.can_skip`` rules it out:
Laplace estimate more than ``LAPLACE_SCREEN`` nats below the best importance-sampled evidence, and
a pilot of importance draws agreeing. This script fits the shipped synthetic logs and every real
channel (``../shared``; skipped when absent) with the screen off, so that every candidate (widened
ones included) is importance-sampled, then asks ``can_skip`` about each candidate against the
final best evidence (the fit asks against the best so far, which is lower: it skips fewer). It
prints, per log, how many candidates the rule skips and the largest importance-sampled evidence
among them relative to the best, and the error of the Laplace estimate on the candidates within
50 nats of the best. Run: ``python scripts/laplace_screen.py [--quick]`` (about 10 minutes; the
sampler is cut short, only the model selection matters here).
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
        # the units do not change the evidences
        yield f"synthetic:{name}", log.values, float(entry["rate_hz"])


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--quick", action="store_true", help="synthetic logs and three real channels"
    )
    args = parser.parse_args(argv)
    import importlib

    from bayes_imu import allan_variance
    from validate_real import DATA, RATE, channels

    # the module (the package exports a function)
    fit_module = importlib.import_module("bayes_imu.inference.fit")
    from bayes_imu.inference.selection import can_skip

    laplace, sampled = {}, {}
    laplace_fn, evidence_fn = fit_module.laplace_log_evidence, fit_module.log_evidence

    def record_laplace(post, u):
        out = laplace_fn(post, u)
        laplace[id(post)] = (post, u, out[0], out[1])
        return out

    def record_evidence(post, u, **kw):
        out = evidence_fn(post, u, **kw)
        sampled[id(post)] = out.log_z
        return out

    fit_module.laplace_log_evidence, fit_module.log_evidence = record_laplace, record_evidence
    fit_module.can_skip = lambda *args, **kw: False  # every candidate importance-sampled
    sources = list(synthetic())
    if DATA.exists():
        real = [(name, y, RATE) for name, _, y in channels()]
        sources += real[:3] if args.quick else real
    else:
        print(f"real data not found ({DATA}): synthetic logs only")
    rng = np.random.default_rng(20261123)
    skipped_worst, errors, n_all, n_skipped = -np.inf, [], 0, 0
    print(
        f"{'log':24s} {'candidates':>10s} {'skipped':>7s}  {'best skipped (nats from best)':>29s}  "
        "Laplace - importance within 50 nats of the best"
    )
    for name, y, rate in sources:
        laplace.clear()
        sampled.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit_module.fit_allan(allan_variance(y, rate_hz=rate), rng=0, max_steps=250)
        best = max(sampled.values())
        skipped, near = [], []
        for key, (post, u, lz, cov) in laplace.items():
            if can_skip(post, u, lz, cov, best, rng):
                skipped.append(sampled[key] - best)
            if sampled[key] > best - 50.0:
                near.append(lz - sampled[key])
        n_all += len(laplace)
        n_skipped += len(skipped)
        errors += near
        top = max(skipped) if skipped else -np.inf
        skipped_worst = max(skipped_worst, top)
        print(
            f"{name:24s} {len(laplace):10d} {len(skipped):7d}  {top:29.1f}  {min(near):+6.2f} to "
            f"{max(near):+5.2f}"
        )
    errors = np.array(errors)
    print(
        f"\n{n_skipped} of {n_all} candidates of {len(sources)} logs skipped; the best of them is "
        f"{skipped_worst:.1f} nats below the best evidence of its log"
    )
    print(
        f"Laplace - importance on the {errors.size} candidates within 50 nats of the best: "
        f"{errors.min():+.2f} to {errors.max():+.2f} nats (median {np.median(errors):+.2f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
