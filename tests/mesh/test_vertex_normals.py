"""Tests for facecap.mesh.vertex_normals against libigl's normals."""

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.mesh.vertex_normals import face_normals, vertex_normals
from facecap.io.ict_sample import load_ict_sample


@pytest.fixture(scope="module")
def face():
    sample = load_ict_sample()
    V, F = sample.mesh.vertices, sample.mesh.faces
    rng = np.random.default_rng(0)
    # three frames: the face, an expression, and the expression bent by a smooth field
    frames = np.stack([V, V + 3.0 * sample.expression_deltas[5], V + np.sin(V / 20.0) * 2.0])
    return frames, F, rng.choice(len(V), 50, replace=False)


def test_vertex_normals_match_libigl_area_weighted_normals(face):
    frames, F, some = face
    stacked = vertex_normals(frames, F, some)
    for k, V in enumerate(frames):
        used = np.unique(F)  # libigl gives vertices without triangles a zero normal, ours NaN
        ref = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
        np.testing.assert_allclose(vertex_normals(V, F)[used], ref[used], atol=1e-9)
        np.testing.assert_allclose(stacked[k], ref[some], atol=1e-9)
        np.testing.assert_allclose(vertex_normals(V, F, some), ref[some], atol=1e-9)


def test_face_normals_are_libigl_unit_normals_times_twice_the_area(face):
    frames, F, _ = face
    N = face_normals(frames, F)
    assert N.shape == (3, len(F), 3)
    for k, V in enumerate(frames):
        unit = igl.per_face_normals(V, F, np.zeros(3))
        np.testing.assert_allclose(N[k], unit * igl.doublearea(V, F)[:, None], atol=1e-9)


def test_a_vertex_with_only_degenerate_triangles_has_no_normal():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [5, 5, 5]])
    F = np.array([[0, 1, 2], [0, 1, 3]])
    N = vertex_normals(V, F)
    np.testing.assert_allclose(N[[0, 1, 3]], [[0, 0, 1]] * 3)
    assert np.isnan(N[2]).all() and np.isnan(N[4]).all()  # collinear only; no triangle at all


def test_bad_indices_are_refused():
    V = np.zeros((3, 3))
    with pytest.raises(InputError, match="vertices"):
        vertex_normals(V, np.array([[0, 1, 2]]), np.array([3]))
    with pytest.raises(InputError):
        vertex_normals(V, np.array([[0, 1, 5]]))
