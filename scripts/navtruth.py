"""Exact navigation-error truth of one horizontal channel (issue 36), independent of bayes_imu.

The loop (small angles, local level, stationary vehicle; the brief of issue 36):
``p' = v``, ``v' = -g phi + a_err``, ``phi' = v / R + w_err`` (Schuler on; ``schuler=False``
drops ``v / R``, leaving the uncoupled ``g``-tilt forms), ``g = 9.80665 m/s^2``,
``R = 6371000 m`` by default (parameters). The accelerometer lies along the channel, the gyro
about the perpendicular horizontal axis.

**Sampling convention: zero-order hold.** Sensor sample ``y_i`` (i = 0 at the outage start)
is held constant over ``[i dt, (i+1) dt)``; the error input is ``y_i - b`` with ``b`` the
plain mean of the ``N`` samples before the outage (calibrated bias semantics, both sensors),
and ``p = v = phi = 0`` at the outage start. A held-constant sample integrates exactly:
tilt from a gyro without Schuler and velocity from an accelerometer with ``g = 0`` are the
Euler sums ``dt sum (y_i - b)`` of ``scenegen``; a double integral weighs sample ``i`` by
``dt^2 (k - i - 1/2)`` (the Euler convention has ``k - 1 - i``: a difference of relative size
``dt / t``).

Two exact methods, cross-checked in ``tests/test_navtruth.py`` (and against a Monte Carlo of
a Runge-Kutta simulation of the loop driven by ``scenegen``'s simulators):

1. ``nav_covariance``: covariance propagation of the augmented state ``z = (p, v, phi,
   gyro noise states, accel noise states, b_gyro, b_accel)``. Between samples ``z`` flows
   under the continuous loop with the held inputs; the block exponential
   ``expm([[F, B], [0, 0]] dt) = [[Phi, Gamma], [0, I]]`` (Van Loan's construction for a
   held input) gives the exact transition. At each sample the Gauss-Markov states take
   their exact AR(1) step, random walks their increment, and the white samples enter
   through ``Gamma`` as fresh noise. The initial covariance is exact: the bias estimate's
   parts ``b = mean_{j=1..N} y_{-j}`` have ``Var = sigma_w^2 / N`` (white),
   ``sigma^2 / N^2 (N + 2 sum_{l=1}^{N-1} (N - l) a^l)`` (each Gauss-Markov, correlated with
   its state at the outage start by ``Cov(x_0, b) = sigma^2 / N sum_{j=1}^N a^j``) and
   ``q (N + 1)(2 N + 1) / (6 N)`` (random walk, increment variance ``q``, measured from its
   value at the outage start, which the contrast annihilates). ``k`` steps are taken
   by repeated doubling (``A^(2m) = A^m A^m``, ``S_(2m) = A^m S_m A^mT + S_m``).
2. ``nav_weights`` + ``scenegen.quad``: the error is a linear functional of the samples
   through the loop's impulse responses (accelerometer -> position ``sin(ws s)/ws``, gyro ->
   position ``-R (1 - cos ws s)``, ...) integrated exactly over each held sample, minus the
   response to the bias estimate; its variance is the exact quadratic form of ``scenegen``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

import scenegen as sg

__all__ = ["G", "R_EARTH", "loop_matrices", "nav_covariance", "nav_weights", "nav_truth",
           "simulate_loop", "QUANTITIES"]

G = 9.80665
R_EARTH = 6371000.0
QUANTITIES = ("position", "velocity", "tilt")       # state order p, v, phi


def loop_matrices(dt, *, g=G, radius=R_EARTH, schuler=True):
    """(Phi, Gamma): exact transition and held-input map over one sample; inputs (accel, gyro)."""
    f = np.zeros((5, 5))
    f[0, 1] = 1.0
    f[1, 2] = -g
    f[2, 1] = 1.0 / radius if schuler else 0.0
    f[1, 3] = 1.0                                      # accelerometer into v'
    f[2, 4] = 1.0                                      # gyro into phi'
    e = expm(f * dt)
    return e[:3, :3], e[:3, 3:]


def _bias_parts(term, n_cal, dt):
    """(state variance or None, Var(its part of b), Cov(state, its part of b), innovation, a)."""
    if isinstance(term, sg.White):
        return None, term.sigma ** 2 / n_cal, 0.0, 0.0, 0.0
    if isinstance(term, sg.GaussMarkov):
        a = math.exp(-dt / term.tau)
        s2 = term.sigma ** 2
        lags = np.arange(1, n_cal, dtype=float)
        var_b = s2 / n_cal ** 2 * (n_cal + 2 * float(np.sum((n_cal - lags) * a ** lags)))
        cov = s2 / n_cal * float(np.sum(a ** np.arange(1, n_cal + 1, dtype=float)))
        return s2, var_b, cov, s2 * -math.expm1(-2 * dt / term.tau), a
    if isinstance(term, sg.RandomWalk):
        q = term.k ** 2 * dt
        return 0.0, q * (n_cal + 1) * (2 * n_cal + 1) / (6 * n_cal), 0.0, q, 1.0
    if isinstance(term, sg.Flicker):
        raise TypeError("expand a Flicker into its Gauss-Markov parts first")
    raise TypeError(f"navigation truth supports White, GaussMarkov, RandomWalk; got {term!r}")


def _expand(terms):
    out = []
    for t in terms:
        out.extend(t.parts if isinstance(t, sg.Flicker) else (t,))
    return out


def _system(gyro, accel, n_cal, dt, phi, gam):
    """Augmented (A, Q, P0)."""
    sensors = ((_expand(accel), 0), (_expand(gyro), 1))
    states = [(sensor, _bias_parts(t, n_cal, dt)) for terms, sensor in sensors for t in terms]
    dyn = [(s, p) for s, p in states if p[0] is not None]
    d = 3 + len(dyn) + 2
    a_mat, q_mat, p0 = np.zeros((d, d)), np.zeros((d, d)), np.zeros((d, d))
    a_mat[:3, :3] = phi
    ib = {0: d - 1, 1: d - 2}                          # b_accel, b_gyro
    for sensor in (0, 1):
        a_mat[:3, ib[sensor]] = -gam[:, sensor]
        a_mat[ib[sensor], ib[sensor]] = 1.0
    for sensor, (_, var_b, _, _, _) in states:
        p0[ib[sensor], ib[sensor]] += var_b
    for sensor, parts in states:
        if parts[0] is None:                           # white: fresh held sample each step
            s2 = parts[1] * n_cal
            q_mat[:3, :3] += s2 * np.outer(gam[:, sensor], gam[:, sensor])
    for j, (sensor, (s2, _, cov, innov, a)) in enumerate(dyn):
        i = 3 + j
        a_mat[:3, i] = gam[:, sensor]
        a_mat[i, i] = a
        q_mat[i, i] = innov
        p0[i, i] = s2
        p0[i, ib[sensor]] = p0[ib[sensor], i] = cov
    return a_mat, q_mat, p0


def nav_covariance(gyro, accel, t_s, *, dt, calibration_s, g=G, radius=R_EARTH, schuler=True):
    """1-sigma (position m, velocity m/s, tilt rad) at whole-sample times ``t_s`` (ascending).

    ``gyro`` (rad/s) and ``accel`` (m/s^2) are sequences of ``scenegen`` White, GaussMarkov,
    RandomWalk or Flicker terms. Returns a dict quantity -> ``(n_t,)``.
    """
    phi, gam = loop_matrices(dt, g=g, radius=radius, schuler=schuler)
    n_cal = int(round(calibration_s / dt))
    a_mat, q_mat, p = _system(gyro, accel, n_cal, dt, phi, gam)
    ks = [int(round(t / dt)) for t in np.atleast_1d(t_s)]
    blocks = [(a_mat, q_mat)]
    while 2 ** len(blocks) <= max(ks):
        am, sm = blocks[-1]
        blocks.append((am @ am, am @ sm @ am.T + sm))
    out, done = [], 0
    for k in ks:
        step = k - done
        if step < 0:
            raise ValueError("times must be ascending")
        bit = 0
        while step:
            if step & 1:
                am, sm = blocks[bit]
                p = am @ p @ am.T + sm
            step >>= 1
            bit += 1
        done = k
        out.append(np.sqrt(np.clip(np.diag(p)[:3], 0.0, None)))
    out = np.array(out)
    return {q: out[:, i] for i, q in enumerate(QUANTITIES)}


def _x_minus_sin(x):
    """x - sin x without cancellation."""
    x = np.asarray(x, float)
    small = np.abs(x) < 0.5
    xs = x[small]
    x2 = xs * xs
    series = xs * x2 / 6 * (1 - x2 / 20 * (1 - x2 / 42 * (1 - x2 / 72 * (1 - x2 / 110 * (
        1 - x2 / 156 * (1 - x2 / 210))))))
    out = x - np.sin(x)
    out[small] = series
    return out


def nav_weights(k, n_cal, dt, quantity, sensor, *, g=G, radius=R_EARTH):
    """Weights on samples ``-N..k-1`` of ``quantity`` from ``sensor`` (Schuler on), ZOH exact.

    Impulse responses at age ``s`` (time from the input to the outage end), ``ws = sqrt(g/R)``:
    accel -> p ``sin(ws s)/ws``, v ``cos(ws s)``, phi ``sin(ws s)/(R ws)``; gyro -> p
    ``-R (1 - cos ws s)``, v ``-g sin(ws s)/ws``, phi ``cos(ws s)``. Sample ``i`` is held over
    ages ``[lo, hi] = [(k-1-i) dt, (k-i) dt]``: its weight is the response integrated there.
    """
    w = math.sqrt(g / radius)
    lo = (k - 1 - np.arange(k)) * dt
    hi = lo + dt
    sin_int = (2 * np.sin(w * hi / 2) ** 2 - 2 * np.sin(w * lo / 2) ** 2) / w   # int sin(ws)
    cos_int = (np.sin(w * hi) - np.sin(w * lo)) / w                             # int cos(ws)
    if sensor == "accel":
        h = {"position": sin_int / w, "velocity": cos_int, "tilt": sin_int / (radius * w)}
    else:
        one_minus_cos = (_x_minus_sin(w * hi) - _x_minus_sin(w * lo)) / w
        h = {"position": -radius * one_minus_cos, "velocity": -g * sin_int / w, "tilt": cos_int}
    out = h[quantity]
    return np.concatenate((np.full(n_cal, -out.sum() / n_cal), out))


def nav_truth(gyro, accel, t_s, *, dt, calibration_s, g=G, radius=R_EARTH):
    """Same as :func:`nav_covariance` (Schuler on) by the impulse-response weights."""
    n_cal = int(round(calibration_s / dt))
    out = {}
    for q in QUANTITIES:
        vals = []
        for t in np.atleast_1d(t_s):
            k = int(round(t / dt))
            v = sum(sg.quad(terms, nav_weights(k, n_cal, dt, q, s, g=g, radius=radius), dt)
                    for terms, s in ((gyro, "gyro"), (accel, "accel")) if terms)
            vals.append(math.sqrt(v))
        out[q] = np.array(vals)
    return out


def simulate_loop(y_gyro, y_accel, n_cal, ks, dt, *, g=G, radius=R_EARTH, schuler=True,
                  substeps=4):
    """Monte Carlo reference: RK4 integration of the loop with held, calibrated inputs.

    ``y_*`` have shape ``(reps, n_cal + max(ks))``. Returns quantity -> ``(reps, len(ks))``.
    """
    u_g = y_gyro[:, n_cal:] - y_gyro[:, :n_cal].mean(1, keepdims=True)
    u_a = y_accel[:, n_cal:] - y_accel[:, :n_cal].mean(1, keepdims=True)
    inv_r = 1.0 / radius if schuler else 0.0
    x = np.zeros((3, y_gyro.shape[0]))
    h = dt / substeps

    def f(s, a, w):
        return np.stack((s[1], -g * s[2] + a, s[1] * inv_r + w))

    snaps = {}
    for i in range(max(ks)):
        for _ in range(substeps):
            k1 = f(x, u_a[:, i], u_g[:, i])
            k2 = f(x + h / 2 * k1, u_a[:, i], u_g[:, i])
            k3 = f(x + h / 2 * k2, u_a[:, i], u_g[:, i])
            k4 = f(x + h * k3, u_a[:, i], u_g[:, i])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if i + 1 in ks:
            snaps[i + 1] = x.copy()
    return {q: np.stack([snaps[k][j] for k in ks], axis=1) for j, q in enumerate(QUANTITIES)}
