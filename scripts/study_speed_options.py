"""Speed options of issue 17, adopted or not, each measured and printed as a table, so that the
numbers the docs quote can be rerun:

1. ``--kernels``: the first drift grid in a fresh process, from the precompiled extension and from
   numba's JIT build of the same source (loaded from numba's on-disk cache; a first compile costs
   more).
2. ``--figures``: allan_fit.png as drawn (a fixed layout, plain-text log labels, minor ticks at 2
   and 5 of each decade), with matplotlib's layout pass added (``tight_layout``, as it was drawn
   before), with mathtext labels, and with matplotlib's minor ticks (2..9 of each decade), on a fit
   of the bench log and two real ADIS16405 ones (5 and 7 parameters; ``../shared``, where present);
   then corner.png as drawn (its own grid of
   :func:`corner.hist2d` panels, :func:`bayes_imu.report.plots._corner_grid`), the same grid with
   corner's own density shading (a polygon per bin, instead of one mesh), with
   matplotlib's mathtext tick labels instead of plain text
   (:func:`bayes_imu.report.plots.plain_log_formatter`), and as it was drawn before
   (``corner.corner``, plain labels, a tight bounding box), on the same fits. Each way is timed in
   turn in each of five rounds and its best round printed (:func:`_interleaved`): timed one way
   after another, the order alone moved a corner plot's time (docs/speed_under_load.md#figures).
3. ``--modes``: the mode searches of a fit (every posterior and its starts, as the model search
   passes them) by the Newton search that replaced BFGS
   (:func:`bayes_imu.inference.selection.newton_mode`) and by BFGS from the identity with
   central-difference gradients, as before: time, and how far the densest end points differ in
   ``-log p`` (negative: the Newton search found a denser mode), on the bench log and, where
   ``../shared`` has them, six real ADIS16405 channels. (A BFGS started from the inverse
   finite-difference Hessian, measured by an earlier version of this script, was about as fast as
   the identity start and found other local modes on three of five real channels; not adopted.)

4. ``--sampler``: the ensemble as the fit runs it
   (:func:`bayes_imu.inference.sampling.ensemble_sampler`: emcee's sampler and moves with less
   Python per step) against emcee's own classes, on the posteriors of the bench fit and two real
   ones: microseconds per step of 32 walkers, the likelihood's share, and whether the chains are the
   same bit for bit.
5. ``--seeds``: imu4 gyro x (seven parameters, two Gauss-Markov biases) fitted with seeds 0-7, with
   and without the relabel move, then with ``terms="auto"``: whether each sampler converged, its
   steps, R-hat, the share of draws in the region reached only by relabelling, and seconds.

    python scripts/study_speed_options.py [--kernels] [--figures] [--modes] [--sampler] [--seeds]
    (all without options)
"""

import argparse
import subprocess
import sys
import tempfile
import time
# a callable run with an attribute replaced (the ways a figure was drawn)
from unittest.mock import patch
from pathlib import Path

import numpy as np

# validate_real's DATA, bench_io's best_time
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_io import best_time  # noqa: E402  (best of n wall times)

FIRST_GRID = """
import sys, time
import numpy as np
t = time.perf_counter()
from bayes_imu.noise import euler_sums
if sys.argv[1] == "jit":
    import numba
    from bayes_imu.noise._sources import drift_rows
    euler_sums._drift_kernel = numba.njit(parallel=True, cache=True)(drift_rows)
k = np.arange(1.0, 1001.0); a = np.full(200, 1e-3)
none_a, none_k = np.zeros((1, a.size)), np.zeros((1, k.size))
euler_sums.drift_grid(1, k, a, np.ones_like(a), np.zeros_like(a), none_a, none_k, none_a, none_k)
print(time.perf_counter() - t, "numba" in sys.modules)
"""


def kernels():
    print(f"{'build':>12s} {'first drift grid in a process (s)':>34s} {'numba imported':>15s}")
    # the first JIT run fills numba's cache if it is empty
    for build in ("jit", "jit", "precompiled"):
        out = subprocess.run(
            [sys.executable, "-c", FIRST_GRID, build], capture_output=True, text=True, check=True
        )
        seconds, numba_loaded = out.stdout.split()
        print(f"{build:>12s} {float(seconds):34.2f} {numba_loaded:>15s}")


def _bench_fit():
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.inference.fit import fit_allan
    from bayes_imu.noise.avar_forms import NoiseModel
    from bayes_imu.noise.simulate import simulate_log

    truth = {"noise_variance": 0.25, "bias_variance": 1e-4, "time_constant": 100.0}
    # bench_fit's log
    y = simulate_log(NoiseModel(("white", "gauss_markov"), 0.01), truth, 1_000_000, rng=1)
    return allan_variance(y, rate_hz=100.0), fit_allan


