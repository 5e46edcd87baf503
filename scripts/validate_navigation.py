"""Validation of the navigation channel (docs/navigation.md): a published grade table and coverage.

(a) ``grades``: the three IMU error models of P. D. Groves' companion software for *Principles of
    GNSS, Inertial, and Multisensor Integrated Navigation Systems*, 2nd ed. (Artech House, 2013;
    MATLAB scripts ``Inertial_Demo_1`` tactical, ``Inertial_Demo_2`` aviation, ``Inertial_Demo_3``
    consumer grade, BSD licence, 2012): accelerometer x bias and noise root PSD, gyro y bias and
    noise root PSD (the channel along x). Each bias is a random constant of that standard
    deviation (a Gauss-Markov term of time constant 1e12 s, stationary start, no calibration:
    what is left after an alignment that did not estimate it), the noise white at 100 Hz. The
    1-sigma error of one horizontal channel at 10 s, 60 s, 300 s and 1 h from
    ``Term.nav_variance`` against an independent covariance propagation: the loop with a constant
    bias state and the held noise sample as states, discretised by Van Loan's block matrix
    exponential (``scipy.linalg.expm``) and stepped one sample at a time.
(b) ``coverage``: simulated gyro + accelerometer logs (white, Gauss-Markov, rate random walk; 100
    Hz, ``--hours`` long, parameters drawn per pair), each fitted with ``bayes_imu.fit``
    (model-averaged), then the 90 % bands of ``position`` and ``velocity`` from
    ``navigation_bands`` (Schuler on, calibrated over 60 s) at 10 s - 20 min against the exact
    1-sigma error of the true parameters. Seeds ``--seed`` .. ``--seed + pairs - 1``.

Run: ``nice python scripts/validate_navigation.py grades`` (seconds) and
``nice python scripts/validate_navigation.py coverage --pairs 12`` (minutes).
"""

import argparse
import sys
import time

import numpy as np
import scipy.linalg as sl

from bayes_imu.drift.nav_bands import navigation_bands
from bayes_imu.drift.navigation import GRAVITY, NavLoop
from bayes_imu.inference.fit import fit
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.model import REGISTRY
from bayes_imu.noise.simulate import simulate_log

MICRO_G = 9.80665e-6
DEG_PER_ROOT_HOUR = np.pi / 180.0 / 60.0
DEG_PER_HOUR = np.pi / 180.0 / 3600.0
#: Groves' companion software, channel x: accelerometer x bias (micro-g), gyro y bias (deg/h),
#: noise root PSDs
GRADES = {
    "aviation (Inertial_Demo_2)": {"b_a": 30.0, "b_g": 0.0013, "n_a": 20.0, "n_g": 0.002},
    "tactical (Inertial_Demo_1)": {"b_a": 900.0, "b_g": 13.0, "n_a": 100.0, "n_g": 0.01},
    "consumer (Inertial_Demo_3)": {"b_a": 9000.0, "b_g": 260.0, "n_a": 1000.0, "n_g": 1.0},
}
HORIZONS = (10.0, 60.0, 300.0, 3600.0)
RATE = 100.0
LONG_T = 1e12  # a Gauss-Markov time constant standing for a constant bias [s]


def grade_terms(grade, dt):
    """SI parameters: white per-sample variance (density^2 / dt) and the constant bias as a GM."""
    g = GRADES[grade]
    na, ng = g["n_a"] * MICRO_G, g["n_g"] * DEG_PER_ROOT_HOUR
    return (
        {
            "noise_variance": ng**2 / dt,
            "bias_variance": (g["b_g"] * DEG_PER_HOUR) ** 2,
            "time_constant": LONG_T,
        },
        {
            "noise_variance": na**2 / dt,
            "bias_variance": (g["b_a"] * MICRO_G) ** 2,
            "time_constant": LONG_T,
        },
    )


def closed_form(grade, dt=1.0 / RATE):
    """``(n_t,)`` 1-sigma position error from the terms' nav_variance (white + constant bias)."""
    k = np.round(np.asarray(HORIZONS) / dt)
    total = np.zeros(k.size)
    for sensor, params in zip(("gyro", "accel"), grade_terms(grade, dt)):
        loop = NavLoop(sensor)
        p = {key: np.asarray(v) for key, v in params.items()}
        for name in ("white", "gauss_markov"):
            total += REGISTRY[name].nav_variance(loop, k, p, dt, bias_start="stationary")[:, 2]
    return np.sqrt(total)


def van_loan(grade, dt=1.0 / RATE):
    """The same channel by Van Loan discretisation and one-sample covariance steps.

    States (tilt, v, p, b_g, b_a, u_g, u_a): the loop, the two constant biases and the two
    noise samples held over the period (derivative 0). ``expm([[F, 0], [0, 0]] dt)`` is the exact
    one-step map; each step the held samples are replaced by fresh ones of variance ``q``.
    """
    gyro, accel = grade_terms(grade, dt)
    radius = 6.371e6
    f = np.zeros((7, 7))
    f[0, 1] = 1.0 / radius  # tilt' = v/R + b_g + u_g
    f[0, 3] = f[0, 5] = 1.0
    f[1, 0] = -GRAVITY  # v' = -g tilt + b_a + u_a
    f[1, 4] = f[1, 6] = 1.0
    f[2, 1] = 1.0
    # Van Loan: expm([[-F, Q], [0, F']] dt) gives Phi = lower-right' (no continuous noise: Q = 0)
    block = np.zeros((14, 14))
    block[:7, :7] = -f
    block[7:, 7:] = f.T
    phi = sl.expm(block * dt)[7:, 7:].T
    p = np.zeros((7, 7))
    p[3, 3], p[4, 4] = gyro["bias_variance"], accel["bias_variance"]
    fresh = np.diag([0, 0, 0, 0, 0, gyro["noise_variance"], accel["noise_variance"]])
    keep = np.diag([1.0, 1, 1, 1, 1, 0, 0])
    targets = {int(round(t / dt)): t for t in HORIZONS}
    out = {}
    p = keep @ p @ keep + fresh  # the samples held over the first period
    for step in range(1, max(targets) + 1):
        p = phi @ p @ phi.T
        if step in targets:
            out[targets[step]] = np.sqrt(p[2, 2])
        p = keep @ p @ keep + fresh
    return np.array([out[t] for t in HORIZONS])


