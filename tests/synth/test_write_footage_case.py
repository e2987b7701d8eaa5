"""write_footage_case: a take, a fine scan, calibrated footage of painted wrinkles and the truth, as a user gets them."""

import json

import cv2
import ezc3d
import numpy as np
import pytest

from facecap.cameras import read_camera_file
from facecap.errors import InputError
from facecap.io import read_mesh
from facecap.synth import generate_performance
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkle_scan import subdivide_scan
from facecap.synth.wrinkles import add_wrinkles, every_wrinkle_at_once, place_wrinkles
from facecap.synth.write_footage_case import (MOCAP_RATE_HZ, VIDEO_RATE_HZ, _render_frames, _render_mesh,
                                              write_footage_case)


@pytest.fixture(scope="module")
def footage(tmp_path_factory):
    folder = tmp_path_factory.mktemp("footage")
    files = write_footage_case(folder, n_frames=9, seed=2, levels=1, image_size=(346, 260), ao_rays=16, bits=16,
                               n_markers=30, render_edge_mm=0.6)
    return folder, files


def test_truth_round_trip_and_large_scale(footage):
    folder, files = footage
    case = generate_performance(n_frames=9, rate=MOCAP_RATE_HZ, n_markers=30, seed=2)
    fine = subdivide_scan(case.scan, levels=1)
    with np.load(files.truth) as truth:
        V, L, mask = truth["vertices"], truth["large_scale"], truth["wrinkle_mask"]
        n = fine.mesh.n_vertices
        assert V.shape == L.shape == (9, n, 3) and mask.shape == (n,) and mask.dtype == bool
        expected = np.stack([fine.upsample @ f for f in case.truth_vertices.astype(np.float64)])
        np.testing.assert_allclose(L, expected, atol=2e-5)
        np.testing.assert_array_equal(V[:, ~mask], L[:, ~mask])
        c, k = truth["curve_faces"].shape
        assert truth["curve_points"].shape == (9, c, k, 3) and truth["depths"].shape == (9, c, k)
        assert truth["widths"].shape == (9, c, k) and len(truth["curve_names"]) == c
        assert float(truth["rate"]) == MOCAP_RATE_HZ and float(truth["video_rate"]) == VIDEO_RATE_HZ
        np.testing.assert_allclose(truth["head_pose"], case.head_pose)
    scan = read_mesh(files.scan)
    np.testing.assert_allclose(scan.vertices, fine.mesh.vertices, atol=1e-5)
    np.testing.assert_array_equal(scan.faces, fine.mesh.faces)


