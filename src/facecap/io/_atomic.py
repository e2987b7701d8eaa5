"""Atomic file writing: write to a hidden sibling, rename onto the target on success.

Every facecap writer goes through :func:`atomic_path`, so an interrupted or
failed write never leaves a half-written file under the name the user asked
for, and never destroys an older file of that name.
"""

from __future__ import annotations

import os
import secrets
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

__all__ = ["atomic_folder", "atomic_path", "atomic_write_text"]


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
        If the directory of ``final_path`` does not exist or
        ``final_path`` is a directory.

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
    parent = final.parent if str(final.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write: directory {str(parent)!r} does not exist", path=str(final))
    if final.is_dir():
        raise InputError("cannot write: the path is a directory", path=str(final))
    tmp = _partial_name(final, final.suffix if suffix is None else suffix)
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
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


@contextmanager
def atomic_folder(final_dir: str | os.PathLike[str], *, marker_file: str) -> Iterator[Path]:
    """Build a folder under a hidden staging name and move it onto ``final_dir`` on success.

    Parameters
    ----------
    final_dir : str or path-like
        Destination. If it exists it must be empty or be an earlier result
        of the same kind (it holds ``marker_file``); it is replaced only once
        the block succeeds.
    marker_file : str
        Name of the file that marks a finished folder of this kind; the block
        must write it.

    Yields
    ------
    pathlib.Path
        The staging folder to fill. On an exception it is deleted.

    Raises
    ------
    InputError
        If ``final_dir`` is a file, or a non-empty folder of something else.
    """
    final = Path(final_dir)
    if final.exists():
        if not final.is_dir():
            raise InputError("exists and is not a folder", path=str(final))
        if any(final.iterdir()) and not (final / marker_file).exists():
            raise InputError(f"exists, is not empty and holds no {marker_file}; refusing to overwrite it", path=str(final))
    parent = final.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.partial-", dir=parent))
    try:
        yield staging
        if not (staging / marker_file).exists():
            raise InputError(f"internal: the folder was not finished ({marker_file} missing)", path=str(final))
        if final.exists():
            trash = Path(tempfile.mkdtemp(prefix=f".{final.name}.old-", dir=parent))
            os.replace(final, trash / "old")
            os.replace(staging, final)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.replace(staging, final)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
