"""Independent validation of calibrated-outage drift bands on random scenes (issues 35 and 36).

Scenes, simulators and exact truths come from ``scripts/scenegen.py`` (and
``scripts/navtruth.py`` for ``--nav``), written without the package's code. For each scene of
each family the package is run as a user runs it, through its public API (``--mode api``,
the default: ``allan_variance`` -> ``fit_allan`` -> ``drift_bands(..., bias_start="calibrated",
calibration_s=S)``) or its command line (``--mode cli``: ``bayes-imu fit LOG.npy --rate HZ
--units m/s^2 --sensor accel --times ... --bias-start calibrated --calibration S``, whose
``velocity`` rows are the same integral as ``attitude``), and the 90% band of the 1-sigma
error is compared with the exact truth at horizons 1 s to a quarter of the record
(log-spaced, whole samples): *covered* when ``q05 <= truth <= q95``. Attitude (first
integral) and position (second integral, Euler sums) are both checked.

Seeds: the development range is ``0 .. per_family - 1`` (``--seed-start`` moves it); the
held-out range ``1_000_000 + i`` is used only with ``--held-out`` (the two never overlap).
The package's fit is seeded with the scene seed.

Per family the table gives the coverage with its binomial standard error (points taken as
independent) and the between-log standard error (points of one log are correlated: this is
the honest one), the share of misses below the band (band too high: overcautious would be
above), the models the package selected, and how often its adequacy checks flagged the log.

``--nav`` (issue 36; the ``nav`` command did not exist when this was written, so this mode
is untested against it): pairs of simulated gyro (rad/s) and accelerometer (m/s^2) logs with
white, Gauss-Markov and rate random walk terms, each fitted by ``bayes-imu fit``, then
``bayes-imu nav --gyro G --accel A --times 10,...,1200 --calibration S --out DIR``; the
``position`` and ``velocity`` rows of ``DIR/nav.csv`` (``t_s,quantity,q05,q50,q95,unit``) are
compared with ``navtruth.nav_covariance`` (Schuler loop, ``--gravity``, ``--radius``).

Runs niced (``os.nice(10)``), one fit at a time. Examples::

    python scripts/validate_independent.py --per-family 8 --markdown docs/validation/independent.md
    python scripts/validate_independent.py --per-family 30 --held-out      # the lead, at the end
    python scripts/validate_independent.py --nav --per-family 10
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import navtruth as nt  # noqa: E402
import scenegen as sg  # noqa: E402

HELD_OUT_START = 1_000_000
#: a second held-out range (the first was seen in the session that fixed what it found), and a
#: third (the second was seen by the session that measured position bands on it: issue 35's third
#: session runs range 3 once, at its end), and a fourth (range 3 was seen: the seventh session of
#: issue 39 runs range 4 once, at its end, on the sampler with the independence move), and a fifth
#: (range 4 was seen: the fourteenth session of issue 39 runs range 5 once, at its end, on the
#: tempered sampler; the seventeenth runs range 6 once, at its end, on the jump move)
HELD_OUT_RANGES = {"1": HELD_OUT_START, "2": 3_000_000, "3": 5_000_000, "4": 7_000_000,
                   "5": 9_000_000, "6": 11_000_000}
NAV_TIMES = (10.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1200.0)


def seeds(args):
    held = HELD_OUT_RANGES[getattr(args, "held_out_range", "1")]
    start = held if args.held_out else args.seed_start
    if not args.held_out and start + args.per_family > HELD_OUT_START:
        raise SystemExit("development seeds would reach the held-out range")
    return range(start, start + args.per_family)


def data_rng(family, seed):
    """Generator of a scene's samples (a stream separate from the scene's parameters)."""
    return np.random.default_rng(np.random.SeedSequence(
        [int(seed), sg.FAMILIES.index(family) if family in sg.FAMILIES else 99, 35, 1]))


# ----------------------------------------------------------------------------- the package

def run_api(y, scene, times, window=False):
    """``window``: the Allan variance measures the record's drift at the scene's calibration
    window (``contrast_span_s=S``, as api.md documents) instead of its default."""
    import bayes_imu as bi
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        extra = {"contrast_span_s": scene.calibration_s} if window else {}
        allan = bi.allan_variance(y, rate_hz=scene.rate_hz, **extra)
        fit = bi.fit_allan(allan, rng=scene.seed)
        bands, b_att, b_pos = {}, None, None
        for q in ("attitude", "position"):
            b = bi.drift_bands(fit, times, quantity=q, bias_start="calibrated",
                               calibration_s=scene.calibration_s, rng=scene.seed)
            if not np.allclose(b.t_s, times, rtol=1e-9):
                raise RuntimeError(f"drift_bands moved the times: {b.t_s} vs {times}")
            i05, i95 = (int(np.argmin(np.abs(np.asarray(b.quantiles) - p))) for p in (0.05, 0.95))
            i50 = int(np.argmin(np.abs(np.asarray(b.quantiles) - 0.5)))
            bands[q] = b.total[[i05, i50, i95]]
            b_att = b if q == "attitude" else b_att
            b_pos = b if q == "position" else b_pos
    stat = getattr(fit, "stationarity", None)
    drift_check = getattr(fit.adequacy, "drift", None)
    if drift_check is None:
        drift_check = getattr(b_att, "check", None)
    info = {
        "model": "+".join(fit.model.terms),
        "adequate": bool(fit.adequacy.adequate),
        "adequacy_p": float(fit.adequacy.p_value),
        "stationary": None if stat is None else bool(stat.stationary),
        "widened": bool(getattr(fit, "widened", False)),
        "drift_check": _drift_flag(drift_check),
        "drift_p": float(getattr(drift_check, "p_combined", float("nan"))),
        # the position band's own check (order 2), beside the attitude one
        "position_check": _drift_flag(getattr(b_pos, "check", None)),
        "position_p": float(getattr(getattr(b_pos, "check", None), "p_combined", float("nan"))),
        "warnings": len(caught),
        # the sampler (issue 39): converged, tempered, and the untempered steps discarded where a
        # slow chain went on tempered
        "converged": bool(fit.diagnostics.get("converged", True)),
        "tempered": bool(fit.diagnostics.get("tempered", False)),
        "steps_before_tempering": int(fit.diagnostics.get("steps_before_tempering", 0)),
    }
    return bands, info


def _drift_flag(check):
    """'n/a' when the package has no drift-space check, else whether it flagged the log."""
    if check is None:
        return "n/a"
    for name in ("adequate", "consistent", "ok"):
        if hasattr(check, name):
            return "ok" if bool(getattr(check, name)) else "flagged"
    return "present"


def _drift_json_flag(entry):
    """'ok' / 'flagged' from summary.json's ``adequacy.drift`` ('n/a' when absent or empty)."""
    if not isinstance(entry, dict) or "adequate" not in entry:
        return "n/a"
    return "ok" if entry["adequate"] else "flagged"


