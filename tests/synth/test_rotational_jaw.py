"""The jaw opening along its arc: the screw fit, the correction, and the generator's ``jaw='rotational'``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.synth import (ICT_JAW_SCREW, JawScrew, fit_jaw_screw, generate_performance, load_ict_sample,
                           rotational_jaw_correction)


def _distance_to_axis(points: np.ndarray, screw: JawScrew) -> np.ndarray:
    rel = points - screw.centre
    return np.linalg.norm(rel - np.outer(rel @ screw.axis, screw.axis), axis=1)


def test_screw_fit_recovers_a_known_screw() -> None:
    rng = np.random.default_rng(3)
    axis = np.array([0.3, -0.2, 0.93])
    axis /= np.linalg.norm(axis)
    truth = JawScrew(axis, np.deg2rad(21.0), np.array([4.0, -7.0, 12.0]), 2.5)
    rest = rng.normal(scale=30.0, size=(200, 3))
    fitted = fit_jaw_screw(rest, truth.apply(rest, 1.0))
    assert np.allclose(fitted.axis, truth.axis, atol=1e-9)
    assert fitted.angle_rad == pytest.approx(truth.angle_rad, abs=1e-9)
    assert fitted.slide_mm == pytest.approx(truth.slide_mm, abs=1e-9)
    # the centre is any point of the axis: it must lie on the true one
    assert _distance_to_axis(fitted.centre[None], truth)[0] < 1e-8
    # and the motion at any weight is the same
    assert np.allclose(fitted.apply(rest, 0.4), truth.apply(rest, 0.4), atol=1e-8)


def test_screw_apply_is_rigid_and_takes_a_weight_per_frame() -> None:
    screw = JawScrew(np.array([1.0, 0.0, 0.0]), np.deg2rad(30.0), np.array([0.0, 10.0, -5.0]), 1.0)
    points = np.array([[0.0, 10.0, 95.0], [3.0, -40.0, 60.0]])
    moved = screw.apply(points, np.array([0.0, 0.5, 1.0]))
    assert moved.shape == (3, 2, 3)
    assert np.allclose(moved[0], points)
    # half the angle about x, half the slide along it
    expected = Rotation.from_rotvec([np.deg2rad(15.0), 0, 0]).apply(points - screw.centre) + screw.centre + [0.5, 0, 0]
    assert np.allclose(moved[1], expected)
    for m in moved:
        assert np.allclose(np.linalg.norm(m[0] - m[1]), np.linalg.norm(points[0] - points[1]))


def test_correction_keeps_both_ends_and_puts_a_rotating_vertex_on_the_arc() -> None:
    screw = JawScrew(np.array([1.0, 0.0, 0.0]), np.deg2rad(25.0), np.zeros(3), 0.0)
    rest = np.array([[0.0, -60.0, 80.0],    # on the jaw: its displacement is the rotation's
                     [0.0, 40.0, 90.0],     # moves along a line that has nothing of the rotation
                     [0.0, 0.0, 0.2]])      # next to the axis: under 0.5 mm of rotation, linear
    delta = screw.apply(rest, 1.0) - rest
    delta[1] = [5.0, 0.0, 0.0]
    weights = np.array([0.0, 0.5, 1.0])
    corr = rotational_jaw_correction(rest, delta, weights, screw)
    assert np.allclose(corr[0], 0.0) and np.allclose(corr[2], 0.0)
    assert np.allclose(corr[:, 1:], 0.0)
    half = rest[0] + 0.5 * delta[0] + corr[1, 0]
    assert np.allclose(half, screw.apply(rest[:1], 0.5)[0])
    # the straight line cuts the arc's chord short by r (1 - cos(theta / 2))
    r = np.linalg.norm(rest[0])
    assert np.linalg.norm(corr[1, 0]) == pytest.approx(r * (1 - np.cos(np.deg2rad(12.5))), rel=1e-9)


def test_generator_opens_the_jaw_along_its_arc() -> None:
    sample = load_ict_sample()
    k = sample.expression_names.index("jawOpen")
    W = np.zeros((4, len(sample.expression_names)))
    W[:, k] = [0.0, 0.5, 1.0, 0.5]
    W[3, sample.expression_names.index("mouthSmile_L")] = 0.6
    common = dict(curves=W, seed=2, noise_mm=0.0, gap_fraction=0.0)
    linear = generate_performance(**common)
    arc = generate_performance(**common, jaw="rotational")
    chin = sample.landmarks[8]
    # full weight and rest are ICT's own shapes
    assert np.allclose(arc.truth_vertices[[0, 2]], linear.truth_vertices[[0, 2]], atol=1e-4)
    # the chin's skin also stretches away from the jaw's axis as the jaw opens; along the arc, half
    # weight is about half that stretch (the skin's share of the rotation is under 1, and the rest of
    # its displacement stays linear), while the straight line falls short of it by the chord's sag
    d = [_distance_to_axis(t.truth_vertices[f, [chin]].astype(float), ICT_JAW_SCREW)[0]
         for t, f in ((linear, 0), (linear, 2), (arc, 1), (linear, 1))]
    d_rest, d_full, d_arc, d_line = d
    middle = 0.5 * (d_rest + d_full)
    assert middle - d_line > 1.5  # about 2 mm of sag at the chin, 111 mm from the axis
    assert abs(d_arc - middle) < 0.25 * (middle - d_line)
    # the other expressions still add linearly on top
    smile = sample.expression_deltas[sample.expression_names.index("mouthSmile_L")]
    assert np.allclose(arc.truth_vertices[3] - arc.truth_vertices[1], 0.6 * smile, atol=1e-3)
    # nothing else about the take changes
    assert np.array_equal(arc.head_pose, linear.head_pose)


def test_generator_refuses_an_unknown_jaw() -> None:
    with pytest.raises(InputError, match="jaw"):
        generate_performance(n_frames=3, jaw="hinged")
