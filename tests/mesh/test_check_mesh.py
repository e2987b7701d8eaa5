"""Tests of facecap.mesh.check_mesh."""

from __future__ import annotations

import json
from collections import Counter

import igl
import numpy as np
import pytest

from facecap.errors import InputError, MeshError
from facecap.mesh import check_mesh, weld_duplicate_vertices

TRI_V = np.array([[0.0, 0, 0], [3, 0, 0], [0, 4, 0]])


def grid(nx: int, ny: int, h: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.arange(nx) * h, np.arange(ny) * h)
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return V, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def cube() -> tuple[np.ndarray, np.ndarray]:
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
                  [0, 1, 1]], dtype=float) * 10.0
    F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6],
                  [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return V, F


def test_single_triangle_is_clean() -> None:
    r = check_mesh(TRI_V, np.array([[0, 1, 2]]))
    assert r.problems == []
    assert (r.n_vertices, r.n_faces, r.n_pieces) == (3, 1, 1)
    assert (r.n_boundary_edges, r.n_boundary_loops) == (3, 1)
    assert r.mean_edge_length == pytest.approx((3 + 4 + 5) / 3, rel=1e-15)
    np.testing.assert_array_equal(r.bounding_box, [[0, 0, 0], [3, 4, 0]])
    for a in (r.degenerate_faces, r.unreferenced_vertices, r.duplicate_vertices, r.out_of_range_faces):
        assert a.size == 0
    assert r.non_manifold_edges.shape == (0, 2)


def test_two_triangles_sharing_an_edge() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    r = check_mesh(V, np.array([[0, 1, 2], [2, 1, 3]]))
    assert r.problems == []
    assert (r.n_boundary_edges, r.n_boundary_loops, r.n_pieces) == (4, 1, 1)
    assert r.mean_edge_length == pytest.approx((4 + np.sqrt(2)) / 5)


def test_flat_grid() -> None:
    nx, ny, h = 7, 5, 2.5
    V, F = grid(nx, ny, h)
    r = check_mesh(V, F)
    assert r.problems == []
    assert r.n_boundary_edges == 2 * (nx - 1) + 2 * (ny - 1)
    assert r.n_boundary_loops == 1
    n_axis = nx * (ny - 1) + ny * (nx - 1)
    n_diag = (nx - 1) * (ny - 1)
    assert r.mean_edge_length == pytest.approx(h * (n_axis + np.sqrt(2) * n_diag) / (n_axis + n_diag))
    np.testing.assert_array_equal(r.bounding_box, [[0, 0, 0], [(nx - 1) * h, (ny - 1) * h, 0]])


def test_closed_cube_has_no_boundary() -> None:
    r = check_mesh(*cube())
    assert r.problems == []
    assert (r.n_boundary_edges, r.n_boundary_loops) == (0, 0)


def test_fan_of_three_faces_on_one_edge_is_non_manifold() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]])
    r = check_mesh(V, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))
    np.testing.assert_array_equal(r.non_manifold_edges, [[0, 1]])
    assert len(r.problems) == 1 and "1 edge shared by more than two faces" in r.problems[0]
    assert "vertices 0-1" in r.problems[0]
    assert r.n_boundary_edges == 6


def test_cube_with_a_duplicated_vertex() -> None:
    V, F = cube()
    V = np.concatenate([V, V[[0]]])  # vertex 8 is a copy of vertex 0 (a UV-seam split)
    F = F.copy()
    F[10] = [3, 8, 4]  # one face uses the copy
    r = check_mesh(V, F)
    np.testing.assert_array_equal(r.duplicate_vertices, [8])
    assert [g.tolist() for g in r.duplicate_groups] == [[0, 8]]
    assert r.duplicate_of[8] == 0 and r.duplicate_of[0] == 0
    assert r.n_boundary_edges > 0  # the split opens the surface
    assert any("1 vertex duplicates another" in p and "[0, 8]" in p for p in r.problems)
    assert r.duplicate_tolerance_mm == pytest.approx(1e-6 * r.mean_edge_length)
    # welding closes it again
    Vw, Fw, _ = weld_duplicate_vertices(V, F)
    welded = check_mesh(Vw, Fw)
    assert welded.problems == [] and welded.n_boundary_edges == 0


def test_two_separate_pieces() -> None:
    V1, F1 = grid(3, 3)
    V = np.concatenate([V1, V1 + [10, 0, 0]])
    F = np.concatenate([F1, F1 + 9])
    r = check_mesh(V, F)
    assert r.n_pieces == 2
    np.testing.assert_array_equal(r.piece_labels, [0] * 9 + [1] * 9)
    np.testing.assert_array_equal(r.piece_sizes, [9, 9])
    assert r.n_boundary_loops == 2
    assert r.problems == ["the mesh has 2 separate pieces (vertices: 9, 9)"]


def test_out_of_range_faces_are_reported_not_fatal() -> None:
    V, F = grid(3, 3)
    F = np.concatenate([F, [[0, 1, 99], [-1, 2, 3]]])
    r = check_mesh(V, F)
    np.testing.assert_array_equal(r.out_of_range_faces, [8, 9])
    assert r.n_faces == 10 and r.n_pieces == 1 and r.n_boundary_loops == 1
    assert r.problems == [
        "2 faces referring to vertices that do not exist (the mesh has 9; first: face 8)"
    ]


