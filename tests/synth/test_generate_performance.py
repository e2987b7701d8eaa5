"""Tests for facecap.synth.generate_performance: a synthetic take against the truth that made it."""

import igl
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.mesh.vertex_normals import vertex_normals
from facecap.synth.expression_curves import smooth_expression_curves
from facecap.synth.generate_performance import HEAD_PIVOTS_MM, TURN_DURATION_S, SyntheticCase, generate_performance
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.marker_layout import animface_marker_map, boundary_vertices


RATE = 60.0  # the generator's default rate, Hz


@pytest.fixture(scope="module")
def case() -> SyntheticCase:
    return generate_performance(n_frames=200, seed=4)


def _apply(T: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Rigid transforms (T, 4, 4) applied to points (T, k, 3)."""
    return np.einsum("tij,tkj->tki", T[:, :3, :3], P) + T[:, None, :3, 3]


def _runs(mask: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True down each column of a (T, M) mask."""
    padded = np.pad(mask, ((1, 1), (0, 0))).astype(np.int8)
    d = np.diff(padded, axis=0)
    starts, ends = np.nonzero(d.T == 1), np.nonzero(d.T == -1)
    return ends[1] - starts[1]


def test_frame_zero_is_the_scan_and_truth_follows_the_weights(case):
    s = load_ict_sample()
    assert case.truth_vertices.dtype == np.float32 and case.truth_vertices.shape == (200, 9409, 3)
    assert np.all(case.weights[0] == 0)
    np.testing.assert_array_equal(case.truth_vertices[0], case.scan.vertices.astype(np.float32))
    for t in (60, 120, 199):
        expected = case.scan.vertices + np.tensordot(case.weights[t], s.expression_deltas, axes=1)
        np.testing.assert_allclose(case.truth_vertices[t], expected, atol=2e-4)
    assert case.weights.max() > 0.5  # a real performance, not a twitch


def test_markers_are_the_truth_plus_offset_seen_through_head_and_mocap_frames(case):
    # undo the mocap frame and the head motion: the noiseless markers land 1.5 mm above the skin,
    # along the area-weighted normal of the deformed surface (libigl as the reference)
    world = case.mocap_from_scan[None] @ case.head_pose
    P = _apply(np.linalg.inv(world), case.noiseless_markers)
    mv = case.marker_vertices
    F = case.scan.faces
    for t in (0, 33, 199):
        V = case.truth_vertices[t].astype(np.float64)
        N = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)[mv]
        np.testing.assert_allclose(P[t, : mv.size], V[mv] + 1.5 * N, atol=1e-7)
    # and the head band is where the case says it is, rigid with the head
    np.testing.assert_allclose(P[:, mv.size :], np.broadcast_to(case.headband_points, P[:, mv.size :].shape),
                               atol=1e-7)


def test_noise_and_gaps_have_the_requested_size_and_shape(case):
    observed = case.markers.positions
    gaps = case.markers.gap_mask
    assert np.isnan(observed).any(axis=2).sum() == np.isnan(observed).all(axis=2).sum()  # whole samples
    assert gaps.sum() == round(0.02 * gaps.size)
    assert not gaps[0].any() and not gaps.all(axis=1).any()
    runs = _runs(gaps)
    assert 3 <= np.median(runs) <= 30 and runs.max() <= 60  # occlusion bursts, not salt and pepper
    noise = (observed - case.noiseless_markers)[~gaps]
    assert np.std(noise) == pytest.approx(0.2, rel=0.1)
    assert abs(np.mean(noise)) < 0.02


def test_noise_and_gaps_are_independent_streams_of_the_seed(case):
    clean = generate_performance(n_frames=200, seed=4, noise_mm=0.0, gap_fraction=0.0)
    np.testing.assert_array_equal(clean.markers.positions, case.noiseless_markers)
    np.testing.assert_array_equal(clean.truth_vertices, case.truth_vertices)
    np.testing.assert_array_equal(clean.head_pose, case.head_pose)
    more_gaps = generate_performance(n_frames=200, seed=4, gap_fraction=0.1)
    assert more_gaps.markers.gap_mask.mean() == pytest.approx(0.1, abs=1e-3)


