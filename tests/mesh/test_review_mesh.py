"""review_mesh: a subset of the scan's own vertices, proper triangles, UVs carried by chart."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from facecap.errors import InputError
from facecap.mesh import review_mesh
from facecap.structures import Mesh


def sheet(n: int = 80, size: float = 160.0) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    x, y = (u.ravel() - 0.5) * size, (v.ravel() - 0.5) * size
    V = np.stack([x, y, -0.004 * x**2 - 0.002 * y**2], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def left_uv(P: np.ndarray) -> np.ndarray:
    return np.stack([0.002 * P[:, 0] + 0.2, 0.003 * P[:, 1] + 0.5], 1)


def right_uv(P: np.ndarray) -> np.ndarray:
    return np.stack([-0.002 * P[:, 0] + 0.9, 0.003 * P[:, 1] + 0.4], 1)


def two_chart_mesh() -> tuple[Mesh, np.ndarray]:
    """UVs from two known maps of position: triangles with x < 0 in one chart, the rest in the other."""
    V, F = sheet()
    left = V[F].mean(axis=1)[:, 0] < 0
    n = V.shape[0]
    uvs = np.concatenate([left_uv(V), right_uv(V)])
    corner_uv = np.where(left[:, None], F, F + n)
    return Mesh(V, F, uvs=uvs, uv_indices=corner_uv.ravel()), left


def test_small_mesh_comes_back_unchanged() -> None:
    V, F = sheet(10)
    mesh = Mesh(V, F)
    small, kept = review_mesh(mesh, max_vertices=100)
    assert small is mesh
    np.testing.assert_array_equal(kept, np.arange(100))


def test_kept_vertices_are_exact_and_triangles_proper() -> None:
    V, F = sheet()
    colors = np.random.default_rng(0).uniform(0, 1, (V.shape[0], 3))
    small, kept = review_mesh(Mesh(V, F, vertex_colors=colors), max_vertices=1200)
    assert 0.8 * 1200 <= small.n_vertices <= 1200
    assert np.all(np.diff(kept) > 0)
    np.testing.assert_array_equal(small.vertices, V[kept])  # bit for bit: a frame restricts by indexing
    np.testing.assert_array_equal(small.vertex_colors, colors[kept].astype(np.float32))
    T = small.faces
    assert np.all((T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2]))
    normals = np.cross(small.vertices[T[:, 1]] - small.vertices[T[:, 0]], small.vertices[T[:, 2]] - small.vertices[T[:, 0]])
    assert np.all(np.linalg.norm(normals, axis=1) > 0)
    assert np.unique(np.sort(T, axis=1), axis=0).shape[0] == T.shape[0]  # no duplicates
    assert np.all(normals[:, 2] > 0)  # the sheet's triangles all face +z; orientation kept
    # every vertex is used, and the review mesh still covers the sheet: each scan vertex lies near a kept one
    assert np.array_equal(np.unique(T), np.arange(small.n_vertices))
    spacing = 160.0 / 79
    gap, _ = cKDTree(small.vertices).query(V)
    assert gap.max() < 3.0 * spacing * np.sqrt(V.shape[0] / 1200)


def test_face_varying_uvs_follow_their_chart() -> None:
    mesh, _ = two_chart_mesh()
    small, kept = review_mesh(mesh, max_vertices=900)
    corner_uv = small.uvs[small.uv_indices.reshape(-1, 3)]  # (m, 3, 2)
    P = small.vertices[small.faces]  # (m, 3, 3)
    in_left = np.all(np.isclose(corner_uv, left_uv(P.reshape(-1, 3)).reshape(P.shape[0], 3, 2)), axis=(1, 2))
    in_right = np.all(np.isclose(corner_uv, right_uv(P.reshape(-1, 3)).reshape(P.shape[0], 3, 2)), axis=(1, 2))
    # each corner's UV is its own vertex's UV in one chart, the same chart for the whole triangle
    # (a triangle bridging the cut may fall back to a vertex's other chart: at most the cut's share)
    assert np.mean(in_left | in_right) > 0.97
    x = P.mean(axis=1)[:, 0]
    assert np.all(in_left[x < -10]) and np.all(in_right[x > 10])


def test_per_vertex_uvs_are_indexed() -> None:
    V, F = sheet(40)
    mesh = Mesh(V, F, uvs=left_uv(V))
    small, kept = review_mesh(mesh, max_vertices=300)
    np.testing.assert_array_equal(small.uvs, left_uv(V)[kept])
    assert small.uv_indices is None


def test_bad_input() -> None:
    V, F = sheet(10)
    with pytest.raises(InputError, match="max_vertices"):
        review_mesh(Mesh(V, F), max_vertices=2)
    with pytest.raises(InputError, match="Mesh"):
        review_mesh(V, max_vertices=10)  # type: ignore[arg-type]
