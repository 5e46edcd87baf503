"""Safe outputs: claimed atomically, staged beside the target, never destroying what the run did not
create.

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
  (:data:`MARKER`) records the SHA-256 of every file an earlier run wrote, at any depth, and
  every folder it made. Before anything is removed the whole tree below ``--out`` is checked:
  a file whose content no longer matches its recorded hash (edited, or a forged marker's
  entry), a file or folder the marker does not list (a user's notes in a sub-folder), a
  symbolic link or anything else refuses the run, naming what is there; nothing is removed.
  Only files whose hash matches are removed, then the run's folders once empty. A file
  target (``kalibr --out``) is replaced only if the sidecar marker beside it
  (``.NAME`` + :data:`FILE_MARKER_SUFFIX`, written with it) records the file's current hash; no
  heuristic on the file's content. A marker of an older bayes_imu (no hashes) is not trusted.
* **Inputs.** An output that is, or would contain, an input is refused.
* **Failure and signals.** On any exception (Ctrl-C and SIGTERM included) the staging
  folder, the claim and the parents the run created (if still empty) are removed, and a
  claimed new folder too if nothing else was put in it; previous results stay as they were.
* **Space.** A run is refused before any work when the target's file system has less than
  :data:`MIN_FREE_BYTES` free (a full disk mid-write can crash HDF5 writers).
"""

import errno
import hashlib
import json
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

__all__ = [
    "staged_folder",
    "staged_file",
    "safe_folder_name",
    "file_hashes",
    "user_os_error",
    "MARKER",
    "FILE_MARKER_SUFFIX",
    "MIN_FREE_BYTES",
    "USER_ERRNOS",
]

#: marker file of a bayes_imu result folder: JSON ``{"bayes_imu": version, "entries": [top-level
#: names],
#: "files": {relative path: sha256}, "folders": [relative paths]}``
MARKER = ".bayes_imu.json"
#: a file target's marker: ``.NAME`` + this suffix beside it, JSON ``{"bayes_imu": version, "file":
#: NAME,
#: "sha256": hash}``
FILE_MARKER_SUFFIX = ".bayes_imu.json"
_MARKER_FORMAT = 2
_CLAIM = ".bayes_imu.claim"
#: free space a run needs on the target's file system before it starts
MIN_FREE_BYTES = 64 * 2**20


#: system errors that are the user's to fix (a path, a permission, a full disk), never a bug: exit
#: status 2
USER_ERRNOS = frozenset(
    {
        errno.EACCES,
        errno.EPERM,
        errno.EROFS,
        errno.ENOTDIR,
        errno.EISDIR,
        errno.ENAMETOOLONG,
        errno.ELOOP,
        errno.ENOSPC,
        errno.EDQUOT,
        errno.ENOENT,
        errno.EXDEV,
        errno.EMLINK,
        errno.ETXTBSY,
    }
)


def user_os_error(exc):
    """One line for a system error the user can fix (:data:`USER_ERRNOS`, a symbolic link loop),
    else None."""
    if isinstance(exc, RuntimeError) and "Symlink loop" in str(exc):
        return (
            f"{_short(str(exc).removeprefix('Symlink loop from '), 160)}: a loop of symbolic links"
        )
    if not isinstance(exc, OSError) or exc.errno not in USER_ERRNOS:
        return None
    where = exc.filename if exc.filename is not None else "a file"
    return f"{_short(where, 160)}: {exc.strerror or os.strerror(exc.errno)}"


@contextmanager
def _claiming(target):
    """Turn a system error while claiming ``target`` (read-only file system, a file in its path, a
    name too long,
    a symbolic link loop, no permission) into a one-line :class:`InputError`: nothing was
    written."""
    try:
        yield
    except (OSError, RuntimeError) as exc:
        reason = user_os_error(exc)
        if reason is None:
            raise
        raise InputError(f"out={_short(target, 160)}: cannot write there ({reason}); nothing was "
                         "written") from None


def _check_inputs(target, inputs):
    resolved = target.resolve()
    for item in inputs:
        item = Path(item).resolve()
        if item == resolved or resolved in item.parents:
            raise InputError(
                f"out={target}: it is or contains the input {item}; choose an output that holds "
                "no input file"
            )


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
        raise InputError(
            f"out={target}: only {free / 2**20:.0f} MiB free on its file system; need at least "
            f"{MIN_FREE_BYTES / 2**20:.0f} MiB (nothing was written)"
        )


def _sha256(path):
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


