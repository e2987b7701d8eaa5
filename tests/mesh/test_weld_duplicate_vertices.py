"""Tests of facecap.mesh.weld_duplicate_vertices."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from facecap.errors import InputError, MeshError
from facecap.mesh import weld_duplicate_vertices

CUBE_V = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float
) * 10.0
CUBE_F = np.array(
    [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
     [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
)


def split_cube() -> tuple[np.ndarray, np.ndarray]:
    """The cube cut along the edge 0-4 as at a UV seam: faces of the x=0 side use copies 8, 9."""
    V = np.concatenate([CUBE_V, CUBE_V[[0, 4]]])
    F = CUBE_F.copy()
    side = [10, 11]  # faces (3, 0, 4) and (3, 4, 7)
    F[side] = np.where(F[side] == 0, 8, np.where(F[side] == 4, 9, F[side]))
    return V, F


def test_split_cube_is_welded_back() -> None:
    V, F = split_cube()
    Vw, Fw, index = weld_duplicate_vertices(V, F)
    np.testing.assert_array_equal(Vw, CUBE_V)
    np.testing.assert_array_equal(Fw, CUBE_F)
    np.testing.assert_array_equal(index, [0, 1, 2, 3, 4, 5, 6, 7, 0, 4])
    assert index.dtype == np.int64 and Fw.dtype == np.int64


def test_map_back_and_face_count() -> None:
    rng = np.random.default_rng(2)
    base = rng.normal(size=(40, 3)) * 20
    copies = rng.integers(0, 40, 15)
    V = np.concatenate([base, base[copies] + rng.normal(size=(15, 3)) * 1e-8])
    V = V[rng.permutation(V.shape[0])]
    F = rng.integers(0, V.shape[0], size=(60, 3))
    Vw, Fw, index = weld_duplicate_vertices(V, F)
    assert Vw.shape[0] == 40  # the 15 near-copies (1e-8 mm off) are welded away
    assert Fw.shape == F.shape
    np.testing.assert_array_equal(Fw, index[F])
    assert np.abs(Vw[index] - V).max() < 1e-6  # every vertex is within tolerance of its weld
    # each welded vertex sits at its group's lowest-numbered vertex
    for k in range(Vw.shape[0]):
        np.testing.assert_array_equal(Vw[k], V[np.flatnonzero(index == k).min()])


def test_tolerance() -> None:
    V = np.array([[0, 0, 0], [1e-7, 0, 0], [5e-3, 0, 0], [1, 0, 0], [0, 1, 0], [0.4, 0, 0],
                  [0.8, 0, 0]])
    F = np.array([[0, 3, 4]])
    assert weld_duplicate_vertices(V, F).V.shape[0] == 6  # default 1e-6 mm: only 0 and 1
    assert weld_duplicate_vertices(V, F, tolerance=0.0).V.shape[0] == 7
    assert weld_duplicate_vertices(V, F, tolerance=0.01).V.shape[0] == 5  # 0, 1, 2
    # transitive: 0 - 0.4 - 0.8 - 1 chain at spacing <= 0.4
    index = weld_duplicate_vertices(V, F, tolerance=0.41).welded_index
    assert len(set(index[[0, 1, 2, 3, 5, 6]].tolist())) == 1 and index[4] != index[0]


def test_matches_libigl_remove_duplicate_vertices() -> None:
    rng = np.random.default_rng(9)
    V = rng.random((300, 3)) * 100
    V = np.concatenate([V, V[rng.integers(0, 300, 60)]])  # exact copies
    F = rng.integers(0, V.shape[0], size=(200, 3))
    Vw, Fw, index = weld_duplicate_vertices(V, F, tolerance=1e-9)
    SV, SVI, SVJ, SF = igl.remove_duplicate_vertices(V, F, 1e-9)
    assert Vw.shape[0] == SV.shape[0]
    # same grouping: the maps differ by a relabelling
    pairs = np.unique(np.stack([index, SVJ], 1), axis=0)
    assert pairs.shape[0] == Vw.shape[0]
    np.testing.assert_array_equal(Vw[index], SV[SVJ])


def test_errors() -> None:
    with pytest.raises(MeshError, match="out of range"):
        weld_duplicate_vertices(CUBE_V, CUBE_F + 1)
    with pytest.raises(InputError, match="tolerance"):
        weld_duplicate_vertices(CUBE_V, CUBE_F, tolerance=-1.0)
    with pytest.raises(MeshError, match="V"):
        weld_duplicate_vertices(CUBE_V[:, :2], CUBE_F)
