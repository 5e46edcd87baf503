"""Tests of the independent scene generator in scripts/validate_sampler.py (not of the package).

* exact AVAR of every term (variogram formula) against a brute-force quadratic form of the
  covariance matrix, ``AVAR(m) = w' S w / 2`` with the Allan contrast ``w``, to 1e-10 relative;
* the simulators against the exact AVAR by Monte Carlo: the mean over R independent records of
  the overlapping AVAR estimate is unbiased for every process with stationary increments, so it
  must lie within 5 standard errors (the replicates' sd / sqrt(R)) of the exact value: a false
  failure has probability ~6e-7 per comparison, and the seeds are fixed;
* the blocked AR(1) filter equals the plain recursion;
* scenes are reproducible from their seed, meet their design ranges, and the held-out range is
  refused without ``--held-out``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import validate_sampler as vs  # noqa: E402

DT = 0.01
TERMS = [
    vs.White(0.3),
    vs.Quantization(0.002),
    vs.GaussMarkov(0.5, 0.04),     # 4 samples
    vs.GaussMarkov(2.0, 0.5),      # 50 samples
    vs.RandomWalk(0.7),
]


def brute_avar(term, m, dt):
    w = np.concatenate((-np.ones(m), np.ones(m))) / m
    # away from the random walk's start; the contrast kills the level
    idx = np.arange(2 * m) + 3
    i, j = np.meshgrid(idx, idx, indexing="ij")
    s = term.cov(i, j, dt)
    return 0.5 * float(w @ s @ w)


@pytest.mark.parametrize("term", TERMS, ids=lambda t: type(t).__name__)
@pytest.mark.parametrize("m", [1, 2, 3, 5, 8, 13])
def test_exact_avar_matches_brute_force(term, m):
    exact = vs.term_avar(term, m, DT)
    assert exact == pytest.approx(brute_avar(term, m, DT), rel=1e-10)


def test_closed_forms():
    # white sigma^2 / m, quantization 3 q^2 / tau^2, random walk k^2 dt (2m^2+1)/(6m)
    for m in (1, 7, 100, 1000):
        tau = m * DT
        assert vs.term_avar(TERMS[0], m, DT) == pytest.approx(0.09 / m, rel=1e-12)
        assert vs.term_avar(TERMS[1], m, DT) == pytest.approx(3 * 0.002 ** 2 / tau ** 2, rel=1e-12)
        assert vs.term_avar(TERMS[4], m, DT) == pytest.approx(
            0.49 * DT * (2 * m * m + 1) / (6 * m), rel=1e-10)
    # Gauss-Markov: s2 (1 - a) for m = 1 (half the variance of x_{k+1} - x_k is s2 (1 - a))
    gm = TERMS[3]
    assert vs.term_avar(gm, 1, DT) == pytest.approx(gm.s2 * (1 - gm.a(DT)), rel=1e-12)
    # and large m: 2 s2 T / tau (white-like tail of a continuous GM, tau >> T)
    m = 100_000
    assert vs.term_avar(gm, m, DT) == pytest.approx(2 * gm.s2 * gm.tau / (m * DT), rel=2e-3)


@pytest.mark.parametrize("k", range(len(TERMS)), ids=lambda k: type(TERMS[k]).__name__)
def test_simulators_match_exact_avar(k):
    term = TERMS[k]
    rng = np.random.default_rng(np.random.SeedSequence([12345, k]))
    reps, n = 300, 2048
    ms = (1, 4, 16, 64)
    est = np.empty((reps, len(ms)))
    for r in range(reps):
        y = term.simulate(n, DT, rng)
        est[r] = [vs.overlapping_avar(y, m) for m in ms]
    for j, m in enumerate(ms):
        exact = vs.term_avar(term, m, DT)
        se = est[:, j].std(ddof=1) / math.sqrt(reps)
        assert abs(est[:, j].mean() - exact) < 5 * se, (m, est[:, j].mean(), exact, se)
        assert se < 0.1 * exact        # the test has power: 5 se is under half the value


def test_gm_stationary_variance_and_lag1():
    gm = vs.GaussMarkov(2.0, 0.05)
    rng = np.random.default_rng(7)
    x = np.stack([gm.simulate(200, DT, rng) for _ in range(2000)])
    # every sample has variance s2 (the start is stationary): first, middle and last
    for k in (0, 100, 199):
        v = x[:, k].var()
        assert abs(v - 2.0) < 5 * 2.0 * math.sqrt(2 / 2000)
    c = np.mean(x[:, 50] * x[:, 51])
    assert abs(c - 2.0 * gm.a(DT)) < 5 * 2.0 * math.sqrt(2 / 2000)


def test_ar1_filter_equals_recursion():
    rng = np.random.default_rng(3)
    e = rng.standard_normal(5000)
    for a in (0.0, 0.5, 0.99, 0.9999, math.exp(-1 / 3)):
        x = vs.ar1_filter(e, a, 1.7)
        ref = np.empty_like(e)
        prev = 1.7
        for i, v in enumerate(e):
            prev = a * prev + v
            ref[i] = prev
        np.testing.assert_allclose(x, ref, rtol=1e-10, atol=1e-10)


def test_scenes_reproducible_and_distinct():
    a, b, c = vs.make_scene(5), vs.make_scene(5), vs.make_scene(6)
    assert a == b and a != c
    ya, yb = a.simulate(), b.simulate()
    np.testing.assert_array_equal(ya, yb)
    assert ya.size == a.n


@pytest.mark.parametrize("seed", range(12))
def test_scene_design_ranges(seed):
    s = vs.make_scene(seed)
    assert 100 <= s.rate_hz <= 400 and s.n in (2 ** 18, 2 ** 19, 2 ** 20)
    gms = [t for t in s.terms if isinstance(t, vs.GaussMarkov)]
    assert len(gms) == 2 and 3 <= gms[1].tau / gms[0].tau <= 30
    assert gms[0].tau >= 20 * s.dt - 1e-12 and 1.9 * gms[1].tau < s.record_s / 25
    base = [t for t in s.terms if isinstance(t, (vs.White, vs.Quantization))]
    # each bump: ADEV of the bias at its own peak, over the terms below it, is 10^d, d in [0.3, 1.5]
    for gm, below, d in ((gms[0], base, s.bump_decades[0]),
                         (gms[1], base + [gms[0]], s.bump_decades[1])):
        assert 0.3 <= d <= 1.5
        ms = np.unique(np.round(np.geomspace(0.5 * gm.tau / s.dt, 8 * gm.tau / s.dt, 60))
                       .astype(int))
        g = np.array([vs.term_avar(gm, m, s.dt) for m in ms])
        mp = ms[np.argmax(g)]
        o = sum(vs.term_avar(t, mp, s.dt) for t in below)
        assert 0.5 * math.log10(g.max() / o) == pytest.approx(d, abs=0.02)
    assert s.package_terms()[:1] == ("white",)


def test_held_out_guard():
    with pytest.raises(SystemExit) as e:
        vs.main(["--seeds", "20000000", "--describe"])
    assert e.value.code == 2
    with pytest.raises(SystemExit) as e:
        vs.main(["--seeds", "3,19999999-20000001", "--describe"])
    assert e.value.code == 2
    ns = argparse.Namespace(held_out=True, seeds=None, n=3)
    assert vs.select_seeds(ns) == [20_000_000, 20_000_001, 20_000_002]
    ns = argparse.Namespace(held_out=False, seeds="0-2,7", n=14)
    assert vs.select_seeds(ns) == [0, 1, 2, 7]
