"""setup.py's hook on numba's AOT compiler, pinned to the numba versions it was checked on.

The AOT compiler gives every exported kernel one set of flags; the hook (``precompiled_kernels`` in
setup.py) replaces ``numba.pycc.compiler.compile_extra`` to give the sum-of-squares kernels their
fast-math flags, as their JIT build has. What it guards, the precompiled kernels equal to the JIT
build bit for bit, is ``tests/test_allan.py::test_precompiled_kernels_agree_with_the_jit_build``;
here, that the numba installed is one the hook was checked on, and that the entry point it
replaces still takes what it passes on.
"""

import ast
import inspect
from pathlib import Path

import pytest

SETUP = Path(__file__).resolve().parents[1] / "setup.py"


def _constant(name):
    """A module-level constant of setup.py (read, not imported: importing it runs the build)."""
    tree = ast.parse(SETUP.read_text())
    node = next(n for n in tree.body if isinstance(n, ast.Assign) and n.targets[0].id == name)
    return ast.literal_eval(node.value)


def test_the_installed_numba_is_one_the_compiler_hook_was_checked_on():
    numba = pytest.importorskip("numba")
    checked = _constant("NUMBA_AOT_CHECKED")
    installed = numba.__version__
    assert any(installed == s or installed.startswith(s + ".") for s in checked), (
        f"numba {numba.__version__} is installed; setup.py's hook on "
        f"numba.pycc.compiler.compile_extra was checked on numba {', '.join(checked)}: rebuild "
        "(pip install -e .), run tests/test_allan.py and tests/test_build.py, "
        f"then add {numba.__version__} to NUMBA_AOT_CHECKED"
    )


def test_the_hooked_entry_point_takes_what_the_hook_passes_on():
    compiler = pytest.importorskip(
        "numba.pycc.compiler", reason="numba without its AOT compiler: no hook to check"
    )
    from numba.core.cpu import FastMathOptions

    parameters = tuple(inspect.signature(compiler.compile_extra).parameters)
    expected = _constant("COMPILE_EXTRA_PARAMETERS")
    assert parameters[: len(expected)] == expected
    assert FastMathOptions({"nnan"}).flags == {"nnan"}
