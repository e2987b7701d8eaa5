"""OpenCV FileStorage calibration: files written by cv2.FileStorage, the calibration sample's own format, and back."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from facecap.cameras import Camera, read_opencv_calibration, write_opencv_calibration
from facecap.errors import FileFormatError, InputError

K = np.array([[2400.0, 0.0, 691.5], [0.0, 2410.0, 518.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.31, 1.5e-3, -2.0e-4, -0.45])
RVEC = np.array([0.05, -0.4, 0.01])
T_MM = np.array([12.5, -40.0, 650.0])

# What OpenCV's samples/cpp/calibration.cpp (saveCameraParams) writes, byte for byte in layout, plus R and T
SAMPLE_YAML = """%YAML:1.0
---
calibration_time: "Tue Dec  1 23:12:44 2026"
nframes: 2
image_width: 1384
image_height: 1038
board_width: 9
board_height: 6
square_size: 25.
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 2400., 0., 691.5, 0., 2410., 518.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -0.12, 0.31, 1.5e-03, -2.0e-04, -0.45 ]
avg_reprojection_error: 0.2815
per_view_reprojection_errors: !!opencv-matrix
   rows: 2
   cols: 1
   dt: f
   data: [ 0.27, 0.29 ]
extrinsic_parameters: !!opencv-matrix
   rows: 2
   cols: 6
   dt: d
   data: [ 0.1, 0.2, 0.3, 10., 20., 500., 0.1, 0.2, 0.3, 10., 20., 500. ]
R: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ 0.05, -0.4, 0.01 ]
T: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ 12.5, -40., 650. ]
"""


def _write_reference(path: Path, **keys: object) -> None:
    """The reference writer: cv2.FileStorage itself."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in keys.items():
        fs.write(key, value)
    fs.release()


def test_reads_the_calibration_sample_format(tmp_path: Path) -> None:
    path = tmp_path / "cam0.yml"
    path.write_text(SAMPLE_YAML)
    cam = read_opencv_calibration(path)
    assert cam.name == "cam0" and (cam.width, cam.height) == (1384, 1038)
    np.testing.assert_array_equal(cam.K, K)
    np.testing.assert_array_equal(cam.distortion, DIST)
    np.testing.assert_allclose(cam.R, cv2.Rodrigues(RVEC)[0], atol=1e-15)
    np.testing.assert_array_equal(cam.T, T_MM)
    assert cam.source_unit == "mm"


@pytest.mark.parametrize("suffix", [".yml", ".xml", ".json"])
@pytest.mark.parametrize("rotation", ["matrix", "rodrigues", "rvec"])
def test_reads_files_written_by_cv2_filestorage(tmp_path: Path, suffix: str, rotation: str) -> None:
    path = tmp_path / f"side{suffix}"
    R = cv2.Rodrigues(RVEC)[0]
    pose = ({"R": R, "T": T_MM.reshape(3, 1)} if rotation == "matrix" else
            {"R": RVEC.reshape(3, 1), "T": T_MM.reshape(3, 1)} if rotation == "rodrigues" else
            {"rvec": RVEC.reshape(3, 1), "tvec": T_MM.reshape(1, 3)})
    _write_reference(path, image_width=1384, image_height=1038, camera_matrix=K,
                     distortion_coefficients=DIST.reshape(1, 5), **pose)
    cam = read_opencv_calibration(path, name="side")
    np.testing.assert_allclose(cam.R, R, atol=1e-15)
    np.testing.assert_array_equal(cam.T, T_MM)
    # the camera projects as OpenCV does with the file's values
    X = np.random.default_rng(0).normal(0, 50, (100, 3))
    reference, _ = cv2.projectPoints(X, RVEC, T_MM, K, DIST)
    np.testing.assert_allclose(cam.project(X).pixels, reference.reshape(-1, 2), atol=1e-9)


def test_unit_converts_translation_to_mm(tmp_path: Path) -> None:
    path = tmp_path / "cam.yml"
    _write_reference(path, image_width=640, image_height=480, camera_matrix=K, distortion_coefficients=DIST,
                     R=np.eye(3), T=np.array([0.0125, -0.04, 0.65]))
    cam = read_opencv_calibration(path, unit="m")
    np.testing.assert_allclose(cam.T, [12.5, -40.0, 650.0], rtol=1e-15)
    assert cam.source_unit == "m"


