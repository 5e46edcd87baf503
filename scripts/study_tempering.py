"""Are converged fits right? emcee's ensemble and the tempered one, with and without the jump
move, against a long reference.

For each real log named (the shared ADIS16405 logs, read in place; exits cleanly when absent), the
model the fit selects with seed 0 is fixed, and the fit is run with seeds 0..S-1 up to three
times: the code as it is (``jump``: the tempered ensemble where the fit tempers, with the jump
move of :mod:`bayes_imu.inference.mixture_proposal`), the tempered ensemble without the jump move
(``tempered``: ``bayes_imu.inference.fit.JUMP_PILOT = 0``, the code before the sixteenth session)
and emcee's ensemble only (``emcee``: ``bayes_imu.inference.fit.TEMPER_BELOW = 0``). The
reference is the posterior sampled by the tempered ensemble without the jump move (so independent
of it) for much longer: ``--reference-runs`` runs of ``--reference-steps`` steps each
from the seed-0 fit's draws, a fifth of each dropped, pooled. Each fit's 5%, 50% and 95% quantiles
of every log-parameter are compared with the reference's; the error is in the reference's posterior
standard deviations. A fit that says it converged should be within a few tenths of one
(bulk ESS 400: a quantile's Monte Carlo spread is about 0.06-0.1 standard deviations), if the
reference is right: it is itself a chain, and on a posterior with a small second region it is
right only as far as its runs have mixed (on ADIS16405 imu4 accelerometer z no importance sampler
tried gave an independent answer: effective sizes of 34 to 11 000 and tail quantiles that
disagree; docs/speed_under_load.md, thirteenth session).

    python scripts/study_tempering.py [--logs 4:accel_z_g,5:accel_x_g] [--seeds 6]
        [--reference-steps 60000] [--reference-runs 4] [--samplers jump,tempered,emcee]
        [--lengths 1500,3000,5000,8000,12000]

With ``--lengths``, each log also gets, per seed, tempered chains of fixed lengths from the fit's
own start (its walkers as the fit draws them; the fit itself is not run): without the jump move,
and with it after its pilot (``JUMP_PILOT`` steps, discarded), each chain's first tenth dropped;
one row per seed and chain with the largest quantile error at each length: what
``bayes_imu.inference.fit.JUMP_MIN_KEPT`` rests on (a short chain's autocorrelation time cannot
see a region it has not visited).

Prints one row per fit (sampler, seed, converged, steps run in all, the discarded ones included,
seconds, the largest error and its parameter) and, per sampler, how many fits converged and the
largest and median error among them.
"""

