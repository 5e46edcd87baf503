"""Speed against error for every estimation method, on the same simulated logs.

For each sensor grade (white noise + Gauss-Markov bias, three grades) and log length
(1e4 to 1e7 samples at 100 Hz) the script simulates ``--n-logs`` logs and estimates the
noise variance q, the bias variance sigma_b^2 and the time constant T with:

* ``slope``: the Allan-plot readings of popular robotics tools: q from the Allan deviation
  at tau = 1 s (white level), and the bias from the bias-instability minimum, read as a
  Gauss-Markov bias with sigma_b = min ADEV / 0.664 and T = the tau of the minimum (a
  common navigation heuristic);
* ``ls_log_adev``: unweighted least squares on log Allan deviation;
* ``gmwm_wls``: GMWM-style weighted least squares on the Allan variance, weighted by the
  inverse of its exact covariance (``bayes_imu.noise.avar_covariance``) at the ``ls_log_adev``
  estimate, with asymptotic (sandwich-free, ``(J' W J)^-1``) intervals in log parameters;
* ``map_laplace``: posterior mode of the bayes_imu posterior (default likelihood) with a
  Laplace approximation in log parameters;
* ``mcmc_500``, ``mcmc_2000``, ``mcmc``: the full emcee fit (``fit_allan``, true terms)
  capped at 500 and 2000 steps, and run to convergence.

Every method's parameters are pushed through the same exact drift formulas
(``bayes_imu.drift_sigma``, attitude, zero bias start) for the 60 s and 600 s drift.
Per method, grade and length: median wall time (the Allan variance, shared, excluded),
relative RMSE and bias of q, sigma_b^2, T and the two drifts, and for methods with
intervals the coverage of the 90% interval (q and the 600 s drift). Prints the table,
writes ``speed_vs_error.csv`` and ``pareto.png`` (time vs drift error) into ``--out``.

    python scripts/bench_speed_vs_error.py [--n-logs 4] [--processes 2] [--out docs/speed_vs_error]
    python scripts/bench_speed_vs_error.py --quick     # smoke run: 1 log, 1e4 and 1e5 samples
"""

import argparse
import csv
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

RATE = 100.0
DT = 1.0 / RATE
# per-sample white variance (deg/s)^2 at 100 Hz, bias variance (deg/s)^2, time constant (s)
GRADES = {
    "consumer": {"noise_variance": 0.25, "bias_variance": 1e-3, "time_constant": 30.0},
    "industrial": {"noise_variance": 2.5e-3, "bias_variance": 1e-5, "time_constant": 100.0},
    "tactical": {"noise_variance": 2.5e-5, "bias_variance": 1e-8, "time_constant": 300.0},
}
NAMES = ("noise_variance", "bias_variance", "time_constant")
METHODS = ("slope", "ls_log_adev", "gmwm_wls", "map_laplace", "mcmc_500", "mcmc_2000", "mcmc")
DRIFT_T = np.array([60.0, 600.0])
FLICKER_FACTOR = np.sqrt(2.0 * np.log(2.0) / np.pi)  # 0.664: ADEV plateau of bias instability B


def drift(params):
    """Attitude 1-sigma at 60 and 600 s; ``params`` arrays of shape (n,) -> (n, 2)."""
    from bayes_imu import drift_sigma

    q, s2, tau = (np.atleast_1d(params[k])[:, None] for k in NAMES)
    return drift_sigma(
        DRIFT_T[None, :],
        quantity="attitude",
        dt=DT,
        noise_variance=q,
        bias_variance=s2,
        time_constant=tau,
    ).total


def slope(allan):
    log_tau, log_avar = np.log(allan.tau), np.log(allan.avar)
    at_one = np.exp(np.interp(0.0, log_tau, log_avar))  # AVAR at tau = 1 s (log-log interpolation)
    i = int(np.argmin(allan.adev))
    return {
        "noise_variance": at_one * 1.0 / DT,
        "bias_variance": (allan.adev[i] / FLICKER_FACTOR) ** 2,
        "time_constant": float(allan.tau[i]),
    }, None


def _model():
    from bayes_imu import NoiseModel

    return NoiseModel(("white", "gauss_markov"), DT)


def _starts(allan):
    from bayes_imu.inference.fit import _starts as starts

    return starts(_model(), allan, None)


