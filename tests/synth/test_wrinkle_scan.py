"""subdivide_scan: the original vertices first and unchanged, igl.upsample's surface, a scan fine enough for wrinkles.

refine_near: the same surface, refined only around chosen vertices, with no crack (red-green closure)."""

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.structures import Mesh
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkle_scan import refine_near, subdivide_scan


def _sorted_rows(A):
    return A[np.lexsort(A.T[::-1])]


def test_same_surface_as_igl_upsample_with_the_original_vertices_first():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=1)
    V_igl, F_igl = igl.upsample(sample.mesh.vertices, sample.mesh.faces, 1)
    n = sample.mesh.n_vertices
    assert fine.n_original == n
    np.testing.assert_array_equal(fine.mesh.vertices[:n], sample.mesh.vertices)  # markers stay on their vertices
    assert fine.mesh.vertices.shape == V_igl.shape and fine.mesh.faces.shape == F_igl.shape
    np.testing.assert_allclose(_sorted_rows(fine.mesh.vertices), _sorted_rows(V_igl), atol=1e-12)
    # the same triangles, as sets of corner positions
    corners = lambda V, F: _sorted_rows(np.sort(V[F].reshape(len(F), -1).round(9), axis=1))  # noqa: E731
    np.testing.assert_allclose(corners(fine.mesh.vertices, fine.mesh.faces), corners(V_igl, F_igl), atol=1e-8)


def test_upsample_carries_any_frame_and_keeps_area_and_orientation():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=2)
    frame = sample.mesh.vertices + sample.expression_deltas[sample.expression_names.index("jawOpen")]
    moved = fine.upsample @ frame
    np.testing.assert_array_equal(moved[: fine.n_original], frame)
    area = lambda V, F: 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()  # noqa: E731
    np.testing.assert_allclose(area(moved, fine.mesh.faces), area(frame, sample.mesh.faces), rtol=1e-10)
    # orientation: the summed area vector is unchanged (no flipped triangles)
    vec = lambda V, F: np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0)  # noqa: E731
    np.testing.assert_allclose(vec(moved, fine.mesh.faces), vec(frame, sample.mesh.faces), rtol=1e-9, atol=1e-6)


def test_two_levels_give_over_100k_vertices_spaced_well_below_a_wrinkle_width():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=2)
    assert fine.mesh.n_vertices >= 100_000
    E = igl.edges(fine.mesh.faces)
    length = np.linalg.norm(fine.mesh.vertices[E[:, 0]] - fine.mesh.vertices[E[:, 1]], axis=1)
    region = sample.region_names
    parent = np.minimum(E[:, 0], E[:, 1])  # every fine edge has an original-vertex or midpoint end; use original ones
    on_forehead = (parent < fine.n_original) & (sample.region_labels[np.minimum(parent, fine.n_original - 1)]
                                                == region.index("forehead"))
    assert np.median(length[on_forehead]) < 1.0  # mm: a forehead valley is at least 2 x 0.67 mm wide (w_min, tapered)


def test_bad_levels():
    tri = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    with pytest.raises(InputError, match="levels"):
        subdivide_scan(tri, levels=-1)
    assert subdivide_scan(tri, levels=0).mesh.n_vertices == 3


def _area_vector_and_area(V, F):
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return cross.sum(axis=0), 0.5 * np.linalg.norm(cross, axis=1).sum()


def _boundary_length(V, F):
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, count = np.unique(E, axis=0, return_counts=True)
    once = edges[count == 1]
    return np.linalg.norm(V[once[:, 0]] - V[once[:, 1]], axis=1).sum()


