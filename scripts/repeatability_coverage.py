"""Coverage of the true angle random walk by the 90% intervals on stationary simulated logs (issue
35).

The repeatability between parts (:mod:`bayes_imu.inference.repeatability`) widens every record's
parameter intervals where its parts scatter more than the posterior allows. On a *stationary* log it
should rarely widen, and never inflate coverage beyond reason. This script simulates stationary logs
of ADIS16405-like families (white alone; white + Gauss-Markov + rate random walk; white + filtered
white + Gauss-Markov), fits each with the defaults and counts how often the true ``noise_density``
(``sqrt(q_eff dt)`` of the simulated model: white plus the short-term terms' white equivalents) and
``white_noise_density`` lie in the 90% interval of ``summary.json`` ``parameters`` (with
repeatability) and ``parameters_this_record`` (the posterior alone), with the binomial standard
error, and the median width ratio of the two.

Run: ``nice -n 10 python scripts/repeatability_coverage.py [--logs 40] [--samples 262144]``
(seeds 0.. per family; about 5 s a log)."""

import argparse
import sys
import warnings

import numpy as np

RATE = 100.0
#: family -> (terms, parameters in SI-like units of an ADIS16405 gyro, rad/s)
FAMILIES = {
    "white": (("white",), {"noise_variance": 5e-5}),
    "white+gm+rrw": (("white", "gauss_markov", "random_walk"),
                     {"noise_variance": 5e-5, "bias_variance": 1e-7, "time_constant": 200.0,
                      "rate_random_walk": 2e-5}),
    "white+filtered+gm": (("white", "filtered_white", "gauss_markov"),
                          {"noise_variance": 2.5e-5, "filtered_variance": 6e-6,
                           "bias_variance": 1e-7, "time_constant": 200.0}),
}
NAMES = ("noise_density", "white_noise_density")


def run_family(terms, params, n_logs, n_samples, seed0=0):
    """``{block: {name: (covered (n,), widths (n,))}}`` over ``n_logs`` simulated logs."""
    from bayes_imu import allan_variance, fit_allan
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.noise.model import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    model = NoiseModel(terms, 1.0 / RATE)
    truth = {"noise_density": np.sqrt(model.short_term_variance(params) * model.dt),
             "white_noise_density": np.sqrt(params["noise_variance"] * model.dt)}
    out = {b: {n: ([], []) for n in NAMES} for b in ("parameters", "parameters_this_record")}
    for seed in range(seed0, seed0 + n_logs):
        y = simulate_log(model, params, n_samples, rng=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            s = fit_allan(allan_variance(y, rate_hz=RATE), rng=seed).summary()
        for block, table in out.items():
            for name in NAMES:
                # a white-only fit has one density
                e = s[block].get(name, s[block].get("noise_density"))
                table[name][0].append(e["q05"] <= truth[name] <= e["q95"])
                table[name][1].append(np.log(e["q95"] / e["q05"]))
    return {b: {n: (np.array(c), np.array(w)) for n, (c, w) in t.items()} for b, t in out.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", type=int, default=40)
    parser.add_argument("--samples", type=int, default=2**18)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--families", nargs="*", default=list(FAMILIES))
    args = parser.parse_args(argv)
    print(f"{args.logs} logs of {args.samples} samples at {RATE:g} Hz per family, "
          f"seeds {args.seed0}..\n")
    print("| family | quantity | coverage, parameters (repeatability) "
          "| coverage, this record alone | median width ratio |\n|---|---|---|---|---|")
    totals = {b: [] for b in ("parameters", "parameters_this_record")}
    for family in args.families:
        terms, params = FAMILIES[family]
        res = run_family(terms, params, args.logs, args.samples, args.seed0)
        for name in NAMES:
            cells = []
            for block in ("parameters", "parameters_this_record"):
                c = res[block][name][0]
                totals[block].append(c) if name == "noise_density" else None
                cells.append(f"{c.mean():.3f} +- {np.sqrt(c.mean() * (1 - c.mean()) / c.size):.3f}")
            ratio = np.median(res["parameters"][name][1] / res["parameters_this_record"][name][1])
            print(f"| {family} | {name} | {cells[0]} | {cells[1]} | {ratio:.2f} |")
    for block, parts in totals.items():
        c = np.concatenate(parts)
        print(f"\nnoise_density, all families, {block}: {c.mean():.3f} +- "
              f"{np.sqrt(c.mean() * (1 - c.mean()) / c.size):.3f} ({c.sum()} of {c.size})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
