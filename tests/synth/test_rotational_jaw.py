"""The jaw opening along its arc: the screw fit, the correction, and the generator's ``jaw='rotational'``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.synth import ICT_JAW_SCREW, JawScrew, fit_jaw_screw, generate_performance, rotational_jaw_correction
from facecap.io.ict_sample import load_ict_sample


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


def _arc_reference(p: np.ndarray, d: np.ndarray, w: float) -> np.ndarray:
    """The displacement of the module docstring, computed apart: scipy's rotation about ICT's jaw axis."""
    s = ICT_JAW_SCREW

    def turn(x: np.ndarray, fraction: float) -> np.ndarray:
        return Rotation.from_rotvec(fraction * s.angle_rad * s.axis).apply(x - s.centre) + s.centre - x

    r1 = turn(p, 1.0)
    alpha = np.clip((d * r1).sum(axis=1) / (r1 * r1).sum(axis=1), 0.0, 1.0)
    return alpha[:, None] * turn(p, w) + w * (d - alpha[:, None] * r1)


def test_generator_opens_the_jaw_along_its_arc() -> None:
    sample = load_ict_sample()
    names = sample.expression_names
    k = names.index("jawOpen")
    W = np.zeros((4, len(names)))
    W[:, k] = [0.0, 0.5, 1.0, 0.5]
    W[3, names.index("mouthSmile_L")] = 0.6
    common = dict(curves=W, seed=2, noise_mm=0.0, gap_fraction=0.0)
    linear = generate_performance(**common)
    arc = generate_performance(**common, jaw="rotational")
    assert (linear.jaw, arc.jaw) == ("linear", "rotational")
    # rest and full weight are ICT's own shapes
    assert np.allclose(arc.truth_vertices[[0, 2]], linear.truth_vertices[[0, 2]], atol=1e-4)
    # at half weight, on the chin and the lower lip (moving tens of mm), the arc of the reference
    V0 = sample.mesh.vertices
    d = sample.expression_deltas[k]
    jaw = np.flatnonzero(np.linalg.norm(d, axis=1) > 10.0)
    assert jaw.size > 50 and sample.landmarks[8] in jaw
    expected = V0[jaw] + _arc_reference(V0[jaw], d[jaw], 0.5)
    assert np.abs(arc.truth_vertices[1, jaw] - expected).max() < 1e-3  # float32 truth
    # which is not the straight line: the chin sags about 2 mm on it
    sag = np.linalg.norm(linear.truth_vertices[1, sample.landmarks[8]] - arc.truth_vertices[1, sample.landmarks[8]])
    assert 1.5 < sag < 3.0
    # the other expressions still add linearly on top
    smile = sample.expression_deltas[names.index("mouthSmile_L")]
    assert np.allclose(arc.truth_vertices[3] - arc.truth_vertices[1], 0.6 * smile, atol=1e-3)
    # nothing else about the take changes
    assert np.array_equal(arc.head_pose, linear.head_pose)
    assert np.array_equal(arc.markers.labels, linear.markers.labels)


def test_a_partial_share_of_the_rotation_and_the_clip() -> None:
    screw = JawScrew(np.array([1.0, 0.0, 0.0]), np.deg2rad(20.0), np.zeros(3), 0.0)
    rest = np.array([[0.0, -50.0, 70.0], [0.0, 30.0, 80.0]])
    r1 = screw.apply(rest, 1.0) - rest
    across = np.cross(r1, [1.0, 0.0, 0.0])  # orthogonal to r1
    delta = np.stack([0.4 * r1[0] + 0.1 * across[0],   # 40 % of the rotation plus something else
                      -0.5 * r1[1]])                    # against the rotation: its share clips to 0
    corr = rotational_jaw_correction(rest, delta, np.array([0.3]), screw)[0]
    turned = Rotation.from_rotvec([np.deg2rad(6.0), 0.0, 0.0]).apply(rest[0]) - rest[0]
    assert np.allclose(rest[0] + 0.3 * delta[0] + corr[0], rest[0] + 0.4 * turned + 0.3 * 0.1 * across[0])
    assert np.allclose(corr[1], 0.0)


def test_bad_input_is_refused() -> None:
    rest = np.zeros((4, 3))
    with pytest.raises(InputError, match="rotation"):
        fit_jaw_screw(np.eye(3) * 10, np.eye(3) * 10 + 1.0)  # a pure translation
    with pytest.raises(InputError, match="weights"):
        rotational_jaw_correction(rest, rest, np.ones((2, 2)), ICT_JAW_SCREW)
    with pytest.raises(InputError, match="weights"):
        rotational_jaw_correction(rest, rest, np.array([0.5, np.nan]), ICT_JAW_SCREW)
    with pytest.raises(InputError, match="jaw_delta"):
        rotational_jaw_correction(rest, np.zeros((3, 3)), np.array([0.5]), ICT_JAW_SCREW)


def test_generator_refuses_an_unknown_jaw() -> None:
    with pytest.raises(InputError, match="jaw"):
        generate_performance(n_frames=3, jaw="hinged")
