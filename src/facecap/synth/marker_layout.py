"""Where the virtual markers go on the face: a realistic facial marker layout."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_vertices

__all__ = ["choose_marker_vertices", "boundary_vertices"]


def boundary_vertices(F: IntArray, n_vertices: int) -> np.ndarray:
    """(n,) bool: vertices on a boundary edge (edges used by exactly one triangle)."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, counts = np.unique(E, axis=0, return_counts=True)
    mask = np.zeros(n_vertices, dtype=bool)
    mask[edges[counts == 1].ravel()] = True
    return mask


def choose_marker_vertices(
    V: FloatArray,
    F: IntArray,
    expression_deltas: np.ndarray,
    n_markers: int,
    *,
    seed: int = 0,
    motion_weight: float = 1.5,
    exclude: np.ndarray | None = None,
) -> IntArray:
    """Pick marker vertices the way a facial capture layout is designed.

    Farthest-point sampling over the face, with distances scaled up where the
    face moves (the largest displacement of each vertex over the expression
    blendshapes), so markers are denser around the mouth, eyes and brows and
    sparser on the nose bridge and temples, as in real 60-120 marker layouts.
    Boundary vertices (the rim of the scan, the eye openings and the lips'
    inner edge) and their neighbours are excluded: a marker cannot sit on the
    lip seam or the eyelid margin.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
    F : (m, 3) int64 array
    expression_deltas : (k, n, 3) array, mm
        Per-expression vertex offsets used to find where the face moves.
    n_markers : int
    seed : int, default 0
        Picks the starting vertex among the most mobile ones.
    motion_weight : float, default 1.5
        How strongly motion attracts markers (0: uniform spacing).
    exclude : (n,) bool array, optional
        Vertices that must not carry a marker (besides the boundary ones).

    Returns
    -------
    (n_markers,) int64 array
        Distinct vertex indices, in picking order.
    """
    V = as_vertices(V)
    F = as_faces(F, V.shape[0])
    if n_markers < 1:
        raise InputError(f"n_markers: expected a positive count, got {n_markers}")
    n = V.shape[0]
    boundary = boundary_vertices(F, n)
    rows = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    cols = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    A = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n)).tocsr()
    A = A + A.T
    near_boundary = boundary | ((A @ boundary.astype(float)) > 0)
    allowed = ~near_boundary
    if exclude is not None:
        allowed &= ~np.asarray(exclude, dtype=bool)
    candidates = np.flatnonzero(allowed)
    if candidates.size < n_markers:
        raise InputError(f"n_markers: only {candidates.size} vertices can carry a marker, asked for {n_markers}")
    motion = np.linalg.norm(np.asarray(expression_deltas, dtype=np.float64), axis=2).max(axis=0)[candidates]
    scale = 1.0 + motion_weight * motion / max(float(motion.max()), 1e-12)
    rng = np.random.default_rng(seed)
    top = np.argsort(motion)[-20:]
    chosen = [int(top[rng.integers(top.size)])]
    distance = np.full(candidates.size, np.inf)
    P = V[candidates]
    for _ in range(n_markers - 1):
        distance = np.minimum(distance, np.linalg.norm(P - P[chosen[-1]], axis=1))
        chosen.append(int(np.argmax(distance * scale)))
    return candidates[np.array(chosen, dtype=np.int64)]
