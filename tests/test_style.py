"""House style checks that need no linter: every line of the package, the tests, the scripts and
setup.py is at most 100 characters long (the limit ``[tool.ruff]`` sets in pyproject.toml for
``ruff check``, checked here in pure Python so that the default suite enforces it)."""

from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the longest line allowed, in characters (pyproject.toml's ``[tool.ruff] line-length``)
MAX_LINE = 100
#: how many offending lines the failure message names
SHOWN = 20


def _python_files():
    """Every .py file of bayes_imu/, tests/ and scripts/ (caches excluded), and setup.py."""
    files = [ROOT / "setup.py"]
    for folder in ("bayes_imu", "tests", "scripts"):
        files += sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)
    return files


def _long_lines(path, limit=MAX_LINE):
    """(line number, length) of each line of ``path`` longer than ``limit`` characters."""
    lines = path.read_text(encoding="utf-8").split("\n")
    lengths = (len(line.rstrip("\r")) for line in lines)
    return [(number, length) for number, length in enumerate(lengths, 1) if length > limit]


def test_line_length():
    offenders = [(path.relative_to(ROOT).as_posix(), number, length) for path in _python_files()
                 for number, length in _long_lines(path)]
    if offenders:
        per_file = Counter(path for path, _, _ in offenders).most_common()
        files = ", ".join(f"{path} ({count})" for path, count in per_file[:10])
        more = ", ..." if len(per_file) > 10 else ""
        first = "\n".join(f"  {path}:{number}: {length} characters"
                           for path, number, length in offenders[:SHOWN])
        pytest.fail(f"{len(offenders)} lines longer than {MAX_LINE} characters in "
                    f"{len(per_file)} files, most in {files}{more}; the first:\n{first}",
                    pytrace=False)


def test_line_length_finds_a_planted_long_line(tmp_path):
    # the checker on a file with a line of exactly the limit and one a character longer
    planted = tmp_path / "planted.py"
    planted.write_text("x = 1\n" + "#" * MAX_LINE + "\n" + "y = '" + "z" * (MAX_LINE - 5) + "'\n")
    assert _long_lines(planted) == [(3, MAX_LINE + 1)]
    assert ROOT / "setup.py" in _python_files() and Path(__file__).resolve() in _python_files()
