"""The facecap camera file: exact round trip, units, the documented schema, clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from facecap.cameras import CAMERA_FILE_FORMAT, Camera, CameraSetup, read_camera_file, write_camera_file
from facecap.errors import FileFormatError, InputError


def _setup() -> CameraSetup:
    rng = np.random.default_rng(7)
    cameras = []
    for i, n in enumerate((5, 14)):
        R = cv2.Rodrigues(rng.normal(0, 0.4, 3))[0]
        K = [[2400.0 + i, 0.0, 691.5], [0.0, 2410.0, 518.5], [0.0, 0.0, 1.0]]
        cameras.append(Camera(f"cam{i}", K=K, distortion=rng.normal(0, 0.01, n), width=1384, height=1038,
                              R=R, T=rng.normal(0, 100, 3)))
    return CameraSetup(tuple(cameras), video_rate_hz=12.5, first_mocap_frame=-2)


def test_round_trip_is_bit_exact(tmp_path: Path) -> None:
    setup = _setup()
    write_camera_file(tmp_path / "cameras.json", setup)
    back = read_camera_file(tmp_path / "cameras.json")
    assert back.names == ("cam0", "cam1")
    assert back.video_rate_hz == 12.5 and back.first_mocap_frame == -2.0 and back.source_unit == "mm"
    for a, b in zip(setup.cameras, back.cameras):
        for attr in ("K", "distortion", "R", "T"):
            np.testing.assert_array_equal(getattr(a, attr), getattr(b, attr))
        assert (a.width, a.height) == (b.width, b.height)
    assert [p.name for p in tmp_path.iterdir()] == ["cameras.json"]


def test_file_follows_the_documented_schema(tmp_path: Path) -> None:
    write_camera_file(tmp_path / "cameras.json", _setup(), unit="m")
    document = json.loads((tmp_path / "cameras.json").read_text())
    assert document["format"] == CAMERA_FILE_FORMAT and document["version"] == 1 and document["unit"] == "m"
    assert document["footage"] == {"rate_hz": 12.5, "first_mocap_frame": -2.0}
    entry = document["cameras"][0]
    assert set(entry) == {"name", "image_width", "image_height", "camera_matrix", "distortion_coefficients", "R", "T"}
    np.testing.assert_allclose(np.array(entry["T"]) * 1000, _setup().cameras[0].T, rtol=1e-15)
    back = read_camera_file(tmp_path / "cameras.json")
    np.testing.assert_allclose(back.cameras[0].T, _setup().cameras[0].T, rtol=1e-15)
    assert back.source_unit == "m"


def test_hand_written_file_with_rodrigues_rotation(tmp_path: Path) -> None:
    rvec = [0.1, -0.2, 0.05]
    document = {"format": "facecap-cameras", "version": 1, "unit": "cm",
                "footage": {"rate_hz": 12.5, "first_mocap_frame": 0},
                "cameras": [{"name": "left", "image_width": 640, "image_height": 480,
                             "camera_matrix": [[800, 0, 319.5], [0, 800, 239.5], [0, 0, 1]],
                             "distortion_coefficients": [0.01, 0, 0, 0], "R": rvec, "T": [1, 2, 60]}]}
    (tmp_path / "c.json").write_text(json.dumps(document))
    cam = read_camera_file(tmp_path / "c.json").camera("left")
    np.testing.assert_allclose(cam.R, cv2.Rodrigues(np.array(rvec))[0], atol=1e-15)
    np.testing.assert_allclose(cam.T, [10.0, 20.0, 600.0])


def test_setup_synchronizes_with_its_rate_and_offset() -> None:
    sync = _setup().synchronize(50.0, 100, 27)
    assert sync.ratio == 4.0 and sync.mocap_frame(1) == 2.0
    with pytest.raises(InputError, match="footage shorter than the take"):
        _setup().synchronize(50.0, 200, 27, footage_name="cam0")
    with pytest.raises(InputError, match="no footage rate"):
        CameraSetup(_setup().cameras).synchronize(50.0, 100, 25)


def test_setup_validation() -> None:
    cams = _setup().cameras
    with pytest.raises(InputError, match="distinct"):
        CameraSetup((cams[0], cams[0]))
    with pytest.raises(InputError, match="at least one"):
        CameraSetup(())
    with pytest.raises(InputError, match="positive"):
        CameraSetup(cams, video_rate_hz=0)
    with pytest.raises(InputError, match="no camera named 'x'"):
        CameraSetup(cams).camera("x")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(format="something"), "not a facecap camera file"),
        (lambda d: d.update(version=99), "version 99"),
        (lambda d: d["cameras"][0].pop("T"), r"cameras\[0\]: missing \['T'\]"),
        (lambda d: d["cameras"][0].update(R=[[1, 0], [0, 1]]), r"cameras\[0\]\.R"),
        (lambda d: d["cameras"][1].update(name="cam0"), "distinct"),
        (lambda d: d.update(unit="furlong"), "unit"),
        (lambda d: d["cameras"][0].update(distortion_coefficients=[1, 2]), "coefficients"),
        (lambda d: d.update(cameras=[]), "non-empty"),
    ],
)
def test_bad_files_raise_file_format_error_naming_the_file(tmp_path: Path, edit, message: str) -> None:
    write_camera_file(tmp_path / "cameras.json", _setup())
    document = json.loads((tmp_path / "cameras.json").read_text())
    edit(document)
    (tmp_path / "cameras.json").write_text(json.dumps(document))
    with pytest.raises(FileFormatError, match=message) as info:
        read_camera_file(tmp_path / "cameras.json")
    assert str(tmp_path / "cameras.json") in str(info.value)


def test_not_json_and_missing(tmp_path: Path) -> None:
    (tmp_path / "c.json").write_text("{not json")
    with pytest.raises(FileFormatError, match="not a JSON file"):
        read_camera_file(tmp_path / "c.json")
    with pytest.raises(FileFormatError, match="not found"):
        read_camera_file(tmp_path / "none.json")
