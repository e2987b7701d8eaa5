"""The command line: exit codes, one-line errors naming the file, nothing written on failure."""

import json
from pathlib import Path

import numpy as np
import pytest

from facecap.cli import main
from facecap.io import write_markers
from facecap.structures import MarkerSequence


def _animate(case, out, *extra):
    return main(["--quiet", "animate", "--scan", str(case.scan_path), "--markers", str(case.markers_path),
                 "--map", str(case.map_path), "--out", str(out), *extra])


def _one_line_error(capsys, *needles):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("facecap: error: ")
    for needle in needles:
        assert needle in err[0], err[0]
    assert "Traceback" not in err[0]


def test_animate_then_info_and_evaluate(capture_case, tmp_path, capsys):
    out = tmp_path / "result"
    assert _animate(capture_case, out, "--stabilize", "auto", "--export", "usd") == 0
    assert (out / "vertices.npy").exists() and (out / "performance.usdc").exists()
    capsys.readouterr()
    V = np.load(out / "vertices.npy")
    # the stabilised face against the expression-only truth
    assert main(["evaluate", "--truth", str(capture_case.truth_path), "--result", str(out), "--json",
                 "--frame", "stabilized"]) == 0
    summary = json.loads(capsys.readouterr().out)
    expected = np.linalg.norm(V - capture_case.truth.astype(np.float32), axis=2)
    assert summary["mean_mm"] == pytest.approx(float(expected.mean()), rel=1e-4)
    assert summary["max_mm"] == pytest.approx(float(expected.max()), rel=1e-5)
    # by default in the world: the face moved by the head motion it wrote, the truth by the true one
    assert main(["evaluate", "--truth", str(capture_case.truth_path), "--result", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    motion = np.load(out / "head_motion.npy")
    truth_pose = np.tile(np.eye(4), (motion.shape[0], 1, 1))  # the case's head does not move
    world = np.einsum("tij,tnj->tni", motion[:, :3, :3], V) + motion[:, None, :3, 3]
    world_truth = (np.einsum("tij,tnj->tni", truth_pose[:, :3, :3], capture_case.truth.astype(np.float64))
                   + truth_pose[:, None, :3, 3])
    expected = np.linalg.norm(world - world_truth, axis=2)
    assert summary["mean_mm"] == pytest.approx(float(expected.mean()), rel=1e-4)
    assert main(["info", str(capture_case.markers_path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["markers"] == 34 and info["frames"] == 40 and info["rate_hz"] == 60.0
    assert main(["info", str(capture_case.scan_path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["vertices"] == len(capture_case.V) and info["triangles"] == len(capture_case.F)
    assert main(["info", str(out)]) == 0
    assert "facecap result" in capsys.readouterr().out


def test_truncated_c3d(capture_case, tmp_path, capsys):
    data = capture_case.markers_path.read_bytes()
    capture_case.markers_path.write_bytes(data[: len(data) // 2])
    out = tmp_path / "result"
    assert _animate(capture_case, out) == 2
    _one_line_error(capsys, "take.c3d")
    assert not out.exists()


def test_trc_with_missing_columns(capture_case, tmp_path, capsys):
    trc = tmp_path / "take.trc"
    write_markers(MarkerSequence(capture_case.take.positions, capture_case.take.labels, 60.0), trc)
    lines = trc.read_text().splitlines()
    lines[-1] = "\t".join(lines[-1].split("\t")[:10])  # a data row cut short
    trc.write_text("\n".join(lines) + "\n")
    capture_case.markers_path = trc
    assert _animate(capture_case, tmp_path / "result") == 2
    _one_line_error(capsys, "take.trc")
    assert not (tmp_path / "result").exists()


def test_obj_with_face_index_out_of_range(capture_case, tmp_path, capsys):
    with open(capture_case.scan_path, "a") as fh:
        fh.write("f 1 2 99999\n")
    assert _animate(capture_case, tmp_path / "result") == 2
    _one_line_error(capsys, "scan.obj", "99999")
    assert not (tmp_path / "result").exists()


@pytest.mark.parametrize(
    "entry, needle",
    [({"NOT_A_MARKER": 3}, "NOT_A_MARKER"), ({"M00": 10**7}, "10000000")],
)
def test_map_naming_a_missing_marker_or_vertex(capture_case, tmp_path, capsys, entry, needle):
    mapping = json.loads(capture_case.map_path.read_text())
    mapping.update(entry)
    capture_case.map_path.write_text(json.dumps(mapping))
    assert _animate(capture_case, tmp_path / "result") == 2
    _one_line_error(capsys, "map.json", needle)
    assert not (tmp_path / "result").exists()


def test_all_markers_missing_at_the_rest_frame(capture_case, tmp_path, capsys):
    P = capture_case.take.positions.copy()
    P[5] = np.nan
    write_markers(MarkerSequence(P, capture_case.take.labels, 60.0), capture_case.markers_path)
    assert _animate(capture_case, tmp_path / "result", "--rest-frame", "5") == 2
    _one_line_error(capsys, "take.c3d", "rest frame 5")
    assert not (tmp_path / "result").exists()


def test_fewer_than_four_usable_markers(capture_case, tmp_path, capsys):
    mapping = dict(list(json.loads(capture_case.map_path.read_text()).items())[:3])
    capture_case.map_path.write_text(json.dumps(mapping))
    assert _animate(capture_case, tmp_path / "result") == 2
    _one_line_error(capsys, "at least 4")
    assert not (tmp_path / "result").exists()


def test_missing_file_and_unknown_export(capture_case, tmp_path, capsys):
    capture_case.scan_path = tmp_path / "nope.obj"
    assert _animate(capture_case, tmp_path / "result") == 2
    _one_line_error(capsys, "nope.obj")


def test_unknown_export_format(capture_case, tmp_path, capsys):
    assert _animate(capture_case, tmp_path / "result", "--export", "fbx") == 2
    _one_line_error(capsys, "fbx")
    assert not (tmp_path / "result").exists()


def test_synth_writes_a_case_and_its_footage(tmp_path, capsys):
    import json as _json

    import numpy as np

    from facecap.cameras import open_footage, read_camera_file
    from facecap.io import read_markers, read_mesh
    from facecap.synth.ict_sample import load_ict_sample
    from facecap.synth.wrinkle_scan import subdivide_scan

    assert main(["-q", "synth", "--out", str(tmp_path / "a"), "--frames", "12", "--seed", "2"]) == 0
    assert main(["-q", "synth", "--out", str(tmp_path / "b"), "--frames", "12", "--seed", "2", "--identity", "4"]) == 0
    take = read_markers(tmp_path / "a" / "take.c3d")
    truth = np.load(tmp_path / "a" / "truth.npz")
    assert take.n_frames == 12 and truth["vertices"].shape[0] == 12
    a, b = read_mesh(tmp_path / "a" / "scan.obj"), read_mesh(tmp_path / "b" / "scan.obj")
    assert a.n_vertices == b.n_vertices and np.abs(a.vertices - b.vertices).max() > 1.0  # another actor
    assert len(_json.loads((tmp_path / "a" / "map.json").read_text())) == take.n_markers - 4  # less the head band

    # one subdivision (37k vertices), rendered from the scan itself, keeps the test short; the default's two and
    # the refined rendering are write_footage_case's tests
    assert main(["-q", "synth", "--out", str(tmp_path / "f"), "--frames", "5", "--footage", "--levels", "1",
                 "--render-edge", "0"]) == 0
    assert _json.loads((tmp_path / "f" / "footage.json").read_text())["render_edge_mm"] is None
    ict = load_ict_sample().mesh
    assert read_mesh(tmp_path / "f" / "scan.obj").n_vertices == subdivide_scan(ict, levels=1).mesh.n_vertices
    setup = read_camera_file(tmp_path / "f" / "cameras.json")
    assert len(setup.cameras) == 2 and setup.video_rate_hz == 12.5
    for camera in setup.cameras:
        with open_footage(tmp_path / "f" / camera.name) as footage:
            assert len(footage) == 2 and footage.frame(0).shape[:2] == (camera.height, camera.width)
    truth = np.load(tmp_path / "f" / "truth.npz")
    assert truth["vertices"].shape == truth["large_scale"].shape and truth["wrinkle_mask"].any()

    assert main(["synth", "--out", str(tmp_path / "bad"), "--frames", "1"]) == 2
    assert "--frames" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    assert main(["synth", "--out", str(tmp_path / "bad"), "--frames", "5", "--levels", "3"]) == 2
    assert "--levels" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    assert main(["synth", "--out", str(tmp_path / "bad"), "--frames", "5", "--footage", "--levels", "-1"]) == 2
    assert "levels" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    for bad in (["--footage", "--render-edge", "0.01"], ["--footage", "--render-edge", "inf"],
                ["--footage", "--render-edge", "nan"], ["--render-edge", "0.3"]):
        assert main(["synth", "--out", str(tmp_path / "bad"), "--frames", "5", *bad]) == 2
        assert "--render-edge" in capsys.readouterr().err and not (tmp_path / "bad").exists()


def test_synth_renders_footage_from_the_refined_scan_by_default(tmp_path, monkeypatch):
    import importlib

    # the module itself: the package re-exports its function under the same name
    footage_module = importlib.import_module("facecap.synth.write_footage_case")

    asked = []

    def record(out, **options):  # stands in for the renderer: only the argument the CLI passes is checked here
        asked.append(options["render_edge_mm"])
        (Path(out) / "truth.npz").write_bytes(b"")

    monkeypatch.setattr(footage_module, "write_footage_case", record)
    for extra, expected in (([], footage_module.RENDER_EDGE_MM), (["--render-edge", "0"], None),
                            (["--render-edge", "0.5"], 0.5)):
        assert main(["-q", "synth", "--out", str(tmp_path / str(len(asked))), "--frames", "5", "--footage", *extra]) == 0
        assert asked[-1] == expected
