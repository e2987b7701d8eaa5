"""One chunk of frames: compute it with the stage and write its file atomically; read it back.

The chunk file is the done-marker. It is written under a hidden temporary name,
flushed to disk and renamed onto its final name in one step
(:func:`~facecap.io.atomic_write.atomic_path`), so a file under the final name is
always complete: a worker killed while writing leaves only a hidden
``.chunk-….partial-…`` file, which a later run ignores and deletes. There is no
separate marker that could disagree with the data (a worker killed between
writing data and marker is exactly the case a separate marker has to handle).

The file is a ``.npz`` (a ZIP of ``.npy`` files, so ``numpy.load`` opens it)
written with fixed member order and timestamps and no compression: the same
chunk computed twice gives the same bytes, and whichever of two concurrent
writers renames last leaves the same file.

Members: ``chunk.json`` (format, run id, index, frames, array names),
``frames/<name>.npy`` for each result array and ``state/<name>.npy`` for the
state handed to the next chunk of the segment.
"""

from __future__ import annotations

import io
import json
import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_path
from .frame_stage import FrameStage, StageState
from .plan_chunks import FrameChunk

__all__ = ["CHUNK_FORMAT", "ChunkContents", "chunk_file_name", "read_chunk", "run_chunk"]

#: Format tag written into every chunk file's ``chunk.json``.
CHUNK_FORMAT = "facecap.runner.chunk/1"

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# The earliest time a ZIP member can carry: the same bytes whenever the chunk is written.
_FIXED_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


class ChunkContents(NamedTuple):
    """What a chunk file holds.

    Attributes
    ----------
    arrays : dict of str to ndarray
        The stage's results for the chunk, each ``(stop - start, ...)``.
    state : dict of str to ndarray, or None
        The state the stage returned for the next chunk of its segment.
    header : dict
        ``chunk.json``: ``format``, ``run_id``, ``index``, ``start``, ``stop``,
        ``arrays`` (name -> ``{'dtype', 'shape'}``), ``state`` (names or None).
    """

    arrays: dict[str, np.ndarray]
    state: dict[str, np.ndarray] | None
    header: dict[str, Any]


def chunk_file_name(chunk: FrameChunk) -> str:
    """The file name of a chunk, ``chunk-<index>-frames-<start>-<stop>.npz``.

    Examples
    --------
    >>> chunk_file_name(FrameChunk(3, 96, 128, 3, None))
    'chunk-000003-frames-00000096-00000128.npz'
    """
    return f"chunk-{chunk.index:06d}-frames-{chunk.start:08d}-{chunk.stop:08d}.npz"


def run_chunk(
    stage: FrameStage,
    chunk: FrameChunk,
    path: str | os.PathLike[str],
    *,
    run_id: str,
    previous: str | os.PathLike[str] | None = None,
) -> Path:
    """Compute one chunk with the stage and write it atomically to ``path``.

    Safe to call twice, even at the same time in two processes: each call writes
    its own temporary file and renames it onto ``path``; a deterministic stage
    makes both files identical byte for byte.

    Parameters
    ----------
    stage : FrameStage
        The stage; called once as ``stage(chunk.start, chunk.stop, state)``.
    chunk : FrameChunk
        The chunk to compute.
    path : str or path-like
        The chunk's file (its folder must exist).
    run_id : str
        The run's identity (the manifest's hash), written into the file so that a
        chunk is never taken for one of another run.
    previous : str or path-like or None, optional
        The previous chunk's file, whose state the chunk starts from; required
        exactly when ``chunk.previous`` is not None.

    Returns
    -------
    path : pathlib.Path
        The finished chunk file.

    Raises
    ------
    InputError
        If ``previous`` is missing or not the chunk's predecessor, or the stage
        returns something other than named arrays of ``stop - start`` frames.
    FileFormatError
        If the previous chunk file cannot be read.
    """
    path = Path(path)
    state: StageState = None
    if chunk.previous is not None:
        if previous is None:
            raise InputError(f"chunk {chunk.index} continues chunk {chunk.previous}: give its file as previous")
        before = read_chunk(previous, run_id=run_id)
        if before.header["index"] != chunk.previous or before.header["stop"] != chunk.start:
            raise InputError(
                f"chunk {chunk.index} (frames {chunk.start}-{chunk.stop}) does not continue chunk "
                f"{before.header['index']} (frames {before.header['start']}-{before.header['stop']})",
                path=str(previous),
            )
        state = before.state
    elif previous is not None:
        raise InputError(f"chunk {chunk.index} starts its segment cold: previous must be None")
    result = stage(chunk.start, chunk.stop, state)
    arrays, next_state = _check_stage_result(result, chunk, stage)
    header = {
        "format": CHUNK_FORMAT,
        "run_id": run_id,
        "index": chunk.index,
        "start": chunk.start,
        "stop": chunk.stop,
        "arrays": {name: {"dtype": a.dtype.str, "shape": list(a.shape)} for name, a in sorted(arrays.items())},
        "state": None if next_state is None else sorted(next_state),
    }
    members: list[tuple[str, np.ndarray | bytes]] = [("chunk.json", json.dumps(header, sort_keys=True).encode())]
    members += [(f"frames/{name}.npy", arrays[name]) for name in sorted(arrays)]
    if next_state is not None:
        members += [(f"state/{name}.npy", next_state[name]) for name in sorted(next_state)]
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            _write_zip(handle, members)
            handle.flush()
            # On disk before the rename makes it count as done: a crash leaves no
            # final-named file with missing bytes.
            os.fsync(handle.fileno())
    return path


