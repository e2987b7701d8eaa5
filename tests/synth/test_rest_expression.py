"""A resting face that is not the scan's, and a map picked by hand: the generator against its own inputs."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.synth import RESTING_SHAPES, as_rest_weights, generate_performance, random_rest_expression
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.rest_expression import MAX_REST_WEIGHT


def test_random_rest_expression_has_the_asked_mean_over_the_face():
    sample = load_ict_sample()
    face = sample.region_labels != sample.region_names.index("other")
    allowed = {name for group in RESTING_SHAPES for name in group}
    for seed in range(6):
        rest = random_rest_expression(seed, mean_mm=0.4, sample=sample)
        assert set(rest) <= allowed and max(rest.values()) <= MAX_REST_WEIGHT + 1e-12
        w = as_rest_weights(rest, sample.expression_names)
        moved = np.linalg.norm(np.tensordot(w, sample.expression_deltas, axes=1)[face], axis=1).mean()
        # exactly the mean asked for, unless a weight reached its cap (then less)
        assert moved == pytest.approx(0.4, rel=1e-9) or (moved < 0.4 and max(rest.values()) == pytest.approx(MAX_REST_WEIGHT))
    assert random_rest_expression(3) == random_rest_expression(3) != random_rest_expression(4)


def test_the_resting_expression_is_under_every_frame():
    sample = load_ict_sample()
    rest = {"mouthSmile_L": 0.1, "mouthSmile_R": 0.12, "browDown_L": 0.2}
    plain = generate_performance(n_frames=40, seed=2, sample=sample)
    held = generate_performance(n_frames=40, seed=2, sample=sample, rest_expression=rest)
    w = as_rest_weights(rest, sample.expression_names)
    np.testing.assert_allclose(held.rest_weights, w)
    np.testing.assert_allclose(held.weights, np.clip(plain.weights + w, 0.0, 1.0))
    expected0 = sample.mesh.vertices + np.tensordot(w, sample.expression_deltas, axes=1)
    np.testing.assert_allclose(held.truth_vertices[0], expected0, atol=2e-4)  # frame 0 is not the scan
    assert np.linalg.norm(held.truth_vertices[0] - held.scan.vertices, axis=1).max() > 1.0
    # the head motion, mocap frame, noise and gaps do not change with it
    np.testing.assert_array_equal(held.head_pose, plain.head_pose)
    np.testing.assert_array_equal(np.isnan(held.markers.positions), np.isnan(plain.markers.positions))
    assert plain.rest_weights is None


def test_a_hand_picked_map_lies_on_the_scan_off_the_true_place_along_the_skin():
    case = generate_performance(n_frames=5, seed=3, map_error_mm=1.0)
    truth = generate_performance(n_frames=5, seed=3)
    np.testing.assert_array_equal(case.markers.positions, truth.markers.positions)  # the take is the same
    assert all(isinstance(v, int) for v in truth.correspondence.values())
    V, F = case.scan.vertices, case.scan.faces
    picked = np.array([case.correspondence[label] for label in case.face_labels])
    distance_to_surface = np.sqrt(igl.point_mesh_squared_distance(picked, V, F)[0])
    assert distance_to_surface.max() < 1e-6
    off = np.linalg.norm(picked - V[case.marker_vertices], axis=1)
    # two tangent directions of sd 1 mm: a Rayleigh distance, mean sqrt(pi/2) = 1.25 mm
    assert off.mean() == pytest.approx(np.sqrt(np.pi / 2), rel=0.2)


@pytest.mark.parametrize("rest, match", [
    ({"smile": 0.1}, "unknown expression"),
    ({"mouthSmile_L": 1.5}, "within"),
    (np.zeros(3), "weights"),
])
def test_bad_rest_expressions(rest, match):
    with pytest.raises(InputError, match=match):
        generate_performance(n_frames=3, rest_expression=rest)
    with pytest.raises(InputError, match="map_error_mm"):
        generate_performance(n_frames=3, map_error_mm=-1.0)