def figures():
    import matplotlib.figure
    from matplotlib.ticker import LogFormatterSciNotation

    from bayes_imu.report import plots

    allan, fit_allan = _bench_fit()
    fit = fit_allan(allan, rng=0)
    plots.import_plotting()
    fits = [("bench log (synthetic)", fit)] + _real_fits(
        fit_allan, ((1, "gyro_x_dps"), (4, "gyro_x_dps"))
    )
    figure = matplotlib.figure.Figure
    savefig = figure.savefig

    def laid_out(self, *args, **kwargs):  # the layout pass the figure had before its fixed layout
        self.tight_layout()
        return savefig(self, *args, **kwargs)

    def allan_fit_ways(fit, path):
        def draw():
            plots.plot_allan_fit(fit, path, rng=0, unit="u")

        return [draw, patch.object(figure, "savefig", laid_out)(lambda: _quietly(draw)),
                patch.object(plots, "plain_log_formatter", LogFormatterSciNotation)(draw),
                patch.object(plots, "thin_log_minor_ticks", lambda axis: None)(draw)]

    _time_table(
        fits,
        ["allan_fit.png as drawn (s)", "with a tight_layout pass (s)", "mathtext labels (s)",
         "minor ticks 2..9 (s)"],
        allan_fit_ways,
    )
    _corner_ways(plots, fits)


def _interleaved(ways, rounds=5):
    """Best wall time of each callable in ``ways`` over ``rounds`` rounds, each round calling every
    way once in turn: no way gains from running after the others (caches, garbage) or loses to a
    busy moment."""
    best = [np.inf] * len(ways)
    for _ in range(rounds):
        for i, way in enumerate(ways):
            start = time.perf_counter()
            way()
            best[i] = min(best[i], time.perf_counter() - start)
    return best


def _real_allans(cases):
    """``(name, Allan variance)`` of real ADIS16405 channels ``(unit, column)`` (``../shared``),
    where present."""
    from bayes_imu.allan.estimator import allan_variance
    from bayes_imu.io.readers import read_log
    from validate_real import DATA

    out = []
    for unit, column in cases:
        path = DATA / f"adis_16405_imu{unit}.csv.gz"
        if path.exists():
            out.append(
                (
                    f"adis{unit} {column}",
                    allan_variance(read_log(path, column=column).values, rate_hz=100.0),
                )
            )
    return out


def _real_fits(fit_allan, cases=((1, "gyro_x_dps"),)):
    """Fits of real ADIS16405 channels (``../shared``), where present."""
    import warnings

    out = []
    for name, allan in _real_allans(cases):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out.append((name, fit_allan(allan, rng=0)))
    return out


def _corner_ways(plots, fits):
    """corner.png as drawn, with corner's own density shading (``ax.pcolor``, a polygon per bin:
    :func:`bayes_imu.report.plots._pair_panel`), with mathtext tick labels, and through
    ``corner.corner`` as before."""
    from matplotlib.ticker import LogFormatterSciNotation

    def pcolor_panel(corner, ax, x, y, ranges, bins):
        corner.hist2d(x, y, ax=ax, range=list(ranges), axes_scale=["log", "log"], bins=bins,
                      color="k")

    def ways(fit, path):
        def draw():
            plots.plot_corner(fit, path)

        return [draw, patch.object(plots, "_pair_panel", pcolor_panel)(draw),
                patch.object(plots, "plain_log_formatter", LogFormatterSciNotation)(draw),
                lambda: _quietly(lambda: _corner_before(plots, fit, path))]

    print()
    _time_table(
        fits, ["corner.png as drawn (s)", "density by pcolor (s)", "mathtext labels (s)",
               "corner.corner, before (s)"], ways
    )


def _time_table(fits, columns, ways):
    """One row per ``(name, fit)`` of ``fits``: its parameters and the times of the callables
    ``ways(fit, path)`` (:func:`_interleaved`), one per column, each drawing a figure to
    ``path``."""
    print(f"{'fit':>22s} {'parameters':>10s} " + " ".join(f"{c:>{len(c) + 1}s}" for c in columns))
    with tempfile.TemporaryDirectory() as folder:
        for name, fit in fits:
            times = _interleaved(ways(fit, Path(folder) / "figure.png"))
            print(f"{name:>22s} {fit.samples.shape[1]:10d} "
                  + " ".join(f"{t:{len(c) + 1}.3f}" for c, t in zip(columns, times)))


