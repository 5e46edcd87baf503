"""Accuracy: posterior medians vs a GMWM-style weighted least-squares fit, on the same logs.

For ``--n-logs`` simulated white + Gauss-Markov gyro logs (1e6 samples at 100 Hz, the
``gyro_lowgrade`` truth of data_synthetic/), both estimators fit the true terms to the
same octave Allan variance:

* bayes_imu: posterior median (``fit_allan``, correlated likelihood);
* WLS: ``min sum_i (avar_i - AVAR_i(theta))^2 / (2 avar_i^2 / edf_i)`` over log-parameters
  (the weighting of GMWM-type estimators, Guerrier et al. 2013, with the Allan variance in
  place of the Haar wavelet variance and a diagonal weight matrix), started from the same
  points.

Prints, per parameter, the median absolute relative error and the RMS of the log error
of each, and the worst relative error of the noise variance.

    python scripts/bench_accuracy.py --n-logs 20
"""

import argparse
import warnings

import numpy as np
from scipy import optimize

TRUTH = {"noise_variance": 0.25, "bias_variance": 1e-4, "time_constant": 100.0}


def wls(model, allan, starts):
    weights = np.sqrt(allan.edf / 2.0) / allan.avar
    evaluate = model.avar_evaluator(allan.m)
    best = None
    for start in starts:
        res = optimize.least_squares(
            lambda p: (allan.avar - evaluate(np.exp(p))) * weights, start, method="lm"
        )
        if best is None or res.cost < best.cost:
            best = res
    return dict(zip(model.parameter_names, np.exp(best.x)))


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n-logs", type=int, default=20)
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.fit import _starts, fit_allan
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    model = NoiseModel(("white", "gauss_markov"), 0.01)
    rng = np.random.default_rng(args.seed)
    errors = {"bayes_imu": {k: [] for k in TRUTH}, "WLS": {k: [] for k in TRUTH}}
    for _ in range(args.n_logs):
        allan = allan_variance(simulate_log(model, TRUTH, args.samples, rng=rng), rate_hz=100.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            result = fit_allan(allan, terms=model.terms, rng=rng)
        est = {
            "bayes_imu": {k: float(np.median(result.draws(k))) for k in TRUTH},
            "WLS": wls(model, allan, _starts(model, allan, None)),
        }
        for method, values in est.items():
            for k in TRUTH:
                errors[method][k].append(np.log(values[k] / TRUTH[k]))
    print(f"{args.n_logs} logs of {args.samples} samples, white + Gauss-Markov, truth {TRUTH}\n")
    print(
        f"{'parameter':16s} {'method':10s} {'median |rel err|':>16s} {'rms log err':>11s} "
        f"{'max |rel err|':>13s}"
    )
    for k in TRUTH:
        for method in errors:
            e = np.array(errors[method][k])
            rel = np.abs(np.expm1(e))
            print(
                f"{k:16s} {method:10s} {np.median(rel):16.4f} {np.sqrt(np.mean(e * e)):11.4f} "
                f"{rel.max():13.4f}"
            )


if __name__ == "__main__":
    main()
