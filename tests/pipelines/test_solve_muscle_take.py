"""``facecap solve-muscles``: a take made by the forward model from known controls, solved from its files.

One small model (the bundled ICT face at ``n_tets=2000``, about 3,900 tetrahedra), 120 markers 1.5 mm
above the skin, a 6-frame take with 0.2 mm noise written as a CSV with a JSON map. The truth (controls,
noise-free skin) comes from :func:`facecap.muscles.forward_markers` on a model of its own.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from facecap.cli import main
from facecap.io import read_markers, read_result, write_markers
from facecap.muscles import FOLLOWER_WEIGHT_LIMIT, MuscleControls, MuscleModel, forward_markers, marker_embedding
from facecap.structures import MarkerSequence
from facecap.synth import choose_marker_vertices
from facecap.io.ict_sample import load_ict_sample

N_MARKERS = 120
N_FRAMES = 6
NOISE_MM = 0.2


class Case(NamedTuple):
    model_dir: Path
    take: Path
    map: Path
    labels: list[str]
    muscles: tuple[str, ...]
    activations: np.ndarray  # (T, k) the known controls
    jaw_pose: np.ndarray  # (T, 3)
    skin: np.ndarray  # (T, n, 3) noise-free forward skin, mm
    crania: np.ndarray  # (T, 3, 4) the head's frames


@pytest.fixture(scope="module")
def case(anatomy, tmp_path_factory) -> Case:
    root = tmp_path_factory.mktemp("muscle_case")
    anatomy.save(root / "model")
    model = MuscleModel(anatomy)
    # the layout of tests/muscles/conftest.py: denser where the muscles and the jaw move the skin
    model.equilibrium(np.zeros(model.n_muscles), np.eye(3, 4))
    dXa, dXb = model.jacobians()
    rest_skin = model.skin(model.rest_positions)
    deltas = np.stack([model.skin(model.rest_positions + d) - rest_skin for d in np.concatenate([dXa, 0.2 * dXb[:9]])])
    V, F = anatomy.scan_vertices, anatomy.scan_faces
    vertices = choose_marker_vertices(V, F, deltas, N_MARKERS, exclude=~(anatomy.skin_meshed & model.skin_follows))
    normals = np.zeros_like(V)
    face_normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for corner in range(3):
        np.add.at(normals, F[:, corner], face_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    e = marker_embedding(anatomy, vertices, V[vertices] + 1.5 * normals[vertices])
    # frame 0 the scan's expression; then muscles ramp in, the jaw opens and slides, the head turns and moves
    rng = np.random.default_rng(5)
    k = model.n_muscles
    target = rng.uniform(0, 0.6, k) * (rng.uniform(size=k) < 0.5)
    activations, poses, skin, markers, crania = [], [], [], [], []
    for t in range(N_FRAMES):
        s = t / (N_FRAMES - 1)
        turn = np.radians(2.0 * s)
        cranium = np.hstack([[[np.cos(turn), 0, np.sin(turn)], [0, 1, 0], [-np.sin(turn), 0, np.cos(turn)]],
                             [[1.0 * s], [-0.5 * s], [0.5 * s]]])
        c = MuscleControls(s * target, cranium, model.jaw.transform(np.radians(6 * s), 0.5 * s, s))
        truth = forward_markers(model, e, c, noise_mm=NOISE_MM, seed=100 + t)
        activations.append(c.activations)
        crania.append(cranium)
        poses.append(model.jaw.pose(c.mandible))
        skin.append(truth.skin)
        markers.append(truth.markers)
    labels = [f"M{i:03d}" for i in range(N_MARKERS)]
    take = root / "take.csv"
    write_markers(MarkerSequence(np.stack(markers), tuple(labels), rate=60.0), take)
    mapping = root / "map.json"
    mapping.write_text(json.dumps({label: int(v) for label, v in zip(labels, vertices)}))
    return Case(root / "model", take, mapping, labels, tuple(anatomy.muscle_names), np.stack(activations),
                np.stack(poses), np.stack(skin), np.stack(crania))


def _solve(case: Case, out: Path, *extra: str) -> int:
    return main(["-q", "solve-muscles", "--model", str(case.model_dir), "--markers", str(case.take),
                 "--map", str(case.map), "--out", str(out), "--no-smooth", "--rest-average", "0", *extra])


def _activations(out: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    with open(out / "activations.csv", newline="") as f:
        rows = list(csv.reader(f))
    table = np.array(rows[1:], dtype=np.float64)
    return rows[0], table[:, 0].astype(int), table[:, 1:]


@pytest.fixture(scope="module")
def solved(case, tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("solved")
    assert _solve(case, root / "out", "--scheduler", "synchronous", "--work", str(root / "work"),
                  "--chunk-frames", "3", "--max-warm-steps", "3") == 0
    return root / "out", root / "work"


def test_the_result_folder_holds_the_forward_models_face(case, solved, anatomy) -> None:
    out, _ = solved
    result = read_result(out)
    assert (result.n_frames, result.n_vertices) == (N_FRAMES, case.skin.shape[1]) and result.rate == 60.0
    frames = result.frames().astype(np.float64) * result.mm_per_unit
    error = np.linalg.norm(frames - case.skin, axis=2)  # every scan vertex, every frame
    # A vertex carried by the affine extension of a tetrahedron it lies outside (inner lips and
    # eyelids: weights up to FOLLOWER_WEIGHT_LIMIT) gets its corners' errors times the sum of its
    # weights' magnitudes, so the tail is judged per unit of that amplification (1 inside the mesh;
    # 1 for the vertices that move rigidly with the cranium). fTetWild's mesh differs from build to
    # build, and that tail with it: over 42 builds its 99th percentile ranged 0.29-0.63 mm unnormalised
    # (0.63 failed a CI run), and over 22 of them 0.26-0.43 mm normalised.
    weights = np.abs(np.asarray(anatomy.skin_weights))
    amplification = np.where(weights.max(axis=1) <= FOLLOWER_WEIGHT_LIMIT, weights.sum(axis=1), 1.0)
    assert error.mean() < NOISE_MM, error.mean()
    assert np.percentile(error / amplification, 99) < 3 * NOISE_MM, (np.percentile(error / amplification, 99), error.max())
    # activations.csv: the muscles by name, one row per frame, the known controls back
    header, numbers, activations = _activations(out)
    assert header == ["frame", *case.muscles] and numbers.tolist() == list(range(N_FRAMES))
    assert np.abs(activations - case.activations).mean() <= 0.05
    assert activations.min() >= -1e-4 and activations.max() <= 1 + 1e-4
    # the jaw in bone_transforms.npz
    with np.load(out / "bone_transforms.npz") as bones:
        assert bones["cranium"].shape == (N_FRAMES, 3, 4) and bones["mandible"].shape == (N_FRAMES, 3, 4)
        assert np.abs(np.degrees(bones["jaw_pose"][:, 0] - case.jaw_pose[:, 0])).max() < 0.5
        assert bones["frames"].tolist() == list(range(N_FRAMES))
    # report.json: per-frame marker residuals at the noise level (3-D norm of 0.2 mm per axis: 0.35 mm rms)
    report = json.loads((out / "report.json").read_text())
    residual = np.array(report["marker_residual_mm"]["per_frame"], dtype=np.float64)
    assert residual.shape == (N_FRAMES, N_MARKERS) and report["marker_residual_mm"]["labels"] == case.labels
    assert 0.25 < report["marker_residual_mm"]["rms"] < 0.45
    assert report["cold_frames"] == [0, 3] and report["frames_flagged"] == 0
    info = json.loads((out / "performance.json").read_text())
    assert info["method"] == "sifakis2005-muscle-activations" and info["muscles"] == list(case.muscles)
    assert info["retarget"] == "rigid" and not info["stabilized"] and not (out / "head_motion.npy").exists()
    assert (out / "activations.png").stat().st_size > 10_000
    assert result.markers is not None and result.markers.shape == (N_FRAMES, N_MARKERS, 3)


def test_a_resumed_run_skips_finished_chunks_and_gives_the_same_bytes(case, solved, tmp_path) -> None:
    out, work = solved
    chunks = sorted((work / "chunks").glob("chunk-*.npz"))
    assert len(chunks) == 2
    first = chunks[0].stat()
    chunks[1].unlink()  # as if the run had stopped after its first chunk
    again = tmp_path / "again"
    assert _solve(case, again, "--scheduler", "synchronous", "--work", str(work), "--chunk-frames", "3",
                  "--max-warm-steps", "3") == 0
    kept = chunks[0].stat()
    assert (kept.st_ino, kept.st_mtime_ns) == (first.st_ino, first.st_mtime_ns)  # not computed again
    report = json.loads((again / "report.json").read_text())
    assert report["runner"] == {"chunks": 2, "computed": [1], "reused": [0]}
    for name in ("vertices.npy", "activations.csv", "bone_transforms.npz", "markers.npy"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name


def test_a_frame_range_is_that_part_of_the_take(case, solved, tmp_path) -> None:
    """--frames 3:6 in chunks of 3 is the full run's second chunk: the same frames, bit for bit."""
    out, _ = solved
    part = tmp_path / "part"
    assert _solve(case, part, "--scheduler", "synchronous", "--frames", "3:6", "--chunk-frames", "3",
                  "--max-warm-steps", "3") == 0
    result = read_result(part)
    assert result.n_frames == 3
    assert np.array_equal(result.frames(), read_result(out).frames(3, 6))
    _, numbers, activations = _activations(part)
    assert numbers.tolist() == [3, 4, 5]
    assert np.array_equal(activations, _activations(out)[2][3:])
    info = json.loads((part / "performance.json").read_text())
    assert info["frames"] == [3, 6] and info["first_frame"] == 3


