"""Connected pieces of a triangle mesh."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..typing import IntArray
from ..validate import as_faces

__all__ = ["connected_pieces"]


def connected_pieces(F: Any, n_vertices: int) -> tuple[int, IntArray]:
    """Split a mesh into its connected pieces.

    Two vertices are in the same piece when a chain of faces joins them,
    neighbouring faces sharing at least one vertex (as libigl's
    ``vertex_components``). Vertices that no face uses belong to no piece.

    Parameters
    ----------
    F : (m, 3) int64 array
        Triangle vertex indices, each in ``[0, n_vertices)``.
    n_vertices : int
        Number of vertices n of the mesh (vertices after the last one a face
        uses count too).

    Returns
    -------
    n_pieces : int
        Number of pieces.
    labels : (n,) int64 array
        Piece of each vertex in ``0 .. n_pieces - 1``, or -1 for a vertex
        that no face uses. Pieces are numbered in the order of their
        lowest-numbered vertex.

    Raises
    ------
    InputError
        If ``n_vertices`` is not a non-negative integer.
    MeshError
        If ``F`` is not (m, 3) integers in range or is empty.

    Notes
    -----
    The vertex graph with an edge for two sides of every triangle (enough to
    link its three corners) is handed to
    :func:`scipy.sparse.csgraph.connected_components`: O(n + m).

    Examples
    --------
    >>> import numpy as np
    >>> connected_pieces(np.array([[0, 1, 2], [3, 4, 5], [2, 1, 6]]), 8)
    (2, array([ 0,  0,  0,  1,  1,  1,  0, -1]))
    """
    if isinstance(n_vertices, bool) or not isinstance(n_vertices, (int, np.integer)) or n_vertices < 0:
        raise InputError(f"n_vertices: expected a non-negative integer, got {n_vertices!r}")
    n = int(n_vertices)
    F = as_faces(F, n, name="F")
    rows = np.concatenate([F[:, 0], F[:, 1]])
    cols = np.concatenate([F[:, 1], F[:, 2]])
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n)).tocsr()
    _, raw = connected_components(graph, directed=False)
    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    used_idx = np.flatnonzero(used)
    comp = raw[used_idx]
    # number the pieces by their lowest vertex
    uniq, first, inverse = np.unique(comp, return_index=True, return_inverse=True)
    rank = np.empty(uniq.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(uniq.size)
    labels = np.full(n, -1, dtype=np.int64)
    labels[used_idx] = rank[inverse.reshape(-1)]
    return int(uniq.size), labels