def _quietly(draw):
    """``draw()`` without the warnings the old ways print (tight_layout's with a legend outside the
    axes, corner's "Too few points to create valid contours" through logging): the table stays
    readable."""
    import logging
    import warnings

    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return draw()
    finally:
        logging.disable(logging.NOTSET)


def _corner_before(plots, fit, path):
    """corner.png as plot_corner drew it before its own grid: ``corner.corner`` on log axes, plain
    edge labels, and a tight bounding box (corner places its axis labels outside the figure)."""
    plt = plots.pyplot()
    corner = plots.import_corner()
    data, k = fit.samples, fit.samples.shape[1]
    fig = corner.corner(
        data,
        labels=list(fit.parameter_names),
        axes_scale="log",
        quantiles=[0.05, 0.5, 0.95],
        label_kwargs={"fontsize": 8},
        labelpad=0.15,
        max_n_ticks=3,
    )
    axes = np.array(fig.axes).reshape(k, k)
    for i in range(k):
        q = np.quantile(data[:, i], [0.05, 0.5, 0.95])
        axes[i, i].set_title(f"{q[1]:.4g}\n[{q[0]:.3g}, {q[2]:.3g}]", fontsize=7)
    for axis in [axes[-1, j].xaxis for j in range(k)] + [axes[i, 0].yaxis for i in range(1, k)]:
        axis.set_major_formatter(
            plots.plain_log_formatter(labelOnlyBase=False, minor_thresholds=(2, 0.5))
        )
        axis.set_minor_formatter(
            plots.plain_log_formatter(labelOnlyBase=False, minor_thresholds=(2, 0.5))
        )
    for ax in fig.axes:
        ax.tick_params(which="both", labelsize=6)
    fig.subplots_adjust(left=0.13, bottom=0.13)
    fig.savefig(path, dpi=90, bbox_inches="tight", pad_inches=0.1)
    plt.close(fig)


def _mode_searches(allan, fit_allan):
    """Every (posterior, starts) a fit's model search passes to posterior_mode."""
    import importlib

    selection = importlib.import_module("bayes_imu.inference.selection")
    fit_module = importlib.import_module("bayes_imu.inference.fit")
    original, calls = selection.posterior_mode, []

    def record(post, starts):
        calls.append((post, np.array(starts, float)))
        return original(post, starts)

    selection.posterior_mode = fit_module.posterior_mode = record
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit_allan(allan, rng=0, max_steps=500)
    finally:
        selection.posterior_mode = fit_module.posterior_mode = original
    return calls


def _mode_bfgs(post, starts):
    """The mode search before the Newton search (issue 17): BFGS from each start (scipy's identity
    start, central-difference gradient); returns ``-log p`` of the densest end point."""
    from scipy import optimize

    from bayes_imu.inference import selection as s

    best = np.inf
    for phi0 in np.atleast_2d(starts):
        u0 = s._to_u(np.asarray(phi0, float), post.bounds)
        if not np.isfinite(s._log_density_u(post, u0)[0]):
            continue
        res = optimize.minimize(
            s._neg_log_density,
            u0,
            args=(post,),
            jac=s._neg_gradient,
            method="BFGS",
            options={"gtol": 1e-5, "maxiter": 2000},
        )
        best = min(best, float(res.fun))
    return best


def modes():
    from bayes_imu.inference.selection import posterior_mode

    bench, fit_allan = _bench_fit()
    cases = [("bench log (synthetic)", bench)] + _real_allans(
        (
            (1, "gyro_x_dps"),
            (3, "gyro_y_dps"),
            (4, "gyro_x_dps"),
            (5, "accel_x_g"),
            (2, "accel_z_g"),
            (6, "gyro_z_dps"),
        )
    )
    print(
        f"{'log':>22s} {'searches':>8s} {'starts':>6s} {'bfgs_s':>7s} {'newton_s':>8s} "
        f"{'min d(-log p)':>13s} {'max d(-log p)':>13s} {'denser>0.01':>11s} {'less>0.01':>9s}"
    )
    for name, allan in cases:
        calls = _mode_searches(allan, fit_allan)
        start = time.perf_counter()
        ref = [_mode_bfgs(p, s) for p, s in calls]
        middle = time.perf_counter()
        new = [posterior_mode(p, s).neg_log_density for p, s in calls]
        end = time.perf_counter()
        d = np.array(new) - np.array(ref)
        n_starts = sum(len(np.atleast_2d(s)) for _, s in calls)
        print(
            f"{name:>22s} {len(calls):8d} {n_starts:6d} {middle - start:7.2f} {end - middle:8.2f} "
            f"{d.min():13.3g} {d.max():13.3g} {int(np.sum(d < -1e-2)):11d} "
            f"{int(np.sum(d > 1e-2)):9d}"
        )
    print(
        "d(-log p): the Newton search's end point minus BFGS's, per search (negative: Newton's is "
        "denser)"
    )


