"""Safe outputs: claimed atomically, staged beside the target, never destroying what the run did not create.

Rules (the README's "Exit status and outputs" section states them for users):

* **Claim.** ``--out`` is claimed atomically when the run starts: a new folder is created
  with ``mkdir`` (a second run into the same new folder fails at once); an existing empty
  folder, or a previous bayes_imu result being replaced, gets a claim file created with
  ``O_EXCL``. A file target (``kalibr --out``) is claimed by creating it with ``O_EXCL``.
* **Stage.** The command writes into a temporary sibling on the same file system; only when
  it succeeds are its entries moved into the claimed folder, one by one. Nothing the run did
  not create is deleted or replaced: an entry that appears in ``--out`` meanwhile (a user's
  notes) stays, and one that collides with an output name stops the run with an error.
* **--force** replaces only a previous bayes_imu result: a folder whose marker file
  (:data:`MARKER`) lists what an earlier run wrote, and only those entries are removed; a
  folder holding anything else is refused, naming what is there. A file target is replaced
  only if it is a bayes_imu file (its first line starts with ``# bayes_imu``, or a JSON
  object with ``bayes_imu_version``).
* **Inputs.** An output that is, or would contain, an input is refused.
* **Failure and signals.** On any exception (Ctrl-C and SIGTERM included) the staging
  folder, the claim and the parents the run created (if still empty) are removed, and a
  claimed new folder too if nothing else was put in it; previous results stay as they were.
* **Space.** A run is refused before any work when the target's file system has less than
  :data:`MIN_FREE_BYTES` free (a full disk mid-write can crash HDF5 writers).
"""

import errno
import json
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

__all__ = ["staged_folder", "staged_file", "safe_folder_name", "MARKER", "MIN_FREE_BYTES"]

#: marker file of a bayes_imu result folder: JSON ``{"bayes_imu": version, "entries": [...]}``
MARKER = ".bayes_imu.json"
_CLAIM = ".bayes_imu.claim"
#: free space a run needs on the target's file system before it starts
MIN_FREE_BYTES = 64 * 2**20


