"""Atomic file writing: write to a hidden sibling, rename onto the target on success.

Every facecap writer goes through :func:`atomic_path` (one file) or
:func:`atomic_folder` (a result folder), so an interrupted or failed write
never leaves a half-written file under the name the user asked for, and never
destroys an older file of that name.

Three promises to the user, kept here for every writer:

- **Nothing is lost.** A result folder that already holds a finished result is
  replaced only when the caller says so (``overwrite=True``, the CLI's
  ``--overwrite``); a folder or file that is not a facecap result of that kind is
  never replaced, not even then. Checked before the work starts
  (:func:`check_folder_destination`, :func:`check_file_destination`) and again
  at the rename.
- **A destination that cannot be written is named with the cause**: the path the
  user gave and why the system refused (permission denied, read-only file
  system, a file where a folder should be), never a temporary name.
- **Recorded paths are final.** While a folder is being built under its
  staging name, :func:`recorded_path` gives the path a written file must record
  for a source or sibling file: where it will be once every staging folder
  being built round it has been moved into place.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

__all__ = ["atomic_folder", "atomic_path", "atomic_write_text", "check_file_destination",
           "check_folder_destination", "ensure_folder", "final_path", "recorded_path", "resolve_recorded_path"]

_STAGED: dict[Path, Path] = {}
"""Staging folders being built in this process (resolved) -> where each will be renamed to."""
_STAGED_LOCK = threading.Lock()

_CANNOT_WRITE = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT}
"""What the system answers a writer that cannot write its file: reported under the user's name, with the cause."""


def _nearest_existing(path: Path) -> Path:
    """``path`` itself or its nearest ancestor that exists (a file or a folder)."""
    here = Path(os.path.abspath(path))
    while not os.path.lexists(here) and here.parent != here:
        here = here.parent
    return here


def _refusal(final: Path, exc: OSError | None, *, action: str) -> InputError:
    """One line naming the destination the user gave and why it cannot be written."""
    where = _nearest_existing(final.parent if final.parent != final else final)
    code = None if exc is None else exc.errno
    if not where.is_dir():
        reason = f"{where} is a file, not a folder"
    elif code in (errno.EACCES, errno.EPERM):
        reason = f"permission denied in {where}"
    elif code == errno.EROFS:
        reason = f"{where} is on a read-only file system"
    elif code in (errno.ENOSPC, errno.EDQUOT):
        reason = f"no space left in {where}"
    elif code == errno.ENOENT:
        reason = f"{where} takes no new files (No such file or directory)"
    else:
        reason = (exc.strerror or str(exc)) if exc is not None else "cannot be written"
    return InputError(f"cannot {action}: {reason}", path=str(final))


def _probe_writable(folder: Path, final: Path, *, action: str) -> None:
    """Create and remove a hidden entry in ``folder`` (or its nearest existing ancestor); refuse with the cause."""
    where = _nearest_existing(folder)
    if not where.is_dir():
        raise _refusal(final, None, action=action)
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".facecap-probe-", dir=where))
    except OSError as exc:
        raise _refusal(final, exc, action=action) from None


def _check_file_folder(final: Path) -> Path:
    """The folder of a file to write; refused (naming ``final``) when it does not exist or is a file."""
    parent = final.parent if str(final.parent) else Path(".")
    if not parent.is_dir():
        if not os.path.lexists(parent) and _nearest_existing(parent).is_dir():
            raise InputError(f"cannot write: directory {str(parent)!r} does not exist", path=str(final))
        raise _refusal(final, None, action="write")
    return parent


def _partial_name(final: Path, suffix: str) -> Path:
    """A fresh hidden sibling name ``.<name>.partial-<hex><suffix>`` that does not exist yet."""
    while True:
        candidate = final.with_name(f".{final.name}.partial-{secrets.token_hex(4)}{suffix}")
        if not os.path.lexists(candidate):
            return candidate


