"""Face and vertex normals of a triangle mesh, for one frame or a stack of frames, everywhere or at a few vertices."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces

__all__ = ["face_normals", "vertex_normals"]


def face_normals(V: FloatArray, F: IntArray) -> FloatArray:
    """Unnormalised face normals ``(x_1 - x_0) x (x_2 - x_0)``: their length is twice the triangle's area.

    Parameters
    ----------
    V : (..., n, 3) float array, mm
        Vertex positions, one frame or a stack.
    F : (m, 3) int array
        Triangles (indices are not checked here: :func:`vertex_normals` checks them).

    Returns
    -------
    (..., m, 3) float64 array, mm^2

    Examples
    --------
    >>> face_normals(np.array([[0.0, 0, 0], [2, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])).tolist()
    [[0.0, 0.0, 2.0]]
    """
    X = np.asarray(V, dtype=np.float64)
    a = X[..., F[:, 0], :]
    return np.cross(X[..., F[:, 1], :] - a, X[..., F[:, 2], :] - a)


def vertex_normals(V: FloatArray, F: IntArray, vertices: IntArray | None = None) -> FloatArray:
    """Area-weighted unit vertex normals, for one frame or a stack, at every vertex or at some.

    Only the triangles round ``vertices`` are evaluated, so asking for a
    hundred markers on a long take is cheap.

    Parameters
    ----------
    V : (n, 3) or (T, n, 3) float array, mm
        Vertex positions (one frame or a stack).
    F : (m, 3) int array
        Triangles, consistently oriented.
    vertices : (k,) int array, optional
        Where the normals are wanted; default all ``n``.

    Returns
    -------
    (k, 3) or (T, k, 3) float64 array
        Unit normals; a vertex with no (or only degenerate) triangles gets NaN.

    Raises
    ------
    InputError
        If ``F`` or ``vertices`` index outside ``V``.

    Notes
    -----
    ``n(v) = normalize(sum_{f ∋ v} (x_1 - x_0) × (x_2 - x_0))``: the sum of the
    incident face normals weighted by twice their areas, as libigl's
    ``per_vertex_normals`` with area weighting computes it (one frame at a time).

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> vertex_normals(V, np.array([[0, 1, 2]]), np.array([0])).tolist()
    [[0.0, 0.0, 1.0]]
    """
    X = np.asarray(V)
    n = X.shape[-2]
    F = as_faces(F, n)
    vertices = np.arange(n) if vertices is None else np.asarray(vertices, dtype=np.int64)
    if vertices.ndim != 1 or (vertices.size and (vertices.min() < 0 or vertices.max() >= n)):
        raise InputError(f"vertices: expected 1-D vertex indices in 0..{n - 1}")
    row = np.full(n, -1, dtype=np.int64)
    row[vertices] = np.arange(vertices.size)
    Fi = F[(row[F] >= 0).any(axis=1)]
    used, local = np.unique(Fi, return_inverse=True)
    normals = face_normals(X[..., used, :], local.reshape(Fi.shape))  # (..., f, 3)
    r = row[Fi].ravel()
    keep = r >= 0
    S = sp.csr_matrix(
        (np.ones(int(keep.sum())), (r[keep], np.repeat(np.arange(Fi.shape[0]), 3)[keep])),
        shape=(vertices.size, Fi.shape[0]),
    )
    lead = normals.shape[:-2]
    flat = np.moveaxis(normals, -2, 0).reshape(Fi.shape[0], -1)
    N = np.moveaxis((S @ flat).reshape((vertices.size, *lead, 3)), 0, -2)
    length = np.linalg.norm(N, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(length > 0, N / length, np.nan)
