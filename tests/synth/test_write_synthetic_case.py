import json

import numpy as np

from facecap.io import read_markers, read_mesh
from facecap.report.evaluate_result import read_truth
from facecap.synth import generate_performance, write_synthetic_case


def test_written_case_reads_back_in_the_chosen_units(tmp_path):
    case = generate_performance(n_frames=20, seed=2, n_markers=40)
    files = write_synthetic_case(case, tmp_path, scan_unit="cm")
    scan = read_mesh(files.scan, unit="cm")
    np.testing.assert_allclose(scan.vertices, case.scan.vertices, atol=1e-5)
    take = read_markers(files.markers)
    np.testing.assert_allclose(take.positions, case.markers.positions, atol=1e-3, equal_nan=True)
    assert json.loads(files.map.read_text()) == case.correspondence
    truth = read_truth(files.truth)
    assert str(truth["units"]) == "cm"
    np.testing.assert_allclose(truth["vertices"] * 10, case.truth_vertices, atol=1e-4)
    np.testing.assert_allclose(truth["head_pose"][:, :3, 3] * 10, case.head_pose[:, :3, 3], atol=1e-9)


def test_colour_option_writes_scans_with_colours_and_changes_nothing_else(tmp_path):
    from facecap.io.read_mesh import read_mesh
    from facecap.synth import SkinRegions, write_planned_scans
    from facecap.io.ict_sample import load_ict_sample

    case = generate_performance(n_frames=8, seed=2, n_markers=40)
    sample = load_ict_sample()
    plain = write_synthetic_case(case, tmp_path / "plain")
    files = write_synthetic_case(case, tmp_path / "col", colors=True, region_labels=sample.region_labels,
                                 region_names=list(sample.region_names))
    scan = read_mesh(files.scan)
    assert read_mesh(plain.scan).vertex_colors is None
    np.testing.assert_array_equal(scan.vertices, read_mesh(plain.scan).vertices)
    c = scan.vertex_colors
    assert c.shape == (case.scan.n_vertices, 3) and 0.3 < float(c.mean()) < 0.9
    assert files.markers.read_bytes() == plain.markers.read_bytes()
    regions = SkinRegions(sample.region_labels, sample.region_names)
    for fmt in ("ply", "obj"):
        paths = write_planned_scans(case, [3, 6], tmp_path / fmt, target_vertices=3000, file_format=fmt,
                                    colors=True, skin_regions=regions)
        for p in paths:
            m = read_mesh(p)
            assert m.vertex_colors is not None and m.vertex_colors.shape == (m.n_vertices, 3)
    plain_scans = write_planned_scans(case, [3], tmp_path / "noc", target_vertices=3000, file_format="ply")
    assert read_mesh(plain_scans[0]).vertex_colors is None
    np.testing.assert_array_equal(read_mesh(plain_scans[0]).vertices, read_mesh(tmp_path / "ply" / plain_scans[0].name).vertices)