def _check_inputs(target, inputs):
    resolved = target.resolve()
    for item in inputs:
        item = Path(item).resolve()
        if item == resolved or resolved in item.parents:
            raise InputError(f"out={target}: it is or contains the input {item}; choose an output that holds "
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
        try:
            p.mkdir()
        except FileExistsError:  # a concurrent run made it: not ours
            created.remove(p)
    return created


def _remove_created(created):
    for p in created:  # innermost first; only if still empty
        try:
            p.rmdir()
        except OSError:
            break


def _check_space(folder, target):
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return
    if free < MIN_FREE_BYTES:
        raise InputError(f"out={target}: only {free / 2**20:.0f} MiB free on its file system; need at least "
                         f"{MIN_FREE_BYTES / 2**20:.0f} MiB (nothing was written)")


def previous_entries(folder):
    """Entries a previous bayes_imu run wrote into ``folder`` (from its marker), or None."""
    try:
        doc = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        entries = doc["entries"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(entries, list) or not all(isinstance(e, str) and "/" not in e and e not in ("", ".", "..")
                                                for e in entries):
        return None
    return entries


def _claim_folder(target, force):
    """Claim ``target``: returns ``(made_it, previous_entries)``; raises InputError if it is not ours to write."""
    if target.exists() and not target.is_dir():
        raise InputError(f"out={target}: exists and is not a folder; expected a folder to write into")
    try:
        target.mkdir()
        made = True
    except FileExistsError:
        made = False
    previous = []
    busy = InputError(f"out={target}: another bayes-imu run is writing there ({_CLAIM} exists); wait for it, "
                      "or remove that file if no run is active")
    if not made:
        if (target / _CLAIM).exists():
            raise busy
        present = sorted(p.name for p in target.iterdir())
        if present:
            previous = previous_entries(target)
            if not force:
                raise InputError(f"out={target}: folder exists and is not empty ({_names(present)}); use a new "
                                 "folder, or force=True to replace a previous bayes_imu result there")
            if previous is None:
                raise InputError(f"out={target}: force=True replaces only a previous bayes_imu result, and this folder "
                                 f"holds {_names(present)} with no {MARKER} marker; choose another folder")
            foreign = [n for n in present if n not in previous and n != MARKER]
            if foreign:
                raise InputError(f"out={target}: force=True would leave {_names(foreign)}, which no bayes_imu run "
                                 "wrote there; move them away or choose another folder")
    try:
        os.close(os.open(target / _CLAIM, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
    except FileExistsError:
        raise busy from None
    return made, previous


def _names(names, limit=5):
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


@contextmanager
def staged_folder(target, *, force=False, inputs=()):
    """Yield a temporary folder whose entries move into ``target`` when the block succeeds (rules above).

    Raises
    ------
    InputError
        ``target`` is a file, holds an input, is claimed by another run, or is a non-empty
        folder that is not a previous bayes_imu result (or is one, without ``force``).
    """
    from .._version import __version__

    target = Path(target)
    _check_inputs(target, inputs)
    created = _make_parents(target)
    try:
        _check_space(target.parent, target)
        made, previous = _claim_folder(target, force)
    except BaseException:
        _remove_created(created)
        raise
    tmp = None
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
        _umask_mode(tmp, 0o777)
        yield tmp
        entries = sorted(p.name for p in tmp.iterdir())
        clash = [n for n in entries if (target / n).exists() and n not in previous]
        if clash:
            raise InputError(f"out={target}: {_names(clash)} appeared there during the run; nothing was replaced "
                             "(the new results were not kept)")
        (tmp / MARKER).write_text(json.dumps({"bayes_imu": __version__, "entries": entries}) + "\n", encoding="utf-8")
        for name in previous:  # the previous result, now being replaced: only what that run wrote
            old = target / name
            if old.is_dir() and not old.is_symlink():
                shutil.rmtree(old)
            else:
                old.unlink(missing_ok=True)
        for name in entries + [MARKER]:
            os.replace(tmp / name, target / name)
    except BaseException as exc:
        _cleanup_folder(target, tmp, made, created)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise InputError(f"out={target}: the disk is full ({exc.strerror}); nothing was kept from this run"
                             + (" and the previous results are unchanged" if previous else "")) from None
        raise
    (target / _CLAIM).unlink(missing_ok=True)
    tmp.rmdir()


def _cleanup_folder(target, tmp, made, created):
    if tmp is not None:
        shutil.rmtree(tmp, ignore_errors=True)
    (target / _CLAIM).unlink(missing_ok=True)
    if made:
        try:
            target.rmdir()  # only if the user put nothing there meanwhile
        except OSError:
            return
    _remove_created(created)


@contextmanager
def staged_file(target, *, force=False, inputs=()):
    """Yield a temporary file path that replaces ``target`` when the block succeeds (rules above)."""
    target = Path(target)
    if target.is_dir():
        raise InputError(f"out={target}: is a folder; expected a file name")
    _check_inputs(target, inputs)
    created = _make_parents(target)
    made = False
    try:
        _check_space(target.parent, target)
        try:
            os.close(os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            made = True
        except FileExistsError:
            if not force:
                raise InputError(f"out={target}: file exists; use force=True to replace a previous bayes_imu file") \
                    from None
            if not _is_ours(target):
                raise InputError(f"out={target}: force=True replaces only a file bayes_imu wrote (first line "
                                 "'# bayes_imu ...'); this one is not, choose another name") from None
    except BaseException:
        _remove_created(created)
        raise
    tmp = None
    try:
        handle, name = tempfile.mkstemp(prefix=f".{target.name}.partial-", dir=target.parent)
        os.close(handle)
        tmp = Path(name)
        _umask_mode(tmp, 0o666)
        yield tmp
        os.replace(tmp, target)
    except BaseException as exc:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if made and target.exists() and target.stat().st_size == 0:
            target.unlink()
        _remove_created(created)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise InputError(f"out={target}: the disk is full ({exc.strerror}); nothing was written") from None
        raise


def _is_ours(path):
    """A file bayes_imu wrote: a '# bayes_imu' header line, or a JSON object with 'bayes_imu_version'."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 20)
    except OSError:
        return False
    if head.startswith(b"# bayes_imu"):
        return True
    try:
        return "bayes_imu_version" in json.loads(head.decode("utf-8"))
    except (ValueError, TypeError, UnicodeDecodeError):
        return False


def safe_folder_name(text, taken=()):
    """A folder name from ``text`` (letters, digits, ``_.-``), made unique against ``taken``."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "log"
    while name in taken:
        name += "_"
    return name
