"""Which way a surface's triangles face: away from the surface's own centre, or towards it."""

from __future__ import annotations

import igl
import numpy as np

from ..errors import MeshError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_vertices

__all__ = ["facing_outward"]


def facing_outward(vertices: FloatArray, faces: IntArray) -> float:
    """Area-weighted mean of ``n . (c_f - c)``: how far the triangles face away from the surface's centroid (mm).

    Parameters
    ----------
    vertices : (n, 3) float array, mm
    faces : (f, 3) int array
        Triangles; their winding (counter-clockwise seen from outside) gives
        each normal ``n``.

    Returns
    -------
    float
        Positive when the triangles face away from the surface's area centroid
        ``c`` (outward-wound), negative when they face into it, near zero when
        the surface is too flat to tell. ``c_f`` is a triangle's centroid.

    Raises
    ------
    MeshError
        If the arrays are not (n, 3) finite vertices and (f, 3) faces indexing
        them, or the surface has no area.

    Notes
    -----
    For a closed surface wound outward the divergence theorem gives
    ``3 V / A`` (a sphere of radius ``r``: ``r``). A face scan is an open cap
    whose centroid lies behind its surface, inside the head: a hemisphere of
    radius ``r`` gives ``3 r / 4``; the generated 20k-vertex face scans 39 mm
    (their bounding-box diagonal about 250 mm). Reversing every triangle
    negates the value, so its sign tells a scan's winding from its geometry
    alone. :func:`~facecap.registration.register_markers_to_scan` uses it;
    deciding by which side the markers fit better went wrong on 6 of 30
    scans of a generated take whose 4 head-band markers are not on the skin.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    >>> F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    >>> round(facing_outward(V, F), 4), round(facing_outward(V, F[:, ::-1]), 4)  # an octahedron: 1/sqrt(3)
    (0.5774, -0.5774)
    """
    V = as_vertices(vertices, name="vertices")
    F = as_faces(faces, V.shape[0], name="faces")
    area = igl.doublearea(V, F) / 2.0
    total = float(area.sum())
    if not total > 0:
        raise MeshError("facing_outward: the surface has no area")
    normals = np.nan_to_num(igl.per_face_normals(V, F, np.zeros(3)))
    centres = V[F].mean(axis=1)
    centroid = area @ centres / total
    return float(area @ np.einsum("fd,fd->f", normals, centres - centroid) / total)
