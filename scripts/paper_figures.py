"""Reproduce Figs 1-11 of Wall & Bevly with the package's public API, formulas against Monte Carlo.

Writes PNGs into ``--out`` (default ``docs/paper_figures``) and prints, for every Monte Carlo
figure, the worst deviation between the exact variance formula and the simulated variance,
in standard errors of the simulated variance (``var * sqrt(2 / (n - 1))`` for ``n`` paths;
the points along a curve are correlated, so a worst of ~3 over a curve is ordinary).

* Fig 1: autocorrelation of a simulated Gauss-Markov process, sigma^2 = 4, tau = 300 s
  (``autocorrelation_fit``: the numerical autocorrelation and the fitted eq 4).
* Figs 2-3: Allan deviation of a simulated low-grade gyro with its analytical curve, and a
  low- against a high-grade gyro (``allan_variance``, ``NoiseModel``).
* Figs 4-7, 9-10: variance of the single / double Euler integral of white noise (eqs 5,
  11), of a Gauss-Markov process (eqs 22, 29) and of their sum (eqs 23, 30), each against
  ``--paths`` Monte Carlo runs of the paper's own recursion (zero initial state,
  ``b_k = A b_{k-1} + dt w_{k-1}``, ``A = 1 - dt/tau``). Where the printed formula is wrong
  (eqs 11 and 29, docs/errata.md) it is drawn too, dashed.
* Figs 8 and 11: the 1-sigma contribution of each error source and their total.

    python scripts/paper_figures.py [--out DIR] [--paths 2000] [--quick]
"""

import argparse
import sys
from pathlib import Path

import numpy as np

DT = 0.01          # s (100 Hz)
Q_WHITE = 1e-4     # white-noise variance per sample (arbitrary units^2)
TAU = 10.0         # Gauss-Markov time constant (s): 1000 samples
# driving-noise variance sigma_omega^2: bias drift overtakes white noise after a few s
Q_MARKOV = 3e-5
SIGMA2_FIG1, TAU_FIG1 = 4.0, 300.0


def printed_eq11(k, dt, q):
    """Eq 11 as printed (an off-by-one: the sum of n^2 runs to k instead of k - 1)."""
    return dt**4 * q * k * (k + 1) * (2 * k + 1) / 6.0


def printed_eq29(k, dt, q, A):
    """Eq 29 as printed: dt**3 for dt**6, no denominator, wrong c1 and c3 (docs/errata.md)."""
    c1 = -2 - 4 * A + 2 * A**4 + 4 * A**3 + 2
    c2 = 9 - 12 * A - 6 * A**2 + 12 * A**3 - 3 * A**4
    c3 = -13 + 8 * A - 8 * A**3 + A**4
    c4 = 6 - 12 * A**2
    Ak = A**k
    return dt**3 * q * (c1 * k**3 + c2 * k**2 + (c3 + 12 * Ak - 12 * Ak * A**2) * k
                        + (c4 - 12 * Ak + 12 * Ak * A**2 + 6 * Ak**2))


def monte_carlo(n_paths, n_steps, rng):
    """Paths of the paper's recursion: white w, Markov b and their first and second Euler integrals.

    Returns the sample variances over paths at k = 0 .. n_steps, for each of
    ``white1, white2, markov1, markov2, sensor1, sensor2``.
    """
    A = 1.0 - DT / TAU
    w = rng.standard_normal((n_paths, n_steps)) * np.sqrt(Q_WHITE)
    u = rng.standard_normal((n_paths, n_steps)) * np.sqrt(Q_MARKOV)
    b = np.zeros((n_paths, n_steps + 1))
    for k in range(n_steps):
        b[:, k + 1] = A * b[:, k] + DT * u[:, k]
    out = {}
    for name, x in (("white", w), ("markov", b[:, :-1]), ("sensor", w + b[:, :-1])):
        # v_k, k = 0..n
        v = np.concatenate([np.zeros((n_paths, 1)), DT * np.cumsum(x, axis=1)], axis=1)
        p = np.concatenate([np.zeros((n_paths, 1)), DT * np.cumsum(v[:, :-1], axis=1)], axis=1)
        out[name + "1"], out[name + "2"] = v.var(axis=0, ddof=1), p.var(axis=0, ddof=1)
    return out