def sampler():
    """The ensemble as the fit runs it (:func:`bayes_imu.inference.sampling.ensemble_sampler`)
    against emcee's own EnsembleSampler, DEMove and StretchMove: 2000 steps of 32 walkers on the
    posterior each fit sampled, from the same walkers and seed; time per step, the likelihood's
    share, and whether the chains are the same."""
    import emcee

    from bayes_imu.inference.sampling import ensemble_sampler

    bench, fit_allan = _bench_fit()
    fits = [("bench log (synthetic)", fit_allan(bench, rng=0))] + _real_fits(
        fit_allan, ((1, "gyro_x_dps"), (4, "gyro_x_dps"))
    )

    def emcee_own(target, start, rng):
        moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]
        made = emcee.EnsembleSampler(
            start.shape[0], start.shape[1], target, vectorize=True, moves=moves
        )
        made.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
        return made

    print(
        f"{'fit':>22s} {'parameters':>10s} {'as run (us/step)':>17s} {'emcee own (us/step)':>20s} "
        f"{'likelihood (us/step)':>21s} {'same chains':>11s}"
    )
    steps = 2000
    for name, fit in fits:
        post = fit.chains.posterior
        # the last kept walkers: inside the box, spread as the posterior
        start = fit.chains.chain[-1]
        times, chains = [], []
        for make in (ensemble_sampler, emcee_own):
            best = np.inf
            for _ in range(3):
                made = make(post, start, np.random.default_rng(0))
                begin = time.perf_counter()
                made.run_mcmc(start, steps, progress=False)
                best = min(best, time.perf_counter() - begin)
            times.append(best / steps * 1e6)
            chains.append(made.get_chain())
        half = start[: start.shape[0] // 2]
        likelihood = 2 * best_time(lambda: post(half), 200) * 1e6
        print(
            f"{name:>22s} {start.shape[1]:10d} {times[0]:17.0f} {times[1]:20.0f} "
            f"{likelihood:21.0f} {str(bool(np.array_equal(*chains))):>11s}"
        )
    print("likelihood: the two vectorised calls of a step (each half of the ensemble), best of 200")
    _autocorr_checks()


def _autocorr_checks():
    """One convergence check's autocorrelation time
    (:func:`bayes_imu.inference.sampling.autocorr_time`) against emcee's ``integrated_time`` on
    chains of 32 walkers x 10 parameters (AR(1) walkers, phi = 0.99: an autocorrelation time of
    ~200 steps, as on the slow real fits) of 10 000 and 40 000 steps: best of 3 seconds each, and
    the largest relative difference."""
    from emcee.autocorr import integrated_time
    from scipy.signal import lfilter

    from bayes_imu.inference.sampling import autocorr_time

    rng = np.random.default_rng(0)
    print(f"\n{'chain (steps x walkers x parameters)':>38s} {'ours (s)':>9s} {'emcee (s)':>10s} "
          f"{'largest relative difference':>28s}")
    for steps in (10_000, 40_000):
        chain = lfilter([1.0], [1.0, -0.99], rng.standard_normal((steps, 32, 10)), axis=0)
        ours = best_time(lambda: autocorr_time(chain), 3)
        theirs = best_time(lambda: integrated_time(chain, tol=0), 3)
        difference = np.max(np.abs(autocorr_time(chain) / integrated_time(chain, tol=0) - 1.0))
        print(f"{f'{steps} x 32 x 10':>38s} {ours:9.3f} {theirs:10.3f} {difference:28.1e}")


def seeds():
    """imu4 gyro x (../shared; white + filtered white + two Gauss-Markov biases + random walk, seven
    parameters) fitted with seeds 0-7, with and without the relabel move
    (:func:`bayes_imu.inference.sampling.relabel_move`), then as a user would (``terms="auto"``,
    with the move): whether the sampler converged within 40 000 steps, its steps, R-hat, the share
    of draws with the slower bias switched off (its variance under a tenth of its median; the first
    bias then takes the slow time constant: the region the local moves reach only through a swap of
    labels) and the fit's seconds; then that region's mass by importance sampling, a check of the
    chain's weight there that does not rely on the chain mixing."""
    import contextlib
    import warnings

    from bayes_imu.inference.fit import fit_allan

    module = sys.modules[fit_allan.__module__]
    cases = _real_allans(((4, "gyro_x_dps"),))
    if not cases:
        print("skipped: ../shared not found")
        return
    name, allan = cases[0]
    two = ("white", "filtered_white", "gauss_markov", "gauss_markov_2", "random_walk")
    ways = (("no relabel", two, patch.object(module, "exchangeable_biases", lambda post: None)),
            ("relabel", two, contextlib.nullcontext()), ("auto", "auto", contextlib.nullcontext()))
    print(
        f"{'log':>16s} {'way':>10s} {'seed':>4s} {'converged':>9s} {'steps':>6s} {'r_hat':>6s} "
        f"{'switched':>9s} {'fit_s':>6s}  model"
    )
    check = None
    for way, terms, replaced in ways:
        with replaced:
            for seed in range(8):
                start = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    fit = fit_allan(allan, terms=terms, rng=seed)
                seconds = time.perf_counter() - start
                d, names = fit.diagnostics, fit.model.parameter_names
                share = (np.mean(_switched_off(fit.samples[:, names.index("bias_variance_2")]))
                         if "bias_variance_2" in names else np.nan)
                print(
                    f"{name:>16s} {way:>10s} {seed:4d} {str(d['converged']):>9s} {d['n_steps']:6d} "
                    f"{d['rhat_max']:6.3f} {share:9.3f} {seconds:6.1f}  "
                    f"{' + '.join(fit.model.terms)}"
                )
                if way == "relabel" and seed == 0:
                    check = fit
    _region_mass_by_importance(check)


def _switched_off(variance, reference=None):
    """Where the slower bias is switched off: its variance under a tenth of the median of
    ``reference`` (its posterior draws; ``variance`` itself by default)."""
    return variance < 0.1 * np.median(variance if reference is None else reference)


def _region_mass_by_importance(fit, n_draws=200_000, rounds=3):
    """The mass of the switched-off region by importance sampling, independent of the chain's
    weights: the proposal is an equal mixture of two Student t (4 dof, covariance inflated 1.5^2, in
    the fit's logit coordinates) fitted to the chain's draws in and out of the region; the
    self-normalised estimate and its standard error, from ``rounds`` independent sets of draws."""
    from bayes_imu.inference import selection

    post, names = fit.chains.posterior, fit.model.parameter_names
    chain = fit.chains.chain.reshape(-1, post.n_par)
    column = names.index("bias_variance_2")
    draws_v2 = fit.samples[:, column]
    off = _switched_off(np.exp(chain[:, column]), draws_v2)
    u = selection._to_u(chain, post.bounds)
    parts = [selection._StudentT(u[m].mean(0), 1.5**2 * np.cov(u[m].T), 4.0) for m in (~off, off)]
    rng = np.random.default_rng(0)
    print(f"\nswitched-off region of the relabel fit with seed 0: {np.mean(off):.3f} of its "
          "kept draws; by importance sampling (two-t proposal from the chain's two regions):")
    for _ in range(rounds):
        first = rng.random(n_draws) < 0.5
        draws = np.where(first[:, None], parts[0].rvs(n_draws, rng), parts[1].rvs(n_draws, rng))
        log_w = selection._log_density_u(post, draws) - np.logaddexp(
            np.log(0.5) + parts[0].logpdf(draws), np.log(0.5) + parts[1].logpdf(draws)
        )
        w = np.exp(log_w - log_w.max())
        w /= w.sum()
        inside = _switched_off(np.exp(selection.to_phi(draws, post.bounds)[:, column]), draws_v2)
        share = float(np.sum(w * inside))
        # self-normalised estimate's standard error
        error = np.sqrt(np.sum(w**2 * (inside - share) ** 2))
        print(f"  {share:.3f} +- {error:.3f} (effective draws {1 / np.sum(w**2):.0f})")


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--kernels", action="store_true")
    parser.add_argument("--figures", action="store_true")
    parser.add_argument("--modes", action="store_true")
    parser.add_argument("--sampler", action="store_true")
    parser.add_argument("--seeds", action="store_true")
    args = parser.parse_args(argv)
    names = ("kernels", "figures", "modes", "sampler", "seeds")
    chosen = [name for name in names if getattr(args, name)] or list(names)
    for name in chosen:
        print(f"\n== {name}")
        globals()[name]()


if __name__ == "__main__":
    main()
