"""A performance in a view: pixels as cv2.projectPoints gives them, occlusion that moves with the head."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from facecap.cameras import Camera, RayCaster, project_performance
from facecap.errors import InputError, MeshError
from facecap.io.ict_sample import load_ict_sample


def _rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_head_turning_in_front_of_a_camera() -> None:
    sample = load_ict_sample()
    V, F = sample.mesh.vertices, sample.mesh.faces
    cam = Camera.look_at("front", [0.0, 20.0, 650.0], [0.0, 0.0, 50.0], focal_px=2400.0, width=1384, height=1038,
                         distortion=[-0.08, 0.03, 5e-4, 2e-4, 0.0])
    angles = np.radians([-30.0, 0.0, 20.0, 45.0])
    frames = np.stack([(V + sample.expression_deltas[k]) @ _rotation_y(a).T for k, a in zip((0, 10, 20, 30), angles)])
    result = project_performance(frames, cam, faces=F)
    assert result.pixels.shape == (4, V.shape[0], 2) and result.visible.shape == (4, V.shape[0])
    rvec = cv2.Rodrigues(cam.R)[0]
    for t in range(4):
        reference, _ = cv2.projectPoints(frames[t], rvec, cam.T, cam.K, cam.distortion)
        np.testing.assert_allclose(result.pixels[t], reference.reshape(-1, 2), atol=1e-9)
        np.testing.assert_allclose(result.depth[t], (frames[t] @ cam.R.T + cam.T)[:, 2], atol=1e-9)
        # turning the head by M in front of the camera = turning the camera by M^-1 around the still head
        M = _rotation_y(angles[t])
        still = V + sample.expression_deltas[(0, 10, 20, 30)[t]]
        turned_camera = Camera("turned", K=cam.K, distortion=cam.distortion, width=cam.width, height=cam.height,
                               R=cam.R @ M, T=cam.T)
        expected = RayCaster(still, F).visible(still, turned_camera)
        agree = np.mean(result.visible[t] == expected)
        assert agree > 0.999  # equal up to float32 rounding at the silhouette
    # the face turns away: fewer of its vertices are seen at 45 degrees than straight on
    assert result.visible[3].sum() < result.visible[1].sum()
    # without faces, visibility is being inside the image
    bare = project_performance(frames, cam)
    np.testing.assert_array_equal(bare.visible, cam.project(frames).in_image)
    assert (result.visible <= bare.visible).all()


def test_single_frame_and_validation() -> None:
    cam = Camera.look_at("c", [0.0, 0.0, 100.0], [0.0, 0.0, 0.0], focal_px=100.0, width=64, height=64)
    one = project_performance(np.zeros((5, 3)), cam)
    assert one.pixels.shape == (1, 5, 2)
    with pytest.raises(InputError, match=r"expected shape \(T, n, 3\)"):
        project_performance(np.zeros((2, 5, 2)), cam)
    with pytest.raises(InputError, match="NaN"):
        project_performance(np.full((1, 5, 3), np.nan), cam)
    with pytest.raises(MeshError, match="out of range"):
        project_performance(np.zeros((1, 5, 3)), cam, faces=[[0, 1, 9]])
