"""``correspondence.npz``: written and read back exactly; damaged files are format errors naming the file."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import FileFormatError
from facecap.io import read_mocap_correspondence, write_mocap_correspondence


def _points(k: int = 6) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    mocap = rng.normal(scale=50.0, size=(k, 3))
    return mocap, mocap + np.array([1.0, -2.0, 900.0])


def test_round_trip_is_exact_and_numpy_reads_it(tmp_path):
    mocap, face = _points()
    motion = np.tile(np.eye(4), (5, 1, 1))
    motion[:, 0, 3] = np.arange(5.0)
    path = tmp_path / "correspondence.npz"
    write_mocap_correspondence(path, mocap, face, [f"m{i}" for i in range(6)], mocap_from_stabilized=motion)
    back = read_mocap_correspondence(path)
    assert np.array_equal(back["mocap_points"], mocap) and np.array_equal(back["face_points"], face)
    assert np.array_equal(back["mocap_from_stabilized"], motion) and back["labels"].tolist() == [f"m{i}" for i in range(6)]
    with np.load(path) as data:  # a plain npz archive, no pickles
        assert str(data["units"]) == "mm"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["correspondence.npz"]  # nothing left beside it


def test_an_unstabilised_result_has_no_motion(tmp_path):
    mocap, face = _points()
    write_mocap_correspondence(tmp_path / "c.npz", mocap, face, list("abcdef"))
    assert "mocap_from_stabilized" not in read_mocap_correspondence(tmp_path / "c.npz")


@pytest.mark.parametrize("arrays, match", [
    ({"face_points": np.zeros((6, 3))}, "lacks mocap_points"),
    ({"mocap_points": np.zeros((6, 3)), "face_points": np.zeros((5, 3))}, "same"),
    ({"mocap_points": np.zeros((3, 3)), "face_points": np.zeros((3, 3))}, "K >= 4"),
    ({"mocap_points": np.full((6, 3), np.nan), "face_points": np.zeros((6, 3))}, "finite"),
    ({"mocap_points": np.zeros((6, 3)), "face_points": np.zeros((6, 3)), "mocap_from_stabilized": np.zeros((4, 4))},
     "mocap_from_stabilized"),
    ({"mocap_points": np.zeros((6, 3)), "face_points": np.zeros((6, 3)),
      "mocap_from_stabilized": np.full((2, 4, 4), np.nan)}, "mocap_from_stabilized"),
    ({"mocap_points": np.full((6, 3), "x"), "face_points": np.zeros((6, 3))}, "numbers"),
    ({"mocap_points": np.zeros((6, 3)), "face_points": np.zeros((6, 3)), "units": np.asarray("cm")}, "units"),
])
def test_damaged_archives_name_the_file_and_the_problem(tmp_path, arrays, match):
    path = tmp_path / "correspondence.npz"
    np.savez(path, **arrays)
    with pytest.raises(FileFormatError, match=match) as caught:
        read_mocap_correspondence(path)
    assert "correspondence.npz" in str(caught.value)


def test_not_an_archive_empty_truncated_or_missing(tmp_path):
    (tmp_path / "text.npz").write_text("not a zip")
    (tmp_path / "empty.npz").write_bytes(b"")
    mocap, face = _points()
    write_mocap_correspondence(tmp_path / "whole.npz", mocap, face, list("abcdef"))
    (tmp_path / "half.npz").write_bytes((tmp_path / "whole.npz").read_bytes()[:300])  # a half-copied file
    (tmp_path / "zipped.npz").write_bytes(b"PK" + b"\x00" * 40)
    for name in ("text.npz", "empty.npz", "half.npz", "zipped.npz"):
        with pytest.raises(FileFormatError, match=name):
            read_mocap_correspondence(tmp_path / name)
    with pytest.raises(FileFormatError, match="gone.npz"):
        read_mocap_correspondence(tmp_path / "gone.npz")


def test_the_writer_refuses_what_it_could_not_read_back(tmp_path):
    mocap, face = _points()
    with pytest.raises(ValueError):
        write_mocap_correspondence(tmp_path / "c.npz", mocap, face[:5], list("abcdef"))
    with pytest.raises(ValueError):
        write_mocap_correspondence(tmp_path / "c.npz", mocap, face, list("abcdef"), mocap_from_stabilized=np.eye(4))
    with pytest.raises(ValueError, match="K >= 4"):
        write_mocap_correspondence(tmp_path / "c.npz", mocap[:3], face[:3], list("abc"))
    with pytest.raises(ValueError, match="finite"):
        write_mocap_correspondence(tmp_path / "c.npz", mocap, face, list("abcdef"),
                                   mocap_from_stabilized=np.full((3, 4, 4), np.nan))
    with pytest.raises(ValueError, match="labels"):
        write_mocap_correspondence(tmp_path / "c.npz", mocap, face, list("abc"))
    assert not list(tmp_path.iterdir())
