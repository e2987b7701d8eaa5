"""capture_detail's maps: write_detail_frame_maps on a quad scan with face-varying UVs, and on one without UVs."""

import json

import numpy as np

from facecap.cameras import read_image
from facecap.pipelines.capture_detail import write_detail_frame_maps
from facecap.structures import Mesh


def quad_scan(k=6, L=30.0, uvs=True):
    x = np.linspace(0, L, k)
    X, Y = np.meshgrid(x, x)
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(k * k)], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    quads = np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], 1)
    corners = quads.ravel()
    faces = np.stack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1).reshape(-1, 3)  # fan order per polygon
    extra = {}
    if uvs:
        # face-varying: every polygon corner its own UV (one island per vertex grid, the same coordinates)
        extra = dict(uvs=0.1 + 0.8 * V[corners, :2] / L, uv_indices=np.arange(corners.size))
    return Mesh(V, faces, polygon_sizes=np.full(len(quads), 4), polygon_indices=corners, **extra)


def test_maps_follow_the_heights_per_video_frame(tmp_path):
    mesh = quad_scan()
    region = np.arange(mesh.n_vertices)
    heights = np.stack([0.01 * mesh.vertices[:, 0], 0.02 * mesh.vertices[:, 1]]).astype(np.float32)
    record = write_detail_frame_maps(tmp_path / "maps", mesh, heights, region, lambda j: mesh.vertices,
                                     np.array([4.0, 4.5]), map_size=32)
    assert record["size"] == 32 and record["ms_per_frame"] > 0
    index = json.loads((tmp_path / "maps" / "maps.json").read_text())
    assert [f["mocap_frame"] for f in index["frames"]] == [4.0, 4.5]
    d1 = read_image(tmp_path / "maps" / "displacement_000001.exr")
    # texel row i: v = 1 - (i + 0.5) / 32, y = (v - 0.1) / 0.8 * 30; a middle row
    i = 16
    y = ((1 - (i + 0.5) / 32) - 0.1) / 0.8 * 30
    np.testing.assert_allclose(d1[i, 8:24], 0.02 * y, atol=1e-5)
    n0 = read_image(tmp_path / "maps" / "normal_000000.png") / 65535.0 * 2 - 1
    np.testing.assert_allclose(n0[16, 16], np.array([-0.01, 0, 1]) / np.sqrt(1.0001), atol=1e-4)


def test_no_maps_without_uvs_or_with_size_zero(tmp_path):
    mesh = quad_scan(uvs=False)
    heights = np.zeros((1, mesh.n_vertices), np.float32)
    record = write_detail_frame_maps(tmp_path / "maps", mesh, heights, np.arange(mesh.n_vertices),
                                     lambda j: mesh.vertices, np.zeros(1), map_size=32)
    assert "no UVs" in record["none"] and not (tmp_path / "maps").exists()
    record = write_detail_frame_maps(tmp_path / "maps", quad_scan(), heights, np.arange(mesh.n_vertices),
                                     lambda j: mesh.vertices, np.zeros(1), map_size=0)
    assert "0" in record["none"] and not (tmp_path / "maps").exists()


def test_a_transfer_against_the_pixel_type_is_flagged():
    import numpy as np

    from facecap.pipelines.capture_detail import _transfer_doubt

    eight, sixteen = np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 3), np.uint16)
    assert _transfer_doubt(eight, "auto", "cam") is None
    assert _transfer_doubt(eight, "srgb", "cam") is None and _transfer_doubt(sixteen, "linear", "cam") is None
    assert "8-bit footage read as linear" in _transfer_doubt(eight, "linear", "cam_left")
    assert "usually linear" in _transfer_doubt(sixteen, "srgb", "cam_left")


def test_a_bilateral_length_that_is_not_one_is_refused_before_anything_is_read_or_written(tmp_path):
    import pytest

    from facecap.errors import InputError
    from facecap.pipelines import capture_detail

    for bad in (0.0, -0.3, float("nan")):
        with pytest.raises(InputError, match="bilateral_mm"):
            capture_detail(tmp_path / "no-such-result", [], [], None, tmp_path / "out", video_rate_hz=25.0,
                           bilateral_mm=bad)
    assert not (tmp_path / "out").exists()
