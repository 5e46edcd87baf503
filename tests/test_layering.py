"""Imports go one way (io -> allan -> noise -> inference -> drift -> report -> cli), the library
never imports the command line, no module reaches for a private name or module of another stage, and
each stage is a subpackage whose docstring says what it owns."""

import ast
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "bayes_imu"
#: the stages in data-flow order; the shared infrastructure (rank 0) is imported by all
STAGES = ("io", "allan", "noise", "inference", "drift", "report", "cli")
#: ``_compiled`` is the extension module of precompiled kernels (``setup.py``) that allan and noise
#: both load
INFRASTRUCTURE = {"errors", "_version", "_progress", "_lazy", "_system", "_compiled"}
STAGE = {name: rank + 1 for rank, name in enumerate(STAGES)}
STAGE.update({name: 0 for name in INFRASTRUCTURE})
STAGE["__init__"] = len(STAGES) + 1  # the top-level namespace re-exports every stage


def _modules():
    """(path, stage, package parts) of every module; the stage is its top-level subpackage."""
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        yield path, parts[0], parts


def _sources():
    """(label, stage, package parts, source text) of every module: what the rule checkers read."""
    for path, top, parts in _modules():
        yield str(path.relative_to(PACKAGE.parent)), top, parts, path.read_text()


def _imports(source, parts):
    """(target parts under bayes_imu, imported names, line) of every import of the package in
    ``source`` (a module at ``parts`` under bayes_imu), at any depth: relative imports, absolute
    ``import bayes_imu.x`` and ``from bayes_imu.x import y``, and
    ``importlib.import_module("bayes_imu.x")`` with a string literal (also
    ``import_module(".x", package="bayes_imu.y")``)."""
    tree = ast.parse(source)
    package = list(parts[:-1])
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)]
            target = base + (node.module.split(".") if node.module else [])
            yield from _targets(target, [a.name for a in node.names], node.lineno)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "bayes_imu":
            names = [a.name for a in node.names]
            yield from _targets(node.module.split(".")[1:], names, node.lineno)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                dotted = alias.name.split(".")
                if dotted[0] == "bayes_imu" and len(dotted) > 1:
                    yield dotted[1:], [], node.lineno
        elif isinstance(node, ast.Call) and _is_import_module(node.func) and node.args:
            name = node.args[0]
            if not (isinstance(name, ast.Constant) and isinstance(name.value, str)):
                continue
            anchor = next((k.value for k in node.keywords if k.arg == "package"), None)
            if len(node.args) > 1:
                anchor = node.args[1]
            if name.value.startswith("."):
                if not (isinstance(anchor, ast.Constant) and isinstance(anchor.value, str)):
                    continue
                level = len(name.value) - len(name.value.lstrip("."))
                base = anchor.value.split(".")
                rest = [p for p in name.value[level:].split(".") if p]
                dotted = base[: len(base) - (level - 1)] + rest
            else:
                dotted = name.value.split(".")
            if dotted[0] == "bayes_imu" and len(dotted) > 1:
                yield dotted[1:], [], node.lineno


def _is_import_module(func):
    """``import_module`` or ``importlib.import_module``."""
    return (isinstance(func, ast.Name) and func.id == "import_module") or (
        isinstance(func, ast.Attribute) and func.attr == "import_module")


def _targets(target, names, line):
    if not target:  # "from . import x" at the top level, "from bayes_imu import x"
        for name in names:
            yield [name], [], line
    else:
        yield target, names, line


def backward_imports(sources):
    """Imports of a later stage, or of the command line from the library, in ``sources``."""
    backwards = []
    for label, top, parts, text in sources:
        for target, _, line in _imports(text, parts):
            if target[0] == top or target[0] not in STAGE:
                continue
            if STAGE[target[0]] > STAGE[top] or (target[0] == "cli" and top != "__init__"):
                backwards.append(f"{label}:{line} imports {'.'.join(target)}")
    return backwards


def private_imports(sources):
    """Private names or modules of another stage imported in ``sources``."""
    private = []
    for label, top, parts, text in sources:
        for target, names, line in _imports(text, parts):
            if target[0] == top:
                continue
            hidden = [p for p in target if p.startswith("_") and p not in INFRASTRUCTURE]
            hidden += [n for n in names if n.startswith("_") and n != "__version__"]
            if hidden:
                private.append(f"{label}:{line} imports {'.'.join(target)} {hidden}")
    return private


def test_every_module_belongs_to_a_stage():
    missing = {top for _, top, _ in _modules()} - set(STAGE)
    assert not missing, (
        f"put {sorted(missing)} in a stage subpackage (tests/test_layering.py, "
        "docs/architecture.md)"
    )


