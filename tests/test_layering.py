"""Imports go one way (io -> allan -> noise -> inference -> drift -> report -> cli), the library never
imports the command line, no module reaches for a private name or module of another stage, and
each stage is a subpackage whose docstring says what it owns."""

import ast
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "bayes_imu"
#: the stages in data-flow order; the shared infrastructure (rank 0) is imported by all
STAGES = ("io", "allan", "noise", "inference", "drift", "report", "cli")
#: ``_compiled`` is the extension module of precompiled kernels (``setup.py``) that allan and noise both load
INFRASTRUCTURE = {"errors", "_version", "_progress", "_lazy", "_compiled"}
STAGE = {name: rank + 1 for rank, name in enumerate(STAGES)}
STAGE.update({name: 0 for name in INFRASTRUCTURE})
STAGE["__init__"] = len(STAGES) + 1  # the top-level namespace re-exports every stage


def _modules():
    """(path, stage, package parts) of every module; the stage is its top-level subpackage."""
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        yield path, parts[0], parts


def _imports(path, parts):
    """(target parts under bayes_imu, imported names, line) of every relative import, at any depth."""
    tree = ast.parse(path.read_text())
    package = list(parts[:-1])
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)]
            target = base + (node.module.split(".") if node.module else [])
            names = [a.name for a in node.names]
            if not target:  # "from . import x" at the top level
                for name in names:
                    yield [name], [], node.lineno
            else:
                yield target, names, node.lineno


def test_every_module_belongs_to_a_stage():
    missing = {top for _, top, _ in _modules()} - set(STAGE)
    assert not missing, f"put {sorted(missing)} in a stage subpackage (tests/test_layering.py, docs/architecture.md)"


@pytest.mark.parametrize("stage", STAGES)
def test_each_stage_is_a_subpackage_that_says_what_it_owns(stage):
    module = importlib.import_module(f"bayes_imu.{stage}")
    assert module.__file__.endswith("__init__.py")
    assert "Owns" in (module.__doc__ or "") or "owns" in (module.__doc__ or "")


def test_imports_go_one_way_and_never_to_the_cli():
    backwards = []
    for path, top, parts in _modules():
        for target, _, line in _imports(path, parts):
            if target[0] == top or target[0] not in STAGE:
                continue
            if STAGE[target[0]] > STAGE[top] or (target[0] == "cli" and top != "__init__"):
                backwards.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {'.'.join(target)}")
    assert not backwards, "imports running backwards:\n" + "\n".join(backwards)


def test_no_private_names_across_stages():
    private = []
    for path, top, parts in _modules():
        for target, names, line in _imports(path, parts):
            if target[0] == top:
                continue
            hidden = [p for p in target if p.startswith("_") and p not in INFRASTRUCTURE]
            hidden += [n for n in names if n.startswith("_") and n != "__version__"]
            if hidden:
                private.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {'.'.join(target)} {hidden}")
    assert not private, "private names imported across stages:\n" + "\n".join(private)


def test_the_check_sees_a_backward_import(tmp_path):
    """The AST walk resolves a relative import two levels up to its stage (the test can fail)."""
    src = tmp_path / "fake.py"
    src.write_text("from ..report.plots import pyplot\nfrom .._lazy import LazyModule\n")
    found = list(_imports(src, ("allan", "fake")))
    assert found[0][0] == ["report", "plots"] and STAGE[found[0][0][0]] > STAGE["allan"]
    assert found[1][0] == ["_lazy"] and STAGE["_lazy"] == 0


def _error_texts(path):
    """(line, text) of the string parts of every ``raise SomeError(...)`` message in a module."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
            for part in ast.walk(node.exc):
                if isinstance(part, ast.Constant) and isinstance(part.value, str):
                    yield node.lineno, part.value


def test_library_errors_name_parameters_not_flags():
    """Outside the cli stage an error names the API's parameters (``out=``, ``force=True``); the command
    line maps them to its flags (``cli.main.as_flags``). Allowed: advice to rerun the command itself."""
    import re

    flag = re.compile(r"(?<![\w-])--[a-z][a-z-]+")
    found = []
    for path, top, _ in _modules():
        if top == "cli":
            continue
        for line, text in _error_texts(path):
            if flag.search(text) and "bayes-imu fit" not in text and "rerun fit" not in text:
                found.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {text!r}")
    assert not found, "library errors naming command-line flags:\n" + "\n".join(found)


def test_the_command_maps_parameters_to_flags():
    from bayes_imu.cli.main import as_flags

    assert as_flags("out=/tmp/a b: folder exists; or force=True to replace") == "--out /tmp/a b: folder exists; or --force to replace"
    assert as_flags("scheduler=tcp://h:1: cannot connect") == "--scheduler tcp://h:1: cannot connect"
    assert as_flags("(or scheduler='serial')") == "(or --serial)"
    assert as_flags("(is rate_hz right?)") == "(is --rate right?)"
    assert as_flags("/data/out=1/log.csv: no such file") == "/data/out=1/log.csv: no such file"
