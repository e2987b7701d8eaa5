import numpy as np

from facecap.synth.ict_sample import load_ict_sample
from facecap.synth.marker_layout import boundary_vertices, choose_marker_vertices


def test_layout_is_distinct_off_the_boundary_and_reproducible():
    s = load_ict_sample()
    V, F = s.mesh.vertices, s.mesh.faces
    mv = choose_marker_vertices(V, F, s.expression_deltas, 90, seed=0)
    assert mv.size == 90 and np.unique(mv).size == 90
    assert not boundary_vertices(F, len(V))[mv].any()
    np.testing.assert_array_equal(mv, choose_marker_vertices(V, F, s.expression_deltas, 90, seed=0))


def test_markers_are_denser_where_the_face_moves():
    s = load_ict_sample()
    V, F = s.mesh.vertices, s.mesh.faces
    motion = np.linalg.norm(s.expression_deltas, axis=2).max(axis=0)
    mv = choose_marker_vertices(V, F, s.expression_deltas, 90, seed=1)
    mobile = motion > np.median(motion)
    assert mobile[mv].mean() > mobile.mean()


def test_boundary_of_a_single_triangle_and_a_closed_tetrahedron():
    assert boundary_vertices(np.array([[0, 1, 2]]), 3).all()
    tet = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]])
    assert not boundary_vertices(tet, 4).any()
