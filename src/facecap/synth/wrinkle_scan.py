"""A scan fine enough to hold wrinkles: the face subdivided, its original vertices kept first."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..structures import Mesh
from ..typing import IntArray

__all__ = ["SubdividedScan", "subdivide_scan"]


class SubdividedScan(NamedTuple):
    """A mesh split by midpoint subdivision, and the linear map from the original vertices.

    Attributes
    ----------
    mesh : Mesh
        The fine mesh (mm, triangles only, no UVs): the original ``n``
        vertices first, unchanged and in order, then the edge midpoints of
        each level.
    upsample : (n_fine, n) scipy.sparse.csr_matrix, float64
        ``mesh.vertices == upsample @ original.vertices``; apply it to any
        per-vertex field of the original (an animated frame, blendshape
        deltas) to carry it to the fine mesh.
    n_original : int
        Number of vertices of the original mesh; fine vertex ``i < n_original``
        is original vertex ``i`` (markers and correspondence maps stay valid).
    """

    mesh: Mesh
    upsample: sp.csr_matrix
    n_original: int


def _midpoint_level(F: IntArray, n: int) -> tuple[IntArray, sp.csr_matrix]:
    """One level of 1-to-4 midpoint subdivision: new faces and the (n + e, n) averaging matrix."""
    corners = np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1)  # (m, 3, 2): edges ab, bc, ca
    edges, inverse = np.unique(np.sort(corners.reshape(-1, 2), axis=1), axis=0, return_inverse=True)
    mid = n + inverse.reshape(-1, 3)
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
    faces = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                            np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)])
    e = edges.shape[0]
    rows = np.concatenate([np.arange(n), np.repeat(n + np.arange(e), 2)])
    cols = np.concatenate([np.arange(n), edges.ravel()])
    vals = np.concatenate([np.ones(n), np.full(2 * e, 0.5)])
    return faces.astype(np.int64), sp.csr_matrix((vals, (rows, cols)), shape=(n + e, n))


def subdivide_scan(scan: Mesh, *, levels: int = 2) -> SubdividedScan:
    """Split every triangle into four, ``levels`` times, keeping the original vertices first.

    Midpoint (not Loop) subdivision: the fine surface is the original one,
    so the original vertices, the markers on them and every large-scale
    quantity carried by :attr:`SubdividedScan.upsample` stay exact. Each
    level multiplies the triangles by 4 and roughly halves the vertex spacing;
    on the ICT face (9,409 vertices, forehead edges 3.75 mm) two levels give
    148,402 vertices and 0.94 mm on the forehead, 0.4 mm around the eyes and
    mouth; three give 590,000 and half that.

    Parameters
    ----------
    scan : Mesh
        The face (mm).
    levels : int, default 2
        Subdivision levels (>= 0).

    Returns
    -------
    SubdividedScan

    Raises
    ------
    InputError
        If ``levels`` is not a non-negative integer.

    Notes
    -----
    Each level adds one vertex per edge ``(i, j)`` at ``(v_i + v_j) / 2`` and
    replaces triangle ``(a, b, c)`` by ``(a, ab, ca), (ab, b, bc), (ca, bc, c),
    (ab, bc, ca)``, which is what ``igl.upsample`` does (up to the numbering
    of the new vertices).

    Examples
    --------
    >>> tri = Mesh(np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]), np.array([[0, 1, 2]]))
    >>> fine = subdivide_scan(tri, levels=1)
    >>> fine.mesh.n_vertices, fine.mesh.n_faces, fine.n_original
    (6, 4, 3)
    """
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 0:
        raise InputError(f"levels: expected an integer >= 0, got {levels!r}")
    n = scan.n_vertices
    F = scan.faces
    S = sp.identity(n, format="csr", dtype=np.float64)
    for _ in range(int(levels)):
        F, level = _midpoint_level(F, S.shape[0])
        S = (level @ S).tocsr()
    V = S @ scan.vertices
    V[:n] = scan.vertices  # exact, not 1.0 * v
    mesh = Mesh(V, F, source_unit=scan.source_unit)
    return SubdividedScan(mesh=mesh, upsample=S, n_original=n)