def test_the_local_cluster_gives_the_synchronous_result(case, solved, tmp_path) -> None:
    """Two worker processes (the default scheduler), with a USD export: the frames of the in-process run."""
    out, _ = solved
    local = tmp_path / "local"
    assert _solve(case, local, "--workers", "2", "--chunk-frames", "3", "--max-warm-steps", "3",
                  "--export", "usd") == 0
    report = json.loads((local / "report.json").read_text())
    assert report["runner"]["computed"] == [0, 1]
    assert np.abs(read_result(local).frames() - read_result(out).frames()).max() < 1e-4
    assert np.abs(_activations(local)[2] - _activations(out)[2]).max() < 1e-5
    # the face in the USD is the scan's own: the ICT face's quads and UVs, not the solver's triangles
    from pxr import Usd, UsdGeom

    scan = load_ict_sample().mesh
    stage = Usd.Stage.Open(str(local / "performance.usdc"))  # held: its prims die with it
    face = UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face"))
    sizes, _ = scan.export_polygons()
    assert list(face.GetFaceVertexCountsAttr().Get()) == list(sizes) and max(sizes) == 4
    st = UsdGeom.PrimvarsAPI(face.GetPrim()).GetPrimvar("st")
    np.testing.assert_allclose(np.array(st.Get()), scan.uvs, atol=1e-6)