def ls_log_adev(allan):
    from scipy import optimize

    model = _model()
    evaluate = model.avar_evaluator(allan.m)
    best = None
    for start in _starts(allan):
        res = optimize.least_squares(
            lambda p: 0.5 * (np.log(evaluate(np.exp(p))) - np.log(allan.avar)), start
        )
        if best is None or res.cost < best.cost:
            best = res
    return dict(zip(NAMES, np.exp(best.x))), None


def gmwm_wls(allan, rng):
    from scipy import optimize

    from bayes_imu.noise.avar_covariance import avar_covariance

    model = _model()
    pilot, _ = ls_log_adev(allan)
    cov = avar_covariance(model, pilot, allan.m, allan.n_samples)
    whiten = np.linalg.inv(np.linalg.cholesky(cov))
    evaluate = model.avar_evaluator(allan.m)
    residual = lambda p: whiten @ (allan.avar - evaluate(np.exp(p)))  # noqa: E731
    best = None
    for start in [np.log([pilot[k] for k in NAMES]), *_starts(allan)]:
        res = optimize.least_squares(residual, start)
        if best is None or res.cost < best.cost:
            best = res
    jac = best.jac  # d residual / d log theta
    log_cov = np.linalg.pinv(jac.T @ jac)
    return dict(zip(NAMES, np.exp(best.x))), _gaussian_draws(best.x, log_cov, rng)


def map_laplace(allan, rng):
    from bayes_imu.inference.fit import _covariance, _pilot
    from bayes_imu.inference.likelihood import LogPosterior, default_bounds
    from bayes_imu.inference.selection import negative_hessian, posterior_mode

    model = _model()
    pilot = _pilot(model, allan)
    post = LogPosterior.from_covariance(
        model,
        allan,
        _covariance(model, pilot, allan),
        model.avar(allan.m, pilot),
        default_bounds(model, allan),
        kind="copula",
    )
    phi = posterior_mode(post, [np.log([pilot[k] for k in NAMES]), *_starts(allan)]).phi
    hessian = negative_hessian(post.log_likelihood, phi)  # the prior is flat in log parameters
    w, v = np.linalg.eigh(hessian)
    log_cov = (v / np.clip(w, 1e-6, None)) @ v.T
    return dict(zip(NAMES, np.exp(phi))), _gaussian_draws(phi, log_cov, rng)


def _gaussian_draws(mean, cov, rng, n=2000):
    # an unidentified parameter (T on a short log) has a huge log variance: clamp to finite values
    draws = np.exp(
        np.clip(rng.multivariate_normal(mean, cov, size=n, check_valid="ignore"), -300.0, 300.0)
    )
    return {k: draws[:, i] for i, k in enumerate(NAMES)}


def mcmc(allan, rng, max_steps):
    from bayes_imu import fit_allan
    from bayes_imu.errors import ConvergenceWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        res = fit_allan(allan, terms=("white", "gauss_markov"), rng=rng, max_steps=max_steps)
    draws = {k: res.draws(k) for k in NAMES}
    return {k: float(np.median(v)) for k, v in draws.items()}, draws


def one_log(job):
    grade, n_samples, index, seed, quick = job
    from bayes_imu import allan_variance, simulate_log

    rng = np.random.default_rng([seed, list(GRADES).index(grade), int(np.log10(n_samples)), index])
    truth = GRADES[grade]
    allan = allan_variance(simulate_log(_model(), truth, n_samples, rng=rng), rate_hz=RATE)
    true_drift = drift({k: np.array([v]) for k, v in truth.items()})[0]
    runs = {
        "slope": lambda: slope(allan), "ls_log_adev": lambda: ls_log_adev(allan),
        "gmwm_wls": lambda: gmwm_wls(allan, rng), "map_laplace": lambda: map_laplace(allan, rng),
        "mcmc_500": lambda: mcmc(allan, rng, 500), "mcmc_2000": lambda: mcmc(allan, rng, 2000),
        "mcmc": lambda: mcmc(allan, rng, 2000 if quick else 40000),
    }
    out = []
    for method, run in runs.items():
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            estimate, draws = run()
        seconds = time.perf_counter() - start
        est_drift = drift({k: np.array([v]) for k, v in estimate.items()})[0]
        row = {"grade": grade, "n_samples": n_samples, "method": method, "seconds": seconds}
        for k in NAMES:
            row[f"err_{k}"] = estimate[k] / truth[k] - 1.0
        for t, e, d in zip(DRIFT_T, est_drift, true_drift):
            row[f"err_drift{t:g}"] = e / d - 1.0
        if draws is not None:
            row["cover_noise_variance"] = float(
                np.quantile(draws["noise_variance"], 0.05)
                <= truth["noise_variance"]
                <= np.quantile(draws["noise_variance"], 0.95)
            )
            d600 = drift(draws)[:, 1]
            row["cover_drift600"] = float(
                np.quantile(d600, 0.05) <= true_drift[1] <= np.quantile(d600, 0.95)
            )
        out.append(row)
    return out


