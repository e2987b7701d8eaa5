"""Editing in muscle space (sec. 9): interpolation, exaggeration by the force-length curve, a kinematic sphere."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.fem import SphereContact
from facecap.muscles import (JawConstraints, MuscleControls, MuscleEditor, MuscleModel, interpolate_controls,
                             interpolate_rigid_motions)
from facecap.muscles.muscle_model import apply_affine


def _controls(model: MuscleModel, seed: int, opening_deg: float, turn_deg: float) -> MuscleControls:
    rng = np.random.default_rng(seed)
    k = model.n_muscles
    a = rng.uniform(0.1, 0.5, k) * (rng.uniform(size=k) < 0.5)
    R = Rotation.from_rotvec(np.radians(turn_deg) * np.array([0.2, 1.0, 0.1]) / np.linalg.norm([0.2, 1.0, 0.1]))
    cranium = np.hstack([R.as_matrix(), rng.normal(0, 2.0, (3, 1))])
    return MuscleControls(a, cranium, model.jaw.transform(np.radians(opening_deg), rng.uniform(0, 1), rng.uniform(0, 1)))


@pytest.fixture(scope="module")
def editor(anatomy) -> MuscleEditor:
    return MuscleEditor(anatomy)


def _forward_skin(model: MuscleModel, c: MuscleControls) -> np.ndarray:
    x = model.equilibrium(c.activations, c.mandible).positions
    return apply_affine(c.cranium, model.skin(x))


def test_interpolated_controls_are_linear_in_activations_and_rigid_on_the_joint(model) -> None:
    a, b = _controls(model, 1, 2.0, 0.0), _controls(model, 2, 12.0, 4.0)
    # ends as a solve leaves them: an activation a hair above 1, a jaw a hair off its track
    a = MuscleControls(np.r_[1 + 1e-5, a.activations[1:]], a.cranium, a.mandible + 1e-6)
    path = interpolate_controls(a, b, model.jaw, 5)
    assert len(path) == 5
    A = np.stack([c.activations for c in path])
    assert A.min() >= 0 and A.max() <= 1
    np.testing.assert_allclose(A[2], np.clip(0.5 * (a.activations + b.activations), 0, 1), atol=1e-12)
    np.testing.assert_allclose(A[4], b.activations, atol=1e-12)
    for c in path:  # every frame rigid and on the joint: psi1-psi6 met
        assert model.jaw.violations(c.mandible).max() < 1e-12
        assert np.abs(c.cranium[:, :3].T @ c.cranium[:, :3] - np.eye(3)).max() < 1e-12
    # the jaw's opening and slides linearly; the head's turn by slerp (a quarter of the way: a quarter of the angle,
    # about the same axis), its translation linearly
    poses = np.stack([model.jaw.pose(c.mandible) for c in path])
    np.testing.assert_allclose(np.diff(poses, axis=0), np.diff(poses, axis=0)[:1].repeat(4, axis=0), atol=1e-9)
    np.testing.assert_allclose(poses[-1], model.jaw.pose(b.mandible), atol=1e-9)
    whole = Rotation.from_matrix(b.cranium[:, :3] @ a.cranium[:, :3].T).as_rotvec()
    quarter = Rotation.from_matrix(path[1].cranium[:, :3] @ a.cranium[:, :3].T).as_rotvec()
    np.testing.assert_allclose(quarter, 0.25 * whole, atol=1e-9)
    np.testing.assert_allclose(path[1].cranium[:, 3], 0.75 * a.cranium[:, 3] + 0.25 * b.cranium[:, 3], atol=1e-12)
    with pytest.raises(InputError, match="n_frames"):
        interpolate_controls(a, b, model.jaw, 1)
    with pytest.raises(InputError, match="activations"):
        interpolate_controls(a, MuscleControls.rest(3), model.jaw, 3)


def test_rigid_motions_are_interpolated_as_the_cranium_is() -> None:
    turn = Rotation.from_rotvec(np.radians(20.0) * np.array([0.0, 0.6, 0.8]))
    start, end = np.eye(4, dtype=np.float32), np.eye(4, dtype=np.float32)
    start[:3, 3] = [1.0, 2.0, 3.0]
    end[:3, :3], end[:3, 3] = turn.as_matrix(), [5.0, 2.0, -1.0]
    path = interpolate_rigid_motions(start, end, 5)
    assert path.shape == (5, 4, 4) and path.dtype == np.float32
    np.testing.assert_allclose(path[0], start, atol=1e-6)
    np.testing.assert_allclose(path[-1], end, atol=1e-6)
    np.testing.assert_array_equal(path[:, 3], np.tile([0.0, 0.0, 0.0, 1.0], (5, 1)))
    # a quarter of the way: a quarter of the turn about the same axis, a quarter of the translation
    quarter = Rotation.from_matrix(path[1, :3, :3].astype(np.float64)).as_rotvec()
    np.testing.assert_allclose(quarter, 0.25 * turn.as_rotvec(), atol=1e-6)
    np.testing.assert_allclose(path[1, :3, 3], 0.75 * start[:3, 3] + 0.25 * end[:3, 3], atol=1e-6)
    # the same path interpolate_controls gives the cranium
    jaw = JawConstraints(np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.array([0.0, 40, -60]), 100.0)
    controls = interpolate_controls(MuscleControls(np.zeros(1), start[:3].astype(np.float64), jaw.transform(0.0)),
                                    MuscleControls(np.zeros(1), end[:3].astype(np.float64), jaw.transform(0.0)), jaw, 5)
    np.testing.assert_allclose(path[:, :3], np.stack([c.cranium for c in controls]), atol=1e-6)

def test_interpolation_ends_are_the_solved_faces_and_every_frame_solves(editor, model) -> None:
    a, b = _controls(model, 3, 3.0, 1.0), _controls(model, 4, 10.0, -2.0)
    path = interpolate_controls(a, b, model.jaw, 6)
    x = None
    frames = []
    for c in path:
        frame = editor.solve(c, x)
        assert frame.converged and frame.inverted_tets == 0
        x = frame.nodes
        frames.append(frame)
    # the ends: the forward model's faces of the two controls (warm-started from the other end or not)
    for frame, c in ((frames[0], a), (frames[-1], b)):
        error = np.linalg.norm(frame.skin - _forward_skin(model, c), axis=1)
        assert error.max() < 1e-3, error.max()
    # the path moves the face steadily: no frame jumps more than twice the mean step
    steps = [np.linalg.norm(q.skin - p.skin, axis=1).mean() for p, q in zip(frames, frames[1:])]
    assert max(steps) < 2 * np.mean(steps) and min(steps) > 0


def test_exaggeration_grows_the_muscles_displacement_monotonically(anatomy, model) -> None:
    c = _controls(model, 5, 5.0, 2.0)
    # the muscles' part of the face: the displacement from the face with no muscle force at all
    still = MuscleModel(anatomy, force_length_scale=0.0)
    base = _forward_skin(still, c)
    sizes = []
    x = None
    for scale in (1.0, 1.5, 2.0, 3.0):
        frame = MuscleEditor(anatomy, force_length_scale=scale).solve(c, x)
        assert frame.converged and frame.inverted_tets == 0
        x = frame.nodes
        if scale == 1.0:  # unscaled: the forward model's face
            assert np.linalg.norm(frame.skin - _forward_skin(model, c), axis=1).max() < 1e-3
        sizes.append(np.linalg.norm(frame.skin - base, axis=1).mean())
    assert np.all(np.diff(sizes) > 0.05 * sizes[0]), sizes
    assert sizes[-1] > 1.5 * sizes[0], sizes
    with pytest.raises(InputError, match="force_length_scale"):
        MuscleEditor(anatomy, force_length_scale=0.0)


def test_a_sphere_stays_out_of_the_skin_and_the_bones_hold_its_push(editor, model) -> None:
    c = _controls(model, 6, 6.0, 2.0)
    free = editor.solve(c)
    V = free.skin
    # a 15 mm sphere pressed 4 mm into the left cheek along the skin's normal there
    F = editor.anatomy.scan_faces
    normals = np.zeros_like(V)
    face_normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for corner in range(3):
        np.add.at(normals, F[:, corner], face_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    rest = editor.anatomy.scan_vertices
    candidates = np.flatnonzero(editor.model.skin_follows & editor.anatomy.skin_meshed & (rest[:, 0] > 40)
                                & (rest[:, 2] > 80))
    i = candidates[np.argmax(normals[candidates] @ c.cranium[:, :3] @ [0.5, 0.0, 0.85])]
    radius = 15.0
    centre = V[i] + (radius - 4.0) * normals[i]
    frame = editor.solve(c, free.nodes, sphere=(centre, radius))
    assert frame.converged and frame.inverted_tets == 0
    report = frame.sphere
    # nothing inside: every scan vertex (the output skin) and every skin node, world coordinates
    nodes = apply_affine(c.cranium, frame.nodes)
    depth_scan = radius - np.linalg.norm(frame.skin - centre, axis=1)
    depth_nodes = radius - np.linalg.norm(nodes[editor.skin_nodes] - centre, axis=1)
    assert depth_scan.max() <= 0.05 and depth_nodes.max() <= 0.05
    assert (radius - np.linalg.norm(V - centre, axis=1)).max() > 3.5  # without contact it was 4 mm in
    assert report.scan_penetration_mm == pytest.approx(max(depth_scan.max(), 0.0), abs=1e-9)
    assert report.skin_node_penetration_mm == pytest.approx(max(depth_nodes.max(), 0.0), abs=1e-9)
    # the face is pushed in where the sphere is, and is the same far from it
    moved = np.linalg.norm(frame.skin - V, axis=1)
    distance = np.linalg.norm(V - centre, axis=1) - radius
    assert moved[i] > 3.0
    # (the face proper: the unmeshed neck and ears are extrapolated from the edge tetrahedra, weights up to 3)
    far = (distance > 80) & editor.anatomy.skin_meshed
    assert far.sum() > 1000 and np.median(moved[far]) < 0.01 and np.percentile(moved[far], 99) < 0.05 * 4.0
    # statics: the bones hold what the sphere pushes. The load on the bone (Dirichlet) nodes, the flesh model's
    # elastic forces plus the contact's own share there, sums to the sphere's total force (to zero without it),
    # and its moment about the sphere's centre vanishes (every contact force points away from the centre)
    flesh, C = editor.model.flesh, editor.model.flesh.dirichlet_nodes
    a = np.clip(c.activations, 0, 1)
    Mc = c.cranium[:, :3]
    local_centre = np.linalg.solve(Mc, centre - c.cranium[:, 3])
    on_nodes = SphereContact(editor.contact_points, local_centre, radius, stiffness=report.stiffness)
    load = (flesh.forces(frame.nodes, a)[C] + on_nodes.evaluate(frame.nodes).forces[C]) @ Mc.T  # world, mN
    load_free = flesh.forces(free.nodes, a)[C] @ Mc.T
    total = report.force_mn
    tolerance = flesh.free_nodes.size * editor.model.solver.force_tolerance_mn
    assert np.linalg.norm(total) > 1000  # a 4 mm push is a few newtons
    assert total @ (c.cranium[:, :3] @ [0.5, 0.0, 0.85]) < 0  # into the face
    np.testing.assert_allclose(load_free.sum(axis=0), 0.0, atol=tolerance)
    np.testing.assert_allclose(load.sum(axis=0), total, atol=tolerance)
    arm = nodes[C] - centre
    moment = np.cross(arm, load).sum(axis=0)
    lever = np.linalg.norm(arm, axis=1).mean()
    assert np.linalg.norm(moment) < 0.01 * np.linalg.norm(total) * lever, (moment, total, lever)
    with pytest.raises(InputError, match="radius"):
        editor.solve(c, sphere=(centre, 0.0))