@pytest.mark.parametrize("rotation", ["matrix", "rodrigues"])
@pytest.mark.parametrize("unit", ["mm", "cm"])
def test_write_then_read_round_trip(tmp_path: Path, rotation: str, unit: str) -> None:
    cam = Camera("c", K=K, distortion=np.arange(1, 15) * 1e-3, width=1384, height=1038,
                 R=cv2.Rodrigues(RVEC)[0], T=T_MM)
    path = tmp_path / "c.yml"
    write_opencv_calibration(path, cam, unit=unit, rotation=rotation)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # OpenCV reads what we wrote
    np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), K)
    np.testing.assert_allclose(fs.getNode("T").mat().ravel(), T_MM / (10 if unit == "cm" else 1), rtol=1e-15)
    fs.release()
    back = read_opencv_calibration(path, unit=unit)
    np.testing.assert_array_equal(back.K, cam.K)
    np.testing.assert_array_equal(back.distortion, cam.distortion)
    np.testing.assert_allclose(back.R, cam.R, atol=1e-14 if rotation == "rodrigues" else 0)
    np.testing.assert_allclose(back.T, cam.T, rtol=1e-15)
    assert [p.name for p in tmp_path.iterdir()] == ["c.yml"]


def test_camera_without_distortion_writes_five_zeros(tmp_path: Path) -> None:
    cam = Camera("c", K=K, distortion=[], width=64, height=48, R=np.eye(3), T=[0, 0, 1])
    write_opencv_calibration(tmp_path / "c.yml", cam)
    np.testing.assert_array_equal(read_opencv_calibration(tmp_path / "c.yml").distortion, np.zeros(5))


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ({"image_width": 640, "image_height": 480, "distortion_coefficients": DIST, "R": np.eye(3), "T": T_MM},
         "camera_matrix"),
        ({"image_width": 640, "image_height": 480, "camera_matrix": K, "distortion_coefficients": DIST,
          "T": T_MM}, "R \\(or rvec\\)"),
        ({"image_width": 640, "image_height": 480, "camera_matrix": K, "distortion_coefficients": DIST,
          "R": np.eye(3)}, "T \\(or tvec\\)"),
        ({"image_width": 640, "image_height": 480, "camera_matrix": K, "distortion_coefficients": DIST,
          "R": np.eye(3), "T": T_MM, "tvec": T_MM + 1}, "disagree"),
        ({"image_width": 640, "image_height": 480, "camera_matrix": K, "distortion_coefficients": DIST[:3],
          "R": np.eye(3), "T": T_MM}, "coefficients"),
        ({"image_width": 640, "image_height": 480, "camera_matrix": K, "distortion_coefficients": DIST,
          "R": np.ones((2, 2)), "T": T_MM}, "Rodrigues"),
    ],
)
def test_bad_calibration_files_name_the_file_and_key(tmp_path: Path, keys: dict, message: str) -> None:
    path = tmp_path / "bad.yml"
    _write_reference(path, **keys)
    with pytest.raises(FileFormatError, match=message) as info:
        read_opencv_calibration(path)
    assert str(path) in str(info.value)


def test_missing_or_garbage_file(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="not found"):
        read_opencv_calibration(tmp_path / "none.yml")
    garbage = tmp_path / "garbage.yml"
    garbage.write_bytes(b"\x00\x01 not yaml [")
    with pytest.raises(FileFormatError):
        read_opencv_calibration(garbage)


def test_write_refuses_unknown_suffix_and_leaves_nothing(tmp_path: Path) -> None:
    cam = Camera("c", K=K, distortion=[], width=64, height=48, R=np.eye(3), T=[0, 0, 1])
    with pytest.raises(InputError, match="expected one of"):
        write_opencv_calibration(tmp_path / "c.txt", cam)
    with pytest.raises(InputError, match="does not exist"):
        write_opencv_calibration(tmp_path / "missing" / "c.yml", cam)
    assert list(tmp_path.iterdir()) == []
