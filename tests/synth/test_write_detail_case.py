"""write_detail_case: the detail layer's footage and truth, read back with the project's readers."""

import json

import numpy as np
import pytest

from facecap.cameras import open_footage, read_camera_file, read_light_file
from facecap.errors import InputError
from facecap.io import read_mesh
from facecap.io.ict_sample import load_ict_sample
from facecap.mesh.vertex_normals import vertex_normals
from facecap.synth import generate_performance
from facecap.synth.studio_lights import studio_lights
from facecap.synth.wrinkles import every_wrinkle_at_once
from facecap.synth.write_detail_case import MARKER_RADIUS_MM, write_detail_case

N_FRAMES = 5


def _case():
    sample = load_ict_sample()
    curves = every_wrinkle_at_once(N_FRAMES, sample.expression_names, from_frame=2, weight=0.9)
    return generate_performance(n_frames=N_FRAMES, rate=50.0, n_markers=30, seed=4, curves=curves, sample=sample)


@pytest.fixture(scope="module")
def detail(tmp_path_factory):
    folder = tmp_path_factory.mktemp("detail")
    files = write_detail_case(folder, case=_case(), seed=4, levels=1, detail_edge_mm=0.8, image_size=(692, 519),
                              ao_rays=4)
    return folder, files


def test_truth_detail_is_the_height_along_the_normal_of_the_face_without_it(detail):
    _, files = detail
    scan = read_mesh(files.scan)
    with np.load(files.truth) as truth:
        G, L, h, mask = truth["vertices"], truth["without_detail"], truth["detail_height"], truth["detail_mask"]
        n = scan.n_vertices
        assert G.shape == L.shape == (N_FRAMES, n, 3) and h.shape == (N_FRAMES, n) and mask.shape == (n,)
        np.testing.assert_array_equal(G[:, ~mask], L[:, ~mask])
        assert np.all(h[:, ~mask] == 0) and np.all(h[:2] == 0)  # neutral until frame 2
        normals = vertex_normals(L.astype(np.float64), scan.faces)
        along = np.einsum("tnd,tnd->tn", (G - L).astype(np.float64), normals)
        np.testing.assert_allclose(along, h, atol=2e-5)
        assert 0.02 < -h.min() <= 0.3  # the lines' depths
        # the static texture is in the scan itself: the neutral frame without detail is the scan
        np.testing.assert_allclose(L[0], scan.vertices, atol=1e-4)
        texture = truth["texture_height"]
        assert 0.005 < texture.std() < 0.02
        np.testing.assert_array_equal(truth["video_mocap_frames"], [0, 2, 4])
        assert float(truth["video_rate"]) == 25.0
        for name in ("marker_mask", "freckle_mask", "mole_mask", "brow_mask"):
            assert truth[name].shape == (n,) and truth[name].any()
        assert not (mask & truth["brow_mask"]).all()
        assert truth["albedo"].shape == (n, 3) and truth["reflectance"].shape == (n, 3)
        # the flush comes with the smile (lagging it), and reddens: less green than red is taken
        assert truth["flush_level"][0] == 0 and truth["flush_level"][-1] > truth["flush_level"][2] > 0
    # the refinement: every triangle within the lines' reach has edges of at most the detail edge
    inside = mask[scan.faces].all(axis=1)
    V = scan.vertices[scan.faces[inside]]
    assert np.linalg.norm(V - np.roll(V, 1, axis=1), axis=2).max() <= 0.8 + 1e-9


def test_case_reads_back_with_the_projects_readers(detail):
    folder, files = detail
    scan = read_mesh(files.scan)
    assert scan.uvs is not None and scan.uv_indices.shape == (3 * scan.n_faces,)
    sample = load_ict_sample()
    np.testing.assert_allclose(scan.uvs[: sample.mesh.uvs.shape[0]], sample.mesh.uvs, atol=1e-9)
    setup = read_camera_file(files.cameras)
    assert setup.video_rate_hz == 25.0 and setup.first_mocap_frame == 0
    case = _case()
    lights = read_light_file(files.lights)
    expected = studio_lights(case.scan.vertices, sample.landmarks, case.mocap_from_scan)
    assert [l.kind for l in lights.lights] == ["spot", "point"] and lights.ambient == expected.ambient
    for got, want in zip(lights.lights, expected.lights):
        np.testing.assert_allclose(got.position, want.position, atol=1e-6)
        assert 1000.0 < np.linalg.norm(got.position - case.mocap_from_scan[:3, 3]) < 1700.0
    footage = open_footage(files.videos[0])
    assert len(footage) == 3
    meta = json.loads(files.footage.read_text())
    assert meta["appearance"] == "phong" and meta["video_every"] == 2


def test_markers_appear_where_they_project(detail):
    _, files = detail
    case = _case()
    setup = read_camera_file(files.cameras)
    with np.load(files.truth) as truth:
        G0 = truth["vertices"][0].astype(np.float64)
    scan = read_mesh(files.scan)
    normals = vertex_normals(G0, scan.faces, case.marker_vertices) @ case.mocap_from_scan[:3, :3].T
    centres = case.noiseless_markers[0, : case.n_face_markers]
    checked = 0
    for cam, video in zip(setup.cameras, files.videos):
        image = open_footage(video)[0].astype(np.float64)
        at = cam.project(centres)
        facing = np.einsum("kd,kd->k", normals, cam.centre - centres) > 0.5 * np.linalg.norm(cam.centre - centres, axis=1)
        radius = cam.K[0, 0] * MARKER_RADIUS_MM / at.depth
        for (u, v), r, ok in zip(at.pixels, radius, facing & at.in_image):
            if not ok:
                continue
            centre = image[int(round(v)), int(round(u)), 2]
            ring = [image[int(round(v + (r + 3) * np.sin(a))), int(round(u + (r + 3) * np.cos(a))), 2]
                    for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]
            assert centre > 1.5 * np.median(ring)  # white on skin: blue is what skin lacks
            checked += 1
    assert checked >= 20


def test_bad_options():
    with pytest.raises(InputError, match="appearance"):
        write_detail_case("unused", appearance="lambert")
    with pytest.raises(InputError, match="first_mocap_frame"):
        write_detail_case("unused", video_every=2, first_mocap_frame=2)


def test_the_independent_appearance_has_its_own_lights_model_and_lines(tmp_path):
    files = write_detail_case(tmp_path, case=_case(), seed=4, levels=1, detail_edge_mm=None, image_size=(96, 72),
                              ao_rays=2, appearance="independent", markers_drawn=False)
    lights = read_light_file(files.lights)
    assert [l.kind for l in lights.lights] == ["spot", "directional", "point"]
    meta = json.loads(files.footage.read_text())
    assert meta["appearance"] == "independent" and meta["reflectance_columns"][2] == "roughness"
    with np.load(files.truth) as truth:
        assert str(truth["appearance"]) == "independent"
        assert truth["detail_height"].max() <= 0.0  # double creases: no bulge beside the line
        assert truth["detail_height"].min() < -0.01
