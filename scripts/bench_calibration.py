"""Calibration study: do 90% posterior intervals contain the truth 90% of the time?

For each scenario (white + Gauss-Markov, white only, white + rate random walk) the script
draws ``--n-logs`` true parameter points log-uniformly within +-0.5 decade of a
representative point (SBC-style: the truth varies from log to log), simulates a log
(``bayes_imu.noise.simulate``), and fits it with the true terms once per likelihood
(``--likelihoods``: by default the Gaussian copula, the multivariate normal on log AVAR and
the independent-gamma baseline), on the same log. It prints, per scenario, likelihood and
parameter, the coverage of the central 90% interval with its binomial
standard error, and a chi-squared uniformity p-value of the truth's rank among the
posterior draws (10 bins). A second table gives how often the 90% drift band (attitude,
zero bias start) contains the true 1-sigma drift at 1, 10, 100 and 1000 s; a third how
often evidence-based selection (``terms="auto"``, evidence only) returns the true model.

With ``--auto``, every log is also fitted as a user would (``terms="auto"``: selection,
stepwise search, adequacy, model averaging), and a fourth table gives the coverage of the
model-averaged 90% drift band and of the selected-model band (``models="selected"``, the
behaviour before model averaging), with how often the true model was selected. The
scenarios include two ambiguous ones: a Gauss-Markov bias whose time constant overlaps a
rate random walk (``white+gm+rw``) and a random walk near the detection limit (``weak-rw``).

    python scripts/bench_calibration.py --n-logs 100      # ~10 min on 2 cores
    python scripts/bench_calibration.py --n-logs 100 --likelihoods correlated --no-selection --auto
    --processes 16
"""

import argparse
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np

RATE = 100.0
BAND_TIMES = np.array([1.0, 10.0, 100.0, 1000.0])
SCENARIOS = {
    "white+gm": {"noise_variance": 1e-2, "bias_variance": 1e-5, "time_constant": 20.0},
    "white": {"noise_variance": 1e-2},
    "white+rw": {"noise_variance": 1e-2, "rate_random_walk": 1e-3},
    "white+gm+rw": {
        "noise_variance": 1e-2,
        "bias_variance": 1e-5,
        "time_constant": 200.0,
        "rate_random_walk": 3e-4,
    },
    "weak-rw": {"noise_variance": 1e-2, "rate_random_walk": 3e-5},
}
TERMS = {
    "noise_variance": "white",
    "bias_variance": "gauss_markov",
    "time_constant": "gauss_markov",
    "rate_random_walk": "random_walk",
}


