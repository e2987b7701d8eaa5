"""facecap.report.describe: what ``facecap info`` says about a take, a mesh and a result folder.

Every case is built here from known parameters (a box of known sides written in a
known unit, pieces of known vertex counts, gaps at known markers, a timecode
written by ezc3d), and the description is checked against them.
"""

from __future__ import annotations

import json

import ezc3d
import numpy as np
import pytest

from facecap.io.write_markers import write_markers
from facecap.io.write_mesh import write_mesh
from facecap.report.describe import describe_file, format_description
from facecap.structures import MarkerSequence, Mesh

HEAD_SIDES_MM = (248.0, 338.0, 223.0)  # the ICT head's box; its middle side, 248 mm, is a face's size


def _box(sides, corner=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed box: 8 vertices, 12 outward triangles."""
    unit = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return unit * np.asarray(sides) + np.asarray(corner), F


def _grid(nx: int, ny: int, corner: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A flat nx x ny vertex grid, 1 mm apart: one piece of nx * ny vertices."""
    x, y = np.meshgrid(np.arange(nx, dtype=np.float64), np.arange(ny, dtype=np.float64), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]) + np.asarray(corner)
    i = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
    return V, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def test_a_head_in_centimetres_read_as_mm_is_flagged_with_its_unit(tmp_path):
    V, F = _box(HEAD_SIDES_MM, corner=(-124.0, -190.0, -90.0))
    path = write_mesh(Mesh(V, F), tmp_path / "head.obj", unit="cm")  # the file holds 24.8, 33.8, 22.3
    info = describe_file(path)  # mesh files state no unit: read as mm
    size = info["face_size"]
    assert size["across_mm"] == pytest.approx(24.8) and not size["is_a_face_size"]
    assert size["likely_units"] == ["cm"]
    assert size["across_if_read_as_mm"] == pytest.approx({"mm": 24.8, "cm": 248.0, "m": 24800.0, "in": 24.8 * 25.4})
    text = format_description(info)
    warning = " ".join(line.strip() for line in text.splitlines() if "warning" in line or line.startswith("    "))
    for needle in ("24.8 mm across read as millimetres", "smaller than a face (120-300 mm)",
                   "as centimetres it is 248 mm", "pass --units cm", "as metres 24,800 mm", "as inches 630 mm"):
        assert needle in warning, (needle, text)
    # read in the unit it names, the same file is a face: no warning, its box in mm
    fixed = describe_file(path, unit="cm")
    assert fixed["face_size"]["is_a_face_size"] and fixed["face_size"]["note"] is None
    assert "warning" not in format_description(fixed)
    assert "248 x 338 x 223 mm (x, y, z)" in format_description(fixed)


@pytest.mark.parametrize("unit, file_sides, likely", [
    ("m", (0.248, 0.338, 0.223), ["m"]),
    ("in", (248 / 25.4, 338 / 25.4, 223 / 25.4), ["in"]),
])
def test_the_unit_that_makes_a_face_is_named_for_metres_and_inches(tmp_path, unit, file_sides, likely):
    V, F = _box(file_sides)
    path = write_mesh(Mesh(V, F), tmp_path / "head.ply", unit="mm")  # the numbers as a file in `unit` holds them
    size = describe_file(path)["face_size"]
    assert size["likely_units"] == likely
    assert size["across_if_read_as_mm"][unit] == pytest.approx(248.0)
    assert f"pass --units {unit}" in size["note"]


def test_a_size_no_unit_explains_is_flagged_without_a_unit(tmp_path):
    V, F = _box((1700.0, 500.0, 300.0))  # a body, in mm
    size = describe_file(write_mesh(Mesh(V, F), tmp_path / "body.obj"))["face_size"]
    assert size["across_mm"] == pytest.approx(500.0) and size["likely_units"] == []
    assert "larger than a face" in size["note"] and "no length unit makes it one" in size["note"]


def test_pieces_are_listed_once_largest_first(tmp_path):
    parts = [_grid(nx, ny, (10.0 * k, 0.0, 0.0)) for k, (nx, ny) in
             enumerate([(2, 2), (5, 5), (2, 3), (4, 5), (3, 3), (4, 4), (3, 4)])]
    V = np.concatenate([v for v, _ in parts])
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    F = np.concatenate([f + o for (_, f), o in zip(parts, offsets)])
    info = describe_file(write_mesh(Mesh(V, F), tmp_path / "parts.obj"))
    assert info["pieces"] == {"count": 7, "vertices_each": [25, 20, 16, 12, 9, 6, 4]}
    assert "piece_sizes" not in info["check"] and "problems" not in info["check"]
    assert not any("piece" in p for p in info["problems"])
    text = format_description(info)
    assert text.count("piece") == 1 and "pieces        7: 25, 20, 16, 12, 9 vertices, then 2 of 4 to 6 vertices" in text
    assert json.dumps(info).count("25, 20, 16") == 1  # and once in --json


