"""Tests of facecap.mesh.connected_pieces."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from facecap.errors import InputError, MeshError
from facecap.mesh import connected_pieces


def test_single_triangle() -> None:
    n, labels = connected_pieces(np.array([[0, 1, 2]]), 3)
    assert n == 1
    np.testing.assert_array_equal(labels, [0, 0, 0])
    assert labels.dtype == np.int64


def test_two_triangles_sharing_an_edge_or_a_vertex_are_one_piece() -> None:
    assert connected_pieces(np.array([[0, 1, 2], [2, 1, 3]]), 4)[0] == 1
    assert connected_pieces(np.array([[0, 1, 2], [2, 3, 4]]), 5)[0] == 1  # bow-tie


def test_separate_pieces_and_unused_vertices() -> None:
    # piece A uses 5, 6, 7; piece B uses 0..3 (two triangles); vertex 4 and 8 are unused
    F = np.array([[5, 6, 7], [0, 1, 2], [2, 1, 3]])
    n, labels = connected_pieces(F, 9)
    assert n == 2
    # numbered by lowest vertex: the piece holding vertex 0 is piece 0
    np.testing.assert_array_equal(labels, [0, 0, 0, 0, -1, 1, 1, 1, -1])


def _grid_faces(nx: int, ny: int, offset: int = 0) -> np.ndarray:
    idx = np.arange(nx * ny).reshape(ny, nx) + offset
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_random_mesh_matches_libigl_and_scipy() -> None:
    rng = np.random.default_rng(0)
    # three grids of different sizes, vertices shuffled, plus unused vertices and random extra faces
    F = np.concatenate([_grid_faces(5, 4), _grid_faces(3, 3, 20), _grid_faces(6, 2, 29)])
    n = 29 + 12 + 15
    perm = rng.permutation(n)
    F = perm[F]
    F = np.concatenate([F, rng.integers(0, n, size=(3, 3))])
    F = F[rng.permutation(F.shape[0])]
    n_pieces, labels = connected_pieces(F, n)

    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    np.testing.assert_array_equal(labels == -1, ~used)
    # libigl: every vertex gets a component (unused ones their own)
    ref = igl.vertex_components(F)
    assert ref.shape[0] >= used.nonzero()[0].max() + 1
    ref_used = ref[np.flatnonzero(used)]
    ours_used = labels[used]
    assert n_pieces == np.unique(ref_used).size
    # same partition: the label pairs are one to one
    pairs = np.unique(np.stack([ours_used, ref_used], 1), axis=0)
    assert pairs.shape[0] == n_pieces
    # scipy on the full vertex adjacency (all three edges of each face)
    rows = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    cols = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    A = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    n_all, _ = connected_components(A, directed=False)
    assert n_pieces == n_all - np.count_nonzero(~used)
    # pieces are numbered by their lowest vertex
    lowest = [np.flatnonzero(labels == k).min() for k in range(n_pieces)]
    assert lowest == sorted(lowest)


def test_errors() -> None:
    with pytest.raises(MeshError, match="out of range"):
        connected_pieces(np.array([[0, 1, 5]]), 3)
    with pytest.raises(MeshError, match="no faces"):
        connected_pieces(np.zeros((0, 3), dtype=int), 3)
    with pytest.raises(InputError, match="n_vertices"):
        connected_pieces(np.array([[0, 1, 2]]), -1)
    with pytest.raises(InputError, match="n_vertices"):
        connected_pieces(np.array([[0, 1, 2]]), 3.0)  # type: ignore[arg-type]