@contextmanager
def atomic_path(final_path: str | os.PathLike[str], *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary sibling path to write; rename it onto ``final_path`` on success.

    The temporary path lies in the same directory as ``final_path`` (so the
    rename is atomic on POSIX and Windows) and is named
    ``.<name>.partial-<8 hex digits><suffix>``, for example
    ``.take.c3d.partial-3f9a12bc.c3d``. It keeps the final suffix because
    some writers choose the format from it (USD, trimesh) or append their own
    (ezc3d appends ``.c3d`` to any other name).

    The file is not created: the block writes it. If the block exits without
    an exception the temporary file is renamed onto ``final_path`` (replacing
    any file there); if the block raises, or the rename fails, the temporary
    file is deleted and the exception propagates. ``final_path`` is then
    untouched.

    Parameters
    ----------
    final_path : str or os.PathLike
        Where the finished file must end up.
    suffix : str or None, optional
        Suffix of the temporary name; default None keeps ``final_path``'s
        suffix (``''`` if it has none).

    Yields
    ------
    tmp_path : pathlib.Path
        The path the block must write.

    Raises
    ------
    InputError
        If the directory of ``final_path`` does not exist or is a file,
        ``final_path`` is a directory, or the directory cannot take the file
        (permission denied, read-only file system, no space left): the
        message names ``final_path`` and the cause, never the temporary name.

    Notes
    -----
    Atomic against a failing or interrupted writer; it does not ``fsync``,
    so it does not promise durability across a power cut.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "out.txt") as tmp:
    ...     _ = tmp.write_text("done")
    >>> (folder / "out.txt").read_text()
    'done'
    """
    final = Path(os.fspath(final_path))
    _check_file_folder(final)
    if final.is_dir():
        raise InputError("cannot write: the path is a directory", path=str(final))
    tmp = _partial_name(final, final.suffix if suffix is None else suffix)
    try:  # the real cause, under the user's name, before the writer reports it under the temporary one
        os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        os.unlink(tmp)
    except OSError as exc:
        raise _refusal(final, exc, action="write") from None
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if (isinstance(exc, OSError) and exc.errno in _CANNOT_WRITE
                and exc.filename is not None and os.fspath(exc.filename) == os.fspath(tmp)):
            raise _refusal(final, exc, action="write") from None  # e.g. the disk filled up while writing
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_path`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    text : str
        Content, written as is (no newline translation).
    encoding : str, optional
        Text encoding, default ``'utf-8'``.

    Raises
    ------
    InputError
        If the destination directory does not exist.
    """
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding=encoding, newline="") as handle:
            handle.write(text)


def check_folder_destination(final_dir: str | os.PathLike[str], *, marker_file: str, overwrite: bool = False) -> None:
    """Refuse, before any work, a result folder destination that :func:`atomic_folder` would refuse.

    Accepted: a folder that does not exist yet (its nearest existing ancestor
    must be a folder this process can create entries in), an empty folder,
    and, with ``overwrite``, a folder holding an earlier result of the same
    kind (it holds ``marker_file``).

    Parameters
    ----------
    final_dir : str or path-like
        The destination the user gave.
    marker_file : str
        The file that marks a finished folder of this kind (``performance.json``, ...).
    overwrite : bool, default False
        Whether an earlier result of this kind there may be replaced.

    Raises
    ------
    InputError
        One line naming ``final_dir``: a file is there; a non-empty folder
        that is not a result of this kind is there (refused even with
        ``overwrite``: facecap never deletes what it did not make); an earlier
        result is there and ``overwrite`` is False (the message says to pass
        ``--overwrite``); or the folder cannot be created (the cause).
    """
    final = Path(os.fspath(final_dir))
    if os.path.lexists(final) and not final.is_dir():
        raise InputError("exists and is not a folder; choose another output folder", path=str(final))
    if final.is_dir() and any(final.iterdir()):
        if not (final / marker_file).is_file():
            raise InputError(f"is not empty and is not a facecap result (no {marker_file}); facecap never "
                             "replaces it, even with --overwrite: choose another output folder or empty it",
                             path=str(final))
        if not overwrite:
            raise InputError(f"holds an earlier result ({marker_file}); pass --overwrite to replace it, or choose "
                             "another output folder", path=str(final))
    _probe_writable(final.parent if final.is_dir() else final, final, action="create the folder")