def _face_take(n_markers: int = 90, n_frames: int = 50, rate: float = 120.0) -> MarkerSequence:
    rng = np.random.default_rng(3)
    rest = rng.uniform(-70.0, 70.0, size=(n_markers, 3)) * np.array([1.0, 1.2, 0.5])  # 140 x 168 x 70 mm
    P = rest + rng.normal(scale=0.5, size=(n_frames, n_markers, 3)) + np.array([0.0, 0.0, 1500.0])
    P[10:14, 3] = np.nan  # 4 frames of M003
    P[20:21, 7] = np.nan  # 1 frame of M007
    return MarkerSequence(P, [f"M{i:03d}" for i in range(n_markers)], rate)


def test_a_take_lists_a_few_labels_its_worst_gaps_and_units_on_every_number(tmp_path):
    take = _face_take()
    path = tmp_path / "take.c3d"
    write_markers(take, path)
    info = describe_file(path)
    assert info["gaps"]["missing_samples_per_marker"] == {"M003": 4, "M007": 1}
    assert info["face_size"]["is_a_face_size"] and info["face_size"]["note"] is None
    text = format_description(info)
    lines = text.splitlines()
    assert lines[0] == "take.c3d: marker take (C3D)"
    assert sum("M0" in line for line in lines) <= 3  # not 90 labels on a line
    assert "M000, M001, M002, M003, M004, M005, M006, M007 and 82 more (--labels lists them all)" in " ".join(
        line.strip() for line in lines)
    assert "frames        50 at 120 Hz, 0.417 s" in text
    assert "5 of 4,500 samples missing (0.1%) in 2 of 90 markers; most in M003 (4 frames), M007 (1 frame)" in " ".join(
        line.strip() for line in lines)
    for line in lines[1:]:
        key, _, value = line.strip().partition("  ")
        assert not any(c in value for c in ("[", "{", "', '", "np.", "None", "True", "False")), line  # no reprs
        if key in ("size", "extent", "frames"):
            assert ("mm" if key != "frames" else "Hz") in value, line
    listed = [line.strip().removeprefix("labels").strip()
              for line in format_description(info, labels=True).splitlines()]
    for label in take.labels:  # --labels: one line each, with its gaps
        assert sum(line.split()[0] == label for line in listed if line) == 1, label
    assert "M003  4 frames missing" in listed and "M007  1 frame missing" in listed and "M008" in listed


def test_a_take_in_metres_stated_as_mm_is_flagged(tmp_path):
    take = _face_take()
    path = tmp_path / "take.trc"
    write_markers(MarkerSequence(take.positions / 1000.0, take.labels, take.rate), path)  # numbers in m, says mm
    size = describe_file(path)["face_size"]
    assert not size["is_a_face_size"] and size["likely_units"] == ["m"]
    assert describe_file(path, unit="m")["face_size"]["is_a_face_size"]


def test_the_timecode_a_c3d_holds_is_printed(tmp_path):
    path = tmp_path / "take.c3d"
    write_markers(_face_take(n_markers=10), path)
    c = ezc3d.c3d(str(path))
    c.add_parameter("TIMECODE", "FIRST_FRAME", [10, 22, 31, 12])
    c.add_parameter("TIMECODE", "DROP_FRAMES", [0])
    c.write(str(path))
    info = describe_file(path)
    assert info["timecode"] == "10:22:31:12"
    assert "timecode      10:22:31:12 at the first frame" in format_description(info)
    write_markers(_face_take(n_markers=10), tmp_path / "plain.c3d")
    plain = describe_file(tmp_path / "plain.c3d")
    assert plain["timecode"] is None and "timecode" not in format_description(plain)


def test_a_result_folder_reads_as_a_summary(capture_case, tmp_path):
    from facecap.cli import main

    out = tmp_path / "result"
    assert main(["--quiet", "animate", "--scan", str(capture_case.scan_path), "--markers",
                 str(capture_case.markers_path), "--map", str(capture_case.map_path), "--out", str(out)]) == 0
    info = describe_file(out)
    report = json.loads((out / "report.json").read_text())
    loo = report["warp_leave_one_out_mm"]
    assert info["warp_leave_one_out_mm"]["max"] == pytest.approx(max(loo.values()), abs=1e-3)
    assert info["warp_leave_one_out_mm"]["worst_marker"] == max(loo, key=loo.get)
    text = format_description(info)
    assert text.splitlines()[0] == f"{out}: facecap result (bickel2007-large-scale)"
    assert f"frames        {info['frames']} at {info['rate_hz']:g} Hz" in text
    assert "exports       none" in text and " MB" in text and "{" not in text
