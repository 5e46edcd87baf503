"""The documentation's examples run as written (README walkthrough commands, docs/api.md code)."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _blocks(path, language):
    return re.findall(rf"```{language}\n(.*?)```", (ROOT / path).read_text(), re.S)


@pytest.mark.slow
def test_api_examples_run(tmp_path):
    code = "\n".join(_blocks("docs/api.md", "python"))
    assert "fit_allan" in code and "fit_population" in code
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=600)


@pytest.mark.slow
def test_readme_walkthrough_runs_as_written(tmp_path):
    """Every `bayes-imu` line of the README's walkthrough block, in order, from a copy of the
    project's data."""
    import shutil

    commands = [line for block in _blocks("README.md", "sh") for line in block.splitlines()
                if line.startswith("bayes-imu ")]
    assert len(commands) >= 5
    shutil.copytree(ROOT / "data_synthetic", tmp_path / "data_synthetic")
    for line in commands:
        args = shlex.split(line)
        done = subprocess.run(
            [sys.executable, "-m", "bayes_imu.cli.main", *args[1:]],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=900,
        )
        assert done.returncode == 0, (line, done.stderr)
    for path in ("walk/gyro/summary.json", "walk/gyro/drift.png", "walk/population/population.png",
                 "walk/report/report.html", "walk/imu.yaml"):
        assert (tmp_path / path).exists(), path


def test_the_cli_pages_summary_lists_every_command():
    """docs/cli.md's summary at the top left out ``nav``, ``export`` and ``plan``: every command
    of the parser has a line of it there, and the summary names no command the parser lacks."""
    from bayes_imu.cli.main import _build_parser

    parser = _build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    summary = _blocks("docs/cli.md", "")[0]
    listed = {line.split()[1] for line in summary.splitlines() if line.startswith("bayes-imu ")}
    assert listed == set(commands), sorted(set(commands) ^ listed)
