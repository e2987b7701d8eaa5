"""write_video: lossless videos that FFmpeg (PyAV) sees as meant and open_footage reads back exactly; bad frames refused."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np
import pytest

from facecap.cameras import open_footage, write_video
from facecap.errors import InputError
from footage_frames import FRAMES_8, FRAMES_16


@pytest.mark.parametrize(
    ("suffix", "frames"),
    [(".mkv", FRAMES_8), (".mkv", FRAMES_16), (".mkv", FRAMES_8[:10, :, :, 0]), (".mov", FRAMES_8[:10]),
     (".mov", FRAMES_16[:6]), (".avi", FRAMES_8[:10])],
    ids=["mkv-ffv1-8", "mkv-ffv1-16", "mkv-ffv1-grey", "mov-png-8", "mov-png-16", "avi-ffv1"],
)
def test_lossless_video_round_trip_exact(tmp_path: Path, suffix: str, frames: np.ndarray) -> None:
    path = tmp_path / f"cam0{suffix}"
    write_video(path, frames, rate_hz=12.5)
    with av.open(str(path)) as container:  # FFmpeg itself sees the stream we meant
        stream = container.streams.video[0]
        assert (stream.codec_context.width, stream.codec_context.height) == (61, 37)
        assert stream.average_rate == 12.5
    with open_footage(path) as footage:
        assert (footage.kind, footage.n_frames, footage.width, footage.height) == ("video", len(frames), 61, 37)
        assert footage.rate_hz == 12.5 and footage.dtype == frames.dtype
        decoded = np.stack(list(footage))
        np.testing.assert_array_equal(decoded, frames)
        for i in (len(frames) - 1, 3, 0, len(frames) // 2, 1):  # backward and forward jumps
            np.testing.assert_array_equal(footage.frame(i), frames[i])
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_bad_frames_are_refused_and_leave_nothing(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="every frame must match"):
        write_video(tmp_path / "v.mkv", [FRAMES_8[0], FRAMES_16[0]], rate_hz=12.5)
    with pytest.raises(InputError, match="no frame"):
        write_video(tmp_path / "v.mkv", [], rate_hz=12.5)
    with pytest.raises(InputError, match="uint8 or uint16"):
        write_video(tmp_path / "v.mkv", FRAMES_8.astype(np.float32), rate_hz=12.5)
    with pytest.raises(InputError, match="even width and height"):
        write_video(tmp_path / "v.mp4", FRAMES_8[:2], rate_hz=12.5)
    with pytest.raises(InputError, match="cannot hold 16-bit"):
        write_video(tmp_path / "v.mp4", FRAMES_16[:2, :36, :60], rate_hz=12.5)
    assert list(tmp_path.iterdir()) == []