def test_headband_markers_are_rigid_off_the_forehead_and_not_in_the_map(case):
    labels = case.markers.labels
    assert case.headband_labels == ("HB0", "HB1", "HB2", "HB3")
    assert labels[-4:] == case.headband_labels and not set(case.headband_labels) & set(case.correspondence)
    P = case.noiseless_markers[:, -4:]
    d = np.linalg.norm(P[:, :, None] - P[:, None], axis=3)
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-9)
    # about 15 mm off the skin, above the brows, spread across the head (not collinear)
    sq, _, _ = igl.point_mesh_squared_distance(case.headband_points, case.scan.vertices, case.scan.faces)
    assert np.all((np.sqrt(sq) > 12.0) & (np.sqrt(sq) <= 15.0 + 1e-9))
    brow_top = case.scan.vertices[load_ict_sample().landmarks[17:27], 1].max()
    assert np.all(case.headband_points[:, 1] > brow_top)
    assert np.linalg.svd(case.headband_points - case.headband_points.mean(0), compute_uv=False)[1] > 10.0


def test_head_motion_and_mocap_frame_are_rigid_transforms(case):
    for T in [case.mocap_from_scan, *case.head_pose[::25]]:
        R = T[:3, :3]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    np.testing.assert_array_equal(case.head_pose[0], np.eye(4))
    angles = np.degrees(Rotation.from_matrix(case.head_pose[:, :3, :3]).magnitude())
    assert 0.3 < angles.max() <= 4.0 + 1e-9
    # smooth: no frame-to-frame jump bigger than a slow head turn allows (0.6 Hz, 4 deg)
    assert np.abs(np.diff(angles)).max() < 0.5


def test_head_motion_peaks_at_the_requested_amplitude_over_ten_seconds():
    long = generate_performance(n_frames=600, seed=1, n_markers=10, head_rotation_deg=6.0, head_translation_mm=0.0,
                                noise_mm=0.0, gap_fraction=0.0)
    angles = np.degrees(Rotation.from_matrix(long.head_pose[:, :3, :3]).magnitude())
    assert angles.max() == pytest.approx(6.0, abs=1e-9)
    shift = generate_performance(n_frames=600, seed=1, n_markers=10, head_rotation_deg=0.0, head_translation_mm=3.0,
                                 noise_mm=0.0, gap_fraction=0.0)
    np.testing.assert_allclose(shift.head_pose[:, :3, :3], np.broadcast_to(np.eye(3), (600, 3, 3)), atol=0)
    assert np.linalg.norm(shift.head_pose[:, :3, 3], axis=1).max() == pytest.approx(3.0, abs=1e-9)


def test_default_layout_is_on_the_front_of_the_face_and_off_the_boundary(case):
    s = load_ict_sample()
    mv = case.marker_vertices
    assert mv.size == 90 and np.unique(mv).size == 90
    assert case.face_labels == tuple(f"M{i:03d}" for i in range(90))
    assert case.correspondence == {f"M{i:03d}": int(v) for i, v in enumerate(mv)}
    assert not np.any(s.region_labels[mv] == s.region_names.index("other"))
    assert not boundary_vertices(case.scan.faces, case.scan.n_vertices)[mv].any()


def test_other_layouts_identity_and_mocap_frame():
    s = load_ict_sample()
    animface = generate_performance(n_frames=20, marker_layout="animface", headband_markers=0, seed=3)
    assert animface.correspondence == animface_marker_map() and animface.markers.n_markers == 41
    chosen = np.array([10, 500, 3000])
    X = np.eye(4)
    X[:3, :3] = Rotation.from_rotvec([0.1, -0.7, 0.3]).as_matrix()
    X[:3, 3] = [10.0, -20.0, 900.0]
    a = generate_performance(n_frames=15, marker_layout=chosen, identity=[1.0, -0.5], mocap_frame=X, seed=2,
                             noise_mm=0.0, gap_fraction=0.0, head_rotation_deg=0.0, head_translation_mm=0.0)
    np.testing.assert_array_equal(a.marker_vertices, chosen)
    np.testing.assert_array_equal(a.mocap_from_scan, X)
    np.testing.assert_allclose(a.scan.vertices, s.face([1.0, -0.5]).vertices, atol=0)
    # no head motion: frame 0 markers are X applied to the scan points 1.5 mm along the scan normals
    # (the truth, and so the markers, come from the scan rounded to float32)
    V32 = a.scan.vertices.astype(np.float32).astype(np.float64)
    N = vertex_normals(V32, a.scan.faces, chosen)
    expected = (V32[chosen] + 1.5 * N) @ X[:3, :3].T + X[:3, 3]
    np.testing.assert_allclose(a.markers.positions[0, :3], expected, atol=1e-9)
    named = generate_performance(n_frames=5, marker_layout={"chin": 963, "nose": 1307}, headband_markers=2)
    assert named.markers.labels == ("chin", "nose", "HB0", "HB1")


