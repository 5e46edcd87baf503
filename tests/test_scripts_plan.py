"""Quick runs of the issue-38 scripts (``validate_plan.py``, ``overbound_example.py``)."""

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


@pytest.mark.slow
def test_validate_plan_quick(tmp_path):
    """Two 1 h replicates: the white-noise width predicted within 10% (a small spread)."""
    out = _run("validate_plan.py", "--quick", "--csv", str(tmp_path / "p.csv"))
    ratio = float(re.search(r"1h noise_variance\s+\S+\s+\S+ \+-\S+\s+(\S+)", out).group(1))
    assert 0.9 < ratio < 1.1 and (tmp_path / "p.csv").exists()


@pytest.mark.slow
def test_overbound_example_quick():
    out = _run("overbound_example.py", "--quick")
    row = re.search(r"gyro_lowgrade\s+60\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)", out)
    assert (
        row and float(row.group(3)) >= 1.0
    )  # the white-noise density is never below the point value here
