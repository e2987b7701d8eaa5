"""The rig as UsdSkel blend shapes, read back through UsdSkel's own blend-shape evaluation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel, UsdValidation

from facecap.pipelines import animate_scan, export_result
from facecap.errors import InputError
from facecap.io import (ResultRig, read_correspondence, read_markers, read_mesh, read_result,
                        write_usd_blendshapes)
from facecap.structures import Mesh

from analytic_case import curved_grid


def usdskel_points(path, frames) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Points UsdSkel computes from the stage's blend shapes at ``frames``, and the root's transform there."""
    stage = Usd.Stage.Open(str(path))
    root = UsdSkel.Root(stage.GetDefaultPrim())
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.PrimDefaultPredicate)
    (binding,) = cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate)
    skeleton = cache.GetSkelQuery(binding.GetSkeleton())
    (target,) = binding.GetSkinningTargets()
    shapes = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(target.GetPrim()))
    mapper = target.GetBlendShapeMapper()
    points, transforms = [], []
    for t in frames:
        weights = skeleton.GetAnimQuery().ComputeBlendShapeWeights(t)
        assert min(weights) >= 0.0 and max(weights) <= 1.0  # the range Blender plays without clamping
        if mapper is not None and not mapper.IsNull() and not mapper.IsIdentity():
            weights = mapper.Remap(weights)
        sub, shape_index, sub_index = shapes.ComputeSubShapeWeights(weights)
        P = UsdGeom.Mesh(target.GetPrim()).GetPointsAttr().Get(t)
        assert shapes.ComputeDeformedPoints(sub, shape_index, sub_index, shapes.ComputeBlendShapePointIndices(),
                                            shapes.ComputeSubShapePointOffsets(), P)
        points.append(np.array(P, dtype=np.float64))
        transforms.append(np.array(UsdGeom.Xformable(root.GetPrim()).ComputeLocalToWorldTransform(t)).T)
    return points, transforms


def _assert_valid(path) -> None:
    stage = Usd.Stage.Open(str(path))
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    assert [(str(e.GetType()), e.GetMessage()) for e in errors] == []


def _decaying_rig(n_side: int = 16, K: int = 6, T: int = 12, seed: int = 0) -> tuple[Mesh, ResultRig]:
    """Per-vertex weights that fall off with distance from each 'marker', as the shell's do."""
    V, F = curved_grid(n_side)
    rng = np.random.default_rng(seed)
    centres = V[rng.choice(len(V), K, replace=False)]
    d = np.linalg.norm(V[None] - centres[:, None], axis=2)
    W = np.exp(-d / 6.0).astype(np.float32)
    C = rng.normal(scale=4.0, size=(T, K, 3)).astype(np.float32)
    return Mesh(V, F), ResultRig(V.astype(np.float32), W, C, names=tuple(f"M{k}" for k in range(K)))


def test_usdskel_evaluates_the_rig_with_its_head_motion(tmp_path):
    mesh, rig = _decaying_rig()
    T = rig.n_frames
    motion = np.tile(np.eye(4), (T, 1, 1))
    motion[:, :3, 3] = np.outer(np.arange(T), [1.0, -2.0, 0.5])
    stats = write_usd_blendshapes(tmp_path / "rig.usdc", mesh, rig, rate=60.0, head_motion=motion)
    _assert_valid(tmp_path / "rig.usdc")
    assert stats["n_shapes"] == 3 * rig.n_basis
    assert stats["stored_entries"] < 0.8 * stats["dense_entries"]  # the far field is left out...
    frames = [0, T // 2, T - 1]
    points, transforms = usdskel_points(tmp_path / "rig.usdc", frames)
    for t, P, M in zip(frames, points, transforms):
        assert np.abs(P - rig.frames(t, t + 1)[0]).max() <= stats["error_bound_mm"] + 1e-5  # ...within its bound
        np.testing.assert_allclose(M, motion[t], atol=1e-9)
    stage = Usd.Stage.Open(str(tmp_path / "rig.usdc"))
    assert stage.GetTimeCodesPerSecond() == 60.0 and stage.GetEndTimeCode() == T - 1
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.001)


def test_keeping_every_entry_is_exact(tmp_path):
    mesh, rig = _decaying_rig(seed=1)
    stats = write_usd_blendshapes(tmp_path / "rig.usda", mesh, rig, rate=30.0, tolerance_mm=0.0)
    assert stats["stored_entries"] == stats["dense_entries"] and stats["error_bound_mm"] == 0.0
    (P,), _ = usdskel_points(tmp_path / "rig.usda", [5])
    assert np.abs(P - rig.frames(5, 6)[0]).max() < 1e-5



