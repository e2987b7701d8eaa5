"""Points embedded in a tetrahedral mesh: a tetrahedron and four barycentric weights each.

The skin surface of the face model is carried by the soft-tissue mesh: every
scan vertex ``p`` is stored as ``(tet, w)`` with ``p = sum_i w_i X[T[tet, i]]``
and ``sum_i w_i = 1``, so a deformed mesh gives the deformed skin by one sparse
product (:func:`embedding_matrix`), as the landmarks of Sifakis et al. 2005,
sec. 5 (``X_L = W X``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..typing import FloatArray, IntArray

__all__ = ["SkinEmbedding", "embed_points", "embedding_matrix"]

_CANDIDATES = 24
"""Tetrahedra (nearest centroids) tried per point; the one holding it best wins."""
INSIDE_TOLERANCE = 1e-9
"""A point counts as inside its tetrahedron when every weight is at least minus this."""


class SkinEmbedding(NamedTuple):
    """Barycentric embedding of points in a tetrahedral mesh.

    Attributes
    ----------
    tet : (n,) int64 array
        Tetrahedron of each point.
    weights : (n, 4) float64 array
        Barycentric weights (sum 1) over that tetrahedron's corners; all in
        [0, 1] for a point inside the mesh, some negative for a point outside
        (then the tetrahedron is the nearest one and the weights extrapolate
        it affinely, which still reproduces the point exactly).
    inside : (n,) bool array
        Whether the point lies in its tetrahedron (to 1e-9).
    """

    tet: IntArray
    weights: FloatArray
    inside: np.ndarray


def _barycentric(X: FloatArray, T: IntArray, tets: IntArray, P: FloatArray) -> FloatArray:
    """Barycentric weights (k, c, 4) of points P (k, 3) in candidate tets (k, c)."""
    C = X[T[tets]]  # (k, c, 4, 3)
    D = np.swapaxes(C[..., 1:, :] - C[..., :1, :], -1, -2)  # (k, c, 3, 3): columns x1-x0, x2-x0, x3-x0
    rhs = P[:, None, :] - C[..., 0, :]
    lam = np.linalg.solve(D, rhs[..., None])[..., 0]
    return np.concatenate([1.0 - lam.sum(axis=-1, keepdims=True), lam], axis=-1)


def embed_points(X: FloatArray, T: IntArray, P: FloatArray, *, chunk: int = 20_000) -> SkinEmbedding:
    """Embed points in a tetrahedral mesh.

    Parameters
    ----------
    X : (N, 3) float64 array, mm
        Nodes.
    T : (M, 4) int64 array
        Positively oriented, non-degenerate tetrahedra.
    P : (n, 3) float64 array, mm
        Points to embed.
    chunk : int, optional
        Points per vectorised batch (memory bound), default 20,000.

    Returns
    -------
    SkinEmbedding

    Notes
    -----
    For each point the 24 tetrahedra with the nearest centroids are tried and
    the one with the largest smallest weight is kept: a tetrahedron holding
    the point if one is among them, else the one it is least outside of.
    The weights are then refined once against the residual so that
    ``sum w_i X_i`` reproduces ``P`` to rounding (about 1e-12 mm at face scale).
    """
    centroids = X[T].mean(axis=1)
    tree = cKDTree(centroids)
    k = min(_CANDIDATES, T.shape[0])
    tet = np.empty(P.shape[0], dtype=np.int64)
    W = np.empty((P.shape[0], 4))
    for start in range(0, P.shape[0], chunk):
        Q = P[start:start + chunk]
        _, cand = tree.query(Q, k=k)
        cand = cand.reshape(Q.shape[0], k)
        lam = _barycentric(X, T, cand, Q)
        best = np.argmax(lam.min(axis=-1), axis=1)
        rows = np.arange(Q.shape[0])
        t = cand[rows, best]
        w = lam[rows, best]
        # one step of iterative refinement: the weights of the residual, summing to 0
        corners = X[T[t]]
        residual = Q - np.einsum("ij,ijk->ik", w, corners)
        D = np.swapaxes(corners[:, 1:] - corners[:, :1], 1, 2)
        lam = np.linalg.solve(D, residual[..., None])[..., 0]
        w = w + np.concatenate([-lam.sum(axis=1, keepdims=True), lam], axis=1)
        tet[start:start + chunk] = t
        W[start:start + chunk] = w
    return SkinEmbedding(tet, W, W.min(axis=1) >= -INSIDE_TOLERANCE)


def embedding_matrix(embedding: SkinEmbedding, n_nodes: int, T: IntArray) -> sp.csr_matrix:
    """Sparse ``(n, N)`` matrix ``W`` with ``points = W @ X``.

    Parameters
    ----------
    embedding : SkinEmbedding
    n_nodes : int
        N, the node count.
    T : (M, 4) int64 array
        The tetrahedra the embedding refers to.

    Returns
    -------
    scipy.sparse.csr_matrix, (n, N) float64
    """
    n = embedding.tet.shape[0]
    rows = np.repeat(np.arange(n), 4)
    cols = T[embedding.tet].ravel()
    return sp.csr_matrix((embedding.weights.ravel(), (rows, cols)), shape=(n, n_nodes))