def file_hashes(folder):
    """``({relative path: sha256}, [relative folders])`` of everything below ``folder`` (no link
    followed).

    Paths use ``/``; a symbolic link or anything that is not a plain file or folder is listed
    in the files with the hash ``None`` (it never matches a recorded one)."""
    files, folders = {}, []
    for root, dirs, names in os.walk(folder, followlinks=False):
        base = Path(root).relative_to(folder)
        for d in list(dirs):
            rel = (base / d).as_posix()
            if os.path.islink(os.path.join(root, d)):
                dirs.remove(d)
                files[rel] = None
            else:
                folders.append(rel)
        for name in names:
            full = os.path.join(root, name)
            rel = (base / name).as_posix()
            files[rel] = (
                _sha256(full) if (not os.path.islink(full) and os.path.isfile(full)) else None
            )
    return files, sorted(folders)


def previous_result(folder):
    """What a previous bayes_imu run recorded in ``folder``'s marker: ``(files, folders)``, or None
    where there is
    no readable marker of this format (none, damaged, or an older bayes_imu's without hashes)."""
    try:
        doc = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        files, folders = doc["files"], doc["folders"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not (isinstance(files, dict) and isinstance(folders, list)
            and all(isinstance(k, str) and isinstance(v, str) for k, v in files.items())
            and all(isinstance(f, str) for f in folders)):
        return None
    return files, set(folders)


def _foreign(target, previous):
    """``(foreign, ours, folders)``: what below ``target`` the previous run did not write (or was
    changed since),
    the files whose content still matches the marker's hashes, and the run's folders present."""
    files, folders = previous
    present, present_folders = file_hashes(target)
    foreign = [rel for rel, digest in present.items()
               if rel not in (MARKER, _CLAIM) and (digest is None or files.get(rel) != digest)]
    foreign += [rel for rel in present_folders if rel not in folders]
    ours = [rel for rel in present if rel not in foreign and rel not in (MARKER, _CLAIM)]
    return sorted(foreign), ours, [rel for rel in present_folders if rel in folders]


def _short(text, limit=80):
    """``text`` with control characters as ``?``, at most ``limit`` characters (an excerpt in a
    one-line error)."""
    text = "".join(c if c.isprintable() else "?" for c in str(text))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _claim_folder(target, force):
    """Claim ``target``: returns ``(made_it, previous)``, ``previous`` being ``None`` or
    ``(recorded, files,
    folders)`` of the result being replaced; raises InputError if it is not ours to write."""
    if target.exists() and not target.is_dir():
        raise InputError(
            f"out={target}: exists and is not a folder; expected a folder to write into"
        )
    try:
        target.mkdir()
        made = True
    except FileExistsError:
        made = False
    previous = None
    busy = InputError(
        f"out={target}: another bayes-imu run is writing there ({_CLAIM} exists); wait for it, "
        "or remove that file if no run is active"
    )
    if not made:
        if (target / _CLAIM).exists():
            raise busy
        present = sorted(p.name for p in target.iterdir())
        if present:
            recorded = previous_result(target)
            if not force:
                raise InputError(
                    f"out={target}: folder exists and is not empty ({_names(present)}); use a new "
                    "folder, or force=True to replace a previous bayes_imu result there"
                )
            if recorded is None:
                raise InputError(
                    f"out={target}: force=True replaces only a previous bayes_imu result, and this "
                    f"folder holds {_names(present)} with no {MARKER} marker with file "
                    "hashes (none, damaged, "
                    "or an older bayes_imu's); choose another folder"
                )
            foreign, ours, folders = _foreign(target, recorded)
            if foreign:
                raise InputError(
                    f"out={target}: force=True would leave {_names(foreign)}, which no bayes_imu "
                    "run wrote there (or changed since); move them away or choose "
                    "another folder"
                )
            previous = (recorded, ours, folders)
    try:
        os.close(os.open(target / _CLAIM, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
    except FileExistsError:
        raise busy from None
    return made, previous


def _names(names, limit=5):
    shown = ", ".join(repr(_short(n)) for n in names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


@contextmanager
def staged_folder(target, *, force=False, inputs=()):
    """Yield a temporary folder whose entries move into ``target`` when the block succeeds (rules
    above).

    Raises
    ------
    InputError
        ``target`` is a file, holds an input, is claimed by another run, or is a non-empty
        folder that is not a previous bayes_imu result (or is one, without ``force``).
    """
    from .._version import __version__

    target = Path(target)
    with _claiming(target):
        _check_inputs(target, inputs)
        created = _make_parents(target)
    try:
        with _claiming(target):
            _check_space(target.parent, target)
            made, previous = _claim_folder(target, force)
    except BaseException:
        _remove_created(created)
        raise
    tmp = None
    try:
        with _claiming(target):
            tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
        _umask_mode(tmp, 0o777)
        yield tmp
        entries = sorted(p.name for p in tmp.iterdir())
        files, folders = file_hashes(tmp)
        (tmp / MARKER).write_text(
            json.dumps(
                {
                    "bayes_imu": __version__,
                    "format": _MARKER_FORMAT,
                    "entries": entries,
                    "files": files,
                    "folders": folders,
                },
                indent=1,
            )
            + "\n",
            encoding="utf-8",
        )
        # checked again now: a file saved below --out during the run stops the run
        if previous is not None:
            foreign, ours, old_folders = _foreign(target, previous[0])
            if foreign:
                raise InputError(f"out={target}: {_names(foreign)} appeared there during the run; "
                                 "nothing was "
                                 "replaced (the new results were not kept)")
            for rel in ours:  # only files whose content is what the previous run wrote
                (target / rel).unlink(missing_ok=True)
            # its folders, innermost first, if empty
            for rel in sorted(old_folders, key=lambda r: -r.count("/")):
                try:
                    (target / rel).rmdir()
                except OSError:
                    pass
        clash = [n for n in entries if os.path.lexists(target / n)]
        if clash:
            raise InputError(
                f"out={target}: {_names(clash)} appeared there during the run; nothing was "
                "replaced (the new results were not kept)"
            )
        for name in entries + [MARKER]:
            os.replace(tmp / name, target / name)
    except BaseException as exc:
        _cleanup_folder(target, tmp, made, created)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise InputError(
                f"out={target}: the disk is full ({exc.strerror}); nothing was kept from this run"
                + (" and the previous results are unchanged" if previous else "")
            ) from None
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


def _file_marker(target):
    return target.with_name(f".{target.name}{FILE_MARKER_SUFFIX}")


def _is_ours(target):
    """Whether ``target`` is what a bayes_imu run wrote there: its sidecar marker records this name
    and the
    file's current SHA-256 (nothing is guessed from the file's content)."""
    try:
        doc = json.loads(_file_marker(target).read_text(encoding="utf-8"))
        return (isinstance(doc, dict) and doc.get("file") == target.name and not target.is_symlink()
                and target.is_file() and doc.get("sha256") == _sha256(target))
    except (OSError, ValueError):
        return False


@contextmanager
def staged_file(target, *, force=False, inputs=()):
    """Yield a temporary file path that replaces ``target`` when the block succeeds (rules above);
    the sidecar
    marker ``.NAME.bayes_imu.json`` beside it records its hash, so that ``force`` may replace it
    later."""
    from .._version import __version__

    target = Path(target)
    with _claiming(target):
        if target.is_dir():
            raise InputError(f"out={target}: is a folder; expected a file name")
        _check_inputs(target, inputs)
        created = _make_parents(target)
    made = False
    try:
        _check_space(target.parent, target)
        try:
            with _claiming(target):
                os.close(os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            made = True
        except FileExistsError:
            if not force:
                raise InputError(
                    f"out={target}: file exists; use force=True to replace a previous bayes_imu "
                    "file"
                ) from None
            if not _is_ours(target):
                raise InputError(f"out={target}: force=True replaces only a file a bayes_imu run "
                                 "wrote there (its "
                                 f"marker {_file_marker(target).name} records its content), and "
                                 "this one is not, "
                                 "or was changed since; choose another name") from None
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
        marker = Path(f"{tmp}.marker")
        marker.write_text(
            json.dumps({"bayes_imu": __version__, "file": target.name, "sha256": _sha256(tmp)})
            + "\n",
            encoding="utf-8",
        )
        os.replace(marker, _file_marker(target))
        os.replace(tmp, target)
    except BaseException as exc:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
            Path(f"{tmp}.marker").unlink(missing_ok=True)
        if made and target.exists() and target.stat().st_size == 0:
            target.unlink()
        _remove_created(created)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise InputError(
                f"out={target}: the disk is full ({exc.strerror}); nothing was written"
            ) from None
        raise


def safe_folder_name(text, taken=()):
    """A folder name from ``text`` (letters, digits, ``_.-``), made unique against ``taken``."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "log"
    while name in taken:
        name += "_"
    return name
