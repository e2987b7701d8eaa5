"""The surface gradient of a function given at the vertices, at each vertex: heights to normals.

Lo et al. represent the detail as heights over the base surface and turn them into
normals "from gradients of neighbor z values" (section 3.2). On a mesh the
gradient of the piecewise-linear function is constant on each triangle (libigl's
``grad``); the gradient at a vertex is the area-weighted mean of its triangles',
a vector in the vertex's tangent plane up to the surface's bending (a sparse
linear map of the heights, with the one-ring's pattern).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..validate import as_faces, as_vertices

__all__ = ["VertexGradient", "vertex_gradient"]


class VertexGradient(NamedTuple):
    """The three components of the vertex gradient as sparse matrices: ``grad f = (x @ f, y @ f, z @ f)``.

    Attributes
    ----------
    x, y, z : (r, c) scipy.sparse.csr_matrix, 1/mm
        Rows: the vertices the gradient is wanted at; columns: the vertices the function is given at
        (values elsewhere are taken as 0).
    """

    x: sp.csr_matrix
    y: sp.csr_matrix
    z: sp.csr_matrix

    def apply(self, values: Any) -> np.ndarray:
        """(r, 3) or (r, 3, k): the gradient of one function (c,) or of k (c, k) at the rows."""
        f = np.asarray(values, dtype=np.float64)
        return np.stack([self.x @ f, self.y @ f, self.z @ f], axis=1)


def vertex_gradient(V: Any, F: Any, rows: Any = None, columns: Any = None) -> VertexGradient:
    """The surface gradient at vertices, as a sparse linear map of values at vertices.

    Parameters
    ----------
    V : (n, 3) float array, mm
    F : (m, 3) int array
    rows : (r,) int array, optional
        Vertices the gradient is wanted at (default: all).
    columns : (c,) int array, optional
        Vertices the function has values at (default: all); elsewhere it is 0.

    Returns
    -------
    VertexGradient

    Examples
    --------
    A linear function's gradient is exact on any mesh:

    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0], [2, 2, 0.5]]); F = np.array([[0, 1, 2], [1, 3, 2]])
    >>> g = vertex_gradient(V, F).apply(3.0 * V[:, 0] - V[:, 1] + 2.0 * V[:, 2])
    >>> g.round(12).tolist()[0]
    [3.0, -1.0, 0.0]
    """
    import igl

    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    n, m = V.shape[0], F.shape[0]
    G = sp.csr_matrix(igl.grad(V, F))  # (3m, n): all x rows, then y, then z
    area = np.asarray(igl.doublearea(V, F), dtype=np.float64).ravel() / 2.0
    corner_rows = F.ravel()
    corner_faces = np.repeat(np.arange(m), 3)
    weight = np.repeat(area, 3)
    total = np.bincount(corner_rows, weights=weight, minlength=n)
    average = sp.csr_matrix((weight / np.maximum(total[corner_rows], 1e-300), (corner_rows, corner_faces)),
                            shape=(n, m))
    if rows is not None:
        average = average[np.asarray(rows, dtype=np.int64)]
    parts = []
    for k in range(3):
        block = average @ G[k * m:(k + 1) * m]
        if columns is not None:
            block = block[:, np.asarray(columns, dtype=np.int64)]
        parts.append(sp.csr_matrix(block))
    return VertexGradient(*parts)
