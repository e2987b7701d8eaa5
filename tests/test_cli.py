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


@pytest.mark.parametrize("neutral, needle", [("5:2", "--neutral 5:2"), ("0:1000", "0 <= A < B <= 40"),
                                             ("missing.c3d", "missing.c3d"), ("few.trc", "at least 4")])
def test_a_bad_neutral_reference_is_one_line_and_writes_nothing(capture_case, tmp_path, capsys, neutral, needle):
    if neutral == "few.trc":  # a neutral take holding 3 of the map's markers
        take = capture_case.take
        write_markers(MarkerSequence(take.positions[:, :3], take.labels[:3], 60.0), tmp_path / "few.trc")
    assert _animate(capture_case, tmp_path / "result", "--neutral", str(tmp_path / neutral)
                    if neutral.endswith(("c3d", "trc")) else neutral) == 2
    _one_line_error(capsys, needle)
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
    from facecap.io.ict_sample import load_ict_sample
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


def test_synth_detail_preset_asks_for_the_detail_footage(tmp_path, monkeypatch, capsys):
    import importlib

    detail_module = importlib.import_module("facecap.synth.write_detail_case")
    asked = []

    def record(out, **options):  # stands in for the renderer: the preset's arguments only
        asked.append(options)
        (Path(out) / "truth.npz").write_bytes(b"")

    monkeypatch.setattr(detail_module, "write_detail_case", record)
    assert main(["-q", "synth", "--out", str(tmp_path / "d"), "--frames", "5", "--footage", "--detail"]) == 0
    assert asked[-1]["appearance"] == "phong" and asked[-1]["n_frames"] == 5 and asked[-1]["levels"] == 2
    assert main(["-q", "synth", "--out", str(tmp_path / "i"), "--frames", "5", "--footage", "--detail",
                 "--appearance", "independent"]) == 0
    assert asked[-1]["appearance"] == "independent"
    for bad, named in ((["--detail"], "--detail"), (["--footage", "--appearance", "independent"], "--appearance"),
                       (["--footage", "--detail", "--render-edge", "0.3"], "--render-edge")):
        assert main(["synth", "--out", str(tmp_path / "bad"), "--frames", "5", *bad]) == 2
        assert named in capsys.readouterr().err and not (tmp_path / "bad").exists()


def _contents(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_second_run_into_a_result_is_refused_at_once_and_loses_nothing(capture_case, tmp_path, capsys):
    out = tmp_path / "result"
    assert _animate(capture_case, out, "--export", "mdd") == 0
    (out / "performance.pc2").write_bytes(b"an export made since")  # what a user adds to a result
    (out / "notes.txt").write_text("shot 12, take 3")
    before = _contents(out)
    assert _animate(capture_case, out) == 2
    _one_line_error(capsys, str(out), "holds an earlier result", "pass --overwrite")
    assert _contents(out) == before and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    # refused before any work: even before the inputs are read (a missing scan would be the error otherwise)
    capture_case.scan_path = tmp_path / "missing.obj"
    assert _animate(capture_case, out) == 2
    _one_line_error(capsys, str(out), "pass --overwrite")
    capture_case.scan_path = tmp_path / "scan.obj"
    # --overwrite replaces the folder as a whole: the new result, nothing of the old one
    assert _animate(capture_case, out, "--overwrite") == 0
    assert not (out / "notes.txt").exists() and not (out / "performance.mdd").exists()
    assert np.array_equal(np.load(out / "vertices.npy"), np.frombuffer(before["vertices.npy"][128:], "<f4").reshape(
        np.load(out / "vertices.npy").shape))  # the same inputs: the same frames
    # a folder that is not a facecap result is never replaced, even with --overwrite
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "holiday.jpg").write_bytes(b"jpeg")
    assert _animate(capture_case, mine, "--overwrite") == 2
    _one_line_error(capsys, str(mine), "not a facecap result", "even with --overwrite")
    assert _contents(mine) == {"holiday.jpg": b"jpeg"}
    # an empty folder made beforehand is written into
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _animate(capture_case, empty) == 0 and (empty / "performance.json").is_file()