def test_refine_near_the_forehead_keeps_the_surface_and_leaves_no_crack():
    sample = load_ict_sample()
    mesh = sample.mesh
    near = sample.region_labels == sample.region_names.index("forehead")
    fine = refine_near(mesh, near, max_edge_mm=1.0)
    V, F, n = fine.mesh.vertices, fine.mesh.faces, fine.n_original
    assert n == mesh.n_vertices and fine.mesh.n_vertices > 2 * n
    np.testing.assert_array_equal(V[:n], mesh.vertices)
    np.testing.assert_allclose(fine.upsample @ mesh.vertices, V, atol=1e-12)
    # the same surface: area, orientation; no crack: a vertex hanging on another triangle's edge would
    # open the edge into two boundary edges, so the boundary would grow
    (vec, area), (vec0, area0) = _area_vector_and_area(V, F), _area_vector_and_area(mesh.vertices, mesh.faces)
    np.testing.assert_allclose(area, area0, rtol=1e-10)
    np.testing.assert_allclose(vec, vec0, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(_boundary_length(V, F), _boundary_length(mesh.vertices, mesh.faces), rtol=1e-12)
    assert igl.is_edge_manifold(F)[0] if isinstance(igl.is_edge_manifold(F), tuple) else igl.is_edge_manifold(F)
    # fine where asked: every triangle inside the original triangles touching the forehead
    touching = near[mesh.faces].any(axis=1)
    centroid = V[F].mean(axis=1)
    _, owner, _ = igl.point_mesh_squared_distance(centroid, mesh.vertices, mesh.faces)
    inside = touching[owner]
    longest = np.max([np.linalg.norm(V[F[:, i]] - V[F[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=0)
    assert inside.sum() > 4 * touching.sum()
    assert longest[inside].max() <= 1.0
    # and untouched away from it: an original triangle sharing no vertex with the refined ones is still there
    ring = np.zeros(n, dtype=bool)
    ring[mesh.faces[touching].ravel()] = True
    far = mesh.faces[~ring[mesh.faces].any(axis=1)]
    kept = {tuple(sorted(f)) for f in F.tolist()}
    assert far.shape[0] > 1000 and all(tuple(sorted(f)) in kept for f in far.tolist())


def test_refine_near_one_triangle_by_hand_and_bad_input():
    # a square of two triangles; refining around vertex 1 splits its triangle in four and halves the other
    quad = Mesh(np.array([[0.0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    fine = refine_near(quad, np.array([False, True, False, False]), max_edge_mm=2.0)
    assert fine.mesh.n_faces == 6 and fine.mesh.n_vertices == 7
    np.testing.assert_allclose(_boundary_length(fine.mesh.vertices, fine.mesh.faces), 8.0)
    assert refine_near(quad, np.zeros(4, dtype=bool), max_edge_mm=0.1).mesh.n_faces == 2
    with pytest.raises(InputError, match="near"):
        refine_near(quad, np.zeros(3, dtype=bool), max_edge_mm=1.0)
    with pytest.raises(InputError, match="max_edge_mm"):
        refine_near(quad, np.ones(4, dtype=bool), max_edge_mm=0.0)


def _planar_charts(seed):
    """A flat 4x4 grid (z = 0) whose every triangle has a UV chart of its own (an affine map, random per
    triangle), so every edge is a seam; the UVs of one corner are shared by the triangles of a 2x2 block only."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(5.0), np.arange(5.0))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(25)])
    q = (np.arange(4)[:, None] * 5 + np.arange(4)[None]).ravel()
    F = np.concatenate([np.stack([q, q + 1, q + 6], 1), np.stack([q, q + 6, q + 5], 1)])
    maps = rng.normal(size=(len(F), 2, 3))  # uv = A [x, y, 1] per triangle
    uvs = np.einsum("fij,fkj->fki", maps, np.concatenate([V[F][..., :2], np.ones((len(F), 3, 1))], axis=2))
    mesh = Mesh(V, F, uvs=uvs.reshape(-1, 2), uv_indices=np.arange(3 * len(F)))
    return mesh, maps


def _check_uvs_are_the_parents_affine_maps(coarse, maps, fine):
    """Every fine corner's UV is its original triangle's map at the corner: exact interpolation, seams kept."""
    V, F = fine.vertices, fine.faces
    corner_uv = fine.uvs[fine.uv_indices.reshape(-1, 3)]
    centroid = V[F].mean(axis=1)[:, :2]
    A = coarse.vertices[coarse.faces][..., :2]  # (m, 3, 2)
    # the original triangle holding each fine triangle's centroid (barycentric coordinates all positive)
    T = np.stack([A[:, 1] - A[:, 0], A[:, 2] - A[:, 0]], axis=2)
    lam = np.linalg.solve(T[None], (centroid[:, None] - A[None, :, 0])[..., None])[..., 0]
    inside = (lam > 1e-9).all(axis=2) & (lam.sum(axis=2) < 1 - 1e-9)
    assert (inside.sum(axis=1) == 1).all()
    parent = inside.argmax(axis=1)
    expected = np.einsum("fij,fkj->fki", maps[parent], np.concatenate([V[F][..., :2], np.ones((len(F), 3, 1))], 2))
    np.testing.assert_allclose(corner_uv, expected, atol=1e-12)


def test_uvs_interpolate_exactly_at_midpoints_and_seams_stay_seams():
    coarse, maps = _planar_charts(0)
    fine = subdivide_scan(coarse, levels=2).mesh
    _check_uvs_are_the_parents_affine_maps(coarse, maps, fine)
    assert fine.uvs.shape[0] > fine.n_vertices  # the midpoint of a seam edge has a UV on each side
    np.testing.assert_array_equal(fine.uvs[: coarse.uvs.shape[0]], coarse.uvs)
    near = np.zeros(coarse.n_vertices, dtype=bool)
    near[12] = True
    refined = refine_near(coarse, near, max_edge_mm=0.3)
    _check_uvs_are_the_parents_affine_maps(coarse, maps, refined.mesh)
    # the green (halved) triangles around the region split their UV triangles the same way
    assert refined.mesh.uv_indices.shape == (3 * refined.mesh.n_faces,)


def test_uvs_shared_across_an_edge_stay_shared_and_survive_the_obj_file(tmp_path):
    from facecap.io import read_mesh, write_mesh

    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=1)
    mesh = fine.mesh
    # the ICT face's UV seams are few: a fine vertex has as many UVs as its original (or edge) had
    n_uv = lambda m: np.unique(np.column_stack([m.faces.ravel(), m.uv_indices]), axis=0).shape[0]  # noqa: E731
    extra = n_uv(mesh) - mesh.n_vertices
    assert 0 < extra < 0.02 * mesh.n_vertices
    near = np.zeros(mesh.n_vertices, dtype=bool)
    near[sample.landmarks[36:48]] = True  # around the eyes
    refined = refine_near(mesh, near, max_edge_mm=0.4).mesh
    write_mesh(refined, tmp_path / "scan.obj")
    back = read_mesh(tmp_path / "scan.obj")
    assert back.n_vertices == refined.n_vertices and back.uvs is not None
    np.testing.assert_allclose(back.uvs[back.uv_indices.reshape(-1, 3)], refined.uvs[refined.uv_indices.reshape(-1, 3)],
                               atol=1e-8)
    np.testing.assert_array_equal(back.faces, refined.faces)