def test_a_textured_scans_rig_binds_its_texture_beside_it(tmp_path):
    from pxr import UsdShade

    from facecap.io.image_file import read_image

    mesh, rig = _decaying_rig(seed=2)
    texture = np.random.default_rng(4).integers(0, 65536, size=(6, 10, 3), dtype=np.uint16)  # 16 bits, as scanners
    uvs = (mesh.vertices[:, :2] - mesh.vertices[:, :2].min(0)) / np.ptp(mesh.vertices[:, :2], axis=0)
    textured = Mesh(mesh.vertices, mesh.faces, uvs=uvs, uv_indices=mesh.faces.ravel(), texture=texture)
    write_usd_blendshapes(tmp_path / "rig.usdc", textured, rig, rate=30.0)
    _assert_valid(tmp_path / "rig.usdc")
    stage = Usd.Stage.Open(str(tmp_path / "rig.usdc"))
    (target,) = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    material, _ = UsdShade.MaterialBindingAPI(target).ComputeBoundMaterial()
    colour = material.ComputeSurfaceSource()[0].GetInput("diffuseColor").GetConnectedSources()[0][0].source
    image = UsdShade.Shader(colour.GetPrim()).GetInput("file").Get().resolvedPath
    assert image == str(tmp_path / "rig_color.png")
    np.testing.assert_array_equal(read_image(image), texture)


def test_animate_and_export_usd_match_vertices(capture_case, tmp_path):
    scan = read_mesh(capture_case.scan_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # head-band markers not in the map: an expected notice
        animate_scan(scan, read_markers(capture_case.markers_path), read_correspondence(capture_case.map_path, scan),
                     tmp_path / "out", stabilize=True, exports=["usd"], progress=False)
    folder = tmp_path / "out"
    assert (folder / "performance.usdc").is_file() and (folder / "performance_rig.usdc").is_file()
    _assert_valid(folder / "performance_rig.usdc")
    vertices = np.load(folder / "vertices.npy")
    motion = np.load(folder / "head_motion.npy")
    frames = [0, 17, vertices.shape[0] - 1]
    points, transforms = usdskel_points(folder / "performance_rig.usdc", frames)
    for t, P, M in zip(frames, points, transforms):
        assert np.abs(P - vertices[t]).max() < 1e-4  # mm
        np.testing.assert_allclose(M, motion[t], atol=1e-6)
    result = read_result(folder)
    assert result.info["exports_report"]["usd"]["n_shapes"] == 90
    assert result.info["files"]["performance_rig.usdc"] == (folder / "performance_rig.usdc").stat().st_size


def test_bad_input(tmp_path):
    mesh, rig = _decaying_rig()
    other = Mesh(*curved_grid(10))
    with pytest.raises(InputError, match="the mesh has 100 vertices, the rig 256"):
        write_usd_blendshapes(tmp_path / "rig.usdc", other, rig, rate=60.0)
    with pytest.raises(InputError, match="head_motion"):
        write_usd_blendshapes(tmp_path / "rig.usdc", mesh, rig, rate=60.0, head_motion=np.eye(4)[None])
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="not a finished facecap result"):
        export_result(tmp_path, "usd")


def test_principal_component_shapes_stay_within_their_stated_error(capture_case, tmp_path):
    scan = read_mesh(capture_case.scan_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # head-band markers not in the map: an expected notice
        animate_scan(scan, read_markers(capture_case.markers_path), read_correspondence(capture_case.map_path, scan),
                     tmp_path / "out", progress=False, write_vertices=False)
    report = export_result(tmp_path / "out", "usd", usd_shapes=8)["usd"]
    assert report["principal_components"] and report["n_shapes"] == 8
    error = report["error"]
    _assert_valid(tmp_path / "out" / "performance_rig.usdc")
    result = read_result(tmp_path / "out")
    frames = list(range(result.n_frames))
    points, _ = usdskel_points(tmp_path / "out" / "performance_rig.usdc", frames)
    residual = np.stack(points) - result.frames()
    worst = np.linalg.norm(residual, axis=2).max()
    rms = np.sqrt(np.mean(np.sum(residual.astype(np.float64) ** 2, axis=2)))
    assert worst == pytest.approx(error["max_mm"], rel=1e-3, abs=1e-4)  # the stated figures are the true ones
    assert rms == pytest.approx(error["rms_mm"], rel=1e-3, abs=1e-5)
    assert 0 < error["rms_mm"] < worst  # and 8 shapes do not rebuild 90 markers' motion exactly
