"""Exports of a finished result, through the command line: what each file holds against the result's frames."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facecap.cli import main
from facecap.io import read_result
from gltf_validator import assert_valid, load, read_accessor


def _animate(case, out, *extra: str) -> None:
    status = main(["-q", "animate", "--scan", str(case.scan_path), "--markers", str(case.markers_path),
                   "--map", str(case.map_path), "--out", str(out), "--stabilize", "auto", *extra])
    assert status == 0


def _glb_frames(path) -> tuple[np.ndarray, dict]:
    """Every frame the GLB plays (mm, at its written vertices), and its asset extras."""
    gltf, blob = load(path)
    primitive = gltf.meshes[0].primitives[0]
    base = read_accessor(gltf, blob, primitive.attributes.POSITION).astype(np.float64)
    offsets = np.stack([read_accessor(gltf, blob, t["POSITION"]) for t in primitive.targets]).astype(np.float64)
    sampler = gltf.animations[0].samplers[gltf.animations[0].channels[0].sampler]
    w = read_accessor(gltf, blob, sampler.output).reshape(-1, offsets.shape[0]).astype(np.float64)
    assert w.min() >= 0.0 and w.max() <= 1.0  # the range Blender plays without clamping
    return 1000.0 * (base[None] + np.einsum("tj,jic->tic", w, offsets)), gltf.asset.extras


def _matching_rows(written_mm: np.ndarray, rest_mm: np.ndarray) -> np.ndarray:
    """The scan vertex each written glTF vertex copies (seam splits duplicate vertices), by position at rest."""
    from scipy.spatial import cKDTree

    distance, index = cKDTree(rest_mm).query(written_mm)
    assert distance.max() < 1e-3
    return index


def test_compact_animate_exports_play_the_result(capture_case, tmp_path):
    out = tmp_path / "out"
    _animate(capture_case, out, "--no-vertices", "--export", "gltf,mdd,pc2,abc", "--gltf-targets", "90")
    assert not (out / "vertices.npy").exists()
    result = read_result(out)
    frames = result.frames()  # mm: the capture case is in mm
    info = json.loads((out / "performance.json").read_text())
    for name in ("performance.glb", "performance.mdd", "performance.pc2", "performance.abc", "performance_rest.obj"):
        assert info["files"][name] == (out / name).stat().st_size

    # glTF: up to 90 targets rebuild the 30-marker shell exactly (as many as the take's rank)
    assert_valid(out / "performance.glb")
    played, extras = _glb_frames(out / "performance.glb")
    gltf_report = info["exports_report"]["gltf"]
    assert gltf_report["n_targets"] == gltf_report["error"]["rank"] <= 90 and not gltf_report["decimated"]
    assert gltf_report["error"]["max_mm"] < 1e-3
    rows = _matching_rows(_first_frame_base(out), result.rig.rest.astype(np.float64))
    assert np.abs(played - frames[:, rows]).max() < 1e-3
    assert extras["facecap"]["principal_component_error_mm"]["max_mm"] == gltf_report["error"]["max_mm"]

    # point caches: every frame, in the result's unit, vertex order kept
    T, n = result.n_frames, result.n_vertices
    mdd = np.fromfile(out / "performance.mdd", dtype=">f4", offset=8 + 4 * T).reshape(T, n, 3)
    pc2 = np.fromfile(out / "performance.pc2", dtype="<f4", offset=32).reshape(T, n, 3)
    np.testing.assert_array_equal(mdd, frames)
    np.testing.assert_array_equal(pc2, frames)


def _first_frame_base(out) -> np.ndarray:
    """The GLB's rest shape in mm at its written vertices: the base mesh plus the targets at the recorded rest weights."""
    gltf, blob = load(out / "performance.glb")
    primitive = gltf.meshes[0].primitives[0]
    rest = read_accessor(gltf, blob, primitive.attributes.POSITION).astype(np.float64)
    weights = gltf.asset.extras["facecap"]["rest_weights"]
    assert len(weights) == len(primitive.targets)
    for w, target in zip(weights, primitive.targets):
        rest += w * read_accessor(gltf, blob, target["POSITION"])
    return 1000.0 * rest


