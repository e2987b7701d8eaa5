"""write_image_sequence: frames read back exactly by open_footage, an earlier sequence replaced whole, other files kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from facecap.cameras import SEQUENCE_FILE, open_footage, write_image_sequence
from facecap.errors import InputError
from footage_frames import FRAMES_8, FRAMES_16


@pytest.mark.parametrize(
    ("suffix", "frames"),
    [(".png", FRAMES_8[:6]), (".png", FRAMES_16[:6]), (".tif", FRAMES_16[:4]),
     (".exr", np.random.default_rng(12).random((5, 37, 61, 3), dtype=np.float32)), (".png", FRAMES_16[:5, :, :, 0])],
    ids=["png8", "png16", "tif16", "exr", "png16-grey"],
)
def test_image_sequence_round_trip_exact(tmp_path: Path, suffix: str, frames: np.ndarray) -> None:
    folder = tmp_path / "cam0"
    write_image_sequence(folder, frames, suffix=suffix)
    assert (folder / SEQUENCE_FILE).is_file()
    with open_footage(folder) as footage:
        assert (footage.kind, footage.n_frames, footage.width, footage.height) == ("images", len(frames), 61, 37)
        assert footage.dtype == frames.dtype and footage.rate_hz is None
        np.testing.assert_array_equal(np.stack(list(footage)), frames)
        np.testing.assert_array_equal(footage.frame(-1), frames[-1])
    assert [p.name for p in tmp_path.iterdir()] == ["cam0"]


def test_sequence_folder_replaces_an_earlier_sequence_but_not_other_files(tmp_path: Path) -> None:
    folder = tmp_path / "cam0"
    write_image_sequence(folder, FRAMES_8[:3])
    write_image_sequence(folder, FRAMES_8[3:5])  # an earlier sequence is replaced whole
    with open_footage(folder) as footage:
        assert footage.n_frames == 2
        np.testing.assert_array_equal(footage.frame(1), FRAMES_8[4])
    other = tmp_path / "photos"
    other.mkdir()
    (other / "holiday.jpg").write_bytes(b"keep me")
    with pytest.raises(InputError, match="never replaces it"):
        write_image_sequence(other, FRAMES_8[:2])
    assert [p.name for p in other.iterdir()] == ["holiday.jpg"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam0", "photos"]


def test_a_ragged_sequence_is_refused_and_leaves_nothing(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="every frame must match"):
        write_image_sequence(tmp_path / "seq", [FRAMES_8[0], FRAMES_8[1, :10]])
    assert list(tmp_path.iterdir()) == []