import argparse
import importlib
import sys
import time
import warnings
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data_real" / "smac_imudata"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=SHARED)
    parser.add_argument("--logs", default="4:accel_z_g,5:accel_x_g")
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--reference-steps", type=int, default=60000)
    parser.add_argument("--reference-runs", type=int, default=4)
    parser.add_argument("--lengths", default="",
                        help="fixed chain lengths (steps) to compare, comma-separated (none by "
                             "default)")
    parser.add_argument("--samplers", default="jump,tempered,emcee",
                        help="which to run: jump, tempered, emcee, comma-separated (all three by "
                             "default)")
    args = parser.parse_args(argv)
    logs = [(args.data / f"adis_16405_imu{u}.csv.gz", c)
            for u, c in (item.split(":") for item in args.logs.split(","))]
    missing = sorted({str(p) for p, _ in logs if not p.exists()})
    if missing:
        print(f"shared real logs not found ({', '.join(missing)}): nothing to do")
        return 0

    from bayes_imu.allan.pipeline import LogSource, allan_from_source
    from bayes_imu.errors import ConvergenceWarning
    from bayes_imu.inference.fit import exchangeable_biases
    from bayes_imu.inference.tempering import TemperedEnsemble

    fit_module = importlib.import_module("bayes_imu.inference.fit")
    temper_below, jump_pilot = fit_module.TEMPER_BELOW, fit_module.JUMP_PILOT
    settings = {"jump": (temper_below, jump_pilot), "tempered": (temper_below, 0),
                "emcee": (0.0, jump_pilot)}
    q = np.array([0.05, 0.5, 0.95])
    worst = {label: [] for label in settings}
    fits = dict.fromkeys(settings, 0)
    print(f"{'log':>24s} {'column':>11s} {'sampler':>8s} {'seed':>4s} {'conv':>5s} {'steps':>6s} "
          f"{'fit_s':>6s} {'max_err_sd':>10s}  parameter")
    for path, column in logs:
        allan = allan_from_source(LogSource(log=path, column=column, rate=100.0)).results[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            first = fit_module.fit_allan(allan, rng=0)
        terms = first.model.terms
        post = first.chains.posterior
        names = list(first.model.parameter_names) + (["model_discrepancy"] if post.discrepancy
                                                      else [])
        pooled = []
        start = time.perf_counter()
        for run in range(args.reference_runs):
            draws = first.chains.chain.reshape(-1, post.n_par)
            rng = np.random.default_rng(1000 + run)
            walkers = draws[rng.choice(draws.shape[0], 32, replace=False)]
            sampler = TemperedEnsemble(post, walkers, rng, exchangeable_biases(post),
                                       capacity=args.reference_steps)
            sampler.run(args.reference_steps)
            kept = sampler.get_chain(discard=args.reference_steps // 5)
            pooled.append(kept.reshape(-1, post.n_par))
        reference = np.concatenate(pooled)
        ref_q, ref_sd = np.quantile(reference, q, axis=0), reference.std(axis=0)
        print(f"# {path.name} {column}: {' + '.join(terms)}; reference {args.reference_runs} x "
              f"{args.reference_steps} tempered steps in {time.perf_counter() - start:.0f} s",
              flush=True)
        if args.lengths:
            lengths = [int(v) for v in args.lengths.split(",")]
            for seed in range(args.seeds):
                for label, errors in _fixed_lengths(fit_module, allan, terms, seed, lengths,
                                                    ref_q, ref_sd, q).items():
                    print(f"{path.name:>24s} {column:>11s} {label:>8s} {seed:4d} fixed lengths "
                          + ", ".join(f"{n}: {e:.2f}" for n, e in zip(lengths, errors)),
                          flush=True)
        for label, (below, pilot) in settings.items():
            if label not in args.samplers.split(","):
                continue
            fit_module.TEMPER_BELOW, fit_module.JUMP_PILOT = below, pilot
            try:
                for seed in range(args.seeds):
                    start = time.perf_counter()
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", ConvergenceWarning)
                        result = fit_module.fit_allan(allan, terms=terms, rng=seed)
                    seconds = time.perf_counter() - start
                    if result.chains.posterior.n_par != post.n_par:
                        print(f"{path.name:>24s} {column:>11s} {label:>8s} {seed:4d} (another "
                              "discrepancy choice: not compared)")
                        continue
                    log_draws = np.log(result.samples)
                    err = np.abs(np.quantile(log_draws, q, axis=0) - ref_q) / ref_sd
                    k = int(np.argmax(err.max(axis=0)))
                    d = result.diagnostics
                    fits[label] += 1
                    if d["converged"]:
                        worst[label].append(float(err.max()))
                    steps = (d["n_steps"] + d.get("steps_before_tempering", 0)
                             + d.get("jump_pilot_steps", 0))
                    print(f"{path.name:>24s} {column:>11s} {label:>8s} {seed:4d} "
                          f"{str(d['converged']):>5s} {steps:6d} {seconds:6.1f} "
                          f"{err.max():10.2f}  {names[k]}", flush=True)
            finally:
                fit_module.TEMPER_BELOW, fit_module.JUMP_PILOT = temper_below, jump_pilot
    for label, errors in worst.items():
        if not fits[label]:
            continue
        if errors:
            print(f"{label}: {len(errors)} of {fits[label]} fits converged, largest quantile error "
                  f"{max(errors):.2f} posterior standard deviations "
                  f"(median {np.median(errors):.2f})")
        else:
            print(f"{label}: no converged fit of {fits[label]}")
    return 0


class _Started(Exception):
    """Raised by the fit's sampler stand-in once it has the fit's start."""


def _fixed_lengths(fit_module, allan, terms, seed, lengths, ref_q, ref_sd, q):
    """``{"tempered": errors, "jump": errors}``: the largest quantile error (reference standard
    deviations) of tempered chains of each length from the seed's fit's own start, without and
    with the jump move (after its pilot), the first tenth of each dropped."""
    from bayes_imu.inference.mixture_proposal import fit_student_mixture
    from bayes_imu.inference.tempering import TemperedEnsemble

    seen = {}

    def capture(post, start, rng, *args, **kwargs):
        seen.update(post=post, start=start, rng=rng)
        raise _Started

    sample = fit_module._sample
    fit_module._sample = capture
    try:
        fit_module.fit_allan(allan, terms=terms, rng=seed)
    except _Started:
        pass
    finally:
        fit_module._sample = sample
    post, rng = seen["post"], seen["rng"]
    widths = np.diff(post.bounds, axis=1).ravel()
    out = {}
    for label in ("tempered", "jump"):
        sampler = TemperedEnsemble(post, seen["start"], rng, fit_module.exchangeable_biases(post),
                                   capacity=max(lengths) + fit_module.JUMP_PILOT)
        if label == "jump":
            sampler.run(fit_module.JUMP_PILOT)
            pilot = sampler.get_chain(discard=fit_module.JUMP_PILOT // 2)
            sampler.add_jump(fit_student_mixture(pilot.reshape(-1, post.n_par), rng,
                                                 scale=widths), fit_module.JUMP_SHARE)
        sampler.run(max(lengths))
        chain = sampler.get_chain()
        out[label] = [float((np.abs(np.quantile(chain[n // 10:n].reshape(-1, post.n_par), q,
                                                axis=0) - ref_q) / ref_sd).max())
                      for n in lengths]
    return out


if __name__ == "__main__":
    sys.exit(main())
