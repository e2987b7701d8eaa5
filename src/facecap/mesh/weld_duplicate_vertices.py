"""Weld vertices that sit at the same position (UV-seam splits) into one."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices
from .duplicate_representatives import duplicate_representatives

__all__ = ["weld_duplicate_vertices", "WeldedMesh"]


class WeldedMesh(NamedTuple):
    """Result of :func:`weld_duplicate_vertices`.

    Attributes
    ----------
    V : (n_welded, 3) float64 array, mm
        One vertex per group of duplicates, at the position of the group's
        lowest-numbered vertex, in the order of those vertices.
    F : (m, 3) int64 array
        The faces, re-indexed into ``V``.
    welded_index : (n,) int64 array
        Welded vertex of each original vertex: ``V[welded_index]`` gives the
        original vertex count back, and ``X[welded_index]`` maps any
        per-vertex result ``X`` computed on the welded mesh back.
    """

    V: FloatArray
    F: IntArray
    welded_index: IntArray


def weld_duplicate_vertices(V: Any, F: Any, *, tolerance: float = 1e-6) -> WeldedMesh:
    """Merge vertices closer than ``tolerance`` into one, keeping the faces.

    Scans and game-style meshes are often split along UV seams: the same
    point is stored once per UV chart, so the surface falls apart into
    pieces at every seam. Solvers that couple neighbouring vertices (the
    Laplacian) need the seams closed; weld, solve, and map back with
    ``welded_index``.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangle vertex indices into ``V``.
    tolerance : float, optional
        Vertices at most this far apart (mm) are merged, transitively (a chain
        of close vertices becomes one). Default 1e-6 mm, which merges exact
        copies and float round-off only; 0 merges exact copies only.

    Returns
    -------
    WeldedMesh
        ``(V, F, welded_index)``, see :class:`WeldedMesh`.

    Raises
    ------
    MeshError
        If ``V`` or ``F`` is malformed or a face index is out of range.
    InputError
        If ``tolerance`` is negative or not a number.

    Notes
    -----
    Faces are kept one for one, so face-indexed data stays valid; a face
    whose corners merge (only with a tolerance larger than its edges)
    becomes degenerate rather than being removed. Close pairs come from
    :meth:`scipy.spatial.cKDTree.query_pairs`, groups from
    :func:`scipy.sparse.csgraph.connected_components`.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]])
    >>> F = np.array([[0, 1, 2], [3, 4, 2]])
    >>> Vw, Fw, index = weld_duplicate_vertices(V, F)
    >>> Fw
    array([[0, 1, 2],
           [1, 3, 2]])
    >>> index
    array([0, 1, 2, 1, 3])
    """
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    tol = as_positive(tolerance, name="tolerance", allow_zero=True)
    rep = duplicate_representatives(V, tol)
    keep = np.flatnonzero(rep == np.arange(V.shape[0]))
    new_of_kept = np.empty(V.shape[0], dtype=np.int64)
    new_of_kept[keep] = np.arange(keep.size)
    welded_index = new_of_kept[rep]
    return WeldedMesh(np.ascontiguousarray(V[keep]), welded_index[F], welded_index)