@pytest.mark.parametrize("problem", ["no model", "not a model", "map names markers not in the take",
                                     "too few markers on the model", "frames outside the take"])
def test_bad_input_is_one_line_naming_the_file(case, tmp_path, capsys, problem) -> None:
    args = {"--model": str(case.model_dir), "--markers": str(case.take), "--map": str(case.map)}
    named = None
    if problem == "no model":
        args["--model"] = named = str(tmp_path / "nowhere")
    elif problem == "not a model":
        (tmp_path / "empty").mkdir()
        args["--model"] = str(tmp_path / "empty")
        named = str(tmp_path / "empty" / "anatomy.json")
    elif problem == "map names markers not in the take":
        doc = json.loads(case.map.read_text())
        doc["NOSE_TIP"] = 0
        args["--map"] = named = str(tmp_path / "map.json")
        Path(named).write_text(json.dumps(doc))
    elif problem == "too few markers on the model":
        from facecap.anatomy import load_anatomy

        off = np.flatnonzero(~load_anatomy(case.model_dir).skin_meshed)  # ear, scalp, neck vertices
        doc = json.loads(case.map.read_text())
        doc = {label: (v if i < 5 else int(off[i % off.size])) for i, (label, v) in enumerate(doc.items())}
        args["--map"] = named = str(tmp_path / "map.json")
        Path(named).write_text(json.dumps(doc))
    else:
        named = str(case.take)
    argv = ["solve-muscles", *[x for kv in args.items() for x in kv], "--out", str(tmp_path / "out"),
            "--scheduler", "synchronous"]
    if problem == "frames outside the take":
        argv += ["--frames", "4:20"]
    assert main(argv) != 0
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("facecap: error:")]
    assert len(errors) == 1 and named in errors[0], err
    if problem == "too few markers on the model":
        assert "only 5 markers land on the model" in errors[0]
    assert not (tmp_path / "out").exists()


