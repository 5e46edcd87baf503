"""The import tricks of ``bayes_imu/_lazy.py`` (emcee without scipy.stats, corner without ArviZ):
pinned to the library versions they were checked on, and loud, never half-working, where a library
changes underneath them.

What they save is timed in docs/reference.md; that the imports stay out of a fit's process is
``tests/test_imports.py``; that emcee's KDE move and corner's ArviZ entry point still work is
``tests/test_sampling.py`` and ``tests/test_plots.py``.
"""

import json
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from bayes_imu._lazy import CHECKED_VERSIONS, in_series

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", sorted(CHECKED_VERSIONS))
def test_each_import_trick_is_checked_on_the_installed_version(name):
    installed = version(name)
    assert in_series(installed, CHECKED_VERSIONS[name]), (
        f"{name} {installed} is installed; bayes_imu/_lazy.py imports it without one of its "
        f"optional imports and was checked on {name} {', '.join(CHECKED_VERSIONS[name])}: run "
        "tests/test_lazy.py, test_imports.py, "
        f"test_sampling.py and test_plots.py on {name} {installed}, then add it to CHECKED_VERSIONS"
    )


#: fake libraries: ``good`` leaves its entry point None without ``dep`` (as emcee and corner do),
#: ``eager`` imports
#: ``dep`` unconditionally, ``changed`` no longer leaves its entry point None
LIBRARIES = {
    "dep/__init__.py": "VALUE = 42\n",
    "good/__init__.py": "try:\n    from dep import VALUE\nexcept ImportError:\n    VALUE = None\n",
    "eager/__init__.py": "from dep import VALUE\n",
    "eager/part.py": "",
    "changed/__init__.py": "VALUE = 'always'\n",
}

CODE = """
import json, os, sys
from bayes_imu._lazy import import_without

def stand_in():
    import dep
    return dep.VALUE

out = {}
for name in ("good", "eager", "changed"):
    try:
        module = import_without(name, "dep", owner=name, attribute="VALUE", stand_in=stand_in)
        out[name] = ["ok", module.VALUE is stand_in, "dep" in sys.modules]
    except ImportError as exc:
        left = sorted(m for m in sys.modules if m.split(".")[0] in (name, "dep"))
        out[name] = ["error", str(exc), left]
print(json.dumps(out))
"""


def _run(folder, **env):
    for path, text in LIBRARIES.items():
        (folder / path).parent.mkdir(exist_ok=True)
        (folder / path).write_text(text)
    done = subprocess.run(
        [sys.executable, "-c", CODE],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
        env={"PYTHONPATH": f"{folder}:{ROOT}", "PATH": "/usr/bin:/bin", **env},
    )
    return json.loads(done.stdout)


def test_a_library_that_changed_underneath_fails_loudly_and_leaves_nothing_half_imported(tmp_path):
    out = _run(tmp_path)
    assert out["good"] == [
        "ok",
        True,
        False,
    ]  # the stand-in in place, dep not imported (nor left marked absent)
    status, message, left = out["eager"]
    assert (
        status == "error" and left == []
    )  # neither eager, eager.part nor a None placeholder for dep remains
    assert message.startswith("eager (version unknown): it no longer imports without dep (")
    assert "set BAYES_IMU_PLAIN_IMPORTS=1" in message and "\n" not in message
    status, message, _ = out["changed"]
    assert status == "error" and message.startswith(
        "changed (version unknown): changed.VALUE is not None without dep"
    )


def test_the_switch_turns_the_tricks_into_plain_imports(tmp_path):
    out = _run(tmp_path, BAYES_IMU_PLAIN_IMPORTS="1")
    assert out["eager"] == ["ok", False, True] and out["changed"] == ["ok", False, True]


def test_a_release_series_holds_its_patch_releases_only():
    assert in_series("3.1.6", ("3.1",)) and in_series("3.1", ("3.1",))
    assert not in_series("3.10.0", ("3.1",)) and not in_series("3.2.0", ("3.1",))
