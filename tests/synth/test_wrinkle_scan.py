"""subdivide_scan: the original vertices first and unchanged, igl.upsample's surface, a scan fine enough for wrinkles."""

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.structures import Mesh
from facecap.synth import load_ict_sample
from facecap.synth.wrinkle_scan import subdivide_scan


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