def test_fewer_targets_state_the_error_they_leave(tmp_path):
    from analytic_case import curved_grid
    from facecap.pipelines import write_blended_performance
    from facecap.structures import Mesh

    V, F = curved_grid(15)
    rng = np.random.default_rng(4)
    bases = V[None] + rng.normal(scale=2.0, size=(8, 1, 3)) * np.sin(V[None, :, :1] / rng.uniform(10, 40, (8, 1, 1)))
    weights = rng.dirichlet(np.ones(8), size=50)
    out = tmp_path / "out"
    write_blended_performance(out, Mesh(V, F), bases, weights, rate=30.0, progress=False)
    assert main(["-q", "export", str(out), "--format", "gltf", "--gltf-targets", "3", "--out", str(tmp_path / "review")]) == 0
    played, extras = _glb_frames(tmp_path / "review" / "performance.glb")
    assert_valid(tmp_path / "review" / "performance.glb")
    result = read_result(out)
    rows = _matching_rows(_first_frame_base(tmp_path / "review"), result.rig.rest.astype(np.float64))
    error = np.linalg.norm(played - result.frames()[:, rows], axis=2)
    stated = extras["facecap"]["principal_component_error_mm"]
    assert stated["rank"] == 9 and stated["n_targets"] == 3  # 8 bases and the weights' sum
    assert error.max() == pytest.approx(stated["max_mm"], rel=0.01)  # the stated error is the true one
    assert np.sqrt(np.mean(error ** 2)) == pytest.approx(stated["rms_mm"], rel=0.01)
    assert stated["max_mm"] > 0.05  # three targets cannot rebuild nine


