"""``facecap edit-muscles``: a solve-muscles result edited from its files, read back and checked.

One small model (the bundled ICT face at ``n_tets=2000``), 100 markers on the moving face, a 4-frame
take made by the forward model from known controls (the rest frame, then muscles ramping, the jaw
opening, the head turning), solved by ``facecap solve-muscles``; then each edit of the command on
that folder.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from muscle_cases import ramping_controls

from facecap.anatomy import load_anatomy
from facecap.cli import main
from facecap.io import read_result, write_markers
from facecap.muscles import JawConstraints, MuscleControls, MuscleModel, forward_markers, marker_embedding
from facecap.structures import MarkerSequence

N_MARKERS = 100
N_FRAMES = 4


class Case(NamedTuple):
    model_dir: Path
    result: Path
    muscles: tuple[str, ...]


def _rotation_y(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])


@pytest.fixture(scope="module")
def case(anatomy, tmp_path_factory) -> Case:
    root = tmp_path_factory.mktemp("edit_case")
    anatomy.save(root / "model")
    model = MuscleModel(anatomy)
    usable = np.flatnonzero(anatomy.skin_meshed & model.skin_follows)
    vertices = np.sort(np.random.default_rng(2).choice(usable, N_MARKERS, replace=False))
    V = anatomy.scan_vertices
    e = marker_embedding(anatomy, vertices, V[vertices])
    controls = ramping_controls(model.n_muscles, N_FRAMES, seed=7, peak=0.5,
                                jaw=lambda s: model.jaw.transform(np.radians(8 * s), 0.3 * s, 0.6 * s),
                                cranium=lambda s: np.hstack([_rotation_y(np.radians(3 * s)), [[s], [-s], [0.5 * s]]]))
    controls[0] = MuscleControls.rest(model.n_muscles)  # the rest frame: the scan's expression
    markers = np.stack([forward_markers(model, e, c).markers for c in controls])
    labels = [f"M{i:03d}" for i in range(N_MARKERS)]
    take = root / "take.csv"
    write_markers(MarkerSequence(markers, tuple(labels), rate=60.0), take)
    mapping = root / "map.json"
    mapping.write_text(json.dumps({label: int(v) for label, v in zip(labels, vertices)}))
    result = root / "solved"
    assert main(["-q", "solve-muscles", "--model", str(root / "model"), "--markers", str(take), "--map", str(mapping),
                 "--out", str(result), "--no-smooth", "--marker-offset", "0", "--rest-average", "0", "--scheduler", "synchronous"]) == 0
    return Case(root / "model", result, tuple(anatomy.muscle_names))


def _edit(case: Case, out: Path, *args: str) -> int:
    return main(["-q", "edit-muscles", "--result", str(case.result), "--out", str(out), *args])


def _activations(out: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    with open(out / "activations.csv", newline="") as f:
        rows = list(csv.reader(f))
    table = np.array(rows[1:], dtype=np.float64)
    return rows[0], table[:, 0].astype(int), table[:, 1:]


def _skin(out: Path) -> np.ndarray:
    result = read_result(out)
    return result.frames().astype(np.float64) * result.mm_per_unit


def test_interpolation_round_trip(case, tmp_path) -> None:
    out = tmp_path / "between"
    assert _edit(case, out, "--interpolate", "0", "3", "--frames", "7") == 0
    skin, source = _skin(out), _skin(case.result)
    assert skin.shape == (7, source.shape[1], 3)
    # the ends are the solved frames' faces (the solve's own tolerance: rigid and on the joint to 1e-5)
    for j, frame in ((0, 0), (6, 3)):
        error = np.linalg.norm(skin[j] - source[frame], axis=1)
        assert error.max() < 0.01, (j, error.max())
    header, numbers, activations = _activations(out)
    _, _, solved = _activations(case.result)
    assert header == ["frame", *case.muscles] and numbers.tolist() == list(range(7))
    s = np.linspace(0, 1, 7)[:, None]
    np.testing.assert_allclose(activations, np.clip((1 - s) * solved[0] + s * solved[3], 0, 1), atol=1e-6)
    with np.load(out / "bone_transforms.npz") as bones, np.load(case.result / "bone_transforms.npz") as before:
        pose = bones["jaw_pose"]
        np.testing.assert_allclose(pose[3], 0.5 * (before["jaw_pose"][0] + before["jaw_pose"][3]), atol=2e-5)
        R = bones["cranium"][:, :, :3]
        assert np.abs(np.einsum("tji,tjk->tik", R, R) - np.eye(3)).max() < 1e-12
        # every frame on the joint: psi1-psi6 met (the ends' 1e-5 of the solve clipped away)
        jaw = JawConstraints.from_anatomy(load_anatomy(case.model_dir))
        assert max(jaw.violations(m).max() for m in bones["mandible"]) < 1e-9
        # (the solve's frames are on the joint only to its tolerance: 7.5e-8 to 1e-5 seen, so the clip is what
        # puts the edited ones within 1e-9)
        assert max(jaw.violations(m).max() for m in before["mandible"]) > 1e-8
    report = json.loads((out / "report.json").read_text())
    assert report["not_converged_frames"] == [] and max(report["inverted_tets"]) == 0
    assert report["jaw_violation_max"] < 1e-9
    info = json.loads((out / "performance.json").read_text())
    assert info["method"] == "sifakis2005-muscle-edit" and info["edit"]["kind"] == "interpolate"
    assert info["edit"]["from_frame"] == 0 and info["edit"]["to_frame"] == 3
    assert not (out / "markers.npy").exists()


def test_exaggeration_round_trip(case, tmp_path) -> None:
    # scale 1 gives the input back; 2 pushes every moving vertex further from its unexaggerated place
    source = _skin(case.result)
    assert _edit(case, tmp_path / "x1", "--scale-force-length", "1") == 0
    same = np.linalg.norm(_skin(tmp_path / "x1") - source, axis=2)
    assert same.max() < 0.01, same.max()
    assert _edit(case, tmp_path / "x2", "--scale-force-length", "2") == 0
    doubled = _skin(tmp_path / "x2")
    change = np.linalg.norm(doubled - source, axis=2)
    assert change[1:].max(axis=1).min() > 0.5  # every frame with activations changes visibly
    _, numbers, activations = _activations(tmp_path / "x2")
    _, _, solved = _activations(case.result)
    assert numbers.tolist() == list(range(N_FRAMES)) and np.array_equal(activations, np.clip(solved, 0, 1))
    info = json.loads((tmp_path / "x2" / "performance.json").read_text())
    assert info["edit"] == {"kind": "scale_force_length", "force_length_scale": 2.0}
    assert read_result(tmp_path / "x2").markers is not None  # the take's markers, as the source's


def _normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    normals = np.zeros_like(V)
    face_normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for corner in range(3):
        np.add.at(normals, F[:, corner], face_normals)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_sphere_round_trip(case, tmp_path) -> None:
    source = _skin(case.result)
    faces = read_result(case.result).mesh.faces
    # a 15 mm sphere pressed 3 mm into the left cheek, moving with it from the first frame to the last
    rest = load_anatomy(case.model_dir).scan_vertices
    first, last = _normals(source[0], faces), _normals(source[-1], faces)
    cheek = np.flatnonzero((rest[:, 0] > 40) & (rest[:, 1] > -35) & (rest[:, 1] < -5))
    i = cheek[np.argmax(first[cheek] @ [0.5, 0.0, 0.85])]
    radius = 15.0
    start = source[0, i] + (radius - 3.0) * first[i]
    end = source[-1, i] + (radius - 3.0) * last[i]
    out = tmp_path / "sphere"
    assert _edit(case, out, "--sphere", *map(str, start), str(radius), "--sphere-to", *map(str, end)) == 0
    skin = _skin(out)
    report = json.loads((out / "report.json").read_text())
    assert report["not_converged_frames"] == [] and max(report["inverted_tets"]) == 0
    for j, centre in enumerate(np.linspace(0, 1, N_FRAMES)[:, None] * (end - start) + start):
        depth = radius - np.linalg.norm(skin[j] - centre, axis=1)
        assert depth.max() <= 0.05 + 1e-4, (j, depth.max())  # (+ the float32 of vertices.npy)
        before = radius - np.linalg.norm(source[j] - centre, axis=1)
        assert before.max() > 2.5  # the sphere did reach into the face
        assert np.linalg.norm(skin[j, i] - source[j, i]) > 2.5  # and pushed it in
    assert report["sphere"]["max_scan_penetration_mm"] <= 0.05
    assert report["sphere"]["max_skin_node_penetration_mm"] <= 0.05
    force = np.array(report["sphere"]["force_mn"])
    assert np.all(np.einsum("ij,ij->i", force, np.stack([first[i], first[i], last[i], last[i]])) < 0)  # inwards
    # the other side of the face is untouched
    right = rest[:, 0] < -40
    assert np.abs(skin[:, right] - source[:, right]).max() < 0.05


@pytest.mark.parametrize("args, message", [
    (["--scale-force-length", "0"], "positive"),
    (["--scale-force-length", "-1"], "positive"),
    (["--interpolate", "0", "9"], "frame 9 is not in the result"),
    (["--sphere", "0", "0", "0", "-2"], "positive radius"),
    (["--sphere", "0", "0", "0", "nan"], "finite"),
    (["--scale-force-length", "2", "--frames", "5"], "--frames: only with --interpolate"),
    (["--interpolate", "0", "2", "--frames", "1"], "at least 2"),
])
def test_bad_input_is_one_line_naming_the_file(case, tmp_path, capsys, args, message) -> None:
    out = tmp_path / "out"
    assert _edit(case, out, *args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("facecap: error:") and message in err[0], err
    assert not out.exists()


def test_a_missing_result_or_model_is_one_line_naming_it(case, tmp_path, capsys) -> None:
    missing = tmp_path / "nothing"
    assert main(["-q", "edit-muscles", "--result", str(missing), "--out", str(tmp_path / "o"),
                 "--scale-force-length", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0] and "no such result folder" in err[0]
    assert _edit(case, tmp_path / "o", "--scale-force-length", "2", "--model", str(missing)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0]
    # a result without its activations
    broken = tmp_path / "broken"
    broken.mkdir()
    for name in ("performance.json", "bone_transforms.npz"):
        (broken / name).write_bytes((case.result / name).read_bytes())
    assert main(["-q", "edit-muscles", "--result", str(broken), "--out", str(tmp_path / "o"),
                 "--scale-force-length", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(broken / "activations.csv") in err[0]
    assert not (tmp_path / "o").exists()
