"""Smoke run of ``scripts/validate_independent.py`` (issue 35): it runs the package on scenes
of the independent generator and writes its coverage table and rows."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "validate_independent.py"


@pytest.mark.slow  # ~10 s: two package fits
def test_validate_independent_quick(tmp_path):
    rows_path, table = tmp_path / "rows.csv", tmp_path / "table.md"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--no-nice", "--csv",
                           str(rows_path), "--markdown", str(table)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(rows_path) as handle:
        rows = list(csv.DictReader(handle))
    assert {r["family"] for r in rows} == {"white+gm", "white+quant"}
    assert {r["quantity"] for r in rows} == {"attitude", "position"}
    for r in rows:
        assert float(r["q05"]) <= float(r["q50"]) <= float(r["q95"])
        assert r["covered"] == str(int(float(r["q05"]) <= float(r["truth"]) <= float(r["q95"])))
    text = table.read_text()
    assert "| **all** | 2 |" in text and "--quick" in text


def test_held_out_seeds_are_disjoint_from_development():
    sys.path.insert(0, str(SCRIPT.parent))
    import validate_independent as vi

    class A:
        held_out, seed_start, per_family = False, 0, 50
    dev = set(vi.seeds(A))
    A.held_out = True
    first = set(vi.seeds(A))
    assert dev.isdisjoint(first)
    A.held_out_range = "2"
    assert dev.isdisjoint(vi.seeds(A)) and first.isdisjoint(vi.seeds(A))
    del A.held_out_range
    A.held_out, A.seed_start = False, vi.HELD_OUT_START - 10
    with pytest.raises(SystemExit):
        vi.seeds(A)


STUB = '''#!{python}
import os, sys
args = sys.argv[1:]
out = args[args.index("--out") + 1]
os.makedirs(out)
if args[0] == "nav":
    wide = os.environ["STUB_MODE"] == "wide"
    with open(os.path.join(out, "nav.csv"), "w") as fh:
        fh.write("t_s,quantity,q05,q50,q95,unit\\n")
        for t in args[args.index("--times") + 1].split(","):
            for q, u in (("tilt", "rad"), ("velocity", "m/s"), ("position", "m")):
                hi = 1e300 if wide else 0.0
                fh.write(f"{{float(t)}},{{q}},0,0,{{hi}},{{u}}\\n")
'''


@pytest.mark.parametrize("mode, expected", [("wide", "100.0%"), ("empty", "0.0%")])
def test_nav_mode_reads_the_documented_nav_csv(tmp_path, mode, expected):
    """The --nav plumbing against a stand-in ``bayes-imu`` that writes the interface of issue 36
    (``nav.csv``: ``t_s,quantity,q05,q50,q95,unit``): bands that hold everything cover every
    point, empty bands none."""
    import os

    stub = tmp_path / "bayes-imu"
    stub.write_text(STUB.format(python=sys.executable))
    stub.chmod(0o755)
    env = dict(os.environ, PATH=f"{tmp_path}{os.pathsep}{os.environ['PATH']}", STUB_MODE=mode)
    proc = subprocess.run([sys.executable, str(SCRIPT), "--nav", "--per-family", "1",
                           "--max-log2n", "18", "--no-nice"],
                          capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for q in ("position", "velocity"):
        assert f"nav {q}: {expected}" in proc.stdout, proc.stdout


def test_drift_alarm_line_counts_and_bounds():
    """The false-alarm line: rejections over the logs the check ran on, with the exact one-sided
    95% Clopper-Pearson bound (0 of 59 -> 1 - 0.05^(1/59) = 4.95%)."""
    sys.path.insert(0, str(SCRIPT.parent))
    import validate_independent as vi

    logs = ([{"drift_check": "ok", "drift_p": 0.5}] * 59
            + [{"drift_check": "n/a", "drift_p": float("nan")}])
    line = vi.drift_alarms(logs)
    assert "0/59 logs rejected" in line and f"{100 * (1 - 0.05 ** (1 / 59)):.1f}%" in line
    logs[0] = {"drift_check": "flagged", "drift_p": 0.01}
    assert "1/59 logs rejected (1.7%" in vi.drift_alarms(logs)
    assert "not available" in vi.drift_alarms(logs[-1:])
