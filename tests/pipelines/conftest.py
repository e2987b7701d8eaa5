"""The scan workflow's case, shared by its three jobs' tests: a small generated take, planned through the CLI,
and its planned expressions scanned (built once a session; tests must not change what it holds)."""

import json

import pytest

from facecap.cli import main
from facecap.synth import generate_performance, write_planned_scans, write_synthetic_case
from facecap.io.ict_sample import load_ict_sample


@pytest.fixture(scope="session")
def scan_workflow(tmp_path_factory):
    root = tmp_path_factory.mktemp("scans")
    s = load_ict_sample()
    case = generate_performance(n_frames=150, seed=21, n_markers=70)
    files = write_synthetic_case(case, root / "inputs", region_labels=s.region_labels,
                                 region_names=list(s.region_names))
    assert main(["-q", "plan-scans", "--markers", str(files.markers), "--out", str(root / "plan.json"),
                 "--max-scans", "4"]) == 0
    frames = json.loads((root / "plan.json").read_text())["frames"]
    scans = [str(p) for p in write_planned_scans(case, frames, root, target_vertices=9000)]
    return root, case, files, frames, scans
