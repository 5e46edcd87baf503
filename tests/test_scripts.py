"""The research scripts' smoke runs (``--quick``): they run, write their outputs, and what they
print holds (corrected formulas agree with the Monte Carlo, the printed ones do not)."""

import csv
import re
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _run(script, *args):
    proc = subprocess.run(
        [sys.executable, str(SCRIPTS / script), *args], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.slow  # ~7 s: a script's quick run, as the others in the nightly job
def test_paper_figures_quick(tmp_path):
    """200 Monte Carlo paths: the corrected formulas within 5 standard errors, the printed eqs 11
    and 29 far off."""
    out = _run("paper_figures.py", "--quick", "--out", str(tmp_path))
    assert len(list(tmp_path.glob("fig*.png"))) == 11
    worst = {
        int(n): float(v)
        for n, v in re.findall(r"Fig (\d+): .*?worst deviation ([\d.]+) standard errors", out)
    }
    assert set(worst) == {4, 5, 6, 7, 9, 10} and max(worst.values()) < 5.0, worst
    printed = [float(v) for v in re.findall(r"printed form: ([\d.e+]+) standard errors", out)]
    assert len(printed) == 2 and min(printed) > 20.0, printed


# ~20 s: the benchmark's quick run
@pytest.mark.slow
def test_speed_vs_error_quick(tmp_path):
    out = _run("bench_speed_vs_error.py", "--quick", "--processes", "1", "--out", str(tmp_path))
    with open(tmp_path / "speed_vs_error.csv") as handle:
        rows = list(csv.DictReader(handle))
    methods = {r["method"] for r in rows}
    assert methods == {
        "slope",
        "ls_log_adev",
        "gmwm_wls",
        "map_laplace",
        "mcmc_500",
        "mcmc_2000",
        "mcmc",
    }
    assert len(rows) == 7 * 3 * 2 and (tmp_path / "pareto.png").stat().st_size > 10_000
    assert all(float(r["median_seconds"]) >= 0 for r in rows) and "mcmc" in out


@pytest.mark.slow  # ~10 s: fits real logs from ../shared
def test_real_data_quick(tmp_path):
    from conftest import shared_file

    shared_file("smac_imudata", "adis_16405_imu1.csv.gz")
    out = _run("real_data.py", "--quick", "--out", str(tmp_path))
    density = float(re.search(r"imu1\s+gyro_x_dps\s+\S+\s+\S+\s+(\S+)", out).group(1))
    # REFERENCE_VALUES.md: OADEV(1 s) of the six recordings 0.038-0.046 deg/s, datasheet ARW 0.0333
    # deg/s/sqrt(Hz)
    assert 0.025 < density < 0.046
    assert (tmp_path / "real_data_posteriors.png").exists()


@pytest.mark.parametrize("script", ["paper_figures.py", "bench_speed_vs_error.py", "real_data.py",
                                    "validate_real.py", "validate_population.py",
                                    "bench_population.py", "study_vibration.py"])
def test_scripts_offer_a_quick_run(script):
    """Each script's own --help (its argument parser, run) offers --quick."""
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, str(SCRIPTS / script), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "--quick" in done.stdout


@pytest.mark.slow
def test_bench_population_quick(tmp_path):
    """Two cells, one replicate each: the table has a row per cell with coverages in [0, 1]."""
    out = _run("bench_population.py", "--quick", "--csv", str(tmp_path / "p.csv"))
    rows = re.findall(
        r"^\s+(0\.\d)\s+(\d)\s+(\d+)\s+([\d.]+) \+-[\d.]+\s+([\d.]+) "
        r"\+-[\d.]+\s+([\d.]+)\s+([\d.]+)$",
        out,
        re.M,
    )
    assert [(r[0], r[1]) for r in rows] == [("0.1", "3"), ("0.3", "3")]
    for r in rows:
        assert all(0.0 <= float(v) <= 1.0 for v in r[3:6]) and float(r[6]) > 0
    with open(tmp_path / "p.csv") as f:
        assert len(list(csv.DictReader(f))) == 2


@pytest.mark.slow
def test_validate_population_quick(tmp_path):
    """gyro_x of three ADIS16405 units, each held out once (skips without ../shared)."""
    out = _run(
        "validate_population.py", "--quick", "--cache", str(tmp_path / "cache"), "--workers", "2"
    )
    if out.startswith("skipped"):
        pytest.skip(out.strip())
    share = float(
        re.search(r"drift: \d+ of \d+ \(unit, axis, horizon\) points = ([\d.]+)%", out).group(1)
    )
    assert share >= 75.0  # 12 points; the full run's table is in docs/validation/population.md


def test_bench_allan_stage_times_follow_the_kernels_path(rng):
    """bench_allan --stages times each stage alone (mean, running sum, sums of the sizes below and
    from 65536 up), with no large-size column without a size from 65536 up; every stage run is timed
    (no relation between the times is asserted: they are milliseconds on a shared machine), on a
    short record and on one the JIT kernels sum."""
    import importlib.util

    import numpy as np

    from bayes_imu.allan import kernels

    spec = importlib.util.spec_from_file_location("bench_allan", SCRIPTS / "bench_allan.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    short = bench._stage_times(rng.standard_normal(5000), 2 ** np.arange(11), 1)
    assert len(short) == 4 and np.isnan(short[3])
    assert all(t > 0 for t in short[:3])
    n = kernels.PRECOMPILED_BELOW + 4096
    times = bench._stage_times(rng.standard_normal(n) + 3.0, 2 ** np.arange(19), 3)
    assert all(np.isfinite(t) and t > 0 for t in times)


def test_compare_band_csvs_counts_identical_edges_and_verdicts(tmp_path):
    """Two three-point runs, one median 10% higher and one verdict flipped: 100% identical q05/q95,
    a 1.00e-01 largest median difference, 2 of 3 verdicts the same; no common point: exit 2."""
    header = "family,seed,quantity,t_s,truth,q05,q50,q95,slow_share,covered,side\n"
    old = ["a,0,attitude,1,1,0.5,1.0,2.0,0,1,", "a,0,attitude,2,1,0.5,1.0,2.0,0,1,",
           "b,1,position,1,1,0.5,1.0,2.0,0,1,"]
    new = ["a,0,attitude,1,1,0.5,1.1,2.0,0,1,", "a,0,attitude,2,1,0.5,1.0,2.0,0,0,below",
           "b,1,position,1,1,0.5,1.0,2.0,0,1,"]
    (tmp_path / "old.csv").write_text(header + "\n".join(old) + "\n")
    (tmp_path / "new.csv").write_text(header + "\n".join(new) + "\n")
    out = _run("compare_band_csvs.py", str(tmp_path / "old.csv"), str(tmp_path / "new.csv"))
    assert "3 common points" in out
    q50 = next(line for line in out.splitlines() if line.split()[:1] == ["q50"]).split()
    assert q50[1] == "66.7%" and float(q50[-1]) == pytest.approx(0.1, rel=1e-6)
    assert all(line.split()[1] == "100.0%" for line in out.splitlines()
               if line.split()[:1] in (["q05"], ["q95"]))
    assert "the same on 2 of 3 points" in out
    (tmp_path / "other.csv").write_text(header + "c,9,attitude,1,1,0.5,1.0,2.0,0,1,\n")
    done = subprocess.run([sys.executable, str(SCRIPTS / "compare_band_csvs.py"),
                           str(tmp_path / "old.csv"), str(tmp_path / "other.csv")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "no common" in done.stderr
