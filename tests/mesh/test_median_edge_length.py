"""Tests for facecap.mesh.median_edge_length."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from facecap.errors import MeshError
from facecap.mesh.median_edge_length import median_edge_length


def _grid(nx, ny, spacing):
    x, y = np.meshgrid(np.arange(nx) * spacing, np.arange(ny) * spacing)
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + nx], 1), np.stack([a + 1, a + nx + 1, a + nx], 1)])
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1), F


def test_a_regular_grid_is_its_spacing_whatever_its_pose_and_scale():
    # each square: four sides of the spacing, two half-diagonals sqrt(2) longer
    V, F = _grid(9, 7, 1.7)
    assert median_edge_length(V, F) == pytest.approx(1.7, rel=1e-12)
    R = Rotation.from_rotvec([0.3, -1.1, 0.4]).as_matrix()
    assert median_edge_length(V @ R.T + [5.0, -2.0, 9.0], F) == pytest.approx(1.7, rel=1e-12)
    assert median_edge_length(3.0 * V, F) == pytest.approx(5.1, rel=1e-12)


def test_matches_trimesh_face_edges_on_a_random_surface():
    s = trimesh.creation.icosphere(subdivisions=3, radius=12.0)
    rng = np.random.default_rng(3)
    V = np.asarray(s.vertices) * rng.uniform(0.7, 1.3, size=(len(s.vertices), 1))  # uneven edges
    F = np.asarray(s.faces, dtype=np.int64)
    edges = trimesh.Trimesh(V, F, process=False).edges  # every face's sides, shared ones twice
    assert len(edges) == 3 * len(F)
    expected = np.median(np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1))
    assert median_edge_length(V, F) == expected


def test_refuses_a_mesh_without_faces_or_with_faces_out_of_range():
    V, F = _grid(3, 3, 1.0)
    with pytest.raises(MeshError, match="no faces"):
        median_edge_length(V, np.zeros((0, 3), dtype=np.int64))
    with pytest.raises(MeshError, match="out of range"):
        median_edge_length(V, F + 1)