def test_markers_off_the_model_are_left_out_with_a_warning(case, solved, tmp_path, capsys) -> None:
    """A real map has markers the face model cannot carry (eyelids, ears): the solve goes on without them."""
    from facecap.anatomy import load_anatomy

    off = int(np.flatnonzero(~load_anatomy(case.model_dir).skin_meshed)[0])
    doc = json.loads(case.map.read_text())
    doc["M007"] = off
    moved = tmp_path / "map.json"
    moved.write_text(json.dumps(doc))
    out = tmp_path / "out"
    assert main(["solve-muscles", "--model", str(case.model_dir), "--markers", str(case.take), "--map", str(moved),
                 "--out", str(out), "--no-smooth", "--rest-average", "0", "--scheduler", "synchronous", "--frames", "0:3",
                 "--chunk-frames", "3", "--max-warm-steps", "3"]) == 0
    err = capsys.readouterr().err
    assert "M007" in err and "left out of the solve" in err
    report = json.loads((out / "report.json").read_text())
    assert report["markers_left_out"] == ["M007"] and "M007" not in report["marker_residual_mm"]["labels"]
    assert len(report["marker_residual_mm"]["labels"]) == N_MARKERS - 1
    assert read_result(out).markers.shape == (3, N_MARKERS - 1, 3)
    # the other 119 markers still give the forward model's face (as with all 120, test above)
    error = np.linalg.norm(read_result(out).frames().astype(np.float64) - case.skin[:3], axis=2)
    assert error.mean() < NOISE_MM, error.mean()


def test_a_take_of_another_face_is_warped_onto_the_scan(case, tmp_path, capsys) -> None:
    """The take 10 % larger than the scan (another actor's face): no rigid fit places it (markers 6-8 mm off), so
    'auto' maps it by animate's triharmonic warp, stabilised, and the known controls still come back.

    The take holds its rest for 8 frames at 30 Hz first: the rest markers are then the default average round
    the rest frame (0.1 s, 2.5 sigma = 8 frames) of the rest alone, as in a real take."""
    take = read_markers(case.take)
    held = 8
    positions = np.concatenate([np.repeat(take.positions[:1], held, axis=0), take.positions])
    centre = np.nanmean(take.positions[0], axis=0)
    bigger = tmp_path / "bigger.csv"
    write_markers(MarkerSequence(centre + 1.1 * (positions - centre), take.labels, rate=30.0), bigger)
    out = tmp_path / "out"
    assert main(["solve-muscles", "--model", str(case.model_dir), "--markers", str(bigger), "--map", str(case.map),
                 "--out", str(out), "--no-smooth", "--scheduler", "synchronous", "--chunk-frames", "14",
                 "--max-warm-steps", "3"]) == 0
    assert "triharmonic warp" in capsys.readouterr().err
    info = json.loads((out / "performance.json").read_text())
    assert info["retarget"] == "warp" and info["stabilized"] and info["take_to_scan_at_rest"] is None
    assert info["parameters"]["rest_average_s"] == 0.1
    result = read_result(out)
    assert result.head_motion.shape == (held + N_FRAMES, 4, 4)
    _, _, activations = _activations(out)
    assert np.abs(activations[held:] - case.activations).mean() <= 0.05
    with np.load(out / "bone_transforms.npz") as bones:
        assert np.abs(np.degrees(bones["jaw_pose"][held:, 0] - case.jaw_pose[:, 0])).max() < 0.5
        solved_crania = bones["cranium"][held:]
    # the expression itself, the head's frame taken out: the solved one from the result, the true one from the truth
    V = result.frames().astype(np.float64)[held:]
    for t in range(N_FRAMES):
        M, m = solved_crania[t][:, :3], solved_crania[t][:, 3]
        C, c = case.crania[t][:, :3], case.crania[t][:, 3]
        face = np.linalg.solve(M, (V[t] - m).T).T
        truth = np.linalg.solve(C, (case.skin[t] - c).T).T
        assert np.linalg.norm(face - truth, axis=1).mean() < 2 * NOISE_MM, t
