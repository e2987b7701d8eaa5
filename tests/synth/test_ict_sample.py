import numpy as np

from facecap.synth.ict_sample import bundled_path, load_ict_sample


def test_sample_is_the_ict_face_region_in_mm():
    s = load_ict_sample()
    m = s.mesh
    assert m.n_vertices == 9409 and m.source_unit == "mm"
    assert m.polygon_sizes.size == 9230 and set(np.unique(m.polygon_sizes)) <= {3, 4}
    # fan triangulation of the polygons gives the triangles
    assert m.n_faces == int((m.polygon_sizes - 2).sum())
    assert m.uv_indices.size == m.polygon_indices.size and m.uv_indices.max() < len(m.uvs)
    # a face is ~180 mm wide, not 18 (cm) or 0.18 (m)
    width = np.ptp(m.vertices[:, 0])
    assert 150 < width < 220
    assert s.expression_deltas.shape == (53, 9409, 3) and len(s.expression_names) == 53
    assert s.region_labels.shape == (9409,) and set(np.unique(s.region_labels)) == set(range(len(s.region_names)))


def test_identity_coefficients_change_the_face_linearly():
    s = load_ict_sample()
    a = np.array([0.5, -0.3])
    face = s.face(a)
    expected = s.mesh.vertices + 0.5 * s.identity_deltas[0] - 0.3 * s.identity_deltas[1]
    np.testing.assert_allclose(face.vertices, expected, atol=1e-5)
    assert face.faces is s.mesh.faces


def test_bundled_files_and_licences_are_there():
    for name in ("eyebrows.c3d", "ict_generic_map.json", "README.md", "LICENSE-ICT-FaceKit.txt"):
        assert bundled_path(name).is_file()
    text = bundled_path("README.md").read_text()
    assert "MIT" in text and "CC BY-SA 4.0" in text
    assert "Permission is hereby granted" in bundled_path("LICENSE-ICT-FaceKit.txt").read_text()