def read_chunk(
    path: str | os.PathLike[str], *, run_id: str | None = None, chunk: FrameChunk | None = None, header_only: bool = False
) -> ChunkContents:
    """Read a chunk file back, checking it belongs to the run and chunk expected.

    Parameters
    ----------
    path : str or path-like
        A chunk file written by :func:`run_chunk`.
    run_id : str or None, optional
        If given, the run the chunk must belong to.
    chunk : FrameChunk or None, optional
        If given, the chunk (index and frames) the file must hold.
    header_only : bool, optional
        Read only ``chunk.json`` (``arrays`` and ``state`` come back empty and
        None); default False.

    Returns
    -------
    ChunkContents

    Raises
    ------
    FileFormatError
        If the file is missing, not a chunk file, truncated, of another run or of
        another chunk.
    """
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            header = json.loads(archive.read("chunk.json"))
            if not isinstance(header, dict) or header.get("format") != CHUNK_FORMAT:
                raise FileFormatError(f"not a facecap chunk file (format {CHUNK_FORMAT} expected)", path=str(path))
            if run_id is not None and header.get("run_id") != run_id:
                raise FileFormatError(
                    f"the chunk belongs to run {header.get('run_id')!r}, not to this run {run_id!r}", path=str(path)
                )
            if chunk is not None and (header.get("index"), header.get("start"), header.get("stop")) != chunk[:3]:
                raise FileFormatError(
                    f"the file holds chunk {header.get('index')} (frames {header.get('start')}-{header.get('stop')}), "
                    f"not chunk {chunk.index} (frames {chunk.start}-{chunk.stop})",
                    path=str(path),
                )
            if header_only:
                return ChunkContents({}, None, header)
            arrays = {name: _read_member(archive, f"frames/{name}.npy") for name in header["arrays"]}
            state = None
            if header["state"] is not None:
                state = {name: _read_member(archive, f"state/{name}.npy") for name in header["state"]}
    except FileNotFoundError:
        raise FileFormatError("the chunk file does not exist", path=str(path)) from None
    except (zipfile.BadZipFile, KeyError, ValueError, EOFError, OSError) as exc:
        if isinstance(exc, FileFormatError):
            raise
        raise FileFormatError(f"unreadable chunk file ({type(exc).__name__}: {exc})", path=str(path)) from exc
    return ChunkContents(arrays, state, header)


def _check_stage_result(
    result: object, chunk: FrameChunk, stage: object
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None]:
    where = f"{type(stage).__qualname__}({chunk.start}, {chunk.stop}, state)"
    if not (isinstance(result, tuple) and len(result) == 2):
        raise InputError(f"{where} must return (arrays, state); got {type(result).__name__}")
    arrays_in, state_in = result
    arrays = _named_arrays(arrays_in, f"the arrays of {where}")
    if not arrays:
        raise InputError(f"{where} returned no arrays")
    for name, array in arrays.items():
        if array.ndim == 0 or array.shape[0] != chunk.stop - chunk.start:
            raise InputError(
                f"{where} returned {name!r} of shape {array.shape}; its first axis must be the "
                f"{chunk.stop - chunk.start} frames of the chunk"
            )
    state = None if state_in is None else _named_arrays(state_in, f"the state of {where}")
    return arrays, state


def _named_arrays(values: object, what: str) -> dict[str, np.ndarray]:
    if not isinstance(values, Mapping):
        raise InputError(f"{what} must be a dict of name -> numpy array; got {type(values).__name__}")
    out = {}
    for name, value in values.items():
        if not isinstance(name, str) or not _NAME.match(name):
            raise InputError(f"{what}: names must be Python identifiers; got {name!r}")
        array = np.ascontiguousarray(value)
        if array.dtype.hasobject:
            raise InputError(f"{what}: {name!r} has dtype object; give numeric arrays")
        out[name] = array
    return out


def _write_zip(handle: io.BufferedWriter, members: list[tuple[str, np.ndarray | bytes]]) -> None:
    with zipfile.ZipFile(handle, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
        for name, value in members:
            info = zipfile.ZipInfo(name, date_time=_FIXED_ZIP_TIME)
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            with archive.open(info, "w", force_zip64=True) as member:
                if isinstance(value, bytes):
                    member.write(value)
                else:
                    np.lib.format.write_array(member, value, allow_pickle=False)


def _read_member(archive: zipfile.ZipFile, name: str) -> np.ndarray:
    with archive.open(name) as member:
        return np.lib.format.read_array(member, allow_pickle=False)
