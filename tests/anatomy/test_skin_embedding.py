"""embed_points and embedding_matrix: points in a box of tetrahedra reproduced by barycentric weights."""

from __future__ import annotations

import numpy as np

from anatomy_meshes import box_tets as _box_tets
from facecap.anatomy import embed_points, embedding_matrix


def test_embedding_reproduces_points_and_flags_inside() -> None:
    X, T = _box_tets(4, 3, 2, 10.0, (0.0, 0.0, 0.0))
    rng = np.random.default_rng(7)
    inside_pts = rng.uniform([0.5, 0.5, 0.5], [39.5, 29.5, 19.5], size=(500, 3))
    outside_pts = rng.uniform([0, 0, 20.5], [40, 30, 22], size=(50, 3))  # just above the box
    P = np.concatenate([inside_pts, outside_pts])
    e = embed_points(X, T, P)
    W = embedding_matrix(e, X.shape[0], T)
    assert np.abs(W @ X - P).max() < 1e-9
    assert np.allclose(e.weights.sum(axis=1), 1.0, atol=1e-12)
    assert e.inside[:500].all() and not e.inside[500:].any()
    # a point inside lies in its tetrahedron: the weights are its barycentric coordinates, all in [0, 1]
    assert e.weights[:500].min() >= -1e-9 and e.weights[:500].max() <= 1 + 1e-9
