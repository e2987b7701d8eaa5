"""Tests for facecap.io.write_usd."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdValidation

from facecap.errors import InputError
from facecap.io.write_usd import UsdPerformanceWriter
from facecap.structures import Mesh


def _quad_tri_mesh(unit: str = "cm", seed: int = 0) -> Mesh:
    """A quad and a triangle sharing an edge, with face-varying UVs (7 corners, 6 UVs)."""
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(5, 3)) * 10.0
    return Mesh(
        V,
        [[0, 1, 2], [0, 2, 3], [1, 4, 2]],
        polygon_sizes=[4, 3],
        polygon_indices=[0, 1, 2, 3, 1, 4, 2],
        uvs=rng.random((6, 2)),
        uv_indices=[0, 1, 2, 3, 4, 5, 2],
        source_unit=unit,
    )


def _take(mesh: Mesh, T: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return mesh.vertices[None] + rng.normal(size=(T, mesh.n_vertices, 3))


def _rigid_poses(T: int, seed: int = 2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    P = np.tile(np.eye(4), (T, 1, 1))
    for t in range(T):
        a = rng.uniform(-0.3, 0.3)
        c, s = np.cos(a), np.sin(a)
        P[t, :3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        P[t, :3, 3] = rng.normal(size=3) * 20.0
    return P


def _write(path, mesh, X, rate, *, blocks=(4,), head_pose=None, **kw) -> UsdPerformanceWriter:
    writer = UsdPerformanceWriter(path, mesh, rate, X.shape[0], **kw)
    start = 0
    sizes = list(blocks) + [X.shape[0]]
    for b in sizes:
        stop = min(X.shape[0], start + b)
        if stop > start:
            pose = None if head_pose is None else head_pose[start:stop]
            writer.write_frames(start, X[start:stop], head_pose=pose)
        start = stop
    writer.close()
    return writer


def _assert_valid(stage) -> None:
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    assert [(str(e.GetType()), e.GetMessage()) for e in errors] == []


def _points(stage, t) -> np.ndarray:
    return np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face")).GetPointsAttr().Get(t), dtype=np.float64)


def _check_static(stage, mesh: Mesh, rate: float, T: int) -> None:
    face = UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face"))
    sizes, idx = mesh.export_polygons()
    assert list(face.GetFaceVertexCountsAttr().Get()) == list(sizes) == [4, 3]
    assert list(face.GetFaceVertexIndicesAttr().Get()) == list(idx)
    st = UsdGeom.PrimvarsAPI(face.GetPrim()).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert st.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray
    np.testing.assert_allclose(np.array(st.Get()), mesh.uvs, atol=1e-7)
    assert list(st.GetIndices()) == list(mesh.uv_indices)
    assert stage.GetTimeCodesPerSecond() == rate and stage.GetFramesPerSecond() == rate
    assert stage.GetStartTimeCode() == 0 and stage.GetEndTimeCode() == T - 1
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path("/Head")


def test_single_file_round_trip(tmp_path):
    mesh = _quad_tri_mesh("cm")
    T, rate = 9, 120.0
    X = _take(mesh, T)
    path = tmp_path / "take.usdc"
    writer = _write(path, mesh, X, rate, blocks=(4, 1))
    assert not writer.use_clips
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.usdc"]  # self-contained, no temporaries
    stage = Usd.Stage.Open(str(path))
    _check_static(stage, mesh, rate, T)
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    for t in (0, 3, 4, 8):
        # Written in the source unit (cm): mm / 10, float32.
        np.testing.assert_allclose(_points(stage, t), X[t] / 10.0, rtol=1e-6, atol=1e-6)
        ext = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face")).GetExtentAttr().Get(t))
        np.testing.assert_allclose(ext, [X[t].min(0) / 10, X[t].max(0) / 10], rtol=1e-6)
    assert not stage.GetPrimAtPath("/Head").GetAttribute("xformOp:transform").IsValid()
    _assert_valid(stage)


def test_clip_round_trip_with_head_pose(tmp_path):
    mesh = _quad_tri_mesh("mm", seed=3)
    T, rate = 10, 60.0
    X = _take(mesh, T, seed=4)
    P = _rigid_poses(T)
    path = tmp_path / "take.usdc"
    writer = _write(path, mesh, X, rate, blocks=(4, 2), head_pose=P, clip_frames=3)
    assert writer.use_clips and writer.clip_frames == 3
    clips_dir = tmp_path / "take_clips"
    assert sorted(p.name for p in clips_dir.iterdir()) == [
        "clip_000000.usdc", "clip_000001.usdc", "clip_000002.usdc", "clip_000003.usdc", "manifest.usdc"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.usdc", "take_clips"]
    # The top layer holds no samples: they all live in the clips.
    top = Sdf.Layer.FindOrOpen(str(path))
    assert list(top.ListAllTimeSamples()) == []
    assert list(Sdf.Layer.FindOrOpen(str(clips_dir / "clip_000001.usdc")).ListAllTimeSamples()) == [3.0, 4.0, 5.0, 6.0]

    stage = Usd.Stage.Open(str(path))
    _check_static(stage, mesh, rate, T)
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.001)
    clips = Usd.ClipsAPI(stage.GetPrimAtPath("/Head"))
    assert len(clips.GetClipAssetPaths()) == 4
    face = stage.GetPrimAtPath("/Head/Face")
    for t in range(T):
        np.testing.assert_allclose(_points(stage, t), X[t], rtol=1e-6, atol=1e-5)
        M = np.array(UsdGeom.Xformable(face).ComputeLocalToWorldTransform(t)).T  # USD: row vectors
        np.testing.assert_allclose(M, P[t], atol=1e-9)
    # Between frames values interpolate, also across a clip boundary (frames 2 -> 3).
    for t in (2.5, 5.25):
        lo = int(np.floor(t))
        expected = X[lo] + (t - lo) * (X[lo + 1] - X[lo])
        np.testing.assert_allclose(_points(stage, t), expected, rtol=1e-5, atol=1e-5)
    _assert_valid(stage)


def test_large_take_switches_to_clips_by_size(tmp_path):
    mesh = _quad_tri_mesh("m")
    X = _take(mesh, 7)
    frame_bytes = 12 * mesh.n_vertices
    writer = _write(tmp_path / "a.usdc", mesh, X, 30.0, single_file_max_bytes=2 * frame_bytes)
    assert writer.use_clips and writer.clip_frames == 2
    stage = Usd.Stage.Open(str(tmp_path / "a.usdc"))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(1.0)
    np.testing.assert_allclose(_points(stage, 6), X[6] / 1000.0, rtol=1e-6)
    writer = _write(tmp_path / "b.usdc", mesh, X, 30.0, single_file_max_bytes=7 * frame_bytes)
    assert not writer.use_clips


@pytest.mark.parametrize("unit, meters", [("mm", 0.001), ("cm", 0.01), ("m", 1.0), ("in", 0.0254)])
def test_meters_per_unit(tmp_path, unit, meters):
    mesh = _quad_tri_mesh(unit)
    _write(tmp_path / "u.usdc", mesh, _take(mesh, 1), 24.0)
    stage = Usd.Stage.Open(str(tmp_path / "u.usdc"))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(meters)


def test_triangle_mesh_without_uvs(tmp_path):
    rng = np.random.default_rng(5)
    mesh = Mesh(rng.normal(size=(4, 3)), [[0, 1, 2], [0, 2, 3]])
    X = _take(mesh, 2)
    _write(tmp_path / "t.usdc", mesh, X, 50.0)
    stage = Usd.Stage.Open(str(tmp_path / "t.usdc"))
    face = UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face"))
    assert list(face.GetFaceVertexCountsAttr().Get()) == [3, 3]
    assert list(face.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 0, 2, 3]
    assert not UsdGeom.PrimvarsAPI(face.GetPrim()).HasPrimvar("st")
    _assert_valid(stage)


def test_abort_leaves_nothing_and_keeps_old_file(tmp_path):
    mesh = _quad_tri_mesh()
    X = _take(mesh, 6)
    path = tmp_path / "take.usdc"
    _write(path, mesh, X, 60.0)
    before = path.read_bytes()
    writer = UsdPerformanceWriter(path, mesh, 60.0, 6, clip_frames=2)
    writer.write_frames(0, X[:5])
    writer.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.usdc"]
    assert path.read_bytes() == before
    with pytest.raises(RuntimeError):
        with UsdPerformanceWriter(path, mesh, 60.0, 6) as w:
            w.write_frames(0, X[:3])
            raise RuntimeError("solver failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.usdc"]
    assert path.read_bytes() == before


def test_rewrite_replaces_clips_and_single_file_removes_stale_clips(tmp_path):
    mesh = _quad_tri_mesh()
    path = tmp_path / "take.usdc"
    _write(path, mesh, _take(mesh, 6, seed=7), 60.0, clip_frames=2)
    X = _take(mesh, 5, seed=8)
    _write(path, mesh, X, 60.0, clip_frames=4)
    assert sorted(p.name for p in (tmp_path / "take_clips").iterdir()) == [
        "clip_000000.usdc", "clip_000001.usdc", "manifest.usdc"
    ]
    np.testing.assert_allclose(_points(Usd.Stage.Open(str(path)), 4), X[4] / 10, rtol=1e-6, atol=1e-6)
    _write(path, mesh, X, 60.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.usdc"]
    (tmp_path / "take_clips").mkdir()
    (tmp_path / "take_clips" / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="refusing"):
        UsdPerformanceWriter(path, mesh, 60.0, 5, clip_frames=2)


def test_bad_input_raises(tmp_path):
    mesh = _quad_tri_mesh()
    X = _take(mesh, 4)
    path = tmp_path / "x.usdc"
    with pytest.raises(InputError, match="rate"):
        UsdPerformanceWriter(path, mesh, 0.0, 4)
    with pytest.raises(InputError, match="n_frames"):
        UsdPerformanceWriter(path, mesh, 60.0, 0)
    with pytest.raises(InputError, match=".usdc"):
        UsdPerformanceWriter(tmp_path / "x.usda", mesh, 60.0, 4)
    with pytest.raises(InputError, match="folder"):
        UsdPerformanceWriter(tmp_path / "nope" / "x.usdc", mesh, 60.0, 4)
    bad_uv = Mesh(mesh.vertices, mesh.faces, polygon_sizes=[4, 3], polygon_indices=[0, 1, 2, 3, 1, 4, 2],
                  uvs=mesh.uvs, uv_indices=[0, 1, 2])
    with pytest.raises(InputError, match="uv_indices"):
        UsdPerformanceWriter(path, bad_uv, 60.0, 4)

    w = UsdPerformanceWriter(path, mesh, 60.0, 4)
    with pytest.raises(InputError, match="start"):
        w.write_frames(1, X[:1])
    with pytest.raises(InputError, match="vertices_mm"):
        w.write_frames(0, X[:2, :3])
    with pytest.raises(InputError, match="exceed"):
        w.write_frames(0, np.concatenate([X, X]))
    nan = X[:2].copy()
    nan[1, 2, 0] = np.nan
    with pytest.raises(InputError, match="frame 1"):
        w.write_frames(0, nan)
    w.write_frames(0, X[:2])
    with pytest.raises(InputError, match="head_pose"):
        w.write_frames(2, X[2:3], head_pose=np.eye(4)[None])
    with pytest.raises(InputError, match="only 2 of 4"):
        w.close()
    w.abort()
    assert not path.exists()


@pytest.mark.parametrize("clip_frames", [None, 2])
def test_a_textured_scan_carries_its_texture_as_a_preview_surface(tmp_path, clip_frames):
    from pxr import Sdf as _Sdf, UsdShade

    from facecap.io.image_file import read_image

    base = _quad_tri_mesh(unit="mm")
    texture = np.random.default_rng(3).integers(0, 256, size=(8, 16, 3), dtype=np.uint8)
    mesh = Mesh(base.vertices, base.faces, polygon_sizes=[4, 3], polygon_indices=[0, 1, 2, 3, 1, 4, 2],
                uvs=base.uvs, uv_indices=base.uv_indices, texture=texture)
    path = tmp_path / "performance.usdc"
    _write(path, mesh, _take(mesh, 5), 30.0, clip_frames=clip_frames)
    stage = Usd.Stage.Open(str(path))
    _assert_valid(stage)  # USD's own validators (shader ids, material binding, asset paths)
    face = stage.GetPrimAtPath("/Head/Face")
    material, _ = UsdShade.MaterialBindingAPI(face).ComputeBoundMaterial()
    assert material and material.GetPath() == _Sdf.Path("/Head/Looks/Skin")
    surface = material.ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    colour = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    shader = UsdShade.Shader(colour.GetPrim())
    assert shader.GetIdAttr().Get() == "UsdUVTexture"
    reader = UsdShade.Shader(shader.GetInput("st").GetConnectedSources()[0][0].source.GetPrim())
    assert reader.GetInput("varname").Get() == "st"  # the mesh's own UVs, checked above
    image = shader.GetInput("file").Get().resolvedPath  # resolved by USD's asset resolver, from the layer's folder
    assert image == str(tmp_path / "performance_color.png")
    np.testing.assert_array_equal(read_image(image), texture)