def one_log(job):
    scenario, index, seed, n_samples, select, kinds, tau_max_record, auto = job
    if tau_max_record is not None:  # prior study: the upper edge of the time-constant prior
        import bayes_imu.noise.gauss_markov

        bayes_imu.noise.gauss_markov.BIAS_T_MAX_RECORD = tau_max_record
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.inference.selection import (
        candidate_terms,
        log_evidence,
        posterior_mode,
        select as choose,
    )
    from bayes_imu.inference.selection import CandidateScore
    from bayes_imu.inference.likelihood import LogPosterior, default_bounds
    from bayes_imu.inference.fit import _pilot, _starts, _covariance

    # independent streams
    rng = np.random.default_rng([seed, list(SCENARIOS).index(scenario), index])
    base = SCENARIOS[scenario]
    truth = {k: v * 10 ** rng.uniform(-0.5, 0.5) for k, v in base.items()}
    terms = tuple(dict.fromkeys(TERMS[k] for k in truth))
    model = NoiseModel(terms, 1.0 / RATE)
    from bayes_imu.noise.simulate import simulate_log

    y = simulate_log(model, truth, n_samples, rng=rng)
    allan = allan_variance(y, rate_hz=RATE)
    out = {"scenario": scenario, "truth": truth}
    for kind in kinds:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            res = fit_allan(allan, terms=terms, likelihood=kind, rng=rng)
        out[kind] = {
            name: (
                float(np.mean(res.draws(name) < truth[name])),
                bool(
                    np.quantile(res.draws(name), 0.05)
                    <= truth[name]
                    <= np.quantile(res.draws(name), 0.95)
                ),
            )
            for name in truth
        }
        out[kind + "_converged"] = bool(res.diagnostics["converged"]) and not caught
        if kind != "independent":  # drift bands (attitude, zero bias start) against the true drift
            from bayes_imu.drift.bands import drift_bands
            from bayes_imu.drift.closed_forms import drift_sigma

            # a flagged log's spread draws
            bands = drift_bands(res, BAND_TIMES, quantity="attitude", bias_start="zero", rng=rng)
            true = drift_sigma(
                BAND_TIMES,
                quantity="attitude",
                dt=1.0 / RATE,
                noise_variance=truth["noise_variance"],
                bias_variance=truth.get("bias_variance", 0.0),
                time_constant=truth.get("time_constant", np.inf),
                random_walk=truth.get("rate_random_walk", 0.0),
            ).total
            out[kind + "_band"] = (bands.quantile(0.05) <= true) & (true <= bands.quantile(0.95))
    if auto:  # as a user would: selection, stepwise search, adequacy, model averaging
        from bayes_imu.drift.bands import drift_bands
        from bayes_imu.drift.closed_forms import drift_sigma

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            res = fit_allan(allan, rng=rng)
        true = drift_sigma(
            BAND_TIMES,
            quantity="attitude",
            dt=1.0 / RATE,
            noise_variance=truth["noise_variance"],
            bias_variance=truth.get("bias_variance", 0.0),
            time_constant=truth.get("time_constant", np.inf),
            random_walk=truth.get("rate_random_walk", 0.0),
        ).total
        for models in ("averaged", "selected"):
            bands = drift_bands(
                res, BAND_TIMES, quantity="attitude", bias_start="zero", models=models, rng=rng
            )
            out["auto_" + models] = (bands.quantile(0.05) <= true) & (true <= bands.quantile(0.95))
        out["auto_selected_true"] = res.model.terms == model.terms
        out["auto_adequate"] = res.adequacy.adequate
        out["auto_two_biases"] = "gauss_markov_2" in res.model.terms
        out["auto_converged"] = res.diagnostics["converged"]
    if select:
        full = NoiseModel(
            ("white", "quantization", "bias_instability", "gauss_markov", "random_walk"), 1.0 / RATE
        )
        ref = _pilot(full, allan)
        cov = _covariance(full, ref, allan)
        ref_avar = full.avar(allan.m, ref)
        scores = []
        for cand in candidate_terms():
            cm = NoiseModel(cand, 1.0 / RATE)
            post = LogPosterior.from_covariance(
                cm, allan, cov, ref_avar, default_bounds(cm, allan), kind=kinds[0]
            )
            mode = posterior_mode(post, _starts(cm, allan, ref))
            u, phi = mode.u, mode.phi
            ev = log_evidence(post, u, rng=rng)
            lz, se, ess = ev.log_z, ev.se, ev.ess
            scores.append(CandidateScore(cm.terms, lz, se, ess, phi))
        out["selected"] = scores[choose(scores)].terms
        out["true_terms"] = model.terms
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n-logs", type=int, default=100, help="logs per scenario")
    parser.add_argument("--n-samples", type=int, default=2**17)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=20261121)
    parser.add_argument("--no-selection", action="store_true")
    parser.add_argument(
        "--tau-max-record",
        type=float,
        default=None,
        help="upper edge of the time-constant prior, in records (default: the package's)",
    )
    parser.add_argument(
        "--auto", action="store_true", help="also fit with terms='auto' (model-averaged bands)"
    )
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma list of scenarios")
    parser.add_argument("--likelihoods", default="copula,correlated,independent",
                        help="comma list; the first is used for the model-selection table")
    args = parser.parse_args(argv)
    kinds = tuple(args.likelihoods.split(","))
    scenarios = args.scenarios.split(",")
    jobs = [
        (
            s,
            i,
            args.seed,
            args.n_samples,
            not args.no_selection,
            kinds,
            args.tau_max_record,
            args.auto,
        )
        for s in scenarios
        for i in range(args.n_logs)
    ]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.processes) as pool:
        results = list(pool.map(one_log, jobs, chunksize=1))
    elapsed = time.perf_counter() - start
    print(f"{len(results)} logs of {args.n_samples} samples at {RATE:g} Hz, {elapsed:.0f} s\n")
    print(
        f"{'scenario':10s} {'likelihood':12s} {'parameter':17s} {'coverage90':>10s} {'+-se':>6s} "
        f"{'rank_p':>7s} {'converged':>9s}"
    )
    for scenario in scenarios:
        rows = [r for r in results if r["scenario"] == scenario]
        for kind in kinds:
            conv = np.mean([r[kind + "_converged"] for r in rows])
            for name in rows[0]["truth"]:
                ranks = np.array([r[kind][name][0] for r in rows])
                cover = np.mean([r[kind][name][1] for r in rows])
                se = np.sqrt(0.9 * 0.1 / len(rows))
                counts = np.histogram(ranks, bins=10, range=(0, 1))[0]
                from scipy import stats

                p = stats.chisquare(counts).pvalue
                print(
                    f"{scenario:10s} {kind:12s} {name:17s} {cover:10.3f} {se:6.3f} {p:7.3f} "
                    f"{conv:9.2f}"
                )
    print(
        f"\n{'scenario':10s} {'likelihood':12s} 90% attitude-drift band covers the true 1-sigma "
        f"drift at t = {BAND_TIMES.tolist()} s"
    )
    for scenario in scenarios:
        rows = [r for r in results if r["scenario"] == scenario]
        for kind in kinds:
            if kind + "_band" in rows[0]:
                cover = np.mean([r[kind + "_band"] for r in rows], axis=0)
                print(f"{scenario:10s} {kind:12s} " + " ".join(f"{c:6.3f}" for c in cover))
    if args.auto:
        print(
            f"\n{'scenario':12s} {'bands':9s} terms='auto': 90% band covers the true drift at t = "
            f"{BAND_TIMES.tolist()} s   true model selected / adequate / two biases selected / "
            "converged"
        )
        for scenario in scenarios:
            rows = [r for r in results if r["scenario"] == scenario]
            for models in ("averaged", "selected"):
                cover = np.mean([r["auto_" + models] for r in rows], axis=0)
                rates = ("auto_selected_true", "auto_adequate", "auto_two_biases", "auto_converged")
                extra = (
                    "   " + " / ".join(f"{np.mean([r[key] for r in rows]):.2f}" for key in rates)
                    if models == "averaged"
                    else ""
                )
                print(f"{scenario:12s} {models:9s} " + " ".join(f"{c:6.3f}" for c in cover) + extra)
    if not args.no_selection:
        print(
            f"\n{'scenario':10s} {'true model':28s} {'selected true':>13s}  most frequent wrong "
            "choice"
        )
        for scenario in scenarios:
            rows = [r for r in results if r["scenario"] == scenario]
            ok = np.mean([r["selected"] == r["true_terms"] for r in rows])
            wrong = [r["selected"] for r in rows if r["selected"] != r["true_terms"]]
            common = max(set(wrong), key=wrong.count) if wrong else "-"
            print(f"{scenario:10s} {'+'.join(rows[0]['true_terms']):28s} {ok:13.3f}  {common}")


if __name__ == "__main__":
    main()