@pytest.mark.parametrize("stage", STAGES)
def test_each_stage_is_a_subpackage_that_says_what_it_owns(stage):
    module = importlib.import_module(f"bayes_imu.{stage}")
    assert module.__file__.endswith("__init__.py")
    assert "Owns" in (module.__doc__ or "") or "owns" in (module.__doc__ or "")


def test_imports_go_one_way_and_never_to_the_cli():
    backwards = backward_imports(_sources())
    assert not backwards, "imports running backwards:\n" + "\n".join(backwards)


def test_no_private_names_across_stages():
    private = private_imports(_sources())
    assert not private, "private names imported across stages:\n" + "\n".join(private)


def test_the_check_sees_a_backward_import(tmp_path):
    """The AST walk resolves a relative import two levels up to its stage (the test can fail)."""
    source = "from ..report.plots import pyplot\nfrom .._lazy import LazyModule\n"
    found = list(_imports(source, ("allan", "fake")))
    assert found[0][0] == ["report", "plots"] and STAGE[found[0][0][0]] > STAGE["allan"]
    assert found[1][0] == ["_lazy"] and STAGE["_lazy"] == 0


#: planted violations in a library module (noise/fake.py): each must fail a rule checker
PLANTED = [
    ("from ..cli.main import main\n", backward_imports),
    ("from bayes_imu.cli.main import main\n", backward_imports),
    ("import bayes_imu.report.plots\n", backward_imports),
    ("import bayes_imu.cli.main as m\n", backward_imports),
    ("from bayes_imu import cli\n", backward_imports),
    ("import importlib\nimportlib.import_module('bayes_imu.report.plots')\n", backward_imports),
    ("from importlib import import_module\nimport_module('bayes_imu.cli')\n", backward_imports),
    ("import importlib\nimportlib.import_module('.report', package='bayes_imu')\n",
     backward_imports),
    ("def f():\n    from bayes_imu.inference.fit import fit_allan\n", backward_imports),
    ("from bayes_imu.io.readers import _parse_plain\n", private_imports),
    ("from bayes_imu.allan import _sources\n", private_imports),
    ("import importlib\nimportlib.import_module('bayes_imu.io._hidden')\n", private_imports),
]


@pytest.mark.parametrize("source, checker", PLANTED,
                         ids=[p[0].splitlines()[-1].strip() for p in PLANTED])
def test_planted_violation_fails_the_rule(source, checker):
    """The rule checkers themselves (not only the parser) flag each planted import in a library
    module, and pass the same module without it."""
    planted = [("bayes_imu/noise/fake.py", "noise", ("noise", "fake"), source)]
    assert checker(planted), source
    clean_source = "from ..allan import estimator\nimport numpy\n"
    clean = [("bayes_imu/noise/fake.py", "noise", ("noise", "fake"), clean_source)]
    assert not checker(clean)


def test_a_planted_module_in_a_copy_of_the_package_fails_the_layering_test(tmp_path):
    """The whole check over a copy of the package, with one absolute import of the command line
    added to a library module: the same functions the layering test runs report it."""
    import shutil

    copy = tmp_path / "bayes_imu"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    planted = '"""Planted."""\n\nfrom bayes_imu.cli.main import main\n'
    (copy / "drift" / "planted.py").write_text(planted)
    parts = {p: p.relative_to(copy).with_suffix("").parts for p in sorted(copy.rglob("*.py"))}
    sources = [(str(p), part[0], part, p.read_text()) for p, part in parts.items()]
    found = backward_imports(sources)
    assert len(found) == 1 and "planted.py:3 imports cli.main" in found[0]


def _error_texts(path):
    """(line, text) of the string parts of every ``raise SomeError(...)`` message in a module."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
            for part in ast.walk(node.exc):
                if isinstance(part, ast.Constant) and isinstance(part.value, str):
                    yield node.lineno, part.value


def test_library_errors_name_parameters_not_flags():
    """Outside the cli stage an error names the API's parameters (``out=``, ``force=True``); the
    command line maps them to its flags (``cli.main.as_flags``). Allowed: advice to rerun the
    command itself."""
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

    assert (
        as_flags("out=/tmp/a b: folder exists; or force=True to replace")
        == "--out /tmp/a b: folder exists; or --force to replace"
    )
    assert (
        as_flags("scheduler=tcp://h:1: cannot connect") == "--scheduler tcp://h:1: cannot connect"
    )
    assert as_flags("(or scheduler='serial')") == "(or --serial)"
    assert as_flags("(is rate_hz right?)") == "(is --rate right?)"
    assert as_flags("/data/out=1/log.csv: no such file") == "/data/out=1/log.csv: no such file"