def run_cli(y, scene, times, workdir):
    log = workdir / "log.npy"
    np.save(log, y)
    out = workdir / "fit"
    cmd = ["bayes-imu", "fit", str(log), "--rate", repr(scene.rate_hz), "--units", "m/s^2",
           "--sensor", "accel", "--times", ",".join(repr(float(t)) for t in times),
           "--bias-start", "calibrated", "--calibration", repr(scene.calibration_s),
           "--seed", str(scene.seed), "--quiet", "--out", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    with open(out / "drift.csv") as fh:
        rows = list(csv.DictReader(fh))
    bands = {}
    for q, name in (("attitude", "velocity"), ("position", "position")):
        sel = [r for r in rows if r["quantity"] == name]
        t = np.array([float(r["t_s"]) for r in sel])
        if not np.allclose(t, times, rtol=1e-6):
            raise RuntimeError(f"drift.csv times {t} differ from {times}")
        bands[q] = np.array([[float(r[c]) for r in sel] for c in ("q05", "q50", "q95")])
    with open(out / "summary.json") as fh:
        summary = json.load(fh)
    adequacy = summary.get("adequacy", {})
    stat = adequacy.get("stationarity") or {}
    info = {
        "model": "+".join(summary.get("model", [])) if isinstance(summary.get("model"), list)
        else str(summary.get("model")),
        "adequate": adequacy.get("adequate"),
        "adequacy_p": adequacy.get("p_value"),
        "stationary": stat.get("stationary"),
        "widened": adequacy.get("widened"),
        "drift_check": _drift_json_flag(adequacy.get("drift")),
        "drift_p": float((adequacy.get("drift") or {}).get("p_value", float("nan"))),
        "warnings": 0,
    }
    shutil.rmtree(out)
    log.unlink()
    return bands, info


# ----------------------------------------------------------------------------- the drift check

def avar_check(scene, y):
    """Scene sanity: largest |ln(measured / exact expected Allan variance)| at octave sizes up
    to n/16 (our own estimator on the simulated record against ``scenegen.avar_truth``)."""
    m = 2 ** np.arange(int(math.log2(scene.n / 16)) + 1)
    return float(np.max(np.abs(np.log(sg.overlapping_avar(y, m, scene.dt) /
                                      sg.avar_truth(scene, m)))))


SHORT_TERMS = (sg.White, sg.Quantization, sg.FilteredWhite)


def slow_share(scene, times, order):
    """Share of the truth's variance from the slow terms (biases, flicker, random walk, ramp)."""
    short = tuple(t for t in scene.terms if isinstance(t, SHORT_TERMS))
    total = sg.drift_truth(scene, times, order) ** 2
    return 1.0 - sg.drift_truth(scene, times, order, terms=short) ** 2 / total


def drift_rows(args):
    rows, logs = [], []
    with tempfile.TemporaryDirectory(prefix="validate_independent_") as tmp:
        for family in args.families:
            for seed in seeds(args):
                scene = sg.make_scene(family, seed, max_log2n=args.max_log2n)
                times = sg.horizons(scene, n_h=args.horizons)
                truth = {"attitude": sg.drift_truth(scene, times, 1),
                         "position": sg.drift_truth(scene, times, 2)}
                y = scene.simulate(data_rng(family, seed))
                t0 = time.perf_counter()
                if args.mode == "api":
                    bands, info = run_api(y, scene, times, window=args.api_window)
                else:
                    bands, info = run_cli(y, scene, times, Path(tmp))
                info.update(avar_check=avar_check(scene, y))
                info.update(family=family, seed=seed, rate_hz=scene.rate_hz, n=scene.n,
                            calibration_s=scene.calibration_s, fit_s=time.perf_counter() - t0,
                            scene=scene.describe())
                logs.append(info)
                share = {"attitude": slow_share(scene, times, 1),
                         "position": slow_share(scene, times, 2)}
                for q in ("attitude", "position"):
                    for j, t in enumerate(times):
                        lo, med, hi = bands[q][:, j]
                        tr = truth[q][j]
                        rows.append(dict(family=family, seed=seed, quantity=q, t_s=float(t),
                                         truth=tr, q05=lo, q50=med, q95=hi,
                                         slow_share=float(share[q][j]),
                                         covered=int(lo <= tr <= hi),
                                         side="below" if tr < lo else ("above" if tr > hi else "")))
                cov = np.mean([r["covered"] for r in rows[-2 * len(times):]])
                print(f"{family:13s} seed {seed:7d} n={scene.n:8d} {scene.rate_hz:5.0f} Hz "
                      f"S={scene.calibration_s:4.0f} model={info['model']:40s} "
                      f"adequate={info['adequate']!s:5s} covered={cov:.2f} "
                      f"({info['fit_s']:.1f} s)", flush=True)
    return rows, logs


def _cov(rows):
    """Coverage, binomial SE, between-log SE, share of misses below the band."""
    if not rows:
        return float("nan"), float("nan"), float("nan"), float("nan"), 0
    c = np.array([r["covered"] for r in rows], float)
    p = c.mean()
    per_log = defaultdict(list)
    for r in rows:
        per_log[(r["family"], r["seed"])].append(r["covered"])
    means = np.array([np.mean(v) for v in per_log.values()])
    se_log = means.std(ddof=1) / math.sqrt(len(means)) if len(means) > 1 else float("nan")
    misses = [r for r in rows if not r["covered"]]
    below = np.mean([r["side"] == "below" for r in misses]) if misses else float("nan")
    return p, math.sqrt(p * (1 - p) / len(c)), se_log, below, len(c)


def _width(att):
    """Median (and 90th percentile) of the attitude bands' width ratio q95 / q05."""
    w = [float(r["q95"]) / float(r["q05"]) for r in att if float(r["q05"]) > 0]
    return f"{np.median(w):.2f} ({np.quantile(w, 0.9):.2f})" if w else "-"


def drift_alarms(logs):
    """One line: the drift-space check's rejections with a 95% Clopper-Pearson upper bound."""
    from scipy import stats

    checked = [x for x in logs if x.get("drift_check") in ("ok", "flagged")]
    if not checked:
        return "Drift-space check: not available on these logs."
    k, n = sum(x["drift_check"] == "flagged" for x in checked), len(checked)
    upper = stats.beta.ppf(0.95, k + 1, n - k) if k < n else 1.0
    ps = np.array([float(x["drift_p"]) for x in checked])
    line = (f"Drift-space check (`adequacy.drift`, alpha 0.05): {k}/{n} logs rejected "
            f"({100 * k / n:.1f}%, one-sided 95% upper bound {100 * upper:.1f}%); "
            f"p < 0.10 on {int(np.sum(ps < 0.1))}, median p {np.median(ps):.2f}.")
    position = [x for x in logs if x.get("position_check") in ("ok", "flagged")]
    if position:
        k2, n2 = sum(x["position_check"] == "flagged" for x in position), len(position)
        upper2 = stats.beta.ppf(0.95, k2 + 1, n2 - k2) if k2 < n2 else 1.0
        p2 = np.array([float(x["position_p"]) for x in position])
        line += (f" Position check (order 2, the position band's): {k2}/{n2} rejected "
                 f"({100 * k2 / n2:.1f}%, upper bound {100 * upper2:.1f}%); median p "
                 f"{np.median(p2):.2f}.")
    return line


def _fmt(p, se_b, se_l):
    return f"{100 * p:.0f}% +- {100 * se_b:.0f} ({100 * se_l:.0f})"


def markdown(rows, logs, args, command):
    seeds_used = sorted({int(r["seed"]) for r in rows})
    held = seeds_used[0] >= HELD_OUT_START
    per_scene = Counter((r["family"], r["seed"]) for r in rows if r["quantity"] == "attitude")
    lines = [
        f"Seeds {seeds_used[0]}..{seeds_used[-1]} ({'HELD-OUT' if held else 'development'}"
        f" range), {len(seeds_used)} scenes per family, {max(per_scene.values())} horizons per "
        f"scene (1 s to a quarter of the record), mode `{args.mode}`.", "",
        "Coverage of the exact truth by the package's 90% band of the 1-sigma error "
        "(goal 90%); `+- a (b)`: binomial standard error (a) and between-log standard error (b); "
        "`slow terms dominate`: attitude points where biases, flicker, random walk or ramp "
        "give more than half the true variance (the points that test the model); "
        "`below`: share of the misses where the truth lies below the band; `AVAR check`: the "
        "largest |ln(measured / exact Allan variance)| over the family's records at octave "
        "sizes up to n/16 (scene sanity: sampling scatter only).", "",
        "| family | logs | attitude | position | attitude 1-10 s | 10-100 s | >100 s | slow terms "
        "dominate | "
        "below | models selected (count) | adequacy flagged | non-stationary | widened | "
        "AVAR check | drift check flagged | attitude q95/q05 |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    fams = list(dict.fromkeys(r["family"] for r in rows)) + ["all"]
    for fam in fams:
        fr = [r for r in rows if fam in ("all", r["family"])]
        fl = [x for x in logs if fam in ("all", x["family"])]
        att = [r for r in fr if r["quantity"] == "attitude"]
        pos = [r for r in fr if r["quantity"] == "position"]
        bins = [[r for r in att if lo <= r["t_s"] < hi]
                for lo, hi in ((0, 10.0 - 1e-9), (10.0 - 1e-9, 100.0), (100.0, np.inf))]
        a, p = _cov(att), _cov(pos)
        bins.append([r for r in att if float(r["slow_share"]) > 0.5])
        binned = [f"{100 * c[0]:.0f}% ({c[4]})" if c[4] else "-" for c in map(_cov, bins)]
        models = Counter(x["model"] for x in fl)
        top = ", ".join(f"{m} ({c})" for m, c in models.most_common(3 if fam != "all" else 4))
        flagged = sum(1 for x in fl if x["adequate"] is False)
        nonstat = sum(1 for x in fl if x["stationary"] is False)
        widened = sum(1 for x in fl if x["widened"])
        below = _cov(fr)[3]
        worst_avar = max((x.get("avar_check", 0.0) for x in fl), default=float("nan"))
        checked = [x for x in fl if x.get("drift_check") in ("ok", "flagged")]
        drift_flagged = sum(1 for x in checked if x["drift_check"] == "flagged")
        name = f"**{fam}**" if fam == "all" else fam
        lines.append(f"| {name} | {len(fl)} | {_fmt(*a[:3])} | {_fmt(*p[:3])} | "
                     f"{' | '.join(binned)} | {100 * below:.0f}% | {top} | {flagged}/{len(fl)} | "
                     f"{nonstat}/{len(fl)} | {widened}/{len(fl)} | {worst_avar:.2f} | "
                     f"{drift_flagged}/{len(checked)} | {_width(att)} |")
    lines += ["", drift_alarms(logs),
              "", f"Command: `{command}`"]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- navigation

def nav_pair(seed, max_log2n):
    """A gyro (rad/s) + accelerometer (m/s^2) pair: white, Gauss-Markov, rate random walk."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 36]))
    rate = float(rng.choice((100.0, 200.0)))
    n = int(round(2 ** rng.uniform(max(18.0, max_log2n - 2), max_log2n)))
    cal = float(rng.choice((30.0, 60.0, 120.0)))
    out = []
    for density in ((1e-4, 3e-3), (3e-4, 3e-3)):          # rad/s/sqrt(Hz), m/s^2/sqrt(Hz)
        nw = sg._lu(rng, *density)
        terms = [sg.White(nw * math.sqrt(rate))]
        rec = n / rate
        if rng.random() < 0.8:
            terms.append(sg._gm(rng, nw, sg._lu(rng, 5.0, rec / 10), 0.0, 1.2))
        if rng.random() < 0.5:
            terms.append(sg._rrw(rng, nw, 30.0, 3 * rec))
        out.append(tuple(terms))
    return rate, n, cal, out[0], out[1]


def nav_rows(args):
    rows = []
    with tempfile.TemporaryDirectory(prefix="validate_nav_") as tmp:
        tmp = Path(tmp)
        for seed in seeds(args):
            rate, n, cal, gyro, accel = nav_pair(seed, args.max_log2n)
            dt = 1.0 / rate
            rng = data_rng("nav", seed)
            times = np.array(NAV_TIMES)
            dirs = {}
            for name, terms, units in (("gyro", gyro, "rad/s"), ("accel", accel, "m/s^2")):
                y = sum(t.simulate(n, dt, rng) for t in terms)
                np.save(tmp / f"{name}.npy", y)
                dirs[name] = tmp / f"fit_{name}"
                subprocess.run(["bayes-imu", "fit", str(tmp / f"{name}.npy"), "--rate", repr(rate),
                                "--units", units, "--sensor", name, "--seed", str(seed), "--quiet",
                                "--out", str(dirs[name])], check=True, capture_output=True)
            out = tmp / "nav"
            subprocess.run(["bayes-imu", "nav", "--gyro", str(dirs["gyro"]), "--accel",
                            str(dirs["accel"]), "--times", ",".join(map(repr, NAV_TIMES)),
                            "--calibration", repr(cal), "--out", str(out)],
                           check=True, capture_output=True)
            truth = nt.nav_covariance(gyro, accel, times, dt=dt, calibration_s=cal,
                                      g=args.gravity, radius=args.radius)
            with open(out / "nav.csv") as fh:
                band = list(csv.DictReader(fh))
            for q in ("position", "velocity"):
                sel = {round(float(r["t_s"]), 6): r for r in band if r["quantity"] == q}
                for j, t in enumerate(times):
                    r = sel[round(float(t), 6)]
                    lo, hi, tr = float(r["q05"]), float(r["q95"]), truth[q][j]
                    rows.append(dict(family="nav", seed=seed, quantity=q, t_s=float(t), truth=tr,
                                     q05=lo, q50=float(r["q50"]), q95=hi,
                                     covered=int(lo <= tr <= hi),
                                     side="below" if tr < lo else ("above" if tr > hi else "")))
            for p in [out, *dirs.values()]:
                shutil.rmtree(p)
            print(f"nav seed {seed}: covered "
                  f"{np.mean([r['covered'] for r in rows if r['seed'] == seed]):.2f}", flush=True)
    return rows


# ----------------------------------------------------------------------------- main

def read_rows(path):
    """Rows and per-log records written by ``--csv`` (to tabulate again without refitting)."""
    def conv(v):
        if v in ("True", "False"):
            return v == "True"
        try:
            return int(v)
        except ValueError:
            try:
                return float(v)
            except ValueError:
                return v
    with open(path) as fh:
        rows = [{k: conv(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    with open(Path(path).with_suffix(".logs.csv")) as fh:
        logs = [{k: conv(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    for r in rows:
        r["t_s"] = float(r["t_s"])
    if rows and "slow_share" not in rows[0]:                 # rows from before that column
        groups = defaultdict(list)
        for r in rows:
            groups[(r["family"], r["seed"], r["quantity"])].append(r)
        for (family, seed, q), grp in groups.items():
            scene = sg.make_scene(family, seed)
            share = slow_share(scene, [r["t_s"] for r in grp], 1 if q == "attitude" else 2)
            for r, v in zip(grp, share):
                r["slow_share"] = float(v)
    return rows, logs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--per-family", type=int, default=8, help="scenes per family (default 8)")
    ap.add_argument("--families", default=",".join(sg.FAMILIES))
    ap.add_argument("--held-out", action="store_true", help="the held-out seed range (lead only)")
    ap.add_argument("--held-out-range", choices=sorted(HELD_OUT_RANGES), default="1",
                    help="which held-out range: 1 (seeds 1,000,000..), 2 (3,000,000..), 3 "
                    "(5,000,000..), 4 (7,000,000..) or 5 (9,000,000..)")
    ap.add_argument("--seed-start", type=int, default=0, help="first development seed")
    ap.add_argument("--horizons", type=int, default=8, help="horizons per scene")
    ap.add_argument("--max-log2n", type=float, default=20.0, help="record length up to 2^this")
    ap.add_argument("--mode", choices=("api", "cli"), default="api")
    ap.add_argument("--api-window", action="store_true",
                    help="API mode: allan_variance(..., contrast_span_s=S) at the scene's window S")
    ap.add_argument("--nav", action="store_true", help="the navigation check (bayes-imu nav)")
    ap.add_argument("--gravity", type=float, default=nt.G)
    ap.add_argument("--radius", type=float, default=nt.R_EARTH)
    ap.add_argument("--csv", help="write every (scene, quantity, horizon) row here")
    ap.add_argument("--markdown", help="write the table (and the command) here")
    ap.add_argument("--from-csv", help="tabulate rows written earlier by --csv (no fitting)")
    ap.add_argument("--no-nice", action="store_true")
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: one short scene of two families")
    args = ap.parse_args(argv)
    if args.quick:
        args.per_family, args.max_log2n, args.families = 1, 16.0, "white+gm,white+quant"
    args.families = [f for f in args.families.split(",") if f]
    unknown = [f for f in args.families if f not in sg.FAMILIES]
    if unknown:
        ap.error(f"unknown families {unknown}; expected some of {sg.FAMILIES}")
    if not args.no_nice:
        os.nice(10)
    command = "python scripts/validate_independent.py " + " ".join(
        sys.argv[1:] if argv is None else argv)
    if args.nav:
        rows = nav_rows(args)
        for q in ("position", "velocity"):
            p, se, se_log, below, n = _cov([r for r in rows if r["quantity"] == q])
            print(f"nav {q}: {100 * p:.1f}% +- {100 * se:.1f} (between pairs {100 * se_log:.1f})"
                  f" of {n} points; misses below the band {100 * below:.0f}%")
        logs = []
    else:
        rows, logs = read_rows(args.from_csv) if args.from_csv else drift_rows(args)
        table = markdown(rows, logs, args, command)
        print(table)
        if args.markdown:
            Path(args.markdown).write_text(table + "\n")
    if args.csv and not args.from_csv:
        write_csv(args.csv, rows)
        if logs:
            write_csv(Path(args.csv).with_suffix(".logs.csv"), logs)
    return 0


def write_csv(path, rows):
    """Rows as CSV, floats to 7 significant digits."""
    def fmt(v):
        return f"{v:.7g}" if isinstance(v, float) else v
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows({k: fmt(v) for k, v in r.items()} for r in rows)


if __name__ == "__main__":
    sys.exit(main())