def test_degenerate_faces() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [1, 1e-9, 0], [1, 1e-6, 0]])
    F = np.array([
        [0, 1, 2],  # fine
        [0, 1, 1],  # repeated vertex
        [0, 1, 3],  # collinear: zero area
        [0, 3, 4],  # height 1e-9 over longest edge 2: 5e-10 <= 1e-8
        [0, 3, 5],  # height 1e-6 over 2: 5e-7 > 1e-8, kept
    ])
    r = check_mesh(V, F)
    np.testing.assert_array_equal(r.degenerate_faces, [1, 2, 3])
    for scale in (1e-3, 1e3):  # the criterion is relative: the same at any scale
        np.testing.assert_array_equal(check_mesh(V * scale, F).degenerate_faces, [1, 2, 3])
    # the criterion is 2 A / l_max^2 against libigl's double area
    dbl = igl.doublearea(V, F[[0, 2, 3, 4]])
    lmax = np.array([np.sqrt(2), 2, 2, 2])
    np.testing.assert_array_equal(dbl / lmax**2 <= 1e-8, [False, True, True, False])
    assert check_mesh(V, F, degenerate_tolerance=1e-6).degenerate_faces.tolist() == [1, 2, 3, 4]
    assert any(p.startswith("3 degenerate faces") for p in r.problems)


def test_nonfinite_and_unreferenced_vertices() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0], [5, 5, 5], [1, 1, 0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    r = check_mesh(V, F)
    np.testing.assert_array_equal(r.nonfinite_vertices, [3])
    np.testing.assert_array_equal(r.degenerate_faces, [1])  # touches the NaN vertex
    np.testing.assert_array_equal(r.unreferenced_vertices, [4, 5])
    np.testing.assert_array_equal(r.bounding_box, [[0, 0, 0], [5, 5, 5]])
    assert np.isfinite(r.mean_edge_length)
    assert "1 vertex with NaN or infinite coordinates (first: 3)" in r.problems
    assert "2 vertices used by no face (first: 4)" in r.problems


def test_no_faces() -> None:
    r = check_mesh(TRI_V, np.zeros((0, 3), dtype=np.int64))
    assert r.problems[0] == "the mesh has no faces"
    assert r.n_pieces == 0 and np.all(r.piece_labels == -1)
    assert r.summary()["mean_edge_length_mm"] is None


def test_summary_is_json_ready() -> None:
    V, F = cube()
    V = np.concatenate([V, V[[0]], [[np.inf, 0, 0]]])
    F = np.concatenate([F, [[0, 0, 1], [0, 1, 50]]])
    s = check_mesh(V, F).summary()
    text = json.dumps(s, allow_nan=False)
    back = json.loads(text)
    assert back["n_out_of_range_faces"] == 1 and back["n_degenerate_faces"] == 1
    assert back["n_duplicate_vertices"] == 1 and back["n_nonfinite_vertices"] == 1
    assert back["n_unreferenced_vertices"] == 2
    assert back["bounding_box_mm"] == [[0, 0, 0], [10, 10, 10]]
    assert len(back["problems"]) == 5


def _slow_edge_counts(F: np.ndarray) -> Counter:
    counts: Counter = Counter()
    for f in F.tolist():
        if len(set(f)) < 3:
            continue
        for i in range(3):
            a, b = f[i], f[(i + 1) % 3]
            counts[(min(a, b), max(a, b))] += 1
    return counts


def test_random_mesh_against_slow_references() -> None:
    rng = np.random.default_rng(12)
    n = 60
    V = rng.normal(size=(n, 3)) * 10
    V[50:54] = V[[3, 3, 7, 20]] + rng.normal(size=(4, 3)) * 1e-9
    V[54] = V[50] + 1e-9  # a copy of a copy
    F = rng.integers(0, 50, size=(150, 3))
    r = check_mesh(V, F)
    counts = _slow_edge_counts(F)
    nm = sorted(e for e, c in counts.items() if c > 2)
    np.testing.assert_array_equal(r.non_manifold_edges.reshape(-1, 2), np.array(nm).reshape(-1, 2))
    assert r.n_boundary_edges == sum(1 for c in counts.values() if c == 1)
    edges = np.array(sorted(counts))
    assert r.mean_edge_length == pytest.approx(np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1).mean())
    # duplicates by brute force: pairs closer than the tolerance, grouped transitively
    tol = 1e-6 * r.mean_edge_length
    D = np.linalg.norm(V[:, None] - V[None], axis=2) <= tol
    reach = D.copy()
    for _ in range(n):
        reach = (reach.astype(int) @ D.astype(int)) > 0
    expected = np.array([np.flatnonzero(reach[i]).min() for i in range(n)])
    np.testing.assert_array_equal(r.duplicate_of, expected)
    assert [g.tolist() for g in r.duplicate_groups] == [[3, 50, 51, 54], [7, 52], [20, 53]]
    # libigl agrees on edge-manifoldness
    assert igl.is_edge_manifold(F[np.array([len(set(f)) == 3 for f in F.tolist()])])[0] == (len(nm) == 0)


def test_input_errors() -> None:
    with pytest.raises(InputError, match="V"):
        check_mesh(np.zeros((3, 2)), np.array([[0, 1, 2]]))
    with pytest.raises(MeshError, match="F"):
        check_mesh(TRI_V, np.array([[0, 1]]))
    with pytest.raises(MeshError, match="integers"):
        check_mesh(TRI_V, np.array([[0, 1, 2.5]]))
    with pytest.raises(InputError, match="duplicate_tolerance"):
        check_mesh(TRI_V, np.array([[0, 1, 2]]), duplicate_tolerance=-1)
