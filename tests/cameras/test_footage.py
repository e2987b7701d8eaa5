"""open_footage: image sequences by folder, pattern or glob, videos (H.264, MJPEG from PyAV); random access; bad input."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np
import pytest

from facecap.cameras import open_footage, write_image, write_image_sequence, write_video
from facecap.errors import FileFormatError, InputError
from footage_frames import FRAMES_8


def test_sequence_by_pattern_glob_and_numbering_from_one(tmp_path: Path) -> None:
    for i in range(1, 5):  # frame numbers 1..4, as many cameras write them
        write_image(tmp_path / f"shot.{i:04d}.png", FRAMES_8[i])
    (tmp_path / "notes.txt").write_text("not an image")
    for path in (tmp_path, tmp_path / "shot.%04d.png", tmp_path / "shot.*.png"):
        footage = open_footage(path)
        assert footage.n_frames == 4 and footage.first_number == 1
        np.testing.assert_array_equal(footage.frame(0), FRAMES_8[1])
        np.testing.assert_array_equal(footage[3], FRAMES_8[4])


def test_numbers_sort_numerically_not_as_text(tmp_path: Path) -> None:
    for i in (8, 9, 10, 11):  # "10" < "8" as text
        write_image(tmp_path / f"f{i}.png", FRAMES_8[i])
    footage = open_footage(tmp_path)
    np.testing.assert_array_equal(np.stack(list(footage)), FRAMES_8[8:12])


def test_mp4_h264_is_read_at_its_true_size(tmp_path: Path) -> None:
    u, v = np.meshgrid(np.arange(62), np.arange(38))
    frames = np.stack([np.stack([u * 3 + t, v * 5, (u + v + 2 * t) % 256], -1) for t in range(30)]).astype(np.uint8)
    write_video(tmp_path / "cam.mp4", frames, rate_hz=25.0)
    with open_footage(tmp_path / "cam.mp4") as footage:
        assert (footage.n_frames, footage.width, footage.height, footage.rate_hz) == (30, 62, 38, 25.0)
        decoded = np.stack(list(footage)).astype(int)
        assert np.abs(decoded - frames).mean() < 3.0  # lossy, but the same picture
        np.testing.assert_array_equal(footage.frame(29), decoded[29])  # a seek gives the decoded frame
        np.testing.assert_array_equal(footage.frame(2), decoded[2])


def test_bad_footage(tmp_path: Path) -> None:
    folder = tmp_path / "gap"
    folder.mkdir()
    for i in (0, 1, 3):
        write_image(folder / f"f{i}.png", FRAMES_8[i])
    with pytest.raises(FileFormatError, match=r"frames missing from the sequence: \[2\]"):
        open_footage(folder)
    (folder / "f2.jpg").write_bytes(b"")
    with pytest.raises(FileFormatError, match="mixes image types"):
        open_footage(folder)
    with pytest.raises(FileFormatError, match="not found"):
        open_footage(tmp_path / "none.mp4")
    (tmp_path / "fake.mp4").write_bytes(b"not a video at all")
    with pytest.raises(FileFormatError, match="cannot open it as a video"):
        open_footage(tmp_path / "fake.mp4")
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    write_image(mixed / "f0.png", FRAMES_8[0])
    write_image(mixed / "f1.png", FRAMES_8[1, :10])
    footage = open_footage(mixed)
    with pytest.raises(FileFormatError, match="every frame of a sequence must match"):
        footage.frame(1)
    with pytest.raises(InputError, match="out of range"):
        footage.frame(2)


def test_check_camera_names_both_sizes(tmp_path: Path) -> None:
    from facecap.cameras import Camera

    write_image_sequence(tmp_path / "cam0", FRAMES_8[:2])  # 61 x 37
    footage = open_footage(tmp_path / "cam0")
    K = [[100.0, 0.0, 30.0], [0.0, 100.0, 18.0], [0.0, 0.0, 1.0]]
    footage.check_camera(Camera("cam0", K=K, distortion=[], width=61, height=37, R=np.eye(3), T=[0, 0, 1]))
    with pytest.raises(InputError, match=r"footage is 61x37 but camera 'big' is calibrated for 122x74 .*scaled by 0.5"):
        footage.check_camera(Camera("big", K=K, distortion=[], width=122, height=74, R=np.eye(3), T=[0, 0, 1]))
    with pytest.raises(InputError, match="swapped"):
        footage.check_camera(Camera("rot", K=K, distortion=[], width=37, height=61, R=np.eye(3), T=[0, 0, 1]))


def test_full_range_mjpeg_written_by_pyav_keeps_its_colours(tmp_path: Path) -> None:
    image = np.zeros((32, 48, 3), np.uint8)
    image[...] = (200, 100, 50)
    image[:, :16] = (20, 240, 130)
    with av.open(str(tmp_path / "cam.avi"), "w") as container:  # the reference writer: PyAV itself
        stream = container.add_stream("mjpeg", rate=25)
        stream.width, stream.height, stream.pix_fmt = 48, 32, "yuvj420p"
        for _ in range(3):
            for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    with open_footage(tmp_path / "cam.avi") as footage:
        assert footage.n_frames == 3 and footage.rate_hz == 25.0
        frame = footage.frame(2).astype(int)
    # away from the colour edge (chroma is subsampled), within JPEG's rounding: full range kept, not squeezed
    assert np.abs(frame[:, 28:] - [200, 100, 50]).max() <= 4
    assert np.abs(frame[:, :8] - [20, 240, 130]).max() <= 4
