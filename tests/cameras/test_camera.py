"""Camera: projection against cv2.projectPoints for every distortion model, rays as its inverse, validation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from facecap.cameras import DISTORTION_SIZES, Camera
from facecap.errors import InputError

K = np.array([[2400.0, 0.0, 691.5], [0.0, 2410.0, 518.5], [0.0, 0.0, 1.0]])


def _distortion(n: int, rng: np.random.Generator) -> np.ndarray:
    """Coefficients of a real-looking lens: mild radial, small tangential and thin-prism, small tilt."""
    scale = np.array([0.1, 0.1, 1e-3, 1e-3, 0.1, 0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3, 1e-3, 0.01, 0.01])
    return rng.normal(0, 1, 14)[:n] * scale[:n]


def _camera(n: int, rng: np.random.Generator) -> tuple[Camera, np.ndarray]:
    rvec = rng.normal(0, 0.3, 3)
    R, _ = cv2.Rodrigues(rvec)
    cam = Camera("cam", K=K, distortion=_distortion(n, rng), width=1384, height=1038, R=R, T=[12.0, -30.0, 650.0])
    return cam, rvec


@pytest.mark.parametrize("n", DISTORTION_SIZES)
def test_project_matches_cv2_project_points(n: int) -> None:
    rng = np.random.default_rng(n)
    cam, rvec = _camera(n, rng)
    X = rng.normal(0, 80, (2000, 3))
    reference, _ = cv2.projectPoints(X, rvec, cam.T, cam.K, cam.distortion if n else None)
    projection = cam.project(X)
    np.testing.assert_allclose(projection.pixels, reference.reshape(-1, 2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(projection.depth, (X @ cam.R.T + cam.T)[:, 2], rtol=0, atol=1e-9)
    assert projection.in_front.all()


def test_project_keeps_leading_shape_and_flags_points_behind_and_outside() -> None:
    cam = Camera("c", K=K, distortion=[], width=1384, height=1038, R=np.eye(3), T=[0, 0, 0])
    X = np.array([[[0.0, 0.0, 100.0], [0.0, 0.0, -100.0]], [[1000.0, 0.0, 100.0], [0.0, 0.0, 1.0]]])
    projection = cam.project(X)
    assert projection.pixels.shape == (2, 2, 2) and projection.depth.shape == (2, 2)
    np.testing.assert_array_equal(projection.in_front, [[True, False], [True, True]])
    np.testing.assert_array_equal(projection.in_image, [[True, False], [False, True]])
    np.testing.assert_allclose(projection.pixels[0, 0], [691.5, 518.5])


@pytest.mark.parametrize("n", DISTORTION_SIZES)
def test_pixel_rays_invert_projection(n: int) -> None:
    rng = np.random.default_rng(100 + n)
    cam, _ = _camera(n, rng)
    X = rng.normal(0, 60, (1000, 3))
    rays = cam.pixel_rays(cam.project(X).pixels)
    np.testing.assert_allclose(np.linalg.norm(rays.directions, axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rays.origins, np.broadcast_to(cam.centre, X.shape), rtol=0, atol=1e-9)
    to_point = X - rays.origins
    along = np.einsum("ij,ij->i", to_point, rays.directions)
    off_ray = np.linalg.norm(to_point - along[:, None] * rays.directions, axis=1)
    assert along.min() > 0
    assert off_ray.max() < 1e-6  # mm, at ~650 mm


def test_pose_centre_and_view_direction() -> None:
    eye = np.array([100.0, 50.0, 600.0])
    target = np.array([0.0, 0.0, 50.0])
    cam = Camera.look_at("front", eye, target, focal_px=2000.0, width=640, height=480)
    np.testing.assert_allclose(cam.centre, eye, atol=1e-12)
    axis = (target - eye) / np.linalg.norm(target - eye)
    np.testing.assert_allclose(cam.view_direction, axis, atol=1e-12)
    np.testing.assert_allclose(cam.project(target[None]).pixels, [[319.5, 239.5]], atol=1e-9)
    # image up is world +y: a point above the target appears above the image centre (smaller v)
    assert cam.project((target + [0, 10, 0])[None]).pixels[0, 1] < 239.5


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"K": [[100, 1, 0], [0, 100, 0], [0, 0, 1]]}, "no skew"),
        ({"K": [[-100, 0, 0], [0, 100, 0], [0, 0, 1]]}, "focal lengths must be positive"),
        ({"K": np.eye(2)}, "expected shape (3, 3)"),
        ({"distortion": [0.1, 0.2, 0.3]}, "coefficients"),
        ({"distortion": [np.nan, 0, 0, 0]}, "NaN"),
        ({"R": np.diag([1.0, 1.0, -1.0])}, "not a rotation"),
        ({"R": 2 * np.eye(3)}, "not a rotation"),
        ({"T": [0, 0]}, "expected shape (3,)"),
        ({"width": 0}, "positive integer"),
        ({"height": 10.5}, "positive integer"),
        ({"name": ""}, "non-empty"),
    ],
)
def test_bad_camera_values_raise_input_error(change: dict, message: str) -> None:
    values = {"name": "bad", "K": K, "distortion": [], "width": 640, "height": 480, "R": np.eye(3), "T": [0, 0, 1]}
    values.update(change)
    name = values.pop("name")
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Camera(name, **values)


def test_camera_arrays_are_read_only() -> None:
    cam = Camera("c", K=K, distortion=[0.1, 0, 0, 0], width=10, height=10, R=np.eye(3), T=[0, 0, 1])
    with pytest.raises(ValueError):
        cam.K[0, 0] = 1.0
