"""Exports of a finished result, through the command line: what each file holds against the result's frames."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facecap.cli import main
from facecap.io import read_result
from test_write_gltf import assert_valid, load, read_accessor


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
    from facecap.blendshapes import write_blended_performance
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


def test_view_writes_the_pages_with_the_true_error(capture_case, tmp_path, capsys):
    from facecap.report import evaluate_result

    out = tmp_path / "out"
    _animate(capture_case, out, "--no-vertices")
    assert main(["view", str(out), "--truth", str(capture_case.truth_path), "--no-serve"]) == 0
    assert "review.html" in capsys.readouterr().out
    assert (out / "performance.glb").is_file() and (out / "review.html").is_file()
    assert 'href="review.html"' in (out / "report.html").read_text()
    from facecap.report.view_result import _error_rows

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