def test_take_and_map_are_the_large_scale_markers(footage):
    folder, files = footage
    case = generate_performance(n_frames=9, rate=MOCAP_RATE_HZ, n_markers=30, seed=2)
    c3d = ezc3d.c3d(str(files.markers))  # an established reader
    points = c3d["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_allclose(points, np.nan_to_num(case.markers.positions, nan=np.nan), atol=1e-3, equal_nan=True)
    assert c3d["parameters"]["POINT"]["RATE"]["value"][0] == MOCAP_RATE_HZ
    assert json.loads(files.map.read_text()) == case.correspondence
    # the fine scan keeps each marker's vertex where the ICT scan had it
    scan = read_mesh(files.scan)
    for vertex in case.correspondence.values():
        np.testing.assert_allclose(scan.vertices[vertex], case.scan.vertices[vertex], atol=1e-5)


def test_calibration_files_project_the_truth_onto_its_paint(footage):
    folder, files = footage
    setup = read_camera_file(files.cameras)
    assert setup.video_rate_hz == VIDEO_RATE_HZ and setup.first_mocap_frame == 0
    with np.load(files.truth) as truth:
        curve0 = truth["curve_points"][0].reshape(-1, 3).astype(np.float64)
        pose = truth["mocap_from_scan"] @ truth["head_pose"][0]
        paint = truth["paint_index"]
        c, k = truth["curve_faces"].shape
    world = curve0 @ pose[:3, :3].T + pose[:3, 3]
    hits = 0
    for calibration, mask_path, video, cam in zip(files.calibrations, files.masks, files.videos, setup.cameras):
        fs = cv2.FileStorage(str(calibration), cv2.FILE_STORAGE_READ)  # OpenCV's own reader
        K, dist = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat().ravel()
        R, T = fs.getNode("R").mat(), fs.getNode("T").mat().ravel()
        size = (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
        fs.release()
        np.testing.assert_allclose(K, cam.K)
        assert size == (346, 260)
        uv = cv2.projectPoints(world[:, None], cv2.Rodrigues(R)[0], T, K, dist)[0].reshape(c, k, 2)
        mask = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
        assert mask.shape == (260, 346) and mask.dtype == np.uint8
        frames = sorted(video.glob("frame_*.png"))
        assert len(frames) == 3  # mocap frames 0, 4, 8 at a quarter of the rate
        image = cv2.imread(str(frames[0]), cv2.IMREAD_UNCHANGED)
        assert image.dtype == np.uint16 and image.shape == (260, 346, 3)
        for i in range(c):
            mid = np.rint(uv[i, k // 4 : 3 * k // 4]).astype(int)
            inside = (mid[:, 0] >= 0) & (mid[:, 0] < 346) & (mid[:, 1] >= 0) & (mid[:, 1] < 260)
            labels = mask[mid[inside, 1], mid[inside, 0]]
            seen = labels > 0  # the other camera may see this curve, or a fold may hide it
            hits += int(seen.sum())
            assert np.all(labels[seen] == paint[i] + 1)
    assert hits > 0.6 * 2 * c * (k // 2)


def test_offset_and_own_cameras(tmp_path, footage):
    _, files = footage
    setup = read_camera_file(files.cameras)
    one = setup.cameras[1]
    out = write_footage_case(tmp_path / "case", n_frames=9, seed=2, levels=1, ao_rays=8, n_markers=30,
                             first_mocap_frame=2, cameras=[one], render_edge_mm=None)
    assert [p.name for p in out.videos] == [one.name] and len(out.masks) == 1
    assert len(sorted(out.videos[0].glob("frame_*.png"))) == 2  # mocap frames 2 and 6
    again = read_camera_file(out.cameras)
    assert again.first_mocap_frame == 2 and again.cameras[0].name == one.name
    np.testing.assert_allclose(again.cameras[0].K, one.K)
    assert json.loads(out.footage.read_text())["first_mocap_frame"] == 2


def test_bad_options_write_nothing(tmp_path):
    for options, message in (({"bits": 12}, "bits"), ({"image_size": (100,)}, "image_size"),
                             ({"image_size": (8, 8)}, "image_size"), ({"ao_rays": 0}, "ao_rays"),
                             ({"render_edge_mm": 0.0}, "render_edge_mm"), ({"render_edge_mm": "fine"}, "render_edge_mm"),
                             ({"first_mocap_frame": 4}, "first_mocap_frame"), ({"cameras": []}, "cameras")):
        with pytest.raises(InputError, match=message):
            write_footage_case(tmp_path / "case", n_frames=2, **options)
    assert not (tmp_path / "case").exists() or not any((tmp_path / "case").iterdir())


def test_the_footage_is_rendered_from_a_surface_that_holds_the_truth_wrinkles():
    """The rendered mesh: the truth's own vertices where the scan has them, the truth's valley bottoms on it.

    The scan's vertices sample the analytic wrinkles (``truth.npz``); rendered as they are, a valley a
    few vertices wide misses its own bottom and shades shallower. The footage's mesh is the scan refined
    around the wrinkles with their heights evaluated at the new vertices: the truth's valley line
    (``curve_points``, depth ``d`` below the large scale) must lie on it.
    """
    import igl

    sample = load_ict_sample()
    case = generate_performance(n_frames=5, rate=MOCAP_RATE_HZ, seed=0, sample=sample,
                                curves=every_wrinkle_at_once(5, sample.expression_names))
    fine = subdivide_scan(case.scan, levels=2)
    large = np.stack([fine.upsample @ f for f in case.truth_vertices.astype(np.float64)]).astype(np.float32)
    curves = place_wrinkles(fine.mesh, sample, seed=0)
    wrinkled = add_wrinkles(large, fine.mesh.faces, curves, case.weights, rest=fine.mesh.vertices)
    render = _render_mesh(fine, wrinkled.mask, 0.3)
    V = _render_frames(render, fine.mesh.faces, large, wrinkled.vertices, curves, wrinkled.activation,
                       np.array([4]))(4)
    n = fine.mesh.n_vertices
    np.testing.assert_array_equal(V[:n], wrinkled.vertices[4])
    deep = wrinkled.depths[4] >= 0.3
    bottoms = wrinkled.curve_points[4][deep].astype(np.float64)
    assert deep.sum() > 100
    on_render = np.sqrt(igl.point_mesh_squared_distance(bottoms, V, render.mesh.faces)[0])
    on_scan = np.sqrt(igl.point_mesh_squared_distance(bottoms, wrinkled.vertices[4].astype(np.float64),
                                                      fine.mesh.faces)[0])
    depth = wrinkled.depths[4][deep]
    assert np.median(on_render / depth) < 0.01  # measured 0.002
    assert np.percentile(on_render, 90) < 0.01  # mm; measured 0.003
    assert np.median(on_scan) > 5 * np.median(on_render)  # the scan itself: 0.022 mm (5 % of the depth)
