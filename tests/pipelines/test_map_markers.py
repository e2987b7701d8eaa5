"""Tests for facecap.pipelines.map_markers: the map written as a user holds it, read back, and its report.

The case is written as a studio would hold it (``scan.obj`` in centimetres, ``take.c3d``), read back
with facecap's readers, mapped, and the written map read with :func:`read_correspondence` is compared
with the generator's true places.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.image import imread

from facecap.errors import CorrespondenceError, InputError, MarkerError, MeshError
from facecap.io import read_correspondence, read_markers, read_mesh
from facecap.structures import Correspondence
from facecap.pipelines import map_markers, map_side_files
from facecap.synth import write_synthetic_case
from marker_map_cases import HEADBAND, map_case


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    mc = map_case(seed=3, n_frames=150)
    folder = tmp_path_factory.mktemp("case")
    written = write_synthetic_case(mc.case, folder, scan_unit="cm")
    return mc, written


@pytest.fixture(scope="module")
def mapped(files, tmp_path_factory):
    mc, written = files
    out = tmp_path_factory.mktemp("map") / "map.json"
    scan = read_mesh(written.scan, unit="cm")
    take = read_markers(written.markers)
    report = map_markers(scan, take, out)
    return mc, written, scan, take, out, report


def test_the_written_map_reads_back_onto_the_true_places(mapped) -> None:
    mc, _, scan, take, out, _ = mapped
    doc = json.loads(out.read_text())
    assert doc["units"] == "cm" and list(doc["markers"]) == [s for s in take.labels if not s.startswith("HB")]
    corr = read_correspondence(out, scan)
    truth = scan.vertices[mc.case.marker_vertices]
    order = [take.labels.index(s) for s in corr.labels]
    error = np.linalg.norm(corr.points(scan.vertices) - truth[order], axis=1)
    assert np.mean(error <= 1.5) >= 0.95 and np.median(error) < 0.5
    assert np.allclose(corr.snap_distances, 0.0, atol=1e-4)  # written on the surface, read back on it


def test_the_report_names_every_marker_and_leaves_the_head_band_out(mapped) -> None:
    mc, _, _, take, out, report = mapped
    report_file, picture = map_side_files(out)
    on_disk = json.loads(report_file.read_text())
    assert on_disk["counts"] == report["counts"] and "summary" not in on_disk
    status = {row["label"]: row["status"] for row in on_disk["markers"]}
    assert list(status) == list(take.labels)
    assert all(status[f"HB{i}"] == "off the skin" for i in range(HEADBAND))
    placed = {s for s, v in status.items() if v in ("placed", "ambiguous", "uncertain")}
    assert placed == set(json.loads(out.read_text())["markers"])
    assert on_disk["search"]["from"] == "global search" and on_disk["search"]["sure"]
    assert sum(on_disk["counts"].values()) == len(take.labels)
    assert any("HB0" in line and "off the skin" in line for line in report["summary"])
    estimate = {row["label"]: row["may_be_off_mm"] for row in on_disk["markers"]}
    assert all((estimate[s] is None) == (s not in placed) for s in status)
    uncertain = [s for s, v in status.items() if v == "uncertain"]
    assert all(estimate[s] >= 1.0 for s in uncertain)  # over 1 mm, rounded to 0.01 in the report
    line = [line for line in report["summary"] if "uncertain" in line]
    assert len(line) == (1 if uncertain else 0)
    assert all(f"{s} ({estimate[s]:.1f} mm)" in line[0] for s in uncertain)
    image = imread(picture)
    assert image.shape[:2] == (1150, 1000)


def test_an_existing_map_is_refused_without_overwrite(mapped) -> None:
    _, _, scan, take, out, _ = mapped
    before = out.read_bytes()
    with pytest.raises(InputError, match="--overwrite"):
        map_markers(scan, take, out)
    assert out.read_bytes() == before


def test_landmarks_give_the_pose(files, tmp_path) -> None:
    mc, written = files
    scan = read_mesh(written.scan, unit="cm")
    take = read_markers(written.markers)
    picks = ("M005", "M020", "M041", "M033")
    vertices = [int(mc.case.marker_vertices[take.labels.index(s)]) for s in picks]
    landmarks = Correspondence(picks, np.repeat(np.array(vertices)[:, None], 3, axis=1), np.eye(3)[[0] * 4])
    report = map_markers(scan, take, tmp_path / "map.json", landmarks=landmarks)
    assert report["search"]["from"] == "landmarks"
    assert report["search"]["landmark_agreement_mm"]["max"] < 1.5  # placed where the landmarks say
    corr = read_correspondence(tmp_path / "map.json", scan)
    truth = scan.vertices[mc.case.marker_vertices]
    error = np.linalg.norm(corr.points(scan.vertices) - truth[[take.labels.index(s) for s in corr.labels]], axis=1)
    assert np.mean(error <= 1.5) >= 0.95


def test_landmarks_naming_unknown_or_too_few_markers_are_refused(files, tmp_path) -> None:
    _, written = files
    scan = read_mesh(written.scan, unit="cm")
    take = read_markers(written.markers)
    unknown = Correspondence(("M001", "Nose", "M003"), np.zeros((3, 3)), np.eye(3)[[0, 0, 0]], source_path="lm.json")
    with pytest.raises(CorrespondenceError, match="Nose"):
        map_markers(scan, take, tmp_path / "map.json", landmarks=unknown)
    two = Correspondence(("M001", "M002"), np.zeros((2, 3)), np.eye(3)[[0, 0]], source_path="lm.json")
    with pytest.raises(CorrespondenceError, match="at least 3"):
        map_markers(scan, take, tmp_path / "map.json", landmarks=two)
    assert not any(tmp_path.iterdir())


def test_bad_input_is_refused_before_anything_is_written(files, tmp_path) -> None:
    _, written = files
    take = read_markers(written.markers)
    with pytest.raises(MeshError, match="--scan-units cm"):
        map_markers(read_mesh(written.scan, unit="mm"), take, tmp_path / "map.json")
    scan = read_mesh(written.scan, unit="cm")
    with pytest.raises(MarkerError, match="outside the take"):
        map_markers(scan, take, tmp_path / "map.json", rest_frame=take.n_frames)
    assert not any(tmp_path.iterdir())


def test_another_persons_markers_are_placed_rigidly_with_a_warning(tmp_path) -> None:
    # the bundled real take was captured on another face than the bundled ICT scan: no resting expression
    # explains the difference, so the markers are placed by the rigid fit alone and the summary says why
    from facecap.io.ict_sample import bundled_path, load_ict_sample

    take = read_markers(bundled_path("eyebrows.c3d"))
    report = map_markers(load_ict_sample().mesh, take, tmp_path / "map.json")
    assert report["fit"]["resting_expression_kept"] is False
    assert report["fit"]["resting_expression_rms_mm"] > 1.5
    assert any(line.startswith("warning: the markers would have to move") for line in report["summary"])
    status = {row["label"]: row["status"] for row in report["markers"]}
    assert status["Leye_Up"] == status["Reye_Up"] == "past the rim"  # upper eyelids over the eye openings
    assert sum(s in ("placed", "ambiguous", "uncertain") for s in status.values()) == len(take.labels) - 2
