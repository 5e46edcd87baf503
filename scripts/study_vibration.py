"""How often the automatic model search selects the vibration line term, with and without a line.

Simulated static logs at 100 Hz (the ADIS16405's rate), ``2**17`` samples each by default:

* *with a line*: white noise + a Gauss-Markov bias + a sinusoid of 18 Hz (the Allan-deviation
  hump near tau = 0.02 s that the ADIS16405 gyro z logs show), amplitude given by ``--amplitude``;
* *without*: white noise + a Gauss-Markov bias + a rate random walk (no line).

Each log is fitted with ``terms="auto"`` (:func:`bayes_imu.inference.fit.fit_allan`); the table
gives the share of logs whose selected model has the line, the mean posterior probability of the
term (the model-averaged share of candidates with it), and, with a line, the median of the fitted
frequency and amplitude. Logs use seeds ``seed, seed + 1, ...`` (one generator per log).

    nice -n 10 python scripts/study_vibration.py [--n-line 10] [--n-null 40] [--samples 131072]
    [--quick]
"""

import argparse
import time

import numpy as np

from bayes_imu.allan.estimator import allan_variance
from bayes_imu.inference.fit import fit_allan
from bayes_imu.noise import NoiseModel
from bayes_imu.noise.simulate import simulate_log

DT = 0.01
BASE = {"noise_variance": 1e-4, "bias_variance": 1e-7, "time_constant": 30.0}
LINE_HZ = 18.0
NULL = {
    "noise_variance": 1e-4,
    "bias_variance": 1e-7,
    "time_constant": 30.0,
    "rate_random_walk": 1e-5,
}


def _fits(terms, params, n_logs, n_samples, seed):
    model = NoiseModel(terms, DT)
    rows = []
    for i in range(n_logs):
        rng = np.random.default_rng(seed + i)
        y = simulate_log(model, params, n_samples, rng=rng)
        start = time.perf_counter()
        fit = fit_allan(allan_variance(y, rate_hz=1.0 / DT), terms="auto", rng=rng)
        seconds = time.perf_counter() - start
        probability = fit.term_probabilities().get("vibration", 0.0)
        selected = "vibration" in fit.model.terms
        f = float(np.median(fit.draws("vibration_frequency"))) if selected else np.nan
        a = float(np.median(fit.draws("vibration_amplitude"))) if selected else np.nan
        rows.append((selected, probability, f, a, seconds, fit.model.terms))
    return rows


def _line(label, rows):
    selected = np.array([r[0] for r in rows])
    k, n = int(selected.sum()), len(rows)
    f = np.nanmedian([r[2] for r in rows]) if k else np.nan
    a = np.nanmedian([r[3] for r in rows]) if k else np.nan
    print(
        f"{label:<34} {n:>5} {k:>9} {k / n:>8.3f} {np.mean([r[1] for r in rows]):>10.3f} "
        f"{f:>10.3g} {a:>10.3g} {np.median([r[4] for r in rows]):>8.1f}"
    )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n-line", type=int, default=10, help="logs with a line (default 10)")
    parser.add_argument("--n-null", type=int, default=40, help="logs without a line (default 40)")
    parser.add_argument(
        "--samples", type=int, default=2**17, help="samples per log (default 2**17)"
    )
    parser.add_argument(
        "--amplitude", type=float, default=1e-2, help="line amplitude [u] (default 1e-2)"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="two logs of each kind, 2**15 samples")
    args = parser.parse_args(argv)
    if args.quick:
        args.n_line, args.n_null, args.samples = 2, 2, 2**15
    line = dict(BASE, vibration_frequency=LINE_HZ, vibration_amplitude=args.amplitude)
    print(
        f"{args.samples} samples at {1 / DT:g} Hz; white q = {BASE['noise_variance']:g} u^2, GM "
        f"s^2 = {BASE['bias_variance']:g} u^2, T = {BASE['time_constant']:g} s; line {LINE_HZ:g} "
        f"Hz, A = {args.amplitude:g} u; null adds K = {NULL['rate_random_walk']:g} u/sqrt(s)"
    )
    print(
        f"{'logs':<34} {'n':>5} {'selected':>9} {'rate':>8} {'mean P':>10} {'f [Hz]':>10} "
        f"{'A [u]':>10} {'s/fit':>8}"
    )
    with_line = _fits(
        ("white", "gauss_markov", "vibration"), line, args.n_line, args.samples, args.seed
    )
    _line("white + GM + 18 Hz line", with_line)
    without = _fits(
        ("white", "gauss_markov", "random_walk"), NULL, args.n_null, args.samples, args.seed + 1000
    )
    _line("white + GM + RRW (no line)", without)
    k = sum(r[0] for r in without)
    n = len(without)
    lo, hi = _clopper_pearson(k, n)
    print(
        f"false selection rate {k}/{n} = {k / n:.3f} (95% Clopper-Pearson interval "
        f"{lo:.3f}-{hi:.3f})"
    )
    for r in without:
        if r[0]:
            print("  selected with a line:", r[5])


def _clopper_pearson(k, n, level=0.95):
    from scipy.stats import beta

    alpha = 1.0 - level
    lo = beta.ppf(alpha / 2, k, n - k + 1) if k > 0 else 0.0
    hi = beta.ppf(1 - alpha / 2, k + 1, n - k) if k < n else 1.0
    return lo, hi


if __name__ == "__main__":
    main()
