"""LocalFrameDetails: an exact round trip, details that turn with a rigid motion, orthonormal right-handed frames."""

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.mesh import LocalFrameDetails, local_frames
from facecap.io.ict_sample import load_ict_sample


def _face_and_detail(seed: int = 0):
    sample = load_ict_sample()
    V, F = sample.mesh.vertices, sample.mesh.faces
    rng = np.random.default_rng(seed)
    return V, F, V + rng.normal(0.0, 0.05, V.shape)  # displacements in every direction, not only normal


def _rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def test_encoding_on_a_base_and_adding_back_on_it_gives_the_detailed_surface():
    base, F, detailed = _face_and_detail()
    details = LocalFrameDetails.encode(detailed, base, F)
    np.testing.assert_allclose(details.add_to(base), detailed, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(details.coefficients, axis=1),
                               np.linalg.norm(detailed - base, axis=1), rtol=1e-12)


def test_details_follow_a_rigid_motion_of_the_base():
    base, F, detailed = _face_and_detail(1)
    rng = np.random.default_rng(2)
    R, t = _rotation(rng), np.array([10.0, -4.0, 30.0])
    details = LocalFrameDetails.encode(detailed, base, F)
    np.testing.assert_allclose(details.add_to(base @ R.T + t), detailed @ R.T + t, atol=1e-10)


def test_frames_are_orthonormal_right_handed_with_libigl_normals_and_t1_along_the_reference_edge():
    base, F, _ = _face_and_detail()
    details = LocalFrameDetails.encode(base, base, F)
    ref = details.reference_neighbour
    frames = local_frames(base, F, ref)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", frames, frames), np.broadcast_to(np.eye(3), frames.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(frames), 1.0, atol=1e-12)
    normals = igl.per_vertex_normals(base, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    np.testing.assert_allclose(frames[:, 2], normals, atol=1e-12)
    edge = base[ref] - base
    assert np.all(np.einsum("nd,nd->n", frames[:, 0], edge) > 0)  # t1 points at the reference neighbour
    np.testing.assert_allclose(np.einsum("nd,nd->n", frames[:, 1], edge), 0.0, atol=1e-12)
    # the reference is a neighbour: it shares an edge
    E = {tuple(sorted(e)) for e in igl.edges(F).tolist()}
    assert all((min(i, j), max(i, j)) in E for i, j in enumerate(ref.tolist()))


def test_mismatched_arrays_raise_input_errors():
    base, F, detailed = _face_and_detail()
    with pytest.raises(InputError, match="detailed: expected shape"):
        LocalFrameDetails.encode(detailed[:-1], base, F)
    details = LocalFrameDetails.encode(detailed, base, F)
    with pytest.raises(InputError, match="base: expected shape"):
        details.add_to(base[:-1])
    with pytest.raises(InputError, match="reference_neighbour"):
        local_frames(base, F, np.zeros(3, dtype=np.int64))