def check_file_destination(final_path: str | os.PathLike[str], *, overwrite: bool = False) -> None:
    """Refuse, before any work, a single output file that exists (unless ``overwrite``) or cannot be written.

    Parameters
    ----------
    final_path : str or path-like
        The file the user asked for (``plan.json``, a mesh, ...).
    overwrite : bool, default False
        Whether an existing file there may be replaced.

    Raises
    ------
    InputError
        One line naming ``final_path``: it is a folder, it exists and
        ``overwrite`` is False (the message says to pass ``--overwrite``), its
        folder does not exist or is a file, or the folder cannot take a new
        file (the cause).
    """
    final = Path(os.fspath(final_path))
    if final.is_dir():
        raise InputError("cannot write: the path is a folder", path=str(final))
    if os.path.lexists(final) and not overwrite:
        raise InputError("exists; pass --overwrite to replace it, or choose another name", path=str(final))
    _probe_writable(_check_file_folder(final), final, action="write")


def ensure_folder(folder: str | os.PathLike[str]) -> Path:
    """Create ``folder`` and its parents if need be (a folder that adds files to what is there, like an export's).

    Raises
    ------
    InputError
        Naming ``folder`` and the cause when it cannot be created (a file in
        the way, permission denied, read-only file system).
    """
    path = Path(os.fspath(folder))
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if os.path.lexists(path) and not path.is_dir():
            raise InputError("exists and is not a folder", path=str(path)) from None
        raise _refusal(path, exc, action="create the folder") from None
    return path


@contextmanager
def atomic_folder(final_dir: str | os.PathLike[str], *, marker_file: str, overwrite: bool = False) -> Iterator[Path]:
    """Build a folder under a hidden staging name and move it onto ``final_dir`` on success.

    Parameters
    ----------
    final_dir : str or path-like
        Destination. If it exists it must be an empty folder, or (with
        ``overwrite``) an earlier result of the same kind: it holds
        ``marker_file``, and is replaced only once the block succeeds.
    marker_file : str
        Name of the file that marks a finished folder of this kind; the block
        must write it.
    overwrite : bool, default False
        Replace an earlier result of this kind. Without it such a folder is
        refused, before the block runs and again at the rename (one may appear
        meanwhile), so every file in it, and every file added to it since it
        was written (exports, review pages), stays.

    Yields
    ------
    pathlib.Path
        The staging folder to fill. On an exception it is deleted. While the
        block runs, :func:`final_path` maps paths inside it to where they will be.

    Raises
    ------
    InputError
        As :func:`check_folder_destination`, on entry. At the rename, if
        ``final_dir`` is no longer acceptable (a result or other files appeared
        there meanwhile): the finished folder is then kept beside it, under
        ``<name>-2`` (or the next free number), and the message names it.

    Notes
    -----
    Decisions: an existing *empty* folder is written into (a user often makes
    the folder first); a non-empty folder without ``marker_file`` is never
    replaced, even with ``overwrite`` (facecap must not delete what it did not
    make). The rename is atomic on POSIX; replacing an earlier result is two
    renames (old result aside, new one in), then the old one is deleted.
    """
    final = Path(os.fspath(final_dir))
    check_folder_destination(final, marker_file=marker_file, overwrite=overwrite)
    parent = final.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.partial-", dir=parent))
    except OSError as exc:
        raise _refusal(final, exc, action="create the folder") from None
    with _STAGED_LOCK:
        _STAGED[staging] = parent / final.name
    try:
        yield staging
        if not (staging / marker_file).exists():
            raise InputError(f"internal: the folder was not finished ({marker_file} missing)", path=str(final))
        _move_into_place(staging, final, parent, marker_file=marker_file, overwrite=overwrite)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    finally:
        with _STAGED_LOCK:
            _STAGED.pop(staging, None)


