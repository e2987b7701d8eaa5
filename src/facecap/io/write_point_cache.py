"""Streamed point caches: MDD and PC2, the vertex caches Blender's Mesh Cache modifier plays.

Both formats hold nothing but one header and the positions of every vertex at
every frame, in the vertex order of the mesh they are applied to; topology,
UVs and units come from that mesh. Layouts (checked against Blender's readers,
``source/blender/modifiers/intern/MOD_meshcache_mdd.cc`` and
``MOD_meshcache_pc2.cc``)::

    MDD (LightWave Motion Designer), big-endian
        int32   frame count T
        int32   point count n
        float32 time of each frame in seconds, T values: k / rate
        float32 x, y, z of every point, frame after frame (T * n * 3 values)

    PC2 (3ds Max Point Cache 2), little-endian
        char[12] 'POINTCACHE2\\0'
        int32   file version, 1
        int32   point count n
        float32 start frame
        float32 sample rate: frames between two samples, 1.0 here
        int32   sample count T
        float32 x, y, z of every point, sample after sample

Both writers take an iterable of ``(start, block)`` pairs and write each block
as it comes, so memory holds one block whatever the take's length. The file
is written under a hidden temporary name and renamed when the last frame is
in (:func:`facecap.io.atomic_write.atomic_path`): a bad block or a short stream
raises :class:`~facecap.errors.InputError` and leaves nothing behind.
``docs/formats.md`` says what to set in Blender's Mesh Cache modifier.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..validate import as_positive
from .atomic_write import atomic_path
from .frame_blocks import as_frame_count, check_frame_blocks, path_with_suffix

__all__ = ["write_mdd", "write_pc2"]

PC2_SIGNATURE = b"POINTCACHE2\0"
"""The 12 bytes a PC2 file starts with."""

_WRITE_BYTES = 32 * 2**20  # frames are converted and written about this many bytes at a time
_TIMES_PER_WRITE = 2**16  # MDD frame times written this many at a time


def write_mdd(
    path: str | os.PathLike[str],
    blocks: Iterable[tuple[int, Any]],
    *,
    n_frames: int,
    n_vertices: int,
    rate: float,
    progress: bool = False,
) -> Path:
    """Write an MDD point cache from a stream of frame blocks.

    Parameters
    ----------
    path : str or path-like
        The ``.mdd`` file to write (replaced if it exists, only once the
        whole take is written).
    blocks : iterable of (int, (b, n, 3) float32 array)
        ``(start, block)`` pairs: ``block`` holds frames ``start .. start + b - 1``
        in the output unit (the unit of the mesh the cache will be applied
        to: the caller decides), in that mesh's vertex order. Blocks must
        come in order without gaps and add up to ``n_frames`` frames.
    n_frames : int
        Number of frames T, at least 1.
    n_vertices : int
        Number of vertices n, at least 1.
    rate : float
        Frame rate in Hz; frame k is stored at time ``k / rate`` seconds.
    progress : bool, optional
        Show a tqdm progress bar; default False.

    Returns
    -------
    path : pathlib.Path
        The file written.

    Raises
    ------
    InputError
        If an argument is invalid, the folder does not exist, a block is out
        of order, of the wrong shape or holds NaN or infinite values, or the
        stream ends before ``n_frames`` frames. No file is left behind.

    Notes
    -----
    Big-endian throughout: two int32 (T, n), T float32 frame times in seconds,
    then T * n * 3 float32 coordinates (layout in the module docstring).
    Coordinates are written as given, with no axis swap: Blender's Mesh Cache
    modifier applies none with its default axes (Forward +Y, Up +Z).

    Examples
    --------
    >>> import numpy as np, os, tempfile
    >>> frames = np.zeros((2, 3, 3), np.float32)
    >>> out = write_mdd(os.path.join(tempfile.mkdtemp(), "take.mdd"), [(0, frames)],
    ...                 n_frames=2, n_vertices=3, rate=60.0)
    >>> out.stat().st_size == 8 + 2 * 4 + 2 * 3 * 12
    True
    """
    final = path_with_suffix(path, ".mdd")
    n_frames = as_frame_count(n_frames, name="n_frames")
    n_vertices = as_frame_count(n_vertices, name="n_vertices")
    rate_hz = as_positive(rate, name="rate")
    with atomic_path(final) as tmp, open(tmp, "wb") as handle:
        handle.write(struct.pack(">ii", n_frames, n_vertices))
        for first in range(0, n_frames, _TIMES_PER_WRITE):
            k = np.arange(first, min(first + _TIMES_PER_WRITE, n_frames), dtype=np.float64)
            handle.write((k / rate_hz).astype(">f4").tobytes())
        _write_positions(handle, blocks, n_frames=n_frames, n_vertices=n_vertices,
                         dtype=np.dtype(">f4"), path=final, progress=progress, desc="MDD")
    return final


def write_pc2(
    path: str | os.PathLike[str],
    blocks: Iterable[tuple[int, Any]],
    *,
    n_frames: int,
    n_vertices: int,
    rate: float,
    start_frame: float = 0,
    progress: bool = False,
) -> Path:
    """Write a PC2 point cache from a stream of frame blocks.

    Parameters
    ----------
    path : str or path-like
        The ``.pc2`` file to write (replaced if it exists, only once the
        whole take is written).
    blocks : iterable of (int, (b, n, 3) float32 array)
        ``(start, block)`` pairs: ``block`` holds frames ``start .. start + b - 1``
        in the output unit (the unit of the mesh the cache will be applied
        to), in that mesh's vertex order; in order, without gaps, adding up
        to ``n_frames`` frames.
    n_frames : int
        Number of frames T (the header's sample count), at least 1.
    n_vertices : int
        Number of vertices n, at least 1.
    rate : float
        Frame rate of the take in Hz. Checked but not stored: PC2 has no
        rate field; its header counts time in scene frames (the client's
        scene must run at ``rate``, see Notes).
    start_frame : float, optional
        The header's start frame: the scene frame of the first sample in
        clients that read it (3ds Max's Point Cache); default 0.
    progress : bool, optional
        Show a tqdm progress bar; default False.

    Returns
    -------
    path : pathlib.Path
        The file written.

    Raises
    ------
    InputError
        As :func:`write_mdd` raises it (a bad argument or block, a missing
        folder, a short stream); no file is left behind.

    Notes
    -----
    The header's sample rate is the number of scene frames between two
    samples (3ds Max's "Sample Rate", which Blender's own PC2 exporter also
    writes as a frame step), not a rate in Hz: 1.0 here, one sample per scene
    frame, sample k at scene frame ``start_frame + k``. Blender's Mesh Cache
    modifier in its default Frame time mode ignores both header values and
    plays sample ``scene frame - Frame Start``; its Seconds mode divides the
    time by the frame rate twice (``MOD_meshcache_pc2.cc``), so use Frame
    mode for PC2.

    Examples
    --------
    >>> import numpy as np, os, tempfile
    >>> frames = np.zeros((2, 3, 3), np.float32)
    >>> out = write_pc2(os.path.join(tempfile.mkdtemp(), "take.pc2"), [(0, frames)],
    ...                 n_frames=2, n_vertices=3, rate=60.0)
    >>> out.read_bytes()[:12]
    b'POINTCACHE2\\x00'
    """
    final = path_with_suffix(path, ".pc2")
    n_frames = as_frame_count(n_frames, name="n_frames")
    n_vertices = as_frame_count(n_vertices, name="n_vertices")
    as_positive(rate, name="rate")
    try:
        start = float(start_frame)
    except (TypeError, ValueError):
        start = float("nan")
    if isinstance(start_frame, bool) or not np.isfinite(start):
        raise InputError(f"start_frame: expected a finite number, got {start_frame!r}")
    header = struct.pack("<12siiffi", PC2_SIGNATURE, 1, n_vertices, start, 1.0, n_frames)
    with atomic_path(final) as tmp, open(tmp, "wb") as handle:
        handle.write(header)
        _write_positions(handle, blocks, n_frames=n_frames, n_vertices=n_vertices,
                         dtype=np.dtype("<f4"), path=final, progress=progress, desc="PC2")
    return final


def _write_positions(
    handle: BinaryIO,
    blocks: Iterable[tuple[int, Any]],
    *,
    n_frames: int,
    n_vertices: int,
    dtype: np.dtype,
    path: Path,
    progress: bool,
    desc: str,
) -> None:
    """Write every frame of ``blocks`` as ``dtype`` xyz triples, a few tens of MB per write call."""
    frames_per_write = max(1, _WRITE_BYTES // (12 * n_vertices))
    with tqdm(total=n_frames, unit="frame", desc=desc, disable=not progress, leave=False) as bar:
        for _, block in check_frame_blocks(blocks, n_frames=n_frames, n_vertices=n_vertices, path=path):
            for j in range(0, block.shape[0], frames_per_write):
                # No copy when the block already is contiguous float32 in the file's byte order.
                handle.write(np.ascontiguousarray(block[j:j + frames_per_write], dtype=dtype).data)
            bar.update(block.shape[0])