def test_export_of_what_is_not_a_finished_result(capture_case, tmp_path, capsys):
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "vertices.npy").write_bytes(b"")
    assert main(["export", str(tmp_path / "half"), "--format", "gltf"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "half: is not a finished facecap result" in err[0]
    assert sorted(p.name for p in (tmp_path / "half").iterdir()) == ["vertices.npy"]

    out = tmp_path / "out"
    _animate(capture_case, out, "--no-vertices")
    assert main(["export", str(out), "--format", "gltf,stl"]) == 2
    assert "unknown format(s) ['stl']" in capsys.readouterr().err
    np.save(out / "rig" / "basis.npy", np.zeros((29, read_result(out).n_vertices), np.float32))  # a marker short
    before = sorted(p.name for p in out.iterdir())
    assert main(["export", str(out), "--format", "mdd"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rig: the basis (29," in err[0] and "disagree" in err[0]
    assert sorted(p.name for p in out.iterdir()) == before


def test_info_describes_a_compact_result(capture_case, tmp_path, capsys):
    out = tmp_path / "out"
    _animate(capture_case, out, "--no-vertices", "--rig-precision", "int16")
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames"] == 40 and info["frames_in"].startswith("rig/ (vertex-weights, 30 x 400, int16, error bound")


def test_export_gltf_writes_the_page_animate_writes_and_the_report_lists_it(capture_case, tmp_path):
    # the README: export writes the same files as --export would; for glTF that is the GLB and the page
    # that plays it, and the result's report.html then links that page
    streamed, exported = tmp_path / "streamed", tmp_path / "exported"
    _animate(capture_case, streamed, "--export", "gltf")
    _animate(capture_case, exported)
    assert 'href="review.html"' not in (exported / "report.html").read_text()
    assert main(["-q", "export", str(exported), "--format", "gltf"]) == 0
    written = {p.name for p in exported.iterdir()}
    assert {"performance.glb", "review.html"} <= written
    assert {p.name for p in streamed.iterdir()} == written
    assert 'href="review.html"' in (exported / "report.html").read_text()
    info = json.loads((exported / "performance.json").read_text())
    assert {"performance.glb", "review.html"} <= set(info["exports_report"]["gltf"]["files"])
    assert info["files"]["report.html"] == (exported / "report.html").stat().st_size  # listed at its new size
    # exported again: both are refused together without --overwrite, nothing touched
    before = (exported / "review.html").stat().st_mtime_ns
    assert main(["-q", "export", str(exported), "--format", "gltf"]) == 2
    assert (exported / "review.html").stat().st_mtime_ns == before


def test_view_writes_the_pages_with_the_true_error(capture_case, tmp_path, capsys):
    from facecap.report import evaluate_result

    out = tmp_path / "out"
    _animate(capture_case, out, "--no-vertices")
    assert main(["view", str(out), "--truth", str(capture_case.truth_path), "--no-serve"]) == 0
    assert "review.html" in capsys.readouterr().out
    assert (out / "performance.glb").is_file() and (out / "review.html").is_file()
    assert 'href="review.html"' in (out / "report.html").read_text()
    from facecap.pipelines.view_result import _error_rows

    rows, frames = _error_rows(read_result(out), capture_case.truth_path, "auto", out / "performance.glb", 7)
    truth = evaluate_result(capture_case.truth_path, out)
    assert len(frames) == 7 and frames[0] == 0 and frames[-1] == 39
    # the capture case has no UVs: the GLB's vertices are the scan's, each once
    np.testing.assert_allclose(rows.mean(axis=1), np.asarray(truth.per_frame_mean_mm)[frames], rtol=1e-5)

    (tmp_path / "not_a_result").mkdir()
    assert main(["view", str(tmp_path / "not_a_result"), "--no-serve"]) == 2
    assert "not a finished facecap result" in capsys.readouterr().err
    assert list((tmp_path / "not_a_result").iterdir()) == []


def test_a_missing_optional_writer_stops_the_run_before_it_starts(capture_case, tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "alembic3d", None)  # `import alembic3d` raises ImportError
    status = main(["animate", "--scan", str(capture_case.scan_path), "--markers", str(capture_case.markers_path),
                   "--map", str(capture_case.map_path), "--out", str(tmp_path / "out"), "--export", "abc"])
    assert status == 2
    err = capsys.readouterr().err
    assert 'pip install "facecap[alembic]"' in err and "factoring" not in err  # refused before the shell set-up
    assert not (tmp_path / "out").exists()


def _read_mdd(path, n_frames, n_vertices) -> np.ndarray:
    """The frames of an MDD file, read by its layout (big-endian: counts, times, then every frame)."""
    header = np.fromfile(path, dtype=">i4", count=2)
    assert header.tolist() == [n_frames, n_vertices]
    return np.fromfile(path, dtype=">f4", offset=8 + 4 * n_frames).reshape(n_frames, n_vertices, 3)


def _read_pc2(path, n_frames, n_vertices) -> np.ndarray:
    assert path.read_bytes()[:12] == b"POINTCACHE2\0"
    return np.fromfile(path, dtype="<f4", offset=32).reshape(n_frames, n_vertices, 3)


def _files(folder) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_an_export_adds_to_the_result_and_removes_nothing(capture_case, tmp_path, capsys):
    out = tmp_path / "out"
    _animate(capture_case, out, "--export", "mdd")
    (out / "notes.txt").write_text("mine")
    before = _files(out)
    # the same export again: refused in one line naming what exists, nothing touched
    assert main(["export", str(out), "--format", "pc2,mdd"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{out}: performance.mdd exists already; pass --overwrite" in err[0]
    assert _files(out) == before
    # a new format beside it: added; the rest mesh both caches share is this result's, so it is no conflict
    assert main(["-q", "export", str(out), "--format", "pc2"]) == 0
    after = _files(out)
    # everything kept as it was, but the two files that list the exports (written again, with pc2 in them)
    listings = {"performance.json", "report.html"}
    assert {k: v for k, v in after.items() if k in before and k not in listings} == \
        {k: v for k, v in before.items() if k not in listings}
    assert b"pc2" not in before["report.html"] and b"pc2" in after["report.html"]
    assert set(after) - set(before) == {"performance.pc2"}
    info = json.loads((out / "performance.json").read_text())
    assert info["exports"] == ["mdd", "pc2"] and set(info["exports_report"]) == {"mdd", "pc2"}
    assert info["files"] == {k: len(v) for k, v in after.items() if k != "performance.json"}
    # a rest mesh that is not this result's is a conflict
    (out / "performance_rest.obj").write_text("# another mesh\n")
    assert main(["export", str(out), "--format", "pc2", "--overwrite"]) == 0
    assert (out / "performance_rest.obj").read_bytes() == before["performance_rest.obj"]
    (out / "performance_rest.obj").write_text("# another mesh\n")
    (out / "performance.pc2").unlink()
    assert main(["export", str(out), "--format", "pc2"]) == 2
    assert "performance_rest.obj exists already" in capsys.readouterr().err
    # --overwrite replaces the export's own files, and nothing else
    assert main(["-q", "export", str(out), "--format", "mdd,pc2", "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "mine" and (out / "performance.mdd").read_bytes() == before["performance.mdd"]
    # a frame folder is refused too, and with --overwrite replaced whole
    assert main(["-q", "export", str(out), "--format", "obj"]) == 0
    assert main(["export", str(out), "--format", "obj"]) == 2
    assert "obj/ exists already" in capsys.readouterr().err
    (out / "obj" / "frame_000003.obj").write_text("edited")
    assert main(["-q", "export", str(out), "--format", "obj", "--overwrite"]) == 0  # facecap's frames: replaced whole
    assert (out / "obj" / "frame_000003.obj").read_text() != "edited" and len(list((out / "obj").iterdir())) == 40
    # a folder of that name that is not facecap's frames is never replaced
    (out / "ply").mkdir()
    (out / "ply" / "scan_cleaned.ply").write_text("mine")
    assert main(["export", str(out), "--format", "ply", "--overwrite"]) == 2
    assert "even with --overwrite" in capsys.readouterr().err and (out / "ply" / "scan_cleaned.ply").exists()


def test_export_usd_writes_what_animate_writes(capture_case, tmp_path):
    from pxr import Usd, UsdGeom

    streamed, exported, compact = tmp_path / "streamed", tmp_path / "exported", tmp_path / "compact"
    _animate(capture_case, streamed, "--export", "usd")
    _animate(capture_case, exported)
    _animate(capture_case, compact, "--no-vertices")
    assert main(["-q", "export", str(exported), "--format", "usd"]) == 0
    assert main(["-q", "export", str(compact), "--format", "usd"]) == 0
    usd_files = {"performance.usdc", "performance_rig.usdc"}
    assert {p.name for p in streamed.glob("*.usdc")} == {p.name for p in exported.glob("*.usdc")} == usd_files
    assert {p.name for p in compact.glob("*.usdc")} == {"performance_rig.usdc"}  # as animate --no-vertices does
    info = json.loads((exported / "performance.json").read_text())
    assert set(info["exports_report"]["usd"]["files"]) == usd_files and info["exports"] == ["usd"]
    frames = read_result(exported).frames()
    for folder in (streamed, exported):
        stage = Usd.Stage.Open(str(folder / "performance.usdc"))
        for k in (0, 17, 39):
            points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face")).GetPointsAttr().Get(k), np.float32)
            np.testing.assert_allclose(points, frames[k], atol=1e-4)



def test_animate_hands_the_usd_export_the_principal_components_it_would_compute(capture_case, tmp_path):
    # animate computes the USD rig's principal components beside writing the rest of the result; the export of
    # the same result computes them itself: the same shapes, the same stated error
    from pxr import Usd, UsdSkel

    early, later = tmp_path / "early", tmp_path / "later"
    _animate(capture_case, early, "--no-vertices", "--export", "usd", "--usd-shapes", "4")
    _animate(capture_case, later, "--no-vertices")
    assert main(["-q", "export", str(later), "--format", "usd", "--usd-shapes", "4"]) == 0

    def shapes(folder):
        stage = Usd.Stage.Open(str(folder / "performance_rig.usdc"))
        found = {prim.GetName(): np.array(UsdSkel.BlendShape(prim).GetOffsetsAttr().Get(), np.float64)
                 for prim in stage.Traverse() if prim.IsA(UsdSkel.BlendShape)}
        return found, json.loads((folder / "performance.json").read_text())["exports_report"]["usd"]

    (a, report_a), (b, report_b) = shapes(early), shapes(later)
    assert len(a) == 4 and a.keys() == b.keys()
    for name in a:
        np.testing.assert_allclose(a[name], b[name], atol=1e-6)
    assert report_a["error"] == pytest.approx(report_b["error"])

def test_point_caches_and_alembic_in_the_world_frame_round_trip(capture_case_head_motion, tmp_path):
    from alembic3d import Abc, AbcGeom

    out = tmp_path / "out"
    _animate(capture_case_head_motion, out, "--export", "mdd,abc", "--export-frame", "world")
    result = read_result(out)
    T, n = result.n_frames, result.n_vertices
    motion = np.load(out / "head_motion.npy")
    assert np.abs(motion[:, :3, 3]).max() > 1.0  # the head moves: world and stabilised differ
    frames = result.frames().astype(np.float64)
    world = np.einsum("tij,tnj->tni", motion[:, :3, :3], frames) + motion[:, None, :3, 3]  # x_world = R x + t
    assert main(["-q", "export", str(out), "--format", "pc2,mdd,abc"]) == 0  # the stabilised ones beside them
    assert main(["-q", "export", str(out), "--format", "pc2", "--export-frame", "world"]) == 0
    np.testing.assert_allclose(_read_mdd(out / "performance_world.mdd", T, n), world, atol=2e-4)
    np.testing.assert_allclose(_read_pc2(out / "performance_world.pc2", T, n), world, atol=2e-4)
    np.testing.assert_array_equal(_read_mdd(out / "performance.mdd", T, n), frames.astype(np.float32))
    np.testing.assert_array_equal(_read_pc2(out / "performance.pc2", T, n), frames.astype(np.float32))
    for name, expected, head_moves in (("performance_world.abc", world, False), ("performance.abc", frames, True)):
        archive = Abc.IArchive(str(out / name))
        head = AbcGeom.IXform(archive.getTop().getChild("Head"), Abc.WrapExistingFlag.kWrapExisting).getSchema()
        assert head.isConstantIdentity() != head_moves  # the world file carries no head transform
        face = AbcGeom.IPolyMesh(archive.getTop().getChild("Head").getChild("Face"),
                                 Abc.WrapExistingFlag.kWrapExisting).getSchema()
        for k in (0, 11, T - 1):
            points = np.asarray(face.getValue(Abc.ISampleSelector(k / result.rate)).getPositions())
            np.testing.assert_allclose(points, expected[k], atol=2e-4)
    info = json.loads((out / "performance.json").read_text())
    assert info["exports"] == ["mdd_world", "abc_world", "pc2", "mdd", "abc", "pc2_world"]
    assert info["exports_report"]["mdd_world"]["frame"] == "world"
    assert set(info["exports_report"]["mdd_world"]["files"]) == {"performance_world.mdd", "performance_rest.obj"}