def _move_into_place(staging: Path, final: Path, parent: Path, *, marker_file: str, overwrite: bool) -> None:
    """Rename the finished ``staging`` onto ``final``, checking ``final`` again; keep it beside on a refusal."""
    try:
        check_folder_destination(final, marker_file=marker_file, overwrite=overwrite)
        if final.is_dir() and any(final.iterdir()):  # an earlier result, and overwrite: old aside, new in
            trash = Path(tempfile.mkdtemp(prefix=f".{final.name}.old-", dir=parent))
            os.replace(final, trash / "old")
            try:
                os.replace(staging, final)
            except OSError:  # something took the name between the two renames: put the earlier result back
                os.replace(trash / "old", final)
                os.rmdir(trash)
                raise
            shutil.rmtree(trash, ignore_errors=True)
        else:
            if final.is_dir():
                os.rmdir(final)  # empty: fails (ENOTEMPTY) if a file appeared there since the check
            os.replace(staging, final)
        return
    except InputError as exc:
        refused = exc.message
    except OSError as exc:  # e.g. ENOTEMPTY: a file appeared in the empty folder after the check
        refused = f"changed while this run worked ({exc.strerror or exc})"
    kept = next(final.with_name(f"{final.name}-{k}") for k in range(2, 10_000)
                if not os.path.lexists(final.with_name(f"{final.name}-{k}")))
    os.replace(staging, kept)
    raise InputError(f"{refused} (found at the end of the run: this run's finished result is kept in {kept})",
                     path=str(final))


def final_path(path: str | os.PathLike[str]) -> Path:
    """Where ``path`` will be once every staging folder being built round it has been moved into place.

    Paths outside any folder :func:`atomic_folder` is building (in this
    process) come back absolute, as given (symbolic links kept); paths inside
    one are mapped onto its destination, through any number of nested
    staging folders (a job writing into a folder of the demo's).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    pathlib.Path
        Absolute.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> root = pathlib.Path(tempfile.mkdtemp()).resolve()
    >>> with atomic_folder(root / "out", marker_file="done") as stage:
    ...     (stage / "done").touch()
    ...     final_path(stage / "inputs" / "scan.obj") == root / "out" / "inputs" / "scan.obj"
    True
    """
    given = Path(os.path.abspath(os.fspath(path)))
    with _STAGED_LOCK:  # the innermost staging folder first: it lies inside the ones round it
        staged = sorted(_STAGED.items(), key=lambda item: len(item[0].parts), reverse=True)
    if not staged:
        return given
    here, moved = given.resolve(), False
    while True:
        for staging, destination in staged:
            if here == staging or staging in here.parents:
                here, moved = destination / here.relative_to(staging), True
                break
        else:
            return here if moved else given


def recorded_path(path: str | os.PathLike[str], *, folder: str | os.PathLike[str]) -> str:
    """The text a file written into ``folder`` records for ``path``: final, and relative where it can be.

    A path inside ``folder`` is recorded relative to it (POSIX separators:
    the folder can be moved or copied whole); any other path absolute. Both
    are where the files will be once the folders being built have been moved
    into place (:func:`final_path`), never a staging name.

    Parameters
    ----------
    path : str or path-like
        The file or folder to record (a source file, a model folder, ...).
    folder : str or path-like
        The folder that holds the file being written (a staging folder is fine).

    Returns
    -------
    str
        Read back with :func:`resolve_recorded_path`.
    """
    target, home = final_path(path), final_path(folder)
    if target == home or home in target.parents:
        return target.relative_to(home).as_posix() or "."
    return str(target)


def resolve_recorded_path(text: str | os.PathLike[str], *, folder: str | os.PathLike[str]) -> Path:
    """The path a file in ``folder`` recorded with :func:`recorded_path`: relative ones are relative to ``folder``."""
    path = Path(os.fspath(text))
    return path if path.is_absolute() else Path(os.fspath(folder)) / path
