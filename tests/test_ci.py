"""The CI script runs what the README says: the Quick start's test command by default, and the slow
tests as well when given ``slow`` (the nightly job); anything else is refused before it installs or
runs anything."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / ".ci" / "run"


def _commands():
    """The script's command lines (comments, blank lines and the shell's control words left out)."""
    lines = [line.strip() for line in SCRIPT.read_text().splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


def test_the_default_job_is_the_quick_start_test_command():
    quick_start = re.search(
        r"## Quick start\n+```\n(.*?)```", (ROOT / "README.md").read_text(), re.S
    ).group(1)
    test_command = quick_start.strip().splitlines()[1]
    assert test_command == 'pip install -e ".[test]" && python -m pytest'
    commands = _commands()
    assert commands.count(test_command) == 1
    # it runs unconditionally: at the script's top level, not inside the slow branch
    slow = commands.index('if [ "${1:-}" = slow ]; then')
    assert commands.index(test_command) < slow
    assert commands[slow + 1 : slow + 3] == ["python -m pytest -m slow", "fi"]


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
def test_an_unknown_job_is_refused_before_anything_runs(tmp_path):
    """The argument is checked first: a typo (``.ci/run slwo``) must not quietly run the default
    job alone."""
    done = subprocess.run(
        [shutil.which("bash"), str(SCRIPT), "slwo"],
        capture_output=True,
        text=True,
        timeout=30,
        env={"PATH": str(tmp_path)},
    )  # no pip, apt or python on PATH: nothing could run
    assert done.returncode == 2
    assert done.stderr == ".ci/run: unknown job 'slwo'; expected no argument (default) or 'slow'\n"