def test_every_command_that_writes_an_output_takes_overwrite():
    from facecap.cli import build_parser

    commands = build_parser()._subparsers._group_actions[0].choices
    writers = {name for name, parser in commands.items()
               if any("--out" in action.option_strings for action in parser._actions)}
    assert writers >= {"animate", "plan-scans", "register-scans", "blend", "scans-pipeline", "synth", "wrinkles",
                       "remove-wrinkles", "build-anatomy", "solve-muscles", "edit-muscles", "demo", "export"}
    for name in writers:
        assert any("--overwrite" in action.option_strings for action in commands[name]._actions), name


def test_an_output_that_cannot_be_written_names_it_and_the_cause(capture_case, tmp_path, capsys):
    (tmp_path / "a_file").write_text("x")
    for out in (tmp_path / "a_file" / "result", tmp_path / "a_file" / "deeper" / "result"):
        assert _animate(capture_case, out) == 2
        _one_line_error(capsys, f"{out}: cannot create the folder: {tmp_path / 'a_file'} is a file, not a folder")
        assert ".partial-" not in capsys.readouterr().err
    # single-file outputs: the plan, a mesh
    plan = tmp_path / "a_file" / "plan.json"
    assert main(["plan-scans", "--markers", str(capture_case.markers_path), "--out", str(plan)]) == 2
    _one_line_error(capsys, f"{plan}: cannot write: {tmp_path / 'a_file'} is a file, not a folder")
    if Path("/proc/self").is_dir():  # the issue's own example, where the system refuses it (Linux)
        assert _animate(capture_case, "/proc/nope") == 2
        _one_line_error(capsys, "/proc/nope: cannot create the folder: /proc takes no new files")
        assert main(["plan-scans", "--markers", str(capture_case.markers_path), "--out", "/proc/plan.json"]) == 2
        _one_line_error(capsys, "/proc/plan.json: cannot write: /proc takes no new files")
    assert (tmp_path / "a_file").read_text() == "x" and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_an_existing_plan_is_kept_without_overwrite(capture_case, tmp_path, capsys):
    plan = tmp_path / "plan.json"
    assert main(["-q", "plan-scans", "--markers", str(capture_case.markers_path), "--out", str(plan)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.glob("plan*")}
    assert sorted(before) == ["plan.conditioned.npz", "plan.json", "plan.png"]
    assert main(["-q", "plan-scans", "--markers", str(capture_case.markers_path), "--out", str(plan),
                 "--tolerance", "0.01"]) == 2
    _one_line_error(capsys, f"{plan}: exists; pass --overwrite")
    assert {p.name: p.read_bytes() for p in tmp_path.glob("plan*")} == before
    assert main(["-q", "plan-scans", "--markers", str(capture_case.markers_path), "--out", str(plan),
                 "--tolerance", "0.01", "--overwrite"]) == 0
    assert json.loads(plan.read_text())["tolerance"] != json.loads(before["plan.json"])["tolerance"]
    assert json.loads(plan.read_text())["markers"] == "take.c3d"  # beside the plan: recorded relative to it


def test_every_recorded_path_is_final(capture_case, tmp_path, monkeypatch):
    """A job run as a user runs it (relative paths, another working folder) and inside a folder being built."""
    from recorded_paths import assert_recorded_paths_are_final

    from facecap.io.atomic_write import atomic_folder

    # relative paths from the inputs' folder, the result elsewhere
    monkeypatch.chdir(tmp_path)
    assert main(["-q", "animate", "--scan", "scan.obj", "--markers", "take.c3d", "--map", "map.json",
                 "--out", "results/res", "--stabilize", "auto", "--export", "gltf"]) == 0
    info = json.loads((tmp_path / "results" / "res" / "performance.json").read_text())
    assert info["source_files"] == {"scan": str(tmp_path / "scan.obj"), "markers": str(tmp_path / "take.c3d")}
    assert info["map"] == str(tmp_path / "map.json")
    assert ": res</title>" in (tmp_path / "results" / "res" / "report.html").read_text()
    assert assert_recorded_paths_are_final(tmp_path / "results") >= 10  # the files listed, the sources

    # as the demo does: the inputs and the job's folder inside a folder that is itself being built
    with atomic_folder(tmp_path / "project", marker_file="done.json") as stage:
        (stage / "inputs").mkdir()
        for name in ("scan.obj", "take.c3d", "map.json"):
            (stage / "inputs" / name).write_bytes((tmp_path / name).read_bytes())
        inputs = stage / "inputs"
        assert main(["-q", "animate", "--scan", str(inputs / "scan.obj"), "--markers", str(inputs / "take.c3d"),
                     "--map", str(inputs / "map.json"), "--out", str(stage / "animation"), "--stabilize", "auto",
                     "--export", "mdd"]) == 0
        assert main(["-q", "plan-scans", "--markers", str(inputs / "take.c3d"), "--out", str(stage / "plan.json")]) == 0
        (stage / "done.json").write_text("{}")
    project = tmp_path / "project"
    info = json.loads((project / "animation" / "performance.json").read_text())
    assert info["source_files"]["scan"] == str(project / "inputs" / "scan.obj")
    assert json.loads((project / "plan.json").read_text())["markers"] == "inputs/take.c3d"  # inside: relative
    assert assert_recorded_paths_are_final(project) >= 10


# The file arguments that read a mesh, a take or a marker map, by their dest; a command added with one of
# these options is checked too. info's FILE reads takes and meshes.
_FILE_ARGUMENTS = {"scan": ("mesh",), "scans": ("mesh",), "template": ("mesh",), "template_texture": ("mesh",),
                   "markers": ("take",), "map": ("map",)}


def test_help_names_every_format_each_file_argument_reads():
    import argparse

    from facecap.cli import build_parser
    from facecap.io import MAP_FORMATS, MARKER_FORMATS, MESH_FORMATS

    formats = {"mesh": MESH_FORMATS, "take": MARKER_FORMATS, "map": MAP_FORMATS}
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    checked = set()
    for command, parser in commands.items():
        page = " ".join(parser.format_help().split())  # as --help prints it, line breaks aside
        for action in parser._actions:
            kinds = ("take", "mesh") if (command, action.dest) == ("info", "file") else _FILE_ARGUMENTS.get(action.dest)
            if not kinds:
                continue
            for kind in kinds:
                for suffix, name in formats[kind].items():
                    assert name in action.help and suffix in action.help, (command, action.dest, action.help)
                    assert f"{name} (" in page and suffix in page, (command, action.dest)
            checked.add((command, action.dest))
    assert {("animate", "scan"), ("animate", "markers"), ("animate", "map"), ("info", "file"),
            ("plan-scans", "markers"), ("register-scans", "scans"), ("register-scans", "template"),
            ("blend", "markers"), ("scans-pipeline", "markers"), ("remove-wrinkles", "scan"),
            ("build-anatomy", "scan"), ("solve-muscles", "markers"), ("solve-muscles", "map")} <= checked


def test_info_prints_text_with_the_unit_warning_and_labels_on_request(tmp_path, capsys):
    from facecap.io import write_mesh
    from facecap.structures import Mesh

    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    head = Mesh(corners * [248.0, 338.0, 223.0], [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                                                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    path = write_mesh(head, tmp_path / "head.obj", unit="cm")
    capsys.readouterr()
    assert main(["info", str(path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert out.startswith("head.obj: mesh (OBJ)") and "pass --units cm" in out
    assert main(["info", str(path), "--units", "cm"]) == 0
    assert "warning" not in capsys.readouterr().out
    take = MarkerSequence(np.random.default_rng(0).normal(scale=50.0, size=(3, 20, 3)),
                          [f"dot{i}" for i in range(20)], 100.0)
    write_markers(take, tmp_path / "take.csv")
    assert main(["info", str(tmp_path / "take.csv")]) == 0
    assert "and 12 more (--labels lists them all)" in " ".join(capsys.readouterr().out.split())
    assert main(["info", str(tmp_path / "take.csv"), "--labels"]) == 0
    listed = [line.split()[-1] for line in capsys.readouterr().out.splitlines() if "dot" in line]
    assert listed == list(take.labels)
