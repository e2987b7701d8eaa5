"""facecap build-anatomy and facecap remove-wrinkles from the command line, on the bundled ICT face."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from facecap.anatomy import load_anatomy
from facecap.cli import main
from facecap.io import read_mesh, write_mesh
from facecap.io.ict_sample import load_ict_sample


def _scan(tmp_path: Path) -> Path:
    sample = load_ict_sample()
    path = tmp_path / "scan.obj"
    write_mesh(sample.face(), path)
    return path


def test_build_anatomy_writes_a_model_that_loads(tmp_path: Path) -> None:
    scan = _scan(tmp_path)
    out = tmp_path / "model"
    assert main(["-q", "build-anatomy", "--scan", str(scan), "--out", str(out), "--tets", "2000"]) == 0
    model = load_anatomy(out)
    assert (out / "layout.png").stat().st_size > 10_000
    # every scan vertex is carried by its tetrahedron exactly (the embedding of the model read back)
    V = read_mesh(scan).vertices
    inside = model.skin_inside
    assert np.abs(model.skin_positions()[inside] - V[inside]).max() < 1e-6
    # the scan it was built from, recorded where it is (the model was written under a temporary name)
    from recorded_paths import assert_recorded_paths_are_final

    assert json.loads((out / "anatomy.json").read_text())["provenance"]["scan"] == str(scan)
    assert assert_recorded_paths_are_final(out) >= 1
    # a second build into the model is refused before the build (a missing scan would be the error otherwise)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["-q", "build-anatomy", "--scan", str(tmp_path / "missing.obj"), "--out", str(out)]) == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_remove_wrinkles_changes_the_region_only_and_refuses_a_bad_region(tmp_path: Path, capsys) -> None:
    scan = _scan(tmp_path)
    V = read_mesh(scan).vertices
    sample = load_ict_sample()
    forehead = np.flatnonzero(sample.region_labels == list(sample.region_names).index("forehead"))
    region = tmp_path / "region.json"
    region.write_text(json.dumps(forehead.tolist()))
    out = tmp_path / "smooth.obj"
    assert main(["-q", "remove-wrinkles", "--scan", str(scan), "--region", str(region), "--out", str(out)]) == 0
    W = read_mesh(out).vertices
    outside = np.ones(len(V), dtype=bool)
    outside[forehead] = False
    assert np.abs(W[outside] - V[outside]).max() < 1e-5  # the OBJ's decimals
    assert np.abs(W[forehead] - V[forehead]).max() > 1e-3
    region.write_text(json.dumps([len(V) + 5]))
    code = main(["-q", "remove-wrinkles", "--scan", str(scan), "--region", str(region), "--out", str(tmp_path / "x.obj")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "region.json" in err[0]
    assert not (tmp_path / "x.obj").exists()
    # the output named as the scan itself (or any existing file): refused before any work, unless --overwrite
    region.write_text(json.dumps(forehead.tolist()))
    before = scan.read_bytes()
    assert main(["-q", "remove-wrinkles", "--scan", str(scan), "--region", str(region), "--out", str(scan)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{scan}: exists; pass --overwrite" in err[0] and scan.read_bytes() == before
    assert main(["-q", "remove-wrinkles", "--scan", str(scan), "--region", str(region), "--out", str(scan),
                 "--overwrite"]) == 0
    np.testing.assert_array_equal(read_mesh(scan).vertices, W)
