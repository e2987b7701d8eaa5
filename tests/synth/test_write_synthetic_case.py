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
