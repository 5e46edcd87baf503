"""Imports go one way (io -> allan -> noise -> inference -> drift -> report -> cli), the library never
imports the command line, and no module reaches for a private name of another module."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "bayes_imu"
STAGES = {
    0: {"errors", "_version", "_progress", "_lazy"},
    1: {"io", "timebase", "bags"},
    2: {"allan", "allan_table", "outofcore", "autocorr", "_kernels"},
    3: {"noise", "models", "simulate", "avar_covariance", "_euler", "datasheet"},
    4: {"likelihood", "selection", "stationarity", "fit", "population", "archive"},
    5: {"drift", "bands", "display"},
    6: {"report", "report_html", "plots", "kalibr", "fleet", "_output"},
    7: {"cli", "_sources", "__init__"},
}
STAGE = {name: rank for rank, names in STAGES.items() for name in names}
STAGE["drift"] = 3  # the closed forms (paper eqs 5-29) are what the noise terms' drift variances call


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        top = parts[0]
        yield path, top, parts


def _imports(path, parts):
    """(target top-level module, imported names, line) of every relative import, at any depth."""
    tree = ast.parse(path.read_text())
    package = list(parts[:-1])
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
            target = (base + (node.module.split(".") if node.module else []))
            names = [a.name for a in node.names]
            if not target:  # "from . import x"
                for name in names:
                    yield name, [], node.lineno
            else:
                yield target[0], names, node.lineno


def test_every_module_has_a_stage():
    missing = {top for _, top, _ in _modules()} - set(STAGE)
    assert not missing, f"assign a stage to {sorted(missing)} in tests/test_layering.py and docs/architecture.md"


def test_imports_go_one_way_and_never_to_the_cli():
    backwards = []
    for path, top, parts in _modules():
        for target, _, line in _imports(path, parts):
            if target == top or target not in STAGE:
                continue
            if STAGE[target] > STAGE[top] or (target == "cli" and top != "__init__"):
                backwards.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}")
    assert not backwards, "imports running backwards:\n" + "\n".join(backwards)


def test_no_private_names_across_modules():
    private = []
    for path, top, parts in _modules():
        for target, names, line in _imports(path, parts):
            if target == top:
                continue
            for name in names:
                if name.startswith("_") and name != "__version__":
                    private.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}.{name}")
    assert not private, "private names imported across modules:\n" + "\n".join(private)
