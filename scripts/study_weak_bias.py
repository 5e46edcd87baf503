"""Where drift bands under-cover: a Gauss-Markov bias barely above the white-noise floor.

Simulates ``--n-logs`` white + Gauss-Markov logs of 2**15 samples at 100 Hz, truth drawn
log-uniformly within +-0.5 decade of (q = 1e-2, sigma_b^2 = ``--bias-variance``, T = 10 s),
fits each with the true terms and prints how often the 90% interval contains the truth
for sigma_b^2 T (the long-term drift level) and for the attitude drift at 1, 10 and 100 s
(zero bias start), with the rank histogram of sigma_b^2 T. Prior and likelihood options
reproduce the README's experiments:

    python scripts/study_weak_bias.py --bias-variance 1e-5                      # barely detected
    python scripts/study_weak_bias.py --bias-variance 1e-4                      # clearly detected
    python scripts/study_weak_bias.py --bias-variance 1e-5 --likelihood copula
    python scripts/study_weak_bias.py --bias-variance 1e-5 --prior-decades-below 2
    python scripts/study_weak_bias.py --bias-variance 1e-5 --tau-max-record 1
"""

import argparse
import sys
import warnings

import numpy as np

TIMES = np.array([1.0, 10.0, 100.0])


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n-logs", type=int, default=40)
    parser.add_argument("--bias-variance", type=float, default=1e-5)
    parser.add_argument("--likelihood", default="correlated")
    parser.add_argument("--prior-decades-below", type=float, default=None)
    parser.add_argument("--tau-max-record", type=float, default=None)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    import bayes_imu.inference.likelihood as likelihood
    from bayes_imu.noise import gauss_markov
    from bayes_imu import NoiseModel, allan_variance, drift_sigma, fit_allan, simulate_log
    from bayes_imu.drift.bands import drift_draws
    from bayes_imu.errors import ConvergenceWarning

    if args.prior_decades_below is not None:
        likelihood.PRIOR_DECADES_BELOW = args.prior_decades_below
    if args.tau_max_record is not None:
        gauss_markov.BIAS_T_MAX_RECORD = args.tau_max_record
    base = {"noise_variance": 1e-2, "bias_variance": args.bias_variance, "time_constant": 10.0}
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    rng = np.random.default_rng(args.seed)
    ranks = []
    for _ in range(args.n_logs):
        truth = {k: v * 10 ** rng.uniform(-0.5, 0.5) for k, v in base.items()}
        allan = allan_variance(simulate_log(model, truth, 2**15, rng=rng), rate_hz=100.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            res = fit_allan(allan, terms=model.terms, rng=rng, likelihood=args.likelihood)
        total = drift_draws(res, TIMES, quantity="attitude", bias_start="zero")["total"]
        true = drift_sigma(
            TIMES,
            quantity="attitude",
            dt=0.01,
            noise_variance=truth["noise_variance"],
            bias_variance=truth["bias_variance"],
            time_constant=truth["time_constant"],
        ).total
        product = res.draws("bias_variance") * res.draws("time_constant")
        ranks.append(
            [
                np.mean(product < truth["bias_variance"] * truth["time_constant"]),
                *np.mean(total < true, axis=0),
            ]
        )
    ranks = np.array(ranks)
    cover = np.mean((ranks > 0.05) & (ranks < 0.95), axis=0)
    print(
        f"{args.n_logs} logs, sigma_b^2 = {args.bias_variance:g}, likelihood {args.likelihood}, "
        f"prior decades below {likelihood.PRIOR_DECADES_BELOW:g}, tau max "
        f"{gauss_markov.BIAS_T_MAX_RECORD:g} record"
    )
    print(f"90% coverage: sigma_b^2 T {cover[0]:.3f}; attitude band at {TIMES.tolist()} s: "
          + " / ".join(f"{c:.3f}" for c in cover[1:]))
    print(
        "rank histogram of sigma_b^2 T (10 bins):",
        np.histogram(ranks[:, 0], bins=10, range=(0, 1))[0].tolist(),
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
