"""The exact compact form (rig/) and the one reader of result folders."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from facecap.pipelines import animate_scan
from facecap.errors import InputError
from facecap.io import ResultRig, read_correspondence, read_markers, read_mesh, read_result, read_rig, write_rig


def _random_rig(kind: str, seed: int = 0, n: int = 50, K: int = 6, T: int = 9) -> ResultRig:
    rng = np.random.default_rng(seed)
    rest = rng.normal(scale=50.0, size=(n, 3)).astype(np.float32)
    if kind == "vertex-weights":
        basis = rng.random((K, n)).astype(np.float32)
        coefficients = rng.normal(scale=5.0, size=(T, K, 3)).astype(np.float32)
    else:
        basis = rng.normal(scale=3.0, size=(K, n, 3)).astype(np.float32)
        coefficients = rng.random((T, K)).astype(np.float32)
    return ResultRig(rest, basis, coefficients, names=tuple(f"m{k}" for k in range(K)))


@pytest.mark.parametrize("kind", ["vertex-weights", "shapes"])
def test_frames_are_the_linear_combination(kind, tmp_path):
    rig = _random_rig(kind)
    B, C = rig.basis.astype(np.float64), rig.coefficients.astype(np.float64)
    expected = rig.rest[None] + (np.einsum("kn,tkc->tnc", B, C) if kind == "vertex-weights"
                                 else np.einsum("knc,tk->tnc", B, C))
    np.testing.assert_allclose(rig.frames(), expected, atol=1e-4)
    np.testing.assert_allclose(rig.frames(3, 5), expected[3:5], atol=1e-4)
    # small vertex blocks give the same frames
    out = np.empty((rig.n_frames, rig.n_vertices, 3), np.float32)
    np.testing.assert_allclose(rig.frames_into(0, rig.n_frames, out, vertex_block=7), expected, atol=1e-4)
    # the blendshape form (3 shapes per element for per-vertex weights) is the same thing
    shapes, names = rig.shapes()
    w = rig.shape_weights()
    np.testing.assert_allclose(rig.rest[None] + np.einsum("mnc,tm->tnc", shapes, w), expected, atol=1e-4)
    assert len(names) == shapes.shape[0] == w.shape[1] == (3 * rig.n_basis if kind == "vertex-weights" else rig.n_basis)
    # round trip through the files, basis memory-mapped
    write_rig(tmp_path / "rig", rig)
    back = read_rig(tmp_path / "rig")
    assert isinstance(back.basis, np.memmap) and back.kind == kind and back.names == rig.names
    np.testing.assert_array_equal(back.frames(), rig.frames())


def test_a_fortran_ordered_basis_is_written_as_it_lies_and_reads_back_the_same(tmp_path):
    rig = _random_rig("vertex-weights", seed=2)
    transposed = ResultRig(rig.rest, np.asfortranarray(rig.basis), rig.coefficients, names=rig.names)  # as the shell's
    write_rig(tmp_path / "rig", transposed)
    with open(tmp_path / "rig" / "basis.npy", "rb") as f:
        np.lib.format.read_magic(f)
        assert np.lib.format.read_array_header_1_0(f)[1] is True  # fortran_order: saved without a C copy
    back = read_rig(tmp_path / "rig")
    np.testing.assert_array_equal(np.asarray(back.basis), rig.basis)
    np.testing.assert_array_equal(back.frames(), rig.frames())
    np.testing.assert_array_equal(back.frames(2, 6), rig.frames(2, 6))


@pytest.mark.parametrize("kind", ["vertex-weights", "shapes"])
def test_int16_stays_within_its_stated_bound(kind, tmp_path):
    rig = _random_rig(kind, seed=3, n=400, K=12, T=30)
    q = rig.quantized()
    assert q.basis.dtype == np.int16 and q.precision == "int16"
    assert q.basis.nbytes * 2 == rig.basis.nbytes
    error = np.abs(q.frames().astype(np.float64) - rig.frames()).max()
    assert 0 < error <= q.error_bound + 1e-5  # float32 rounding of the sums on top of the bound
    assert q.error_bound < 1e-3 * np.abs(rig.frames() - rig.rest).max()  # and the bound is small
    write_rig(tmp_path / "rig", q)
    info = json.loads((tmp_path / "rig" / "rig.json").read_text())
    assert info["precision"] == "int16" and info["error_bound"] == pytest.approx(q.error_bound)
    np.testing.assert_array_equal(read_rig(tmp_path / "rig").frames(), q.frames())


def test_disagreeing_parts_are_refused(tmp_path):
    rest = np.zeros((5, 3), np.float32)
    with pytest.raises(InputError, match=r"basis \(4, 5\) and the coefficients \(3, 6, 3\) disagree"):
        ResultRig(rest, np.zeros((4, 5), np.float32), np.zeros((3, 6, 3), np.float32))
    with pytest.raises(InputError, match="basis is for 6 vertices"):
        ResultRig(rest, np.zeros((4, 6), np.float32), np.zeros((3, 4, 3), np.float32))
    with pytest.raises(InputError, match="NaN"):
        ResultRig(rest, np.zeros((4, 5, 3), np.float32), np.full((3, 4), np.nan, np.float32))
    rig = _random_rig("shapes")
    write_rig(tmp_path / "rig", rig)
    np.save(tmp_path / "rig" / "coefficients.npy", np.zeros((9, 5), np.float32))  # one element short
    with pytest.raises(InputError, match="disagree"):
        read_rig(tmp_path / "rig")


def _animate(case, out, **kwargs):
    scan = read_mesh(case.scan_path)
    take = read_markers(case.markers_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # head-band markers not in the map: an expected notice
        return animate_scan(scan, take, read_correspondence(case.map_path, scan), out, stabilize=True,
                            progress=False, **kwargs)


def test_animate_rig_reproduces_vertices_and_stands_alone(capture_case, tmp_path):
    _animate(capture_case, tmp_path / "full")
    full = read_result(tmp_path / "full")
    assert full.has_vertices and full.rig is not None and full.rig.kind == "vertex-weights"
    vertices = np.load(tmp_path / "full" / "vertices.npy")
    assert np.abs(full.rig.frames() - vertices).max() < 1e-4  # mm: the bar
    assert full.head_motion is not None and full.markers.shape == (full.n_frames, 30, 3)
    info = json.loads((tmp_path / "full" / "performance.json").read_text())
    assert info["files"]["vertices.npy"] == (tmp_path / "full" / "vertices.npy").stat().st_size
    assert "rig/basis.npy" in info["files"] and info["frames_in"] == ["vertices.npy", "rig/"]

    _animate(capture_case, tmp_path / "compact", write_vertices=False)
    compact = read_result(tmp_path / "compact")
    assert not compact.has_vertices and not (tmp_path / "compact" / "vertices.npy").exists()
    assert np.abs(compact.frames() - vertices).max() < 1e-4
    blocks = list(compact.blocks(7))
    assert [start for start, _ in blocks] == list(range(0, compact.n_frames, 7))
    np.testing.assert_allclose(np.concatenate([b for _, b in blocks]), compact.frames(), atol=1e-5)  # summation order
    # the mesh of the folder is the scan: topology and rest vertices
    scan = read_mesh(capture_case.scan_path)
    np.testing.assert_array_equal(compact.mesh.faces, scan.faces)
    np.testing.assert_allclose(compact.mesh.vertices, scan.vertices, atol=1e-4)

    _animate(capture_case, tmp_path / "int16", write_vertices=False, rig_precision="int16")
    small = read_result(tmp_path / "int16")
    bound = small.rig.error_bound
    assert 0 < np.abs(small.frames() - vertices).max() <= bound + 1e-4
    assert (tmp_path / "int16" / "rig" / "basis.npy").stat().st_size < 0.6 * (tmp_path / "compact" / "rig" / "basis.npy").stat().st_size


def test_animate_in_another_unit_keeps_the_rig_exact(capture_case, tmp_path):
    scan = read_mesh(capture_case.scan_path, unit="mm")
    scan_cm = scan.__class__(scan.vertices, scan.faces, source_unit="cm")  # same mm geometry, written in cm
    take = read_markers(capture_case.markers_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # head-band markers not in the map: an expected notice
        animate_scan(scan_cm, take, read_correspondence(capture_case.map_path, scan), tmp_path / "cm", progress=False)
    result = read_result(tmp_path / "cm")
    vertices = np.load(tmp_path / "cm" / "vertices.npy")
    assert result.units == "cm" and result.rig.units == "cm"
    assert np.abs(result.rig.frames() - vertices).max() * 10.0 < 1e-4  # cm -> mm


def test_reader_refuses_what_is_not_a_result(capture_case, tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="not a finished facecap result"):
        read_result(tmp_path / "empty")
    _animate(capture_case, tmp_path / "r", write_vertices=False)
    np.save(tmp_path / "r" / "rig" / "coefficients.npy", np.zeros((3, 30, 3), np.float32))
    with pytest.raises(InputError, match=r"rig.json states 40 frames"):
        read_result(tmp_path / "r")
