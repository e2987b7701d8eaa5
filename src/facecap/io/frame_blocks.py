"""The checks every streamed writer of frame blocks makes (MDD, PC2, Alembic), in one home.

A streamed writer takes ``(start, block)`` pairs, ``block`` a ``(b, n, 3)``
float array, in frame order; :func:`check_frame_blocks` checks each pair as it
passes, :func:`as_frame_count` the frame and vertex counts the formats store
as int32, :func:`path_with_suffix` the destination's file name.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["check_frame_blocks", "as_frame_count", "path_with_suffix"]

_INT32_MAX = 2**31 - 1
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def path_with_suffix(path: str | os.PathLike[str], suffix: str) -> Path:
    """``path`` as a Path, checked to end in ``suffix`` (any case).

    Raises
    ------
    InputError
        If the file name does not end in ``suffix``.
    """
    p = Path(os.fspath(path))
    if p.suffix.lower() != suffix:
        raise InputError(f"path: expected a {suffix} file name, got {str(p)!r}")
    return p


def as_frame_count(value: Any, *, name: str) -> int:
    """``value`` as an int in ``[1, 2**31 - 1]`` (the formats store int32 counts), or raise.

    Raises
    ------
    InputError
        Naming ``name``, if ``value`` is not such an integer (a bool is not).
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= int(value) <= _INT32_MAX:
        raise InputError(f"{name}: expected a positive integer below 2**31, got {value!r}")
    return int(value)


def check_frame_blocks(
    blocks: Iterable[tuple[int, Any]], *, n_frames: int, n_vertices: int, path: Path
) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(start, block)`` from ``blocks`` after checking each one; raise at the first bad one.

    The one home of the checks every streamed exporter of frame blocks makes
    (MDD, PC2, Alembic).

    Parameters
    ----------
    blocks : iterable of (int, (b, n, 3) float array)
        The stream, as the writers take it.
    n_frames, n_vertices : int
        The take's frame and vertex counts.
    path : pathlib.Path
        The file being written, named in errors.

    Yields
    ------
    start : int
        Index of the block's first frame.
    block : (b, n, 3) float array
        The block as given (not copied), finite and within the float32 range.

    Raises
    ------
    InputError
        If an item is not a pair, a block does not start where the previous
        one ended, has the wrong shape or a non-float dtype, runs past
        ``n_frames``, holds NaN, infinite or beyond-float32 values, or the
        stream ends early.
    """
    written = 0
    for item in blocks:
        try:
            start, block = item
        except (TypeError, ValueError):
            raise InputError(f"blocks: expected (start, block) pairs, got {type(item).__name__}",
                             path=str(path)) from None
        if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or int(start) != written:
            raise InputError(f"blocks: expected the block starting at frame {written} (blocks in order, "
                             f"without gaps or overlaps), got start={start!r}", path=str(path))
        arr = np.asarray(block)
        if arr.ndim != 3 or arr.shape[0] < 1 or arr.shape[1:] != (n_vertices, 3):
            raise InputError(f"blocks: expected a (b, {n_vertices}, 3) block at frame {written}, "
                             f"got shape {arr.shape}", path=str(path))
        if not np.issubdtype(arr.dtype, np.floating):
            raise InputError(f"blocks: expected float32 positions at frame {written}, got {arr.dtype}",
                             path=str(path))
        b = arr.shape[0]
        if written + b > n_frames:
            raise InputError(f"blocks: frames {written}..{written + b - 1} run past n_frames={n_frames}",
                             path=str(path))
        # One summing pass finds NaN and infinities (they survive a float64 sum; finite float32 cannot overflow it).
        if not np.isfinite(arr.sum(dtype=np.float64)):
            bad = written + int(np.flatnonzero(~np.isfinite(arr).all(axis=(1, 2)))[0])
            raise InputError(f"blocks: frame {bad} contains NaN or infinite values", path=str(path))
        if arr.dtype.itemsize > 4 and np.abs(arr).max() > _FLOAT32_MAX:  # would turn into inf as float32
            raise InputError(f"blocks: frames {written}..{written + b - 1} hold values beyond the float32 range",
                             path=str(path))
        yield written, arr
        written += b
    if written != n_frames:
        raise InputError(f"blocks: the stream ended after {written} of {n_frames} frames", path=str(path))
