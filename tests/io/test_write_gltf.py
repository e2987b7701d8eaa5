"""write_gltf: every file the Khronos validator passes, read back by pygltflib and trimesh against known arrays."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from facecap.deform import principal_targets_from_rig
from facecap.errors import InputError
from facecap.io import write_gltf
from facecap.mesh import review_mesh
from facecap.structures import Mesh
from gltf_validator import (COMPONENT_DTYPES, assert_valid, decode_meshopt, issue_summary, load, read_accessor,
                            validate_gltf)

write_gltf_module = importlib.import_module("facecap.io.write_gltf")  # facecap.io.write_gltf is the function
GRID = 12
RATE = 30.0


def seamed_grid(n: int = GRID, size: float = 100.0) -> Mesh:
    """A curved sheet (mm) whose UVs are cut along the middle column: those vertices carry two UVs."""
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    x, y = (u.ravel() - 0.5) * size, (v.ravel() - 0.5) * size
    V = np.stack([x, y, -0.005 * x**2 - 0.002 * y**2], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    column = np.arange(n * n) % n
    # UV index per vertex, plus a second UV for the seam column used by the triangles right of it
    uvs = np.stack([u.ravel() * 0.45, v.ravel()], 1)
    seam = np.flatnonzero(column == n // 2)
    right_uv = np.stack([0.55 + (u.ravel()[seam] - 0.5) * 0.9, v.ravel()[seam]], 1)
    uvs = np.concatenate([uvs, right_uv])
    second = np.full(n * n, -1)
    second[seam] = n * n + np.arange(seam.size)
    corner_uv = F.copy()
    right_of_seam = column[F].min(axis=1) >= n // 2  # triangles on the right side of the cut
    for k in range(3):
        use = right_of_seam & (column[F[:, k]] == n // 2)
        corner_uv[use, k] = second[F[use, k]]
    return Mesh(V, F, uvs=uvs, uv_indices=corner_uv.ravel())


def known_take(mesh: Mesh, n_targets: int = 3, n_frames: int = 25) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    P = mesh.vertices
    fields = [np.stack([np.sin(P[:, 0] / (20 + 5 * j)), np.cos(P[:, 1] / 30), np.exp(-P[:, 0] ** 2 / 900)], 1)
              for j in range(n_targets)]
    targets = 3.0 * np.stack(fields)  # mm
    t = np.arange(n_frames) / RATE
    weights = np.stack([np.sin(2 * np.pi * (j + 1) * t / t[-1]) for j in range(n_targets)], 1)
    weights += 0.01 * rng.standard_normal(weights.shape)
    return targets, weights


def test_morph_targets_and_weights_rebuild_every_frame(tmp_path: Path) -> None:
    mesh = seamed_grid()
    targets, weights = known_take(mesh)
    path = tmp_path / "take.glb"
    info = write_gltf(path, mesh, targets=targets, weights=weights, rate=RATE,
                      target_names=["jaw", "brow", "smile"], extras={"take": "known"})
    assert_valid(path)
    gltf, blob = load(path)
    source = info["vertex_source"]
    primitive = gltf.meshes[0].primitives[0]
    base = read_accessor(gltf, blob, primitive.attributes.POSITION)
    np.testing.assert_array_equal(base, (mesh.vertices[source] / 1000.0).astype(np.float32))  # metres
    offsets = np.stack([read_accessor(gltf, blob, t["POSITION"]) for t in primitive.targets])
    animation = gltf.animations[0]
    (channel,) = animation.channels
    assert channel.target.path == "weights" and gltf.nodes[channel.target.node].mesh == 0
    sampler = animation.samplers[channel.sampler]
    assert sampler.interpolation == "LINEAR"
    times = read_accessor(gltf, blob, sampler.input)
    np.testing.assert_array_equal(times, (np.arange(len(weights)) / RATE).astype(np.float32))
    w = read_accessor(gltf, blob, sampler.output).reshape(len(weights), -1)
    # frame t in the file (metres) against the frame built from the known arrays (mm)
    frames_mm = mesh.vertices[None] + np.einsum("tj,jic->tic", weights, targets)
    file_frames_m = base[None].astype(np.float64) + np.einsum("tj,jic->tic", w.astype(np.float64), offsets)
    np.testing.assert_allclose(file_frames_m * 1000.0, frames_mm[:, source], atol=2e-4)  # float32 of ~60 mm
    assert gltf.meshes[0].extras["targetNames"] == ["jaw", "brow", "smile"]
    assert gltf.meshes[0].weights == [0.0, 0.0, 0.0]
    assert gltf.asset.extras == {"take": "known"}
    # POSITION min/max, the targets' included, are the data's own
    for accessor_index, data in [(primitive.attributes.POSITION, base), *[(t["POSITION"], o) for t, o in zip(primitive.targets, offsets)]]:
        accessor = gltf.accessors[accessor_index]
        assert accessor.min == data.min(axis=0).tolist() and accessor.max == data.max(axis=0).tolist()
    assert info["n_targets"] == 3 and info["n_frames"] == len(weights)
    assert info["gpu_morph_bytes"] == info["n_vertices"] * 3 * 16
    assert info["bytes"] == path.stat().st_size


def test_uv_seam_split_is_consistent(tmp_path: Path) -> None:
    mesh = seamed_grid()
    path = tmp_path / "seam.glb"
    info = write_gltf(path, mesh, rate=RATE)
    assert_valid(path)
    gltf, blob = load(path)
    source = info["vertex_source"]
    # split exactly along the cut: the seam column twice, every other vertex once
    split = np.bincount(source, minlength=mesh.n_vertices)
    assert np.array_equal(split, np.where(np.arange(mesh.n_vertices) % GRID == GRID // 2, 2, 1))
    primitive = gltf.meshes[0].primitives[0]
    triangles = read_accessor(gltf, blob, primitive.indices).reshape(-1, 3)
    np.testing.assert_array_equal(source[triangles], mesh.faces)  # same triangles, same order
    uv_file = read_accessor(gltf, blob, primitive.attributes.TEXCOORD_0)
    corner_uv = mesh.uvs[mesh.uv_indices.reshape(-1, 3)]
    np.testing.assert_array_equal(uv_file[triangles][..., 0], corner_uv[..., 0].astype(np.float32))
    np.testing.assert_allclose(uv_file[triangles][..., 1], 1.0 - corner_uv[..., 1], atol=1e-7)  # glTF v points down
    # trimesh, an independent reader, sees the same base mesh
    scene = trimesh.load(path, process=False, force="scene")
    (geometry,) = scene.geometry.values()
    np.testing.assert_allclose(geometry.vertices, mesh.vertices[source] / 1000.0, atol=1e-9)
    np.testing.assert_array_equal(geometry.faces, triangles)


def test_quads_with_face_varying_uvs(tmp_path: Path) -> None:
    V = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [0, 10, 0], [10, 10, 0], [20, 10, 0]], float)
    polys = np.array([0, 1, 4, 3, 1, 2, 5, 4])
    uvs = np.array([[0, 0], [0.4, 0], [0.4, 1], [0, 1], [0.6, 0], [1, 0], [1, 1], [0.6, 1]])
    quad = Mesh(V, [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]], polygon_sizes=[4, 4], polygon_indices=polys,
                uvs=uvs, uv_indices=np.arange(8))
    path = tmp_path / "quads.glb"
    info = write_gltf(path, quad, targets=np.ones((1, 6, 3)), weights=[[0.0], [1.0]], rate=24.0)
    assert_valid(path)
    assert info["n_vertices"] == 8 and info["n_triangles"] == 4  # the shared edge 1-4 is a UV seam
    gltf, blob = load(path)
    primitive = gltf.meshes[0].primitives[0]
    triangles = read_accessor(gltf, blob, primitive.indices).reshape(-1, 3)
    uv_file = read_accessor(gltf, blob, primitive.attributes.TEXCOORD_0)
    fan = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])  # polygon corners of each triangle
    np.testing.assert_allclose(uv_file[triangles], np.stack([uvs[:, 0], 1 - uvs[:, 1]], 1)[fan], atol=1e-7)


def test_markers_animate_and_hide_in_gaps(tmp_path: Path) -> None:
    mesh = seamed_grid()
    targets, weights = known_take(mesh, n_frames=10)
    rng = np.random.default_rng(3)
    markers = rng.uniform(-40, 40, (10, 4, 3))
    markers[3:6, 1] = np.nan  # a gap
    path = tmp_path / "markers.glb"
    write_gltf(path, mesh, targets=targets, weights=weights, rate=RATE, markers=markers,
               marker_labels=["LBRO", "RBRO", "CHIN", "NOSE"])
    assert_valid(path)
    gltf, blob = load(path)
    by_name = {node.name: i for i, node in enumerate(gltf.nodes)}
    animation = gltf.animations[0]
    channels = {(c.target.node, c.target.path): animation.samplers[c.sampler] for c in animation.channels}
    for k, label in enumerate(["LBRO", "RBRO", "CHIN", "NOSE"]):
        node = by_name[label]
        assert gltf.nodes[node].mesh is not None
        track = read_accessor(gltf, blob, channels[(node, "translation")].output)
        seen = np.isfinite(markers[:, k, 0])
        np.testing.assert_allclose(track[seen], markers[seen, k] / 1000.0, atol=1e-8)
        if not seen.all():
            # the gap is filled on the straight line between the frames around it, and hidden by a STEP scale
            expected = markers[2, k] + (markers[6, k] - markers[2, k]) * (np.arange(3, 6) - 2)[:, None] / 4
            np.testing.assert_allclose(track[3:6], expected / 1000.0, atol=1e-8)
            scale = channels[(node, "scale")]
            assert scale.interpolation == "STEP"
            np.testing.assert_array_equal(read_accessor(gltf, blob, scale.output)[:, 0], seen.astype(np.float32))
        else:
            assert (node, "scale") not in channels


def test_compressed_file_decodes_to_the_same_bytes(tmp_path: Path) -> None:
    mesh = seamed_grid(40)
    targets, weights = known_take(mesh, n_targets=8, n_frames=200)
    plain, packed = tmp_path / "plain.glb", tmp_path / "packed.glb"
    kwargs = dict(targets=targets, weights=weights, rate=RATE, markers=np.zeros((200, 2, 3)))
    write_gltf(plain, mesh, **kwargs)
    info = write_gltf(packed, mesh, compress=True, **kwargs)
    assert_valid(plain)
    report = validate_gltf(packed)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, issue_summary(report, 0)
    # The validator cannot decode EXT_meshopt_compression (it says so as an info): meshoptimizer's own
    # decoder must give back, view by view, the bytes of the uncompressed file.
    assert any("EXT_meshopt_compression" in m for m in issue_summary(report, 2))
    gltf_plain, blob_plain = load(plain)
    gltf_packed, _ = load(packed)
    assert gltf_packed.extensionsRequired == ["EXT_meshopt_compression"]
    decoded_dir = tmp_path / "decoded"
    decoded_dir.mkdir()
    decoded = decode_meshopt(packed, decoded_dir)
    assert decoded == list(range(len(gltf_plain.bufferViews)))
    index_views = {gltf_plain.accessors[p.indices].bufferView: gltf_plain.accessors[p.indices].componentType
                   for m in gltf_plain.meshes for p in m.primitives}
    for i, view in enumerate(gltf_plain.bufferViews):
        raw = blob_plain[view.byteOffset:view.byteOffset + view.byteLength]
        got = (decoded_dir / f"bufferView_{i}.bin").read_bytes()
        assert gltf_packed.bufferViews[i].byteLength == view.byteLength
        if i in index_views:
            # the TRIANGLES codec keeps each triangle and its winding but may start it at another corner
            dtype = COMPONENT_DTYPES[index_views[i]]
            want = np.frombuffer(raw, dtype).reshape(-1, 3)
            tri = np.frombuffer(got, dtype).reshape(-1, 3)
            rotations = [np.roll(tri, k, axis=1) for k in range(3)]
            assert np.all(np.any([np.all(r == want, axis=1) for r in rotations], axis=0)), f"bufferView {i}"
        else:
            assert got == raw, f"bufferView {i}"
    assert info["bytes"] < 0.9 * plain.stat().st_size


def test_review_file_of_a_rig(tmp_path: Path) -> None:
    """The review pipeline: decimate, principal targets on the kept vertices, write; frames within the stated error."""
    mesh = seamed_grid(60)
    rng = np.random.default_rng(11)
    K, T = 10, 120
    centres = rng.uniform(-50, 50, (K, 2))
    basis = np.exp(-((mesh.vertices[None, :, :2] - centres[:, None]) ** 2).sum(-1) / 400.0)  # (K, n)
    coefficients = np.cumsum(rng.normal(0, 0.3, (T, K, 3)), axis=0)
    small, kept = review_mesh(mesh, max_vertices=1500)
    targets, weights, error = principal_targets_from_rig(basis, coefficients, vertex_subset=kept, max_targets=6)
    path = tmp_path / "review.glb"
    info = write_gltf(path, small, targets=targets, weights=weights, rate=RATE, extras={"error_mm": error})
    assert_valid(path)
    gltf, blob = load(path)
    primitive = gltf.meshes[0].primitives[0]
    base = read_accessor(gltf, blob, primitive.attributes.POSITION).astype(np.float64)
    offsets = np.stack([read_accessor(gltf, blob, t["POSITION"]) for t in primitive.targets]).astype(np.float64)
    w = read_accessor(gltf, blob, gltf.animations[0].samplers[0].output).reshape(T, -1).astype(np.float64)
    file_mm = 1000.0 * (base[None] + np.einsum("tj,jic->tic", w, offsets))
    truth = mesh.vertices[None] + np.einsum("ki,tkc->tic", basis, coefficients)  # every frame, computed directly
    err = np.linalg.norm(file_mm - truth[:, kept[info["vertex_source"]]], axis=2)
    assert err.max() <= error["max_mm"] + 1e-3
    assert err.max() >= error["max_mm"] - 1e-3
    assert gltf.asset.extras["error_mm"]["n_targets"] == 6


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(targets=np.zeros((2, 5, 3))), "targets: expected"),
        (dict(targets=np.zeros((2, GRID * GRID, 3)), weights=np.zeros((4, 3))), "weights: expected"),
        (dict(weights=np.zeros((4, 1))), "without targets"),
        (dict(targets=np.full((1, GRID * GRID, 3), np.nan)), "finite"),
        (dict(targets=np.zeros((1, GRID * GRID, 3)), target_names=["a", "b"]), "target_names"),
        (dict(targets=np.zeros((1, GRID * GRID, 3)), weights=np.zeros((4, 1)), markers=np.zeros((5, 2, 3))),
         "markers: 5 frames"),
        (dict(markers=np.zeros((5, 2))), "markers: expected"),
        (dict(extras={"bad": object()}), "extras"),
        (dict(rate=0.0), "rate"),
        (dict(targets=np.zeros((257, GRID * GRID, 3))), "257 morph targets"),
    ],
)
def test_bad_input_raises_and_writes_nothing(tmp_path: Path, kwargs: dict, message: str) -> None:
    kwargs = {"rate": RATE, **kwargs}
    with pytest.raises(InputError, match=message):
        write_gltf(tmp_path / "bad.glb", seamed_grid(), **kwargs)
    assert list(tmp_path.iterdir()) == []


def test_gpu_budget_is_enforced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mesh = seamed_grid()
    n_written = GRID * GRID + GRID  # the seam column is split
    # a budget of exactly 4 targets' texture: 4 pass, 5 do not
    monkeypatch.setattr(write_gltf_module, "MORPH_GPU_BUDGET_BYTES", n_written * 4 * 16)
    write_gltf(tmp_path / "ok.glb", mesh, targets=np.zeros((4, mesh.n_vertices, 3)), rate=RATE)
    with pytest.raises(InputError, match="review_mesh"):
        write_gltf(tmp_path / "big.glb", mesh, targets=np.zeros((5, mesh.n_vertices, 3)), rate=RATE)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.glb"]


def _rigid_motion(n_frames: int, seed: int = 3) -> np.ndarray:
    """Head turns up to ~20 degrees (a half turn of the quaternion sign on the way) and translations in mm."""
    from scipy.spatial.transform import Rotation

    t = np.linspace(0, 1, n_frames)
    rotvec = np.outer(np.sin(2 * np.pi * t), [0.1, 0.35, -0.05])
    M = np.tile(np.eye(4), (n_frames, 1, 1))
    M[:, :3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    M[:, :3, 3] = np.outer(np.sin(np.pi * t), [12.0, -5.0, 30.0]) + [0.0, 1500.0, 0.0]
    return M


def test_head_motion_moves_the_face_and_markers_in_the_world(tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    mesh = seamed_grid()
    targets, weights = known_take(mesh)
    motion = _rigid_motion(len(weights))
    markers = mesh.vertices[None, :4] + np.zeros((len(weights), 1, 1))
    path = tmp_path / "moving.glb"
    info = write_gltf(path, mesh, targets=targets, weights=weights, rate=RATE, markers=markers, head_motion=motion)
    assert_valid(path)
    gltf, blob = load(path)
    head = next(i for i, node in enumerate(gltf.nodes) if node.name == "Head")
    assert gltf.scenes[0].nodes == [head] and 0 in gltf.nodes[head].children
    paths = {}
    for channel in gltf.animations[0].channels:
        if channel.target.node == head:
            sampler = gltf.animations[0].samplers[channel.sampler]
            assert sampler.interpolation == "LINEAR"
            paths[channel.target.path] = read_accessor(gltf, blob, sampler.output)
    translation_m = paths["translation"].reshape(-1, 3)
    q = paths["rotation"].reshape(-1, 4)
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0)  # neighbouring quaternions on the same side: no flip
    R = Rotation.from_quat(q).as_matrix()
    np.testing.assert_allclose(R, motion[:, :3, :3], atol=1e-6)
    np.testing.assert_allclose(translation_m * 1000.0, motion[:, :3, 3], atol=1e-3)  # float32 metres at 1.5 m
    # the face in the world at frame t: M_t (base + sum_j w_j targets_j)
    source = info["vertex_source"]
    primitive = gltf.meshes[0].primitives[0]
    base = read_accessor(gltf, blob, primitive.attributes.POSITION).astype(np.float64)
    offsets = np.stack([read_accessor(gltf, blob, t["POSITION"]) for t in primitive.targets]).astype(np.float64)
    local_mm = 1000.0 * (base[None] + np.einsum("tj,jic->tic", weights, offsets))
    world_mm = np.einsum("tij,tnj->tni", R, local_mm) + translation_m[:, None] * 1000.0
    expected = np.einsum("tij,tnj->tni", motion[:, :3, :3], mesh.vertices[None] + np.einsum("tj,jic->tic", weights, targets)) \
        + motion[:, None, :3, 3]
    np.testing.assert_allclose(world_mm, expected[:, source], atol=2e-3)


def test_head_motion_must_be_rigid(tmp_path: Path) -> None:
    mesh = seamed_grid()
    targets, weights = known_take(mesh)
    motion = _rigid_motion(len(weights))
    motion[3, :3, :3] *= 1.1  # a scale is not a head motion
    with pytest.raises(InputError, match="rigid"):
        write_gltf(tmp_path / "bad.glb", mesh, targets=targets, weights=weights, rate=RATE, head_motion=motion)
    with pytest.raises(InputError, match="head_motion: 5 frames"):
        write_gltf(tmp_path / "bad.glb", mesh, targets=targets, weights=weights, rate=RATE, head_motion=motion[:5])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("compress", [False, True])
def test_the_scans_texture_is_the_files_base_colour(tmp_path: Path, compress: bool) -> None:
    from dataclasses import replace

    mesh = seamed_grid()
    image = np.random.default_rng(3).integers(0, 256, (8, 16, 3)).astype(np.uint8)
    textured = replace(mesh, texture=image)
    path = tmp_path / "textured.glb"
    write_gltf(path, textured, rate=RATE, compress=compress)
    assert_valid(path)
    if compress:
        return  # trimesh cannot decode meshopt; the uncompressed file checks the colours
    # trimesh, an independent reader, finds the same image and samples it at the file's UVs
    scene = trimesh.load(path, process=False, force="scene")
    (geometry,) = scene.geometry.values()
    texture = np.asarray(geometry.visual.material.baseColorTexture.convert("RGB"))
    np.testing.assert_array_equal(texture, image)
    rows, cols = np.mgrid[0:8, 0:16]
    uv = np.stack([(cols.ravel() + 0.5) / 16, 1.0 - (rows.ravel() + 0.5) / 8], axis=1)
    colours = trimesh.visual.color.uv_to_color(uv, geometry.visual.material.baseColorTexture)[:, :3]
    np.testing.assert_array_equal(colours, image[rows.ravel(), cols.ravel()])
