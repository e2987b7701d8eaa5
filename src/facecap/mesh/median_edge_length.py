"""The median length of a triangle mesh's edges: the mesh's typical sampling distance."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..validate import as_faces, as_vertices

__all__ = ["median_edge_length"]


def median_edge_length(V: Any, F: Any) -> float:
    """Median length of the triangles' sides, mm: the scale a mesh is sampled at.

    Every side of every triangle counts once, so an edge shared by two
    triangles counts twice and a border edge once (the median of the
    half-edges). Image pixel sizes and neighbourhood radii that should follow
    the mesh's resolution are set from it.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangles.

    Returns
    -------
    float, mm
        The median of the ``3 m`` side lengths ``|V[F[:, a]] - V[F[:, b]]|``
        over the sides ``(0, 1), (1, 2), (2, 0)``.

    Raises
    ------
    MeshError
        If ``V`` is not finite (n, 3), or ``F`` is empty or indexes outside ``V``.

    Examples
    --------
    A unit square cut along its diagonal: four sides of 1 mm, the diagonal twice.

    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    >>> median_edge_length(V, np.array([[0, 1, 2], [0, 2, 3]]))
    1.0
    """
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return float(np.median(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)))
