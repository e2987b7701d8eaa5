"""Tests for facecap.io.ict_sample: the bundled ICT face region and the AnimFace files."""

import json

import ezc3d
import numpy as np
import pytest
from scipy.spatial import cKDTree

from facecap.errors import InputError
from facecap.io.ict_sample import BUNDLED_FILES, IctSample, bundled_path, load_ict_sample


@pytest.fixture(scope="module")
def s() -> IctSample:
    return load_ict_sample()


def test_sample_is_the_ict_face_region_in_mm(s):
    m = s.mesh
    assert m.n_vertices == 9409 and m.source_unit == "mm"
    assert m.polygon_sizes.size == 9230 and np.all(m.polygon_sizes == 4)
    # every vertex of the region is used by a polygon
    assert np.unique(m.polygon_indices).size == 9409
    # the triangles are the fan triangulation (0, j, j + 1) of the quads
    Q = m.polygon_indices.reshape(-1, 4)
    fan = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    np.testing.assert_array_equal(np.sort(np.sort(m.faces, axis=1), axis=0), np.sort(np.sort(fan, axis=1), axis=0))
    assert m.uv_indices.size == m.polygon_indices.size and m.uv_indices.max() == len(m.uvs) - 1
    assert np.all((m.uvs >= 0) & (m.uvs <= 1))
    # a face is ~180 mm wide, not 18 (cm) or 0.18 (m)
    assert 150 < np.ptp(m.vertices[:, 0]) < 220
    assert s.expression_deltas.shape == (53, 9409, 3) and s.expression_deltas.dtype == np.float64
    assert len(s.expression_names) == 53 and s.expression_names[26] == "jawOpen"
    assert s.identity_deltas.shape == (8, 9409, 3) and len(s.identity_names) == 8


def test_arrays_are_read_only_so_the_shared_sample_cannot_be_corrupted(s):
    assert load_ict_sample() is s
    for a in (s.expression_deltas, s.identity_deltas, s.region_labels, s.mesh.vertices, s.mesh.faces):
        with pytest.raises(ValueError):
            a[0] = 0


def test_left_expressions_move_the_subjects_left_side(s):
    # documented convention: _L is the subject's left, +x
    for k, name in enumerate(s.expression_names):
        if name.endswith("_L") and name.startswith(("brow", "mouthSmile", "eyeBlink", "cheek")):
            mag = np.linalg.norm(s.expression_deltas[k], axis=1)
            assert (mag * s.mesh.vertices[:, 0]).sum() / mag.sum() > 10.0, name


def test_jaw_open_is_centimetres_of_motion_at_the_chin_only(s):
    jaw = np.linalg.norm(s.expression_deltas[s.expression_names.index("jawOpen")], axis=1)
    assert 30.0 < jaw.max() < 60.0  # mm: the chin drops a few cm
    # the forehead barely moves when the jaw opens
    forehead = s.region_labels == s.region_names.index("forehead")
    assert jaw[forehead].max() < 0.05 * jaw.max()


def test_identity_coefficients_change_the_face_linearly(s):
    a = np.array([0.5, -0.3])
    face = s.face(a)
    expected = s.mesh.vertices + 0.5 * s.identity_deltas[0] - 0.3 * s.identity_deltas[1]
    np.testing.assert_allclose(face.vertices, expected, atol=1e-12)
    assert face.faces is s.mesh.faces and s.face(None) is s.mesh
    for bad in (np.zeros(9), np.zeros((2, 2)), [np.nan], "abc"):
        with pytest.raises(InputError, match="identity"):
            s.face(bad)


def test_region_labels_follow_the_landmarks_and_are_symmetric(s):
    names, lab, L = s.region_names, s.region_labels, s.landmarks
    assert names == ("forehead", "brows", "eyes", "nose", "cheeks", "mouth", "chin_jaw", "other")
    assert set(np.unique(lab)) == set(range(len(names)))
    # each landmark group falls in its region
    for group, region in [(range(17, 27), "brows"), (range(36, 48), "eyes"), (range(30, 36), "nose"),
                          (range(48, 68), "mouth"), ([8], "chin_jaw")]:
        assert np.all(lab[L[list(group)]] == names.index(region)), region
    # 'other' is exactly what lies outside the ICT narrow face area (vertices 6706+)
    np.testing.assert_array_equal(lab == names.index("other"), np.arange(9409) >= 6706)
    # the rules are mirror symmetric and so is the neutral: mirror twins share labels
    V = s.mesh.vertices
    d, twin = cKDTree(V).query(V * [-1, 1, 1])
    matched = d < 1e-3
    assert matched.mean() > 0.95
    assert np.mean(lab[matched] == lab[twin[matched]]) > 0.99


def test_bundled_files_and_licences_are_there():
    for name in BUNDLED_FILES:
        assert bundled_path(name).is_file()
    text = bundled_path("README.md").read_text(encoding="utf-8")
    assert "MIT" in text and "CC BY-SA 4.0" in text and "Permission is hereby granted" in text
    assert "Permission is hereby granted" in bundled_path("LICENSE-ICT-FaceKit.txt").read_text(encoding="utf-8")
    with pytest.raises(InputError, match="name"):
        bundled_path("../../etc/passwd")


def test_the_real_take_and_its_map_agree(s):
    c3d = ezc3d.c3d(str(bundled_path("eyebrows.c3d")))
    labels = c3d["parameters"]["POINT"]["LABELS"]["value"]
    assert len(labels) == 41 and c3d["parameters"]["POINT"]["RATE"]["value"][0] == 60
    assert c3d["data"]["points"].shape[2] == 902
    mapping = json.loads(bundled_path("ict_generic_map.json").read_text(encoding="utf-8"))
    assert set(mapping) == set(labels)
    assert all(0 <= v < s.mesh.n_vertices for v in mapping.values())
