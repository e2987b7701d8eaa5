"""Tests for facecap/cameras/read_footage_cameras.py: each footage's camera, by name or in order, and the
footage timing only a camera file gives. The command's own test is tests/pipelines/test_capture_wrinkles.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from facecap.cameras import Camera, CameraSetup, read_footage_cameras, write_camera_file, write_opencv_calibration
from facecap.errors import InputError


def _camera(name: str, focal: float) -> Camera:
    K = [[focal, 0.0, 691.5], [0.0, focal, 518.5], [0.0, 0.0, 1.0]]
    return Camera(name, K=K, distortion=np.zeros(5), width=1384, height=1038, R=np.eye(3), T=[0.0, 0.0, 500.0])


@pytest.fixture
def camera_file(tmp_path: Path) -> Path:
    path = tmp_path / "cameras.json"
    write_camera_file(path, CameraSetup((_camera("left", 2400.0), _camera("right", 2500.0)), video_rate_hz=12.5,
                                        first_mocap_frame=-2))
    return path


def test_footage_named_after_its_cameras_gets_them_in_its_own_order(camera_file: Path, tmp_path: Path) -> None:
    found = read_footage_cameras([camera_file], [tmp_path / "right", tmp_path / "left.mkv"])
    assert [c.name for c in found.cameras] == ["right", "left"]
    assert found.video_rate_hz == 12.5 and found.first_mocap_frame == -2.0


def test_footage_named_otherwise_takes_the_cameras_in_file_order(camera_file: Path, tmp_path: Path) -> None:
    found = read_footage_cameras([str(camera_file)], ["a", "b.mp4"])
    assert [c.name for c in found.cameras] == ["left", "right"]
    with pytest.raises(InputError, match=r"cameras.json: 2 cameras \(left, right\) for 3 footage"):
        read_footage_cameras([camera_file], ["a", "b", "c"])


def test_one_calibration_file_per_footage_with_its_unit(tmp_path: Path) -> None:
    paths = []
    for camera in (_camera("left", 2400.0), _camera("right", 2500.0)):
        paths.append(tmp_path / f"{camera.name}.yml")
        write_opencv_calibration(paths[-1], camera, unit="m")
    found = read_footage_cameras(paths, ["x", "y"], unit="m")
    assert found.video_rate_hz is None and found.first_mocap_frame == 0.0
    assert [c.K[0, 0] for c in found.cameras] == [2400.0, 2500.0]
    np.testing.assert_allclose(found.cameras[1].T, [0.0, 0.0, 500.0])  # read back in mm
    with pytest.raises(InputError, match=r"^--cameras: 2 calibration files for 3 footage \(one per camera\)$"):
        read_footage_cameras(paths, ["x", "y", "z"])
