"""Tests for the harder generator options: neck pivot, quick head turns, no head band, 40-120 markers,
random identities, named curve generators, rapid and asymmetric expressions."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.synth.expression_curves import smooth_expression_curves
from facecap.synth.generate_performance import HEAD_PIVOTS_MM, TURN_DURATION_S, generate_performance
from facecap.synth.ict_sample import load_ict_sample

RATE = 60.0


def _apply(T, P):
    return np.einsum("tij,tkj->tki", T[:, :3, :3], P) + T[:, None, :3, 3]


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


def test_rapid_asymmetric_curves_have_short_onsets_and_different_sides():
    names = load_ict_sample().expression_names
    rate = 240.0
    kw = dict(rate=rate, seed=8, ramp_in_s=(0.06, 0.15), ramp_out_s=(0.06, 0.15))
    sym = smooth_expression_curves(2400, names, **kw)
    asym = smooth_expression_curves(2400, names, **kw, asymmetry=0.4, max_timing_offset_s=0.08)
    # onsets: a rise from 10 % to 90 % of a smile peak takes at most 150 ms
    smile = sym[:, names.index("mouthSmile_L")]
    d = np.diff(smile)
    peaks = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0) & (smile[1:-1] > 0.3)) + 1
    assert peaks.size >= 1
    for p in peaks:
        lo = np.flatnonzero(smile[:p] < 0.1 * smile[p])[-1]
        assert (p - lo) / rate <= 0.15 + 1 / rate
    assert np.abs(d).max() * rate > 5.0  # weight per second: far faster than the default ramps
    # symmetric without the option; L and R differ in size and timing with it
    # (pairs the presets drive symmetrically: side_smirk moves mouthSmile_L and cheekSquint_L alone)
    pairs = [(n, n[:-2] + "_R") for n in ("browDown_L", "browInnerUp_L", "browOuterUp_L", "eyeWide_L",
                                           "eyeSquint_L", "noseSneer_L", "mouthFrown_L", "mouthPress_L",
                                           "mouthStretch_L", "mouthUpperUp_L", "cheekPuff_L")]
    assert max(np.abs(sym[:, names.index(l)] - sym[:, names.index(r)]).max() for l, r in pairs) < 1e-12
    gaps = [np.abs(asym[:, names.index(l)] - asym[:, names.index(r)]).max() for l, r in pairs]
    assert max(gaps) > 0.2
    np.testing.assert_array_equal(asym[:, names.index("eyeBlink_L")], asym[:, names.index("eyeBlink_R")])
    # the defaults are the old curves, draw for draw: the side options draw from their own stream
    np.testing.assert_array_equal(smooth_expression_curves(300, names, seed=8),
                                  smooth_expression_curves(300, names, seed=8, asymmetry=0.0))
    assert asym.min() >= 0 and asym.max() <= 1 and np.all(asym[0] == 0)
    with pytest.raises(InputError, match="asymmetry"):
        smooth_expression_curves(10, names, asymmetry=1.0)
    with pytest.raises(InputError, match="ramp_in_s"):
        smooth_expression_curves(10, names, ramp_in_s=(0.2, 0.1))