def test_reproducible_seed_dependent_and_explicit_curves():
    a = generate_performance(n_frames=30, seed=9, n_markers=40)
    b = generate_performance(n_frames=30, seed=9, n_markers=40)
    np.testing.assert_array_equal(a.markers.positions, b.markers.positions)
    np.testing.assert_array_equal(a.marker_vertices, b.marker_vertices)
    c = generate_performance(n_frames=30, seed=10, n_markers=40)
    assert not np.array_equal(a.marker_vertices, c.marker_vertices)
    still = generate_performance(curves=np.zeros((30, 53)), noise_mm=0, gap_fraction=0,
                                 head_rotation_deg=0, head_translation_mm=0)
    assert still.truth_vertices.shape[0] == 30
    np.testing.assert_array_equal(still.truth_vertices,
                                  np.broadcast_to(still.scan.vertices.astype(np.float32), still.truth_vertices.shape))
    # a still face in a still head: every marker stands still
    np.testing.assert_allclose(still.markers.positions, np.broadcast_to(still.markers.positions[0], (30, 94, 3)),
                               atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_frames": 30, "curves": np.zeros((10, 53))}, "curves"),
        ({"curves": np.full((10, 53), np.nan)}, "curves"),
        ({"curves": np.zeros((10, 3))}, "curves"),
        ({"n_frames": 0}, "n_frames"),
        ({"gap_fraction": 0.8}, "gap_fraction"),
        ({"noise_mm": -1.0}, "noise_mm"),
        ({"rate": 0}, "rate"),
        ({"headband_markers": 40}, "headband_markers"),
        ({"marker_layout": "vicon"}, "marker_layout"),
        ({"marker_layout": np.array([1, 1, 2])}, "marker_layout"),
        ({"marker_layout": np.array([1, 99999])}, "marker_layout"),
        ({"marker_layout": {"HB0": 5, "a": 6}}, "HB0"),
        ({"marker_layout": np.array([1, 2, 3]), "n_markers": 5}, "n_markers"),
        ({"mocap_frame": np.diag([1.0, 1.0, -1.0, 1.0])}, "mocap_frame"),
        ({"mocap_frame": np.eye(3)}, "mocap_frame"),
        ({"identity": np.ones(20)}, "identity"),
        ({"sample": "ict"}, "sample"),
    ],
)
def test_bad_options_are_clear_errors(kwargs, match):
    with pytest.raises(InputError, match=match):
        generate_performance(**kwargs)


# The harder options: neck pivot, quick head turns, no head band, 40-120 markers, random identities,
# named curve generators.


@pytest.fixture(scope="module")
def neck_turns():
    return generate_performance(n_frames=600, seed=21, head_pivot="neck", head_motion="turns",
                                head_rotation_deg=8.0, head_translation_mm=0.0, headband_markers=0,
                                n_markers=40, curves="speech")


def test_neck_pivot_is_fixed_by_every_head_pose_and_undoing_the_pose_restores_the_markers(neck_turns):
    c = neck_turns
    s = load_ict_sample()
    pivot = c.scan.vertices[s.landmarks[8]] + np.array(HEAD_PIVOTS_MM["neck"])
    pivot[0] = c.scan.vertices[:, 0].mean()
    moved = _apply(c.head_pose, np.broadcast_to(pivot, (c.head_pose.shape[0], 1, 3)))
    np.testing.assert_allclose(moved[:, 0], np.broadcast_to(pivot, (600, 3)), atol=1e-9)  # no translation asked
    # the pivot is 9 cm below and 8 cm behind the chin
    assert pivot[1] - c.scan.vertices[s.landmarks[8], 1] == pytest.approx(-90.0)
    # undoing the head pose and the mocap frame gives markers that only follow the expression
    P = _apply(np.linalg.inv(c.mocap_from_scan[None] @ c.head_pose), c.noiseless_markers)
    skin = c.truth_vertices[:, c.marker_vertices].astype(np.float64)
    assert np.linalg.norm(P - skin, axis=2).max() == pytest.approx(1.5, abs=1e-4)  # the marker offset
    # a rotation about the low pivot swings the face sideways: the nose tip moves many mm
    nose = c.scan.vertices[s.landmarks[30]]
    swing = np.linalg.norm(_apply(c.head_pose, np.broadcast_to(nose, (600, 1, 3)))[:, 0] - nose, axis=1)
    assert swing.max() > 10.0


