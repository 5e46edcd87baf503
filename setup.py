"""Build of bayes_imu: the metadata is in setup.cfg; this file adds the precompiled kernels.

``bayes_imu._compiled`` is the ahead-of-time build (numba's AOT compiler, ``numba.pycc``) of the
kernels in ``bayes_imu/allan/_sources.py``, ``bayes_imu/noise/_sources.py`` and
``bayes_imu/io/_sources.py`` (the parser, never JIT-compiled: without it logs are read by numpy):
the same Python functions that numba JIT-compiles at run time for long records (and everywhere,
where the build had no AOT compiler). The drift grid is among them, so a fit with drift bands
compiles nothing either. A command that fits an ordinary log then never imports numba nor loads its
compiler (timings: docs/speed_under_load.md#imports). The code targets any x86-64 (or the build
machine's architecture family), not the build CPU, so a wheel runs wherever it is installed. Where
numba has no AOT compiler the package is built without the extension and every kernel is
JIT-compiled on first use, as before (a warning says so).
"""

import atexit
import copy
import importlib
import os
import shutil
import sys
import tempfile
import types
import warnings
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent
#: exported name -> (source module, numba signature)
KERNELS = {
    "phase_chunk": ("allan", "f8[::1](f8[::1], f8, f8[::1], i8, f8[::1])"),
    "sums_all": ("allan", "f8[::1](f8[::1], i8[::1], i8)"),
    "sum3": ("allan", "f8(f8[::1], f8[::1], f8[::1], i8)"),
    "pair_sums": ("allan", "f8[:, ::1](f8[::1], i8[::1], i8, f8, f8[::1], f8[::1])"),
    "avar_rows": (
        "noise",
        "void(f8[::1], f8[:, ::1], f8[::1], f8[::1], f8[::1], f8[::1], f8[:, ::1], f8, f8[:, ::1])",
    ),
    "parse_table": ("io", "i8(u1[::1], i8, i8, i8, i8[::1], f8[:, ::1])"),
    "pair_sum_lags": ("noise", "f8(f8[::1], f8[::1], f8[::1], i8, i8, i8, i8, i8, i8, i8)"),
    "second_differences_into": ("noise", "void(f8[::1], i8, i8, f8[::1])"),
    "propagate_diagonal": (
        "noise", "void(f8[:, :, ::1], f8[:, :, ::1], f8[:, :, ::1], i8[::1], f8[:, :, ::1])"
    ),
    "drift_rows": (
        "noise",
        "void(i8, f8[::1], f8[::1], f8[::1], f8[:, ::1], f8[::1], f8, f8[::1], f8[::1], f8[:, "
        "::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1])",
    ),
}

#: kernels (of ``bayes_imu/noise/_sources.py``) whose Python wrapper releases the GIL while they
#: run: the navigation bands' propagation runs while a thread imports matplotlib
#: (bayes_imu.report.nav)
RELEASE_GIL = {"propagate_diagonal"}


def _load(stage):
    """A kernel source module ``bayes_imu.<stage>._sources`` from this tree, its package-relative
    imports (``noise/_sources.py`` compiles formulas of ``noise/euler_sums.py``) resolved in
    stand-in packages, so that neither the installed package nor the packages' ``__init__`` (and
    what they import) is needed."""
    for name, folder in (
        ("bayes_imu", HERE / "bayes_imu"),
        (f"bayes_imu.{stage}", HERE / "bayes_imu" / stage),
    ):
        if name not in sys.modules:
            package = types.ModuleType(name)
            package.__path__ = [str(folder)]
            sys.modules[name] = package
    return importlib.import_module(f"bayes_imu.{stage}._sources")


#: numba release series on which the fast-math hook of precompiled_kernels was checked (the
#: precompiled kernels equal numba's JIT build bit for bit: tests/test_allan.py); setup.cfg pins the
#: same series, and tests/test_build.py fails, naming the version, on another
NUMBA_AOT_CHECKED = ("0.68",)
#: the leading parameters of numba.pycc.compiler.compile_extra that the hook passes on
COMPILE_EXTRA_PARAMETERS = ("typingctx", "targetctx", "func", "args", "return_type", "flags")


def _check_compiler_hook(pycc_compiler):
    """Refuse to build, naming numba's version, where the AOT compiler no longer has the entry point
    the fast-math hook replaces: the kernels would otherwise be built without their fast-math
    flags."""
    import inspect

    import numba

    parameters = tuple(inspect.signature(pycc_compiler.compile_extra).parameters)
    if parameters[:len(COMPILE_EXTRA_PARAMETERS)] != COMPILE_EXTRA_PARAMETERS:
        raise RuntimeError(f"numba {numba.__version__}: numba.pycc.compiler.compile_extra"
                           f"{parameters} is not the entry point setup.py's fast-math hook was "
                           f"checked on (numba {', '.join(NUMBA_AOT_CHECKED)}); build with a "
                           "checked numba, or update precompiled_kernels")


def precompiled_kernels():
    """The ``Extension`` of ``bayes_imu._compiled``, or ``None`` where numba has no AOT compiler."""
    # what the build JIT-compiles on the way (a kernel's callee) is cached outside the package: an
    # entry next to the sources would name this build's module, not the installed one
    os.environ["NUMBA_CACHE_DIR"] = cache = tempfile.mkdtemp(prefix="bayes_imu_build_")
    atexit.register(shutil.rmtree, cache, ignore_errors=True)
    try:
        import numba.pycc.compiler as pycc_compiler
        from numba.core.cpu import FastMathOptions
        from numba.pycc import CC
    except ImportError as exc:
        warnings.warn(
            f"bayes_imu: building without precompiled kernels ({exc}); they are JIT-compiled on "
            "first use"
        )
        return None
    _check_compiler_hook(pycc_compiler)
    sources = {stage: _load(stage) for stage in ("allan", "noise", "io")}
    fastmath = sources["allan"].FASTMATH
    plain = pycc_compiler.compile_extra

    def compile_extra(typingctx, targetctx, func, args, return_type, flags, *rest, **kwargs):
        # the AOT compiler gives every export one set of flags: the sum-of-squares kernels get their
        # fast-math flags here (as their JIT build does), the running sums keep strict IEEE
        # arithmetic
        if func.__name__ in fastmath and func.__module__ == sources["allan"].__name__:
            flags = copy.copy(flags)
            flags.fastmath = FastMathOptions(fastmath[func.__name__])
        # and the kernels that run beside a thread release the interpreter (as their JIT build's
        # nogil=True does)
        if func.__name__ in RELEASE_GIL and func.__module__ == sources["noise"].__name__:
            flags = copy.copy(flags)
            flags.release_gil = True
        return plain(typingctx, targetctx, func, args, return_type, flags, *rest, **kwargs)

    pycc_compiler.compile_extra = compile_extra
    # the extension's name is the package of the module that defines it, plus its basename
    owner = types.ModuleType("bayes_imu._build")
    owner.__file__ = str(HERE / "bayes_imu" / "_build.py")
    cc = CC("_compiled", source_module=owner)
    cc.verbose = False
    for name, (stage, signature) in KERNELS.items():
        cc.export(name, signature)(getattr(sources[stage], name))
    return cc.distutils_extension()


extension = precompiled_kernels()
setup(ext_modules=[extension] if extension is not None else [])
