"""A scan given in the wrong length unit is caught (or converted) by its size against the markers'."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from facecap.cli import main
from facecap.errors import FacecapWarning, MeshError
from facecap.io import read_correspondence, read_markers, read_mesh
from facecap.structures import Mesh
from facecap.markers import check_scan_units


def _read(files, unit="mm"):
    scan = read_mesh(files.scan, unit=unit)
    take = read_markers(files.markers)
    return scan, take, read_correspondence(files.map, scan)


@pytest.mark.parametrize(("stored", "name"), [("m", "metres"), ("cm", "centimetres"), ("in", "inches")])
def test_whole_scan_against_markers_names_the_likely_one(case, written, stored, name):
    """Without a map (register-scans): the whole scan's size against the marker cloud."""
    scan = read_mesh(written[stored].scan, unit="mm")
    with pytest.raises(MeshError, match=rf"the scan is .* across but the markers span .* mm: it looks like {name}"):
        check_scan_units(scan, case.markers.positions[0])


@pytest.mark.parametrize("stored", ["mm", "cm", "m", "in"])
def test_right_unit_passes_unchanged(case, written, stored):
    scan, take, corr = _read(written[stored], unit=stored)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_scan_units(scan, case.markers.positions[0]) is scan


def test_robust_to_gaps_and_stray_markers(written):
    scan, take, corr = _read(written["m"])
    P = take.positions.copy()
    P[0, :10] = np.nan                       # occluded at the rest frame
    P[0, 10:13] = [[5000.0, 0, 0], [0, -4000.0, 0], [0, 0, 9000.0]]  # strays (a prop, a mislabel)
    with pytest.raises(MeshError, match="metres"):
        check_scan_units(scan, P[0])
    right, _, _ = _read(written["m"], unit="m")
    assert check_scan_units(right, P[0]) is right


def test_a_larger_head_scan_is_tolerated(case):
    """A scan twice the size of the face markers (whole head, shoulders) is not a unit mistake."""
    big = Mesh(case.scan.vertices * 2.5, case.scan.faces)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_scan_units(big, case.markers.positions[0]) is big


def test_sizes_off_by_no_unit_factor_warn_only(case):
    odd = Mesh(case.scan.vertices * 0.004, case.scan.faces)  # 250x: neither in (25.4) nor m (1000)
    with pytest.warns(FacecapWarning, match="no length unit explains"):
        assert check_scan_units(odd, case.markers.positions[0]) is odd


def test_too_few_markers_is_not_checked(case):
    assert check_scan_units(case.scan, np.full((5, 3), np.nan)) is case.scan


def _animate(files, out, *extra):
    return main(["--quiet", "animate", "--scan", str(files.scan), "--markers", str(files.markers),
                 "--map", str(files.map), "--out", str(out), "--no-smooth", *extra])


def test_cli_refuses_a_metres_scan_in_one_line(written, tmp_path, capsys):
    assert _animate(written["m"], tmp_path / "out") == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert err.startswith(f"facecap: error: {written['m'].scan}: ")
    assert err.endswith("it looks like metres; pass --scan-units m")
    assert not (tmp_path / "out").exists()


def test_cli_auto_equals_the_right_unit(written, tmp_path, capsys):
    assert _animate(written["m"], tmp_path / "auto", "--scan-units", "auto") == 0
    assert _animate(written["m"], tmp_path / "given", "--scan-units", "m") == 0
    assert _animate(written["mm"], tmp_path / "mm") == 0
    auto = np.load(tmp_path / "auto" / "vertices.npy")
    np.testing.assert_array_equal(auto, np.load(tmp_path / "given" / "vertices.npy"))
    # the output keeps the file's unit: the metres run is the mm run / 1000
    np.testing.assert_allclose(auto * 1000.0, np.load(tmp_path / "mm" / "vertices.npy"), atol=2e-3)


def test_cli_auto_prints_a_notice(written, tmp_path, capsys):
    assert main(["animate", "--scan", str(written["cm"].scan), "--markers", str(written["cm"].markers),
                 "--map", str(written["cm"].map), "--out", str(tmp_path / "o"), "--no-smooth",
                 "--scan-units", "auto"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "read as" in line]
    assert len(notes) == 1 and notes[0].startswith(f"facecap: note: {written['cm'].scan}: ")
    assert notes[0].endswith("read as centimetres")


@pytest.fixture(scope="module")
def planned(case, written, tmp_path_factory):
    """A two-scan plan of the mm case, its scans in mm and the same scans written in metres."""
    from facecap.io import write_mesh
    from facecap.synth import write_planned_scans

    root = tmp_path_factory.mktemp("planned")
    plan = root / "plan.json"
    assert main(["--quiet", "plan-scans", "--markers", str(written["mm"].markers), "--max-scans", "2",
                 "--out", str(plan)]) == 0
    import json

    frames = json.loads(plan.read_text())["frames"]
    scans_mm = write_planned_scans(case, frames, root / "mm", target_vertices=3000)
    scans_m = []
    for path in scans_mm:
        mesh = read_mesh(path)
        scans_m.append(root / f"{path.stem}_m.obj")
        write_mesh(Mesh(mesh.vertices / 1000.0, mesh.faces), scans_m[-1])
    return plan, [str(p) for p in scans_mm], [str(p) for p in scans_m]


def _register(written, plan, scans, out, *extra):
    return main(["--quiet", "register-scans", "--plan", str(plan), "--markers", str(written["mm"].markers),
                 "--scans", *scans, "--out", str(out), *extra])


def test_register_scans_refuses_metres_scans(written, planned, tmp_path, capsys):
    plan, _, scans_m = planned
    assert _register(written, plan, scans_m, tmp_path / "bases") == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith(f"facecap: error: {scans_m[0]}: the scan is ")
    assert "it looks like metres" in err and err.endswith("pass --scan-units m")
    assert not (tmp_path / "bases").exists()


def test_register_scans_refuses_a_metres_template(written, planned, tmp_path, capsys):
    plan, scans_mm, scans_m = planned
    assert _register(written, plan, scans_mm, tmp_path / "bases", "--template", scans_m[0]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"facecap: error: {scans_m[0]}: ") and err.endswith("pass --template-units m")


def test_register_scans_auto_converts(written, planned, tmp_path, capsys):
    plan, _, scans_m = planned
    assert main(["register-scans", "--plan", str(plan), "--markers", str(written["mm"].markers),
                 "--scans", *scans_m, "--out", str(tmp_path / "bases"), "--scan-units", "auto"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "read as metres" in line]
    assert len(notes) == len(scans_m)
