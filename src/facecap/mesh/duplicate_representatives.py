"""Groups of vertices that sit at the same position, each named by its lowest-numbered vertex."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..typing import FloatArray, IntArray

__all__ = ["duplicate_representatives"]


def duplicate_representatives(V: FloatArray, tolerance: float) -> IntArray:
    """For each vertex, the lowest-numbered vertex of its group of duplicates.

    Vertices within ``tolerance`` of each other are grouped transitively (a chain of close pairs
    is one group); a vertex with no duplicate is its own representative. The grouping that
    :func:`weld_duplicate_vertices` welds and :func:`check_mesh` reports.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions, all finite (not checked: callers validate).
    tolerance : float, mm
        Two vertices at most this far apart (Euclidean) are duplicates.

    Returns
    -------
    (n,) int64 array
        ``rep[i] <= i``, the smallest index in vertex ``i``'s group; ``rep[rep] == rep``.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 0, 1e-9], [1.0, 0, 1e-9]])
    >>> duplicate_representatives(V, 1e-6).tolist()
    [0, 1, 0, 1]
    """
    n = V.shape[0]
    pairs = cKDTree(V).query_pairs(r=tolerance, output_type="ndarray")
    index = np.arange(n, dtype=np.int64)
    if pairs.size == 0:
        return index
    graph = sp.coo_matrix(
        (np.ones(pairs.shape[0], dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n)
    ).tocsr()
    _, group = connected_components(graph, directed=False)
    _, lowest = np.unique(group, return_index=True)  # groups are labelled 0 .. n_groups - 1
    return lowest[group].astype(np.int64)
