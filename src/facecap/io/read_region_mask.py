"""A region of a mesh's vertices, read from a file: a JSON list of vertex indices or a ``.npy`` bool mask."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..typing import BoolArray

__all__ = ["read_region_mask"]


def read_region_mask(path: str | Path, n_vertices: int) -> BoolArray:
    """Read a region of a mesh's vertices as a bool mask.

    Parameters
    ----------
    path : str or Path
        A ``.npy`` file holding a ``(n_vertices,)`` bool array, or (any other suffix) a JSON
        list of vertex indices, integers in ``0..n_vertices - 1``.
    n_vertices : int
        Vertices of the mesh the region is on.

    Returns
    -------
    (n_vertices,) bool array
        True on the region's vertices.

    Raises
    ------
    FileFormatError
        On a file that is not such an array or list, or indices out of range (the message names the file).
    FileNotFoundError
        On a missing JSON file (a missing ``.npy`` file is not a NumPy array file).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "region.json"
    >>> _ = path.write_text("[0, 2]")
    >>> read_region_mask(path, 4).tolist()
    [True, False, True, False]
    """
    source = Path(path)
    if source.suffix.lower() == ".npy":
        try:
            mask = np.load(source, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise FileFormatError(f"not a NumPy array file ({exc})", path=str(path)) from None
        if mask.dtype != bool or mask.shape != (n_vertices,):
            raise FileFormatError(f"expected a bool array of the scan's {n_vertices} vertices, "
                                  f"got {mask.dtype} {mask.shape}", path=str(path))
        return mask
    try:
        content = json.loads(source.read_text())
    except json.JSONDecodeError:
        raise FileFormatError("expected a JSON list of vertex indices", path=str(path)) from None
    if not isinstance(content, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in content):
        raise FileFormatError("expected a JSON list of vertex indices (integers)", path=str(path))
    indices = np.asarray(content, dtype=np.int64)
    if indices.ndim != 1 or indices.size == 0 or indices.min() < 0 or indices.max() >= n_vertices:
        raise FileFormatError(f"expected vertex indices in 0..{n_vertices - 1}", path=str(path))
    mask = np.zeros(n_vertices, dtype=bool)
    mask[indices] = True
    return mask