def test_turns_reach_the_peak_hold_and_turn_quickly(neck_turns):
    c = neck_turns
    R = Rotation.from_matrix(c.head_pose[:, :3, :3])
    angle = np.degrees(np.linalg.norm(R.as_rotvec(), axis=1))
    assert angle[0] == 0.0 and angle.max() == pytest.approx(8.0, rel=1e-6)  # 600 frames = 10 s: the full amplitude
    speed = np.degrees((R[1:] * R[:-1].inv()).magnitude()) * RATE  # deg/s
    moving = speed > 1e-6
    # holds: most of the take the head is still
    assert (~moving).mean() > 0.4
    # each turn lasts at most TURN_DURATION_S[1] and is quick (peak speed many deg/s)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(int), [0]])))
    durations = (edges[1::2] - edges[::2]) / RATE
    assert durations.size >= 3 and durations.max() <= TURN_DURATION_S[1] + 2 / RATE
    assert speed.max() > 8.0


def test_no_head_band_and_forty_markers(neck_turns):
    c = neck_turns
    assert c.headband_labels == () and c.headband_points.shape == (0, 3)
    assert c.n_face_markers == 40 and c.markers.positions.shape == (600, 40, 3)
    assert np.unique(c.marker_vertices).size == 40


def test_one_hundred_twenty_markers_and_random_identities_give_valid_faces():
    s = load_ict_sample()
    generic = s.mesh.vertices
    F = s.mesh.faces
    n0 = np.cross(generic[F[:, 1]] - generic[F[:, 0]], generic[F[:, 2]] - generic[F[:, 0]])
    rng = np.random.default_rng(5)
    for sd in (0.5, 1.0):
        identity = rng.normal(scale=sd, size=8)
        c = generate_performance(n_frames=60, seed=6, identity=identity, n_markers=120, headband_markers=0,
                                 noise_mm=0.0, gap_fraction=0.0)
        V = c.scan.vertices
        n1 = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        area = 0.5 * np.linalg.norm(n1, axis=1)
        # no collapsed triangle and none flipped (the generic face has slivers of 0.005 mm^2 at the
        # mouth corners, quads with two coincident corners, which any identity may tip over: skip those)
        sound = 0.5 * np.linalg.norm(n0, axis=1) > 0.05
        assert area.min() > 0 and np.all(np.sum(n0 * n1, axis=1)[sound] > 0)
        assert 100 < np.ptp(V[:, 1]) < 300
        assert c.n_face_markers == 120 and np.isfinite(c.markers.positions).all()


def test_named_curves_match_their_generators():
    names = load_ict_sample().expression_names
    c = generate_performance(n_frames=120, seed=3, curves="smooth", n_markers=20)
    np.testing.assert_array_equal(c.weights, smooth_expression_curves(120, names, rate=RATE, seed=3))
    for kind in ("speech", "real", "rapid_asymmetric"):
        W = generate_performance(n_frames=120, seed=3, curves=kind, n_markers=20).weights
        assert W.shape == (120, 53) and np.all(W[0] == 0) and 0 <= W.min() and W.max() <= 1
    with pytest.raises(InputError, match="curves"):
        generate_performance(n_frames=10, curves="mumble", n_markers=5)
    with pytest.raises(InputError, match="head_pivot"):
        generate_performance(n_frames=10, head_pivot="hip", n_markers=5)
    with pytest.raises(InputError, match="head_motion"):
        generate_performance(n_frames=10, head_motion="spin", n_markers=5)
