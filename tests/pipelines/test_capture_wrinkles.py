"""The wrinkle layer end to end on generated footage: facecap animate, then facecap wrinkles, against the truth.

One 9-mocap-frame take (seed 2) at the generator's default scan and full image size: video frame 0
neutral (the scan's expression), frames 1 and 2 with every wrinkle-making expression at once. The
bar of the issue (at most half the wrinkles' own displacement, on the benchmark's takes) is measured
in ``benchmarks/bench_wrinkle_synthesis.py``; here the same quantity is checked with a margin, and
the properties that must hold exactly: nothing added where the scan's expression is filmed, the
interpolation between video frames, the folder's contents, the command line.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from facecap.cameras import read_camera_file
from facecap.cli import main
from facecap.pipelines.animate_scan import animate_scan
from facecap.errors import FacecapWarning, InputError
from facecap.io import read_correspondence, read_markers, read_mesh
from facecap.io.read_result import read_result
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkles import every_wrinkle_at_once
from facecap.synth.write_footage_case import write_footage_case
from facecap.pipelines import capture_wrinkles


@pytest.fixture(scope="module")
def animated_case(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("wrinkle_case")
    curves = every_wrinkle_at_once(9, load_ict_sample().expression_names)
    files = write_footage_case(folder / "case", n_frames=9, seed=2, curves=curves)
    scan = read_mesh(files.scan)
    with warnings.catch_warnings():  # the take's head-band markers are not in the skin map, and a notice says so
        warnings.simplefilter("ignore", FacecapWarning)
        animate_scan(scan, read_markers(files.markers), read_correspondence(files.map, scan), folder / "animate",
                     progress=False)
    return folder / "case", folder / "animate"


@pytest.fixture(scope="module")
def wrinkled(animated_case: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    case, animate = animated_case
    setup = read_camera_file(case / "cameras.json")
    out = tmp_path_factory.mktemp("wrinkled") / "out"
    capture_wrinkles(animate, setup.cameras, [case / c.name for c in setup.cameras],
                     [case / f"mask_{c.name}.png" for c in setup.cameras], out, video_rate_hz=setup.video_rate_hz)
    return out


def test_wrinkles_add_what_the_truth_adds(animated_case: tuple[Path, Path], wrinkled: Path) -> None:
    case, animate = animated_case
    truth = np.load(case / "truth.npz")
    A = read_result(animate).frames()
    W = read_result(wrinkled).frames()
    for t in (4, 8):  # video frames 1 and 2
        true = (truth["vertices"][t] - truth["large_scale"][t]).astype(np.float64)
        added = (W[t] - A[t]).astype(np.float64)
        wrinkle = np.linalg.norm(true, axis=1) > 0.1
        error = np.linalg.norm(added - true, axis=1)[wrinkle].mean()
        assert error < 0.6 * np.linalg.norm(true, axis=1)[wrinkle].mean()
        assert np.linalg.norm(added, axis=1)[~truth["wrinkle_mask"]].max() < 0.05


def test_the_scans_expression_is_left_alone_and_frames_between_are_interpolated(
        animated_case: tuple[Path, Path], wrinkled: Path) -> None:
    _, animate = animated_case
    A = read_result(animate).frames().astype(np.float64)
    W = read_result(wrinkled).frames().astype(np.float64)
    # video frame 0 films the scan's expression: whatever crease it shows is in the scan already
    assert np.abs(W[0] - A[0]).max() < 1e-5
    # mocap frame 6 lies half-way between video frames 1 (mocap 4) and 2 (mocap 8)
    half = 0.5 * ((W[4] - A[4]) + (W[8] - A[8]))
    assert np.abs((W[6] - A[6]) - half).max() < 1e-5


def test_wrinkles_json_describes_every_video_frame(wrinkled: Path) -> None:
    doc = json.loads((wrinkled / "wrinkles.json").read_text())
    assert doc["units"] == "mm" and [f["video_frame"] for f in doc["frames"]] == [0, 1, 2]
    assert [f["mocap_frame"] for f in doc["frames"]] == [0.0, 4.0, 8.0]
    deep = [w for w in doc["frames"][2]["wrinkles"] if max(w["depth_mm"]) > 0.3]
    assert len(deep) >= 6  # forehead, frown, crow's feet and nasolabial folds at full expression
    for w in deep:
        assert len(w["points_mm"]) == len(w["depth_mm"]) == len(w["width_mm"]) == doc["curve_samples"]
        assert set(w["splines_px"]) == set(w["cameras"])
    performance = json.loads((wrinkled / "performance.json").read_text())
    assert performance["method"] == "bickel2007-medium-scale" and performance["anchored"] is True


def test_the_command_line_writes_the_same_result_and_refuses_bad_input(
        animated_case: tuple[Path, Path], wrinkled: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    case, animate = animated_case
    videos = [str(case / "cam_left"), str(case / "cam_right")]
    masks = [str(case / "mask_cam_left.png"), str(case / "mask_cam_right.png")]
    out = tmp_path / "cli"
    code = main(["-q", "wrinkles", "--result", str(animate), "--cameras", str(case / "cameras.json"),
                 "--video", *videos, "--masks", *masks, "--out", str(out)])
    assert code == 0
    assert np.array_equal(read_result(out).frames(), read_result(wrinkled).frames())
    # one mask for two cameras
    code = main(["-q", "wrinkles", "--result", str(animate), "--cameras", str(case / "cameras.json"),
                 "--video", *videos, "--masks", masks[0], "--out", str(tmp_path / "bad")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--masks" in err[0]
    assert not (tmp_path / "bad").exists()


def test_a_result_without_its_correspondence_map_is_refused(animated_case: tuple[Path, Path], tmp_path: Path) -> None:
    import shutil

    case, animate = animated_case
    copy = tmp_path / "old_result"
    shutil.copytree(animate, copy)
    (copy / "correspondence.npz").unlink()
    setup = read_camera_file(case / "cameras.json")
    with pytest.raises(InputError, match="correspondence"):
        capture_wrinkles(copy, setup.cameras, [case / c.name for c in setup.cameras],
                         [case / f"mask_{c.name}.png" for c in setup.cameras], tmp_path / "out", video_rate_hz=12.5)
    assert not (tmp_path / "out").exists()


def test_a_camera_that_does_not_see_the_face_is_refused(animated_case: tuple[Path, Path], tmp_path: Path) -> None:
    from dataclasses import replace

    case, animate = animated_case
    setup = read_camera_file(case / "cameras.json")
    # the right camera's pose two metres off: its footage still shows the paint, its calibration no face
    cameras = [setup.cameras[0], replace(setup.cameras[1], T=setup.cameras[1].T + np.array([2000.0, 0.0, 0.0]))]
    with pytest.raises(InputError, match="camera 'cam_right' does not see the face"):
        capture_wrinkles(animate, cameras, [case / c.name for c in cameras],
                         [case / f"mask_{c.name}.png" for c in cameras], tmp_path / "out", video_rate_hz=12.5)
    assert not (tmp_path / "out").exists()
    with pytest.raises(InputError, match="min_face_in_view"):
        capture_wrinkles(animate, cameras, [case / c.name for c in cameras],
                         [case / f"mask_{c.name}.png" for c in cameras], tmp_path / "out", video_rate_hz=12.5,
                         min_face_in_view=1.5)


def test_a_calibration_off_the_paint_is_flagged(animated_case: tuple[Path, Path]) -> None:
    from dataclasses import replace

    from facecap.cameras import open_footage, read_image
    from facecap.wrinkles import WrinkleFrameStage, check_cameras_see_the_face, check_paint_on_face, track_wrinkles

    case, animate = animated_case
    setup = read_camera_file(case / "cameras.json")
    first_curves = []
    for camera in setup.cameras:
        with open_footage(case / camera.name) as clip:
            tracked = track_wrinkles(clip, read_image(case / f"mask_{camera.name}.png"), camera=camera.name)
        first_curves.append([w.curve() for w in tracked[0]])
    # the face at video frame 0 in the mocap frame, as capture_wrinkles checks it
    stage = WrinkleFrameStage(str(animate), setup.cameras, [], [[] for _ in setup.cameras],
                              [setup.first_mocap_frame], 1)
    _, caster = stage.geometry(0)

    with warnings.catch_warnings():
        warnings.simplefilter("error", FacecapWarning)
        face = check_cameras_see_the_face(caster, setup.cameras)
        paint = check_paint_on_face(caster, setup.cameras, first_curves)
    # the true calibration: the stage cameras see a good part of the face and the paint is all on it
    assert all(0.3 < f < 0.9 for f in face) and all(p > 0.95 for p in paint)
    # the left camera 80 mm off (its translation): the face is still in view, the paint mostly is not on it
    moved = [replace(setup.cameras[0], T=setup.cameras[0].T + np.array([0.0, 80.0, 0.0])), setup.cameras[1]]
    assert check_cameras_see_the_face(caster, moved)[0] > 0.3
    with pytest.warns(FacecapWarning, match="camera 'cam_left': only") as caught:
        paint = check_paint_on_face(caster, moved, first_curves)
    assert not any("cam_right" in str(w.message) for w in caught)
    assert paint[0] < 0.5 and paint[1] > 0.95
    assert np.isnan(check_paint_on_face(caster, moved, [[], first_curves[1]])[0])  # tracks nothing: no check


def test_depth_edits_and_a_drawn_wrinkle(animated_case: tuple[Path, Path], wrinkled: Path, tmp_path: Path) -> None:
    from facecap.wrinkles import read_wrinkle_edits

    case, animate = animated_case
    setup = read_camera_file(case / "cameras.json")
    left = setup.camera("cam_left")
    doc = json.loads((wrinkled / "wrinkles.json").read_text())
    deepest = max(doc["frames"][2]["wrinkles"], key=lambda w: max(w["depth_mm"]))
    first_identity = deepest["wrinkle"].split("+")[0]
    # a valley drawn along the first forehead line's place in the left image at the neutral frame
    truth = np.load(case / "truth.npz")
    M = truth["mocap_from_scan"] @ truth["head_pose"][0]
    line = truth["curve_points"][0, list(truth["curve_names"]).index("forehead_0")].astype(np.float64)
    pixels = left.project(line @ M[:3, :3].T + M[:3, 3]).pixels[8:40]
    svg = "M " + " L ".join(f"{x:.2f} {y:.2f}" for x, y in pixels)
    edits = read_wrinkle_edits({
        "depth": [{"scale": 2.0, "wrinkles": [first_identity], "frames": [8, 8]}],
        "add": [{"camera": "cam_left", "frames": [0, 0], "depth_mm": 0.5, "width_mm": 2.0, "svg_path": svg}],
    })
    out = tmp_path / "edited"
    capture_wrinkles(animate, setup.cameras, [case / c.name for c in setup.cameras],
                     [case / f"mask_{c.name}.png" for c in setup.cameras], out, video_rate_hz=setup.video_rate_hz,
                     edits=edits)
    A = read_result(animate).frames().astype(np.float64)
    plain = read_result(wrinkled).frames().astype(np.float64) - A
    edited = read_result(out).frames().astype(np.float64) - A
    # outside the edit's frames nothing changes
    assert np.array_equal(edited[4], plain[4])
    # at mocap frame 8 the chosen wrinkle's valley is twice as deep: compare vertices on its line only
    points = np.asarray(deepest["points_mm"])
    from scipy.spatial import cKDTree

    near = cKDTree(points).query(A[8], distance_upper_bound=0.5)[0] < 0.5
    deep = near & (np.linalg.norm(plain[8], axis=1) > 0.1)
    ratio = np.linalg.norm(edited[8][deep], axis=1) / np.linalg.norm(plain[8][deep], axis=1)
    assert deep.sum() > 10 and abs(np.median(ratio) - 2.0) < 0.1
    # the drawn valley at the neutral frame: 0.5 mm deep under the drawn curve, where nothing was before
    assert np.abs(plain[0]).max() < 1e-5
    depth = np.linalg.norm(edited[0], axis=1)
    assert 0.4 < depth.max() < 0.55
    deepest_vertex = A[0][np.argmax(depth)]
    seen = left.project(deepest_vertex @ M[:3, :3].T + M[:3, 3]).pixels
    assert np.min(np.linalg.norm(pixels - seen, axis=1)) < 6.0
    drawn = [w for w in json.loads((out / "wrinkles.json").read_text())["frames"][0]["wrinkles"] if w["drawn"]]
    assert len(drawn) == 1 and drawn[0]["wrinkle"] == "cam_left:drawn_0"
    assert max(drawn[0]["depth_mm"]) == pytest.approx(0.5, abs=1e-4)


def test_bad_edit_files_are_refused_naming_the_entry(tmp_path: Path) -> None:
    from facecap.wrinkles import read_wrinkle_edits

    path = tmp_path / "edits.json"
    path.write_text(json.dumps({"add": [{"camera": "cam_left", "depth_mm": 0.5, "width_mm": 2.0}]}))
    with pytest.raises(InputError, match=r"edits.json: add\[0\]: give exactly one of"):
        read_wrinkle_edits(path)
    path.write_text(json.dumps({"depth": [{"scale": -1}]}))
    with pytest.raises(InputError, match=r"depth\[0\]: 'scale' must be >= 0"):
        read_wrinkle_edits(path)
    path.write_text("{not json")
    with pytest.raises(InputError, match="not JSON"):
        read_wrinkle_edits(path)
    with pytest.raises(InputError, match="svg_path"):
        read_wrinkle_edits({"add": [{"camera": "c", "depth_mm": 1, "width_mm": 1, "svg_path": "M 0 0"}]})


def test_svg_path_data_is_sampled_on_the_curve_it_describes(tmp_path: Path) -> None:
    from facecap.wrinkles import read_wrinkle_edits, svg_path_points

    points = svg_path_points("M 10 20 C 10 120 110 120 110 20", spacing_px=2.0)
    t = np.linspace(0, 1, 20001)[:, None]
    P0, P1, P2, P3 = (np.array(p, float) for p in ((10, 20), (10, 120), (110, 120), (110, 20)))
    bezier = (1 - t) ** 3 * P0 + 3 * (1 - t) ** 2 * t * P1 + 3 * (1 - t) * t**2 * P2 + t**3 * P3
    gaps = np.linalg.norm(points[:, None] - bezier[None], axis=2).min(axis=1)
    assert gaps.max() < 0.01 and np.allclose(points[[0, -1]], [P0, P3])
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert steps.max() < 2.2  # about every 2 px along the curve
    # the same path in an SVG file, as a drawing program writes it
    (tmp_path / "drawn.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="1384" height="1038">'
                                        '<path d="M 10 20 C 10 120 110 120 110 20" stroke="red"/></svg>')
    (tmp_path / "edits.json").write_text(json.dumps(
        {"add": [{"camera": "cam_left", "depth_mm": 0.5, "width_mm": 2.0, "svg_file": "drawn.svg"}]}))
    drawn = read_wrinkle_edits(tmp_path / "edits.json").add[0]
    assert np.allclose(drawn.curve_px, svg_path_points("M 10 20 C 10 120 110 120 110 20"))
