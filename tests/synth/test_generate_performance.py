import numpy as np
import pytest

from facecap.errors import InputError
from facecap.synth.generate_performance import generate_performance, vertex_normals_at
from facecap.synth.ict_sample import load_ict_sample


@pytest.fixture(scope="module")
def case():
    return generate_performance(n_frames=200, seed=4)


def test_frame_zero_is_the_scan_and_truth_follows_the_weights(case):
    s = load_ict_sample()
    np.testing.assert_allclose(case.truth_vertices[0], case.scan.vertices, atol=1e-4)
    t = 120
    expected = case.scan.vertices + np.tensordot(case.weights[t], s.expression_deltas.astype(np.float64), axes=1)
    np.testing.assert_allclose(case.truth_vertices[t], expected, atol=1e-3)


def test_markers_are_the_truth_plus_offset_seen_through_head_and_mocap_frames(case):
    # undo the mocap frame and the head motion: the noiseless markers land 1.5 mm above the skin
    world = case.mocap_from_scan[None] @ case.head_pose
    inv = np.linalg.inv(world)
    P = np.einsum("tij,tkj->tki", inv[:, :3, :3], case.noiseless_markers) + inv[:, None, :3, 3]
    mv = case.marker_vertices
    skin = case.truth_vertices[:, mv].astype(np.float64)
    normals = vertex_normals_at(case.truth_vertices, case.scan.faces, mv)
    np.testing.assert_allclose(P[:, : mv.size], skin + 1.5 * normals, atol=1e-4)


def test_noise_and_gaps_have_the_requested_size(case):
    observed = case.markers.positions
    gaps = np.isnan(observed).any(axis=2)
    assert 0.015 < gaps.mean() < 0.03
    assert not gaps[0].any() and not gaps.all(axis=1).any()
    noise = (observed - case.noiseless_markers)[~gaps]
    assert np.std(noise) == pytest.approx(0.2, rel=0.1)


def test_headband_markers_are_rigid_and_not_in_the_map(case):
    labels = case.markers.labels
    band = [i for i, s in enumerate(labels) if s.startswith("HB")]
    assert len(band) == 4 and not set(labels[i] for i in band) & set(case.correspondence)
    P = case.noiseless_markers[:, band]
    d = np.linalg.norm(P[:, :, None] - P[:, None], axis=3)
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-9)


def test_head_motion_and_mocap_frame_are_rigid_transforms(case):
    for T in [case.mocap_from_scan, *case.head_pose[::50]]:
        R = T[:3, :3]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
    angles = np.degrees(np.arccos(np.clip((np.trace(case.head_pose[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)))
    assert 0.5 < angles.max() <= 4.0 + 1e-9


def test_reproducible_and_explicit_curves():
    a = generate_performance(n_frames=30, seed=9, n_markers=40)
    b = generate_performance(n_frames=30, seed=9, n_markers=40)
    np.testing.assert_array_equal(a.markers.positions, b.markers.positions)
    with pytest.raises(InputError, match="curves"):
        generate_performance(n_frames=30, curves=np.zeros((10, 53)))
    still = generate_performance(n_frames=30, curves=np.zeros((30, 53)), noise_mm=0, gap_fraction=0,
                                 head_rotation_deg=0, head_translation_mm=0)
    np.testing.assert_allclose(still.truth_vertices, np.broadcast_to(still.scan.vertices, still.truth_vertices.shape),
                               atol=1e-4)