def formulas(k):
    from bayes_imu import euler_variance

    out = {}
    for order in (1, 2):
        white = euler_variance("white", order, k, dt=DT, noise_variance=Q_WHITE)
        markov = euler_variance(
            "gauss_markov", order, k, dt=DT, noise_variance=Q_MARKOV, time_constant=TAU
        )
        out[f"white{order}"], out[f"markov{order}"], out[f"sensor{order}"] = (
            white,
            markov,
            white + markov,
        )
    return out


def worst_standard_errors(formula, simulated, n_paths):
    """Largest |simulated - formula| in standard errors of the simulated variance (k >= 1)."""
    ok = simulated > 0
    se = simulated[ok] * np.sqrt(2.0 / (n_paths - 1))
    return float(np.max(np.abs(simulated[ok] - formula[ok]) / se))


def fig1(out, rng, quick):
    from bayes_imu import NoiseModel, simulate_log
    from bayes_imu.allan.autocorr import autocorrelation_fit

    rate = 1.0
    n = 40_000 if quick else 300_000  # 133 or 1000 time constants
    model = NoiseModel(("gauss_markov",), 1.0 / rate)
    y = simulate_log(model, {"bias_variance": SIGMA2_FIG1, "time_constant": TAU_FIG1}, n, rng=rng)
    res = autocorrelation_fit(y, rate_hz=rate, max_lag_s=5 * TAU_FIG1)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(res.lag_s, res.acf, lw=1, label="numerical autocorrelation (simulated data)")
    ax.plot(
        res.lag_s,
        SIGMA2_FIG1 * np.exp(-res.lag_s / TAU_FIG1),
        "k--",
        label=r"eq 4, $\sigma^2=4$, $\tau=300$ s",
    )
    ax.plot(res.lag_s, res.bias_variance * np.exp(-res.lag_s / res.time_constant), "r:",
            label=f"fit: $\\sigma^2$={res.bias_variance:.2f}, $\\tau$={res.time_constant:.0f} s")
    ax.set(
        xlabel="lag T (s)", ylabel="R(T)", title="Fig 1: autocorrelation of simulated Markov data"
    )
    ax.legend()
    _save(fig, out / "fig01_autocorrelation.png")
    print(
        f"Fig 1: fitted sigma^2 = {res.bias_variance:.3f} (true 4), tau = {res.time_constant:.1f} "
        f"s (true 300), record = {res.record_over_tau:.0f} tau"
    )


def fig2_3(out, rng, quick):
    from bayes_imu import NoiseModel, allan_variance, simulate_log

    n = 2**18 if quick else 2**21
    low = NoiseModel(("white", "gauss_markov"), DT)
    high = NoiseModel(("white",), DT)
    p_low = {"noise_variance": 0.25, "bias_variance": 1e-3, "time_constant": 30.0}
    p_high = {"noise_variance": 4e-4}
    plt = pyplot()
    curves = {}
    for name, model, p in (("low grade", low, p_low), ("high grade", high, p_high)):
        res = allan_variance(simulate_log(model, p, n, rng=rng), rate_hz=1 / DT)
        curves[name] = (res, model.avar(res.m, p))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    res, model_avar = curves["low grade"]
    ax.errorbar(
        res.tau,
        res.adev,
        yerr=[res.adev - res.adev_low, res.adev_high - res.adev],
        fmt="o",
        ms=3,
        label="simulated low-grade gyro",
    )
    ax.loglog(res.tau, np.sqrt(model_avar), "k-", label="analytical (white + Gauss-Markov)")
    ax.set(
        xlabel="averaging time (s)",
        ylabel="Allan deviation (deg/s)",
        title="Fig 2: Allan deviation, sample gyro",
    )
    ax.legend()
    _save(fig, out / "fig02_allan_sample_gyro.png")
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, (res, model_avar) in curves.items():
        ax.loglog(res.tau, res.adev, "o", ms=3, label=f"{name}: simulated")
        ax.loglog(res.tau, np.sqrt(model_avar), "-", lw=1, label=f"{name}: analytical")
    ax.set(
        xlabel="averaging time (s)",
        ylabel="Allan deviation (deg/s)",
        title="Fig 3: gyro grade comparison",
    )
    ax.legend()
    _save(fig, out / "fig03_allan_grade_comparison.png")
    for name, (res, model_avar) in curves.items():
        inside = np.mean((res.avar_low <= model_avar) & (model_avar <= res.avar_high))
        print(
            f"Fig {2 if name == 'low grade' else 3}: {name}: analytical AVAR inside the 68% "
            f"interval at {inside:.0%} of {res.m.size} cluster sizes"
        )


