"""The stationarity check of the real channels' first halves with a model-free sampling error.

``bayes_imu.inference.stationarity`` takes the sampling error of each part's Allan variance
from the fitted model (its exact EDF). On real logs most fits are inadequate, so this script
repeats the check with Greenhall & Riley's power-law EDF at the noise type identified in each
part (no model): if the flags agreed only because of a misfitting model, they would differ here.
For each of the 37 channels of ``scripts/validate_real.py`` (first halves, four parts) it prints
the Bonferroni p-value, the averaging time of the strongest evidence and the sizes that differ
significantly on their own. Run: ``python scripts/stationarity_real.py`` (about a minute).
"""

import sys

from validate_real import DATA, RATE, channels


def main():
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    from bayes_imu import allan_variance
    from bayes_imu.allan.estimator import greenhall_edf
    from bayes_imu.inference.stationarity import STATIONARITY_ALPHA, segment_test

    flagged = []
    print(
        f"{'channel':14s} {'p_value':>9s} {'worst_tau_s':>11s}  sizes that differ on their own (s)"
    )
    for name, _, y in channels():
        half = allan_variance(y[: y.size // 2], rate_hz=RATE)
        seg = half.segments
        check = segment_test(
            seg, greenhall_edf(half.alpha[: seg.m.size], seg.m, seg.n_samples + 1), RATE
        )
        if not check.stationary:
            flagged.append(name)
        alone = ", ".join(
            f"{t:g}" for t in check.tau_s[check.p_each * check.p_each.size < STATIONARITY_ALPHA]
        )
        print(f"{name:14s} {check.p_value:9.2g} {check.worst_tau_s:11g}  {alone}")
    print(f"\nflagged non-stationary with the model-free EDF: {len(flagged)} of 37")
    return 0


if __name__ == "__main__":
    sys.exit(main())
