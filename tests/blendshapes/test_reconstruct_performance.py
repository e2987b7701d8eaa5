import numpy as np
from scipy.spatial.transform import Rotation

from facecap.blendshapes.reconstruct_performance import blend_rig, blend_weights
from facecap.io.ict_sample import load_ict_sample


def test_weights_of_known_combinations():
    s = load_ict_sample()
    rng = np.random.default_rng(1)
    K, T = 6, 40
    bases = np.stack([s.mesh.vertices + s.expression_deltas[k] for k in (26, 45, 46, 10, 2, 39)])
    true_w = rng.uniform(0, 1, size=(T, K))
    true_w /= true_w.sum(axis=1, keepdims=True)
    frames = np.einsum("tk,knc->tnc", true_w, bases)
    mv = rng.choice(9409, 80, replace=False)
    w, residual = blend_weights(bases[:, mv], frames[:, mv])
    np.testing.assert_allclose(w, true_w, atol=1e-6)
    assert residual.max() < 1e-6


def test_blend_does_not_depend_on_where_either_frame_puts_its_origin():
    # NNLS weights need not sum to one. Blended about a coordinate origin 1.5 m away (a mocap
    # frame), a sum of 1 + e would move the face by e * 1.5 m; the result must instead depend only
    # on the bases and weights: moving the bases' frame, or the output frame, moves nothing but
    # the output by exactly that motion.
    s = load_ict_sample()
    rng = np.random.default_rng(2)
    bases = np.stack([s.mesh.vertices + s.expression_deltas[k] for k in (3, 17, 30)])
    w = rng.uniform(0.2, 0.6, size=(12, 3))  # sums between 0.6 and 1.8
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix()
    pose[:3, 3] = [800.0, -1200.0, 1500.0]

    def blend(B, P, weights=w):  # the rig evaluated: r + sum_k c_tk s_k
        rig = blend_rig(s.mesh.vertices, B, weights, output_from_bases=P)
        assert rig.shapes.shape == (4, *s.mesh.vertices.shape) and rig.coefficients.shape == (12, 4)
        return s.mesh.vertices + np.einsum("tk,knc->tnc", rig.coefficients.astype(np.float64), rig.shapes)

    reference = blend(bases, pose)
    # the bases 1.5 m away in their own frame, the pose undoing it: the same output
    away = np.array([1200.0, 300.0, -1500.0])
    shifted_pose = pose.copy()
    shifted_pose[:3, 3] -= pose[:3, :3] @ away
    np.testing.assert_allclose(blend(bases + away, shifted_pose), reference, atol=2e-3)
    # the output frame moved: the output moves by exactly that, whatever sum(w) is
    moved_pose = pose.copy()
    moved_pose[:3, 3] += [0.0, 0.0, 1000.0]
    np.testing.assert_allclose(blend(bases, moved_pose), reference + [0.0, 0.0, 1000.0], atol=2e-3)
    # and with weights summing to one it is eq. 12 moved rigidly
    unit = w / w.sum(axis=1, keepdims=True)
    expected = np.einsum("tk,knc->tnc", unit, bases) @ pose[:3, :3].T + pose[:3, 3]
    np.testing.assert_allclose(blend(bases, pose, unit), expected, atol=2e-3)


def test_weights_and_head_pose_of_known_blends_seen_turned():
    # Frames that are known blends, each seen turned by up to 2 degrees and shifted by up to 2 mm
    # (a stabilisation from skin markers that moved): the joint solve recovers the weights and
    # undoes each frame's pose; the weights alone cannot.
    from facecap.blendshapes.reconstruct_performance import blend_weights_with_head_pose

    s = load_ict_sample()
    rng = np.random.default_rng(5)
    K, T = 8, 30
    bases = np.stack([s.mesh.vertices] + [s.mesh.vertices + s.expression_deltas[k] for k in (26, 45, 10, 2, 39, 17, 30)])
    true_w = rng.dirichlet(np.ones(K) * 0.5, size=T)
    frames = np.einsum("tk,knc->tnc", true_w, bases)
    mv = rng.choice(6706, 90, replace=False)  # markers on the face
    turn = Rotation.from_rotvec(rng.normal(size=(T, 3)) * np.deg2rad(1.2)).as_matrix()
    shift = rng.uniform(-2, 2, size=(T, 3))
    centre = s.mesh.vertices[mv].mean(axis=0)
    seen = np.einsum("tij,tmj->tmi", turn, frames[:, mv] - centre) + centre + shift[:, None]
    result = blend_weights_with_head_pose(bases[:, mv], seen)
    np.testing.assert_allclose(result.weights, true_w, atol=0.02)
    undone = seen @ np.swapaxes(result.rotations, 1, 2) + result.translations[:, None]
    assert np.abs(undone - frames[:, mv]).max() < 0.05
    assert result.residual_mm.max() < 0.02
    w_only, residual_only = blend_weights(bases[:, mv], seen)
    assert residual_only.mean() > 10 * result.residual_mm.mean()