def monte_carlo_figures(out, rng, n_paths, n_steps):
    k = np.arange(n_steps + 1)
    t = k * DT
    sim = monte_carlo(n_paths, n_steps, rng)
    exact = formulas(k)
    A = 1.0 - DT / TAU
    printed = {"white2": printed_eq11(k, DT, Q_WHITE), "markov2": printed_eq29(k, DT, Q_MARKOV, A)}
    specs = [  # figure, key, title, equation
        (4, "white1", "single integrated white noise", "eq 5"),
        (5, "white2", "double integrated white noise", "eq 11 corrected"),
        (6, "markov1", "integrated Markov process", "eq 22"),
        (7, "sensor1", "integrated sensor measurement", "eq 23"),
        (9, "markov2", "double integrated Markov process", "eq 29 corrected"),
        (
            10,
            "sensor2",
            "double integrated sensor measurement",
            "eq 30 (with eqs 11, 29 corrected)",
        ),
    ]
    plt = pyplot()
    worst = {}
    for number, key, title, eq in specs:
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        ax.plot(
            t[1:], np.sqrt(sim[key][1:]), lw=2, alpha=0.6, label=f"Monte Carlo, {n_paths} paths"
        )
        ax.plot(t[1:], np.sqrt(exact[key][1:]), "k--", lw=1, label=eq)
        if key in printed:
            ax.plot(t[1:], np.sqrt(np.abs(printed[key][1:])), "r:", lw=1.5,
                    label=f"{'eq 11' if key == 'white2' else 'eq 29'} as printed (|value|)")
        ax.set(
            xscale="log",
            yscale="log",
            xlabel="time (s)",
            ylabel="1-sigma",
            title=f"Fig {number}: {title}",
        )
        ax.legend()
        _save(fig, out / f"fig{number:02d}_{key}.png")
        worst[number] = worst_standard_errors(exact[key], sim[key], n_paths)
        extra = ""
        if key in printed:
            extra = (
                f"; printed form: {worst_standard_errors(printed[key], sim[key], n_paths):.3g} "
                "standard errors"
            )
        print(
            f"Fig {number}: {title}: worst deviation {worst[number]:.2f} standard errors "
            f"({eq}){extra}"
        )
    # Figs 8 and 11 need no simulation: the exact formulas on a log grid out to 100 s
    k_long = np.unique(np.geomspace(1, 100.0 / DT, 400).astype(np.int64))
    t_long, long = k_long * DT, formulas(k_long)
    for number, order, quantity in ((8, 1, "angle or velocity"), (11, 2, "position")):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        white, markov = long[f"white{order}"], long[f"markov{order}"]
        ax.loglog(t_long, np.sqrt(white), label="white noise")
        ax.loglog(t_long, np.sqrt(markov), label="bias drift (Gauss-Markov)")
        ax.loglog(t_long, np.sqrt(white + markov), "k", label="total")
        cross = t_long[np.argmax(markov > white)]
        ax.axvline(cross, color="grey", ls=":", label=f"bias drift dominates after {cross:.2f} s")
        ax.set(
            xlabel="time (s)",
            ylabel="1-sigma",
            title=f"Fig {number}: error source contribution ({quantity})",
        )
        ax.legend()
        _save(fig, out / f"fig{number:02d}_contributions.png")
        print(f"Fig {number}: bias drift dominates the {quantity} error after {cross:.2f} s")
    return worst


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    fig.clf()
    import matplotlib.pyplot as plt

    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "paper_figures"
    )
    parser.add_argument(
        "--paths", type=int, default=2000, help="Monte Carlo paths (the paper: 2000)"
    )
    parser.add_argument(
        "--steps", type=int, default=3000, help="Euler steps per path (30 s at 100 Hz)"
    )
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument(
        "--quick", action="store_true", help="smoke run: 200 paths, 300 steps, shorter logs"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.paths, args.steps = 200, 300
    args.out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    fig1(args.out, rng, args.quick)
    fig2_3(args.out, rng, args.quick)
    worst = monte_carlo_figures(args.out, rng, args.paths, args.steps)
    print(f"wrote 11 figures into {args.out}; worst Monte Carlo deviation over Figs 4-7, 9-10: "
          f"{max(worst.values()):.2f} standard errors")
    return 0


if __name__ == "__main__":
    sys.exit(main())