def summarise(rows):
    """One line per (grade, length, method): median time, relative RMSE / bias, coverage."""
    table = []
    keys = sorted({(r["grade"], r["n_samples"], r["method"]) for r in rows},
                  key=lambda k: (list(GRADES).index(k[0]), k[1], METHODS.index(k[2])))
    for grade, n, method in keys:
        sel = [r for r in rows if (r["grade"], r["n_samples"], r["method"]) == (grade, n, method)]
        line = {"grade": grade, "n_samples": n, "method": method, "n_logs": len(sel),
                "median_seconds": float(np.median([r["seconds"] for r in sel]))}
        for k in [*NAMES, "drift60", "drift600"]:
            e = np.array([r[f"err_{k}"] for r in sel])
            line[f"rmse_{k}"] = float(np.sqrt(np.mean(e * e)))
            line[f"bias_{k}"] = float(np.mean(e))
        for k in ("noise_variance", "drift600"):
            c = [r[f"cover_{k}"] for r in sel if f"cover_{k}" in r]
            line[f"cover90_{k}"] = float(np.mean(c)) if c else float("nan")
        table.append(line)
    return table


def print_table(table):
    head = (
        f"{'grade':10s} {'samples':>8s} {'method':12s} {'time_s':>7s} {'rmse_q':>7s} "
        f"{'rmse_s2':>8s} {'rmse_T':>8s} {'rmse_d60':>8s} {'bias_d60':>8s} {'rmse_d600':>9s} "
        f"{'bias_d600':>9s} {'cov_q':>5s} {'cov_d600':>8s}"
    )
    print(head)
    for r in table:
        print(
            f"{r['grade']:10s} {r['n_samples']:8.0e} {r['method']:12s} {r['median_seconds']:7.3f} "
            f"{r['rmse_noise_variance']:7.3f} {r['rmse_bias_variance']:8.3g} "
            f"{r['rmse_time_constant']:8.3g} {r['rmse_drift60']:8.3f} {r['bias_drift60']:+8.3f} "
            f"{r['rmse_drift600']:9.3f} {r['bias_drift600']:+9.3f} "
            f"{r['cover90_noise_variance']:5.2f} {r['cover90_drift600']:8.2f}"
        )


def pareto(table, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for method in METHODS:
        sel = [r for r in table if r["method"] == method]
        ax.scatter(
            [r["median_seconds"] for r in sel],
            [r["rmse_drift600"] for r in sel],
            label=method,
            s=18,
        )
    ax.set(
        xscale="log",
        yscale="log",
        xlabel="median wall time per log (s)",
        ylabel="relative RMSE of the 600 s attitude drift",
        title="speed against error (all grades and lengths)",
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n-logs", type=int, default=4, help="logs per grade and length")
    parser.add_argument("--lengths", default="1e4,1e5,1e6,1e7")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "speed_vs_error"
    )
    parser.add_argument(
        "--quick", action="store_true", help="smoke run: 1 log, 1e4 and 1e5 samples"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.n_logs, args.lengths = 1, "1e4,1e5"
    lengths = [int(float(v)) for v in args.lengths.split(",")]
    jobs = [
        (g, n, i, args.seed, args.quick)
        for g in GRADES
        for n in lengths
        for i in range(args.n_logs)
    ]
    start = time.perf_counter()
    if args.processes > 1:
        with ProcessPoolExecutor(args.processes) as pool:
            rows = [r for batch in pool.map(one_log, jobs, chunksize=1) for r in batch]
    else:
        rows = [r for job in jobs for r in one_log(job)]
    table = summarise(rows)
    print(
        f"{len(jobs)} logs ({args.n_logs} per grade and length), {time.perf_counter() - start:.0f} "
        "s\n"
    )
    print_table(table)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "speed_vs_error.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(table[0]))
        writer.writeheader()
        writer.writerows(table)
    pareto(table, args.out / "pareto.png")
    print(f"\nwrote {args.out / 'speed_vs_error.csv'} and pareto.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
