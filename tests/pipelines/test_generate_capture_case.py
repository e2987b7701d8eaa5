"""Tests for facecap/pipelines/generate_capture_case.py: the case folder as the generator makes it, whole or
not at all. The command end to end (footage too) is tests/test_cli.py's test_synth_* tests."""

import numpy as np
import pytest

from facecap.errors import FacecapError
from facecap.io import read_markers, read_mesh
from facecap.pipelines import generate_capture_case
from facecap.synth import generate_performance, random_identity


def test_the_folder_holds_the_generated_case_and_is_replaced_only_when_asked(tmp_path):
    out = tmp_path / "case"
    generate_capture_case(out, n_frames=10, seed=3, identity_seed=2, progress=False)
    assert sorted(p.name for p in out.iterdir()) >= ["map.json", "scan.obj", "take.c3d", "truth.npz"]
    case = generate_performance(n_frames=10, seed=3, identity=random_identity(2))
    truth = np.load(out / "truth.npz")
    np.testing.assert_allclose(truth["vertices"], case.truth_vertices, atol=1e-5)
    np.testing.assert_allclose(read_mesh(out / "scan.obj").vertices, case.scan.vertices, atol=1e-4)
    assert read_markers(out / "take.c3d").n_frames == 10
    with pytest.raises(FacecapError, match="pass --overwrite"):
        generate_capture_case(out, n_frames=10, progress=False)
    generate_capture_case(out, n_frames=12, progress=False, overwrite=True)
    assert np.load(out / "truth.npz")["vertices"].shape[0] == 12
    assert [p.name for p in tmp_path.iterdir()] == ["case"]  # no staging folder left
