"""Tests for facecap.synth.marker_layout: realistic marker placement on the face."""

import igl
import numpy as np
import pytest
from scipy.spatial.distance import pdist

from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.marker_layout import (
    animface_marker_map,
    boundary_vertices,
    choose_marker_vertices,
)


def _grid(n: int = 21, size: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n))
    V = np.stack([u.ravel(), v.ravel(), np.zeros(n * n)], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def _one_ring(F: np.ndarray, mask: np.ndarray) -> np.ndarray:
    A = igl.adjacency_matrix(F)
    return mask | (A @ mask.astype(float) > 0)


@pytest.fixture(scope="module")
def face():
    s = load_ict_sample()
    return s, s.mesh.vertices, s.mesh.faces


def test_layout_is_distinct_off_the_boundary_ring_and_reproducible(face):
    s, V, F = face
    mv = choose_marker_vertices(V, F, s.expression_deltas, 90, seed=0)
    assert mv.shape == (90,) and mv.dtype == np.int64 and np.unique(mv).size == 90
    # the face region has four boundary loops: the rim, two eye openings and the lip seam
    assert len(igl.boundary_loop_all(F)) == 4
    near = _one_ring(F, boundary_vertices(F, len(V)))
    assert not near[mv].any()
    np.testing.assert_array_equal(mv, choose_marker_vertices(V, F, s.expression_deltas, 90, seed=0))
    assert not np.array_equal(mv, choose_marker_vertices(V, F, s.expression_deltas, 90, seed=1))


def test_markers_are_denser_where_the_face_moves_and_reach_lips_and_eyelids(face):
    s, V, F = face
    other = s.region_labels == s.region_names.index("other")
    mv = choose_marker_vertices(V, F, s.expression_deltas, 90, seed=1, exclude=other)
    assert not other[mv].any()
    area = np.bincount(F.ravel(), weights=np.repeat(igl.doublearea(V, F) / 6, 3), minlength=len(V))
    density = {}
    for region in ("mouth", "eyes", "forehead", "nose"):
        inside = s.region_labels == s.region_names.index(region)
        density[region] = np.isin(mv, np.flatnonzero(inside)).sum() / area[inside].sum()
    # markers per mm^2: the moving mouth and eyes get more than the static forehead and nose
    assert min(density["mouth"], density["eyes"]) > 1.5 * max(density["forehead"], density["nose"])
    # both lips carry markers (the lip seam is at the height of landmarks 62/66)
    seam_y = V[s.landmarks[[62, 66]], 1].mean()
    mouth = mv[s.region_labels[mv] == s.region_names.index("mouth")]
    assert (V[mouth, 1] > seam_y).sum() >= 2 and (V[mouth, 1] < seam_y).sum() >= 2


def test_uniform_farthest_points_cover_the_grid_no_closer_than_they_are_spaced():
    # farthest-point sampling: every vertex lies within the final pick's distance, and the picks
    # are pairwise at least that far apart (the 2-approximation of k-centre)
    V, F = _grid()
    near = _one_ring(F, boundary_vertices(F, len(V)))
    allowed = np.flatnonzero(~near)
    for metric in ("euclidean", "geodesic"):
        mv = choose_marker_vertices(V, F, np.zeros((0, len(V), 3)), 10, motion_weight=0.0, metric=metric)
        assert not near[mv].any()
        if metric == "euclidean":
            cover = np.linalg.norm(V[allowed][:, None] - V[mv][None], axis=2).min(axis=1).max()
            assert pdist(V[mv]).min() >= cover - 1e-9


def test_exclude_takes_a_mask_or_indices_and_too_many_markers_is_an_error():
    V, F = _grid(11)
    D = np.zeros((1, len(V), 3))
    left = np.flatnonzero(V[:, 0] < 50)
    a = choose_marker_vertices(V, F, D, 5, exclude=left)
    b = choose_marker_vertices(V, F, D, 5, exclude=V[:, 0] < 50)
    np.testing.assert_array_equal(a, b)
    assert np.all(V[a, 0] >= 50)
    with pytest.raises(InputError, match="n_markers"):
        choose_marker_vertices(V, F, D, 200)
    with pytest.raises(InputError, match="n_markers"):
        choose_marker_vertices(V, F, D, 0)
    with pytest.raises(InputError, match="expression_deltas"):
        choose_marker_vertices(V, F, np.zeros((2, 5, 3)), 3)
    with pytest.raises(InputError, match="exclude"):
        choose_marker_vertices(V, F, D, 3, exclude=np.array([10_000]))
    with pytest.raises(InputError, match="metric"):
        choose_marker_vertices(V, F, D, 3, metric="manhattan")


def test_boundary_of_a_single_triangle_and_a_closed_tetrahedron():
    assert boundary_vertices(np.array([[0, 1, 2]]), 3).all()
    tet = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]])
    assert not boundary_vertices(tet, 4).any()


def test_animface_map_is_the_real_41_marker_layout(face):
    V = face[1]
    m = animface_marker_map()
    assert len(m) == 41 and len(set(m.values())) == 41
    v = np.array(list(m.values()))
    assert v.min() >= 0 and v.max() < len(V)
    # left markers on the subject's left (+x), right ones on the right
    assert all(V[m[k], 0] > 0 for k in m if k.startswith("L") or k.endswith(("_L", "_L1")))
    assert all(V[m[k], 0] < 0 for k in m if k.startswith("R") or k.endswith(("_R", "_R1")))
    # the chin marker is below the mouth, the forehead markers above the brows
    assert V[m["Chin"], 1] < V[m["Mouth_Down"], 1] < V[m["Mouth_Up"], 1] < V[m["ForeHead_M"], 1]
