"""``facecap map`` and ``facecap info MAP --scan --markers`` from the command line: the files a user gets,
the lines printed, and bad input as one line naming the file, exit status 2, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facecap.cli import main
from facecap.io import read_correspondence, read_mesh, write_markers
from facecap.structures import MarkerSequence
from facecap.synth import write_synthetic_case
from marker_map_cases import map_case
from test_cli import _one_line_error


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    mc = map_case(seed=8, n_frames=120)
    return mc, write_synthetic_case(mc.case, tmp_path_factory.mktemp("case"), scan_unit="cm")


def _map(written, out, *extra):
    return main(["map", "--scan", str(written.scan), "--scan-units", "cm", "--markers", str(written.markers),
                 "--out", str(out), *extra])


def test_map_writes_a_map_animate_can_read_and_info_checks_it(files, tmp_path, capsys):
    mc, written = files
    out = tmp_path / "map.json"
    assert _map(written, out) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out}" in printed and "off the skin" in printed and "HB0" in printed
    assert {p.name for p in tmp_path.iterdir()} == {"map.json", "map_report.json", "map.png"}
    scan = read_mesh(written.scan, unit="cm")
    corr = read_correspondence(out, scan)
    truth = scan.vertices[mc.case.marker_vertices]
    labels = list(mc.case.markers.labels)
    error = np.linalg.norm(corr.points(scan.vertices) - truth[[labels.index(s) for s in corr.labels]], axis=1)
    assert np.mean(error <= 1.5) >= 0.95

    check = ["info", str(out), "--scan", str(written.scan), "--scan-units", "cm", "--markers", str(written.markers)]
    assert main(check) == 0
    assert "flagged       none" in capsys.readouterr().out
    broken = json.loads(out.read_text())
    first, second = list(broken["markers"])[:2]
    broken["markers"][first], broken["markers"][second] = broken["markers"][second], broken["markers"][first]
    (tmp_path / "broken.json").write_text(json.dumps(broken))
    check[1] = str(tmp_path / "broken.json")
    assert main(check) == 0
    printed = capsys.readouterr().out
    assert "flagged       2 entries" in printed and f"    {first}:" in printed and f"    {second}:" in printed
    assert main(check + ["--json"]) == 0
    assert set(json.loads(capsys.readouterr().out)["flagged"]) == {first, second}

    assert _map(written, out) == 2  # a second run into the same map
    _one_line_error(capsys, str(out), "--overwrite")
    assert _map(written, out, "--overwrite", "--quiet") == 0


def test_a_rest_frame_outside_the_take(files, tmp_path, capsys):
    _, written = files
    assert _map(written, tmp_path / "map.json", "--rest-frame", "120") == 2
    _one_line_error(capsys, str(written.markers), "--rest-frame 120", "0..119")
    assert not any(tmp_path.iterdir())


def test_too_few_markers_at_the_rest_frame(files, tmp_path, capsys):
    mc, written = files
    take = mc.case.markers
    positions = take.positions.copy()
    positions[0, 3:] = np.nan
    sparse = tmp_path / "sparse.c3d"
    write_markers(MarkerSequence(positions, take.labels, rate=take.rate), sparse)
    code = main(["map", "--scan", str(written.scan), "--scan-units", "cm", "--markers", str(sparse),
                 "--out", str(tmp_path / "map.json")])
    assert code == 2
    _one_line_error(capsys, str(sparse), "only 3 marker(s) seen at the rest frame 0", "at least 4")
    assert {p.name for p in tmp_path.iterdir()} == {"sparse.c3d"}


def test_a_scan_in_the_wrong_unit(files, tmp_path, capsys):
    _, written = files
    code = main(["map", "--scan", str(written.scan), "--markers", str(written.markers),
                 "--out", str(tmp_path / "map.json")])
    assert code == 2
    _one_line_error(capsys, str(written.scan), "centimetres", "--scan-units cm")
    assert not any(tmp_path.iterdir())


def test_an_unreadable_landmarks_file(files, tmp_path, capsys):
    _, written = files
    landmarks = tmp_path / "landmarks.json"
    landmarks.write_text('{"M001": 12, "M002": ')
    assert _map(written, tmp_path / "map.json", "--landmarks", str(landmarks)) == 2
    _one_line_error(capsys, str(landmarks), "malformed JSON")
    landmarks.write_text('{"Nose": 12, "M002": 40, "M003": 77}')
    assert _map(written, tmp_path / "map.json", "--landmarks", str(landmarks)) == 2
    _one_line_error(capsys, str(landmarks), "Nose")
    assert {p.name for p in tmp_path.iterdir()} == {"landmarks.json"}


def test_info_on_a_map_needs_the_scan_and_the_take(files, capsys):
    _, written = files
    assert main(["info", str(written.map), "--scan", str(written.scan)]) == 2
    _one_line_error(capsys, "--scan", "--markers")
