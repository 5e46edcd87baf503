"""Safe outputs: written to a temporary sibling, moved into place only when complete.

:func:`staged_folder` and :func:`staged_file` are context managers. Inside the ``with``
block the command writes into a temporary folder (or file) next to the target, on the
same file system; on normal exit it is renamed onto the target, on any exception
(including Ctrl-C) it is removed, together with any parent folders created for it, so a
failed run leaves nothing behind. An existing non-empty target is refused unless
``force``; a target that would contain (and so replace) an input file is always refused.
"""

import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .errors import InputError

__all__ = ["staged_folder", "staged_file", "safe_folder_name"]


def _check_inputs(target, inputs):
    resolved = target.resolve()
    for item in inputs:
        item = Path(item).resolve()
        if item == resolved or resolved in item.parents:
            raise InputError(f"--out {target}: it contains the input {item}; choose an output folder that holds "
                             "no input file")


def _umask_mode(path, mode):
    """Give a mkdtemp/mkstemp result (0700/0600) the permissions of an ordinary new entry."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, mode & ~umask)


def _make_parents(folder):
    """Create missing parents of ``folder``; return those created, innermost first."""
    created = []
    parent = folder.parent
    while not parent.exists():
        created.append(parent)
        parent = parent.parent
    for p in reversed(created):
        p.mkdir()
    return created


def _remove_created(created):
    for p in created:  # innermost first; only if still empty
        try:
            p.rmdir()
        except OSError:
            break


@contextmanager
def staged_folder(target, *, force=False, inputs=()):
    """Yield a temporary folder that becomes ``target`` when the block succeeds.

    Raises
    ------
    InputError
        ``target`` is a file, or a non-empty folder without ``force``, or holds an input.
    """
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise InputError(f"--out {target}: exists and is not a folder; expected a folder to write into")
    if target.is_dir() and any(target.iterdir()) and not force:
        raise InputError(f"--out {target}: folder exists and is not empty; use --force to replace it")
    _check_inputs(target, inputs)
    created = _make_parents(target)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
        _umask_mode(tmp, 0o777)
    except OSError as exc:
        _remove_created(created)
        raise InputError(f"--out {target}: cannot write there ({exc.strerror})") from None
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        _remove_created(created)
        raise
    old = None
    if target.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        os.replace(target, old / "previous")
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


@contextmanager
def staged_file(target, *, force=False, inputs=()):
    """Yield a temporary file path that replaces ``target`` when the block succeeds."""
    target = Path(target)
    if target.is_dir():
        raise InputError(f"--out {target}: is a folder; expected a file name")
    if target.exists() and not force:
        raise InputError(f"--out {target}: file exists; use --force to replace it")
    _check_inputs(target, inputs)
    created = _make_parents(target)
    try:
        handle, name = tempfile.mkstemp(prefix=f".{target.name}.partial-", dir=target.parent)
        os.close(handle)
        _umask_mode(name, 0o666)
    except OSError as exc:
        _remove_created(created)
        raise InputError(f"--out {target}: cannot write there ({exc.strerror})") from None
    tmp = Path(name)
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        _remove_created(created)
        raise
    os.replace(tmp, target)


def safe_folder_name(text, taken=()):
    """A folder name from ``text`` (letters, digits, ``_.-``), made unique against ``taken``."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "log"
    while name in taken:
        name += "_"
    return name
