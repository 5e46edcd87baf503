"""Overbounding factors on the shipped synthetic logs: "inflate by what factor?".

For the Gauss-Markov gyro (``gyro_lowgrade``: white + Gauss-Markov bias, 1 h at 100 Hz) and the
accelerometer (``accel_gravity``: white + Gauss-Markov, 30 min at 200 Hz): fit (model selection),
then :func:`bayes_imu.drift.overbound.overbound` at 95% credibility over horizons from one
sample to ``--t-max`` values, and print the Kalibr point values (posterior medians of
:func:`bayes_imu.report.kalibr.axis_densities`), the overbounding pair, the factors and the
horizons where the bound is tight. Run: ``nice -n 10 python scripts/overbound_example.py``
(about a minute); ``--quick``: the gyro and one range.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bayes_imu.allan import allan_variance  # noqa: E402
from bayes_imu.drift.overbound import overbound  # noqa: E402
from bayes_imu.inference.fit import fit_allan  # noqa: E402
from bayes_imu.io.readers import read_log, to_si  # noqa: E402
from bayes_imu.report.kalibr import axis_densities  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data_synthetic"
LOGS = (("gyro_lowgrade", "gyro"), ("accel_gravity", "accel"))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--t-max", default="60,600,1800", help="longest horizons (s), default 60,600,1800"
    )
    parser.add_argument("--quick", action="store_true", help="the gyro, 60 s only")
    args = parser.parse_args(argv)
    truth = json.loads((DATA / "truth.json").read_text())
    ranges = [60.0] if args.quick else [float(v) for v in args.t_max.split(",")]
    print(
        f"{'log':15s} {'t_max':>6} {'N point':>10} {'N bound':>10} {'xN':>6} "
        f"{'K point':>10} {'K bound':>10} "
        f"{'xK':>6}  tight at (s)"
    )
    for name, kind in LOGS[:1] if args.quick else LOGS:
        info = truth[name]
        y = to_si(read_log(DATA / info["file"], column=info["column"]).values, info["unit"])
        fit = fit_allan(allan_variance(y, rate_hz=info["rate_hz"]), rng=1)
        density, walk = (float(np.median(d)) for d in axis_densities(fit))
        for t_max in ranges:
            pair = overbound(fit, kind=kind, t_max=t_max, rng=1)
            f_n, f_k = pair.factors(density, walk)
            tight = ", ".join(f"{q} {t:.3g}" for q, t in pair.tight_s)
            print(
                f"{name:15s} {t_max:6g} {density:10.4g} {pair.noise_density:10.4g} {f_n:6.3g} "
                f"{walk:10.4g} "
                f"{pair.random_walk:10.4g} {f_k:6.3g}  {tight}"
            )
    print(
        "SI units: N rad/s/sqrt(Hz) or m/s^2/sqrt(Hz), K rad/s^2/sqrt(Hz) or m/s^3/sqrt(Hz); "
        "bound: 95% credible drift, bias calibrated over the 60 s before the outage"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
