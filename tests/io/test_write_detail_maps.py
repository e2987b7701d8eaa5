"""write_detail_maps: EXR and 16-bit PNG round trips through read_image, the header's unit, maps.json."""

import json

import numpy as np
import pytest

from facecap.cameras import read_image
from facecap.errors import InputError
from facecap.io.write_detail_maps import detail_map_names, write_detail_maps, write_maps_index


def test_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    displacement = rng.normal(scale=0.2, size=(32, 32)).astype(np.float32)
    normal = rng.integers(0, 65536, size=(32, 32, 3)).astype(np.uint16)
    exr, png = write_detail_maps(tmp_path, 7, displacement, normal, mocap_frame=12.5)
    assert (exr.name, png.name) == detail_map_names(7) == ("displacement_000007.exr", "normal_000007.png")
    back = read_image(exr)
    assert back.dtype == np.float32 and np.array_equal(back, displacement)
    back = read_image(png)
    assert back.dtype == np.uint16 and np.array_equal(back, normal)  # RGB order kept
    import OpenEXR

    with OpenEXR.File(str(exr)) as f:
        header = dict(f.header())
    assert header["unit"] == "mm" and header["facecapVideoFrame"] == 7 and header["facecapMocapFrame"] == 12.5
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(detail_map_names(7))  # no temporary left


def test_index_lists_frames_units_and_conventions(tmp_path):
    path = write_maps_index(tmp_path, size=64, video_frames=[0, 1], mocap_frames=[3.0, 3.5], padding=4)
    document = json.loads(path.read_text())
    assert document["size"] == 64 and document["displacement"]["units"] == "mm"
    assert "OpenGL" in document["normal"]["convention"]
    assert [f["normal"] for f in document["frames"]] == ["normal_000000.png", "normal_000001.png"]
    assert document["frames"][1]["mocap_frame"] == 3.5


def test_bad_maps_are_refused_and_leave_nothing(tmp_path):
    with pytest.raises(InputError, match="normal_map"):
        write_detail_maps(tmp_path, 0, np.zeros((8, 8), np.float32), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(InputError, match="displacement"):
        write_detail_maps(tmp_path, 0, np.full((8, 8), np.nan, np.float32), np.zeros((8, 8, 3), np.uint16))
    assert list(tmp_path.iterdir()) == []