def grades():
    print(
        "| grade (Groves 2nd ed. software) | b_a (ug) | b_g (deg/h) | VRW (ug/rtHz) | "
        "ARW (deg/rth) | " + " | ".join(f"{t:g} s" for t in HORIZONS) + " | max rel. diff |"
    )
    print("|---" * (6 + len(HORIZONS)) + "|")
    worst = 0.0
    for grade, g in GRADES.items():
        ours, ref = closed_form(grade), van_loan(grade)
        rel = float(np.max(np.abs(ours / ref - 1.0)))
        worst = max(worst, rel)
        cells = " | ".join(f"{o:.4g} ({r:.4g})" for o, r in zip(ours, ref))
        print(
            f"| {grade} | {g['b_a']:g} | {g['b_g']:g} | {g['n_a']:g} | {g['n_g']:g} | {cells} "
            f"| {rel:.1e} |"
        )
    print(
        f"\n1-sigma horizontal position error of one channel, m: nav_variance (Van Loan). "
        "Worst relative "
        f"difference {worst:.2e}"
    )
    return worst


def draw_pair(rng):
    """Gyro (rad/s) and accelerometer (m/s^2) parameters: white, Gauss-Markov, rate random walk."""
    gyro = {
        "noise_variance": (10 ** rng.uniform(-3.5, -2.5)) ** 2,
        "bias_variance": (10 ** rng.uniform(-4.5, -3.5)) ** 2,
        "time_constant": 10 ** rng.uniform(1.5, 2.7),
        "rate_random_walk": 10 ** rng.uniform(-6.5, -5.5),
    }
    accel = {
        "noise_variance": (10 ** rng.uniform(-2.5, -1.5)) ** 2,
        "bias_variance": (10 ** rng.uniform(-3.5, -2.5)) ** 2,
        "time_constant": 10 ** rng.uniform(1.5, 2.7),
        "rate_random_walk": 10 ** rng.uniform(-5.5, -4.5),
    }
    return gyro, accel


def exact_sigma(params, sensor, k, dt, n_cal):
    loop = NavLoop(sensor)
    p = {key: np.asarray(v) for key, v in params.items()}
    return sum(
        REGISTRY[name].nav_variance(loop, k, p, dt, n_cal=n_cal)
        for name in ("white", "gauss_markov", "random_walk")
    )


def coverage(pairs, seed, hours):
    horizons = np.array([10.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1200.0])
    dt = 1.0 / RATE
    k = np.round(horizons / dt)
    n = int(hours * 3600 * RATE)
    model = NoiseModel(("white", "gauss_markov", "random_walk"), dt)
    hits = {"velocity": [], "position": []}
    print("| seed | quantity | " + " | ".join(f"{t:g} s" for t in horizons) + " |")
    print("|---" * (2 + horizons.size) + "|")
    start = time.time()
    for s in range(seed, seed + pairs):
        rng = np.random.default_rng(s)
        gp, ap = draw_pair(rng)
        fits = [
            fit(simulate_log(model, p, n, rng=rng), rate_hz=RATE, rng=s, progress=False)
            for p in (gp, ap)
        ]
        bands = navigation_bands(fits[0], fits[1], horizons, calibration_s=60.0, rng=s)
        truth = np.sqrt(
            exact_sigma(gp, "gyro", k, dt, 6000) + exact_sigma(ap, "accel", k, dt, 6000)
        )
        for i, name in ((1, "velocity"), (2, "position")):
            lo, hi = bands.quantities[name].sigma[0], bands.quantities[name].sigma[-1]
            inside = (lo <= truth[:, i]) & (truth[:, i] <= hi)
            hits[name].extend(inside.tolist())
            cells = " | ".join(
                f"{'in' if ok else ('LOW' if tr < a else 'HIGH')} {tr / m:.2f}"
                for ok, tr, a, m in zip(inside, truth[:, i], lo, bands.quantities[name].sigma[1])
            )
            print(f"| {s} | {name} | {cells} |")
        sys.stdout.flush()
    allhits = hits["velocity"] + hits["position"]
    print(
        f"\ncoverage of the 90 % bands (truth / median in the cells; LOW: truth below the band): "
        f"velocity {np.mean(hits['velocity']):.1%}, position {np.mean(hits['position']):.1%}, "
        f"all {np.mean(allhits):.1%} of {len(allhits)} (pair, horizon) points; "
        f"seeds {seed}-{seed + pairs - 1}, "
        f"{hours:g} h logs at {RATE:g} Hz, {time.time() - start:.0f} s"
    )
    return float(np.mean(allhits))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=("grades", "coverage"))
    parser.add_argument("--pairs", type=int, default=12)
    parser.add_argument("--seed", type=int, default=3600)
    parser.add_argument("--hours", type=float, default=1.0)
    args = parser.parse_args(argv)
    if args.what == "grades":
        worst = grades()
        return 0 if worst < 1e-6 else 1
    return 0 if coverage(args.pairs, args.seed, args.hours) >= 0.85 else 1


if __name__ == "__main__":
    sys.exit(main())
