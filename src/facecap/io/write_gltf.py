"""A review file for artists: the scan, its motion as morph targets and a weights animation, in one ``.glb``.

glTF 2.0 has no per-frame vertex positions, so an animated mesh is written as
the rest mesh plus ``r`` morph targets (POSITION offsets) and one animation of
their weights: the position of vertex ``i`` at frame ``t`` is

    p_t[i] = base[i] + sum_j w_j(t) target_j[i]

(glTF 2.0, section 3.7.2.2 "Morph Targets"). A take becomes few targets through
its principal components (:mod:`facecap.deform.principal_targets`), on a
review mesh small enough for a browser (:func:`facecap.mesh.review_mesh`).

Layout of the file::

    scene 0
      node "Face"      mesh 0: triangles, POSITION (+ TEXCOORD_0), r morph targets,
                       extras.targetNames; animation "Performance" drives its weights
      node "Markers"   (when markers are given) one child node per marker, with a
                       small octahedron mesh and a translation animation (and a
                       STEP scale animation that hides it during its gaps)
      node "Head"      (with head motion) the root of both, with a translation and
                       rotation animation: the face in the world

Units: glTF's unit is the metre, facecap's the millimetre; positions, offsets
and marker translations are divided by 1000 here. No normals are written: the
targets carry no normal offsets, so stored normals would stay those of the rest
shape; without them viewers compute flat normals from the moved positions
(glTF 2.0, 3.7.2.1), which is right at every frame.

Limits of viewers checked before anything is written (:data:`MAX_MORPH_TARGETS`,
:data:`MORPH_GPU_BUDGET_BYTES`): three.js (and so most web viewers) packs the
targets into a float texture of 16 bytes per vertex per target, one texture
layer per target; glTF itself sets neither limit.
"""

from __future__ import annotations

import json
import math
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..structures import Mesh
from .atomic_write import atomic_path

__all__ = [
    "write_gltf",
    "MAX_MORPH_TARGETS",
    "MORPH_GPU_BUDGET_BYTES",
    "MORPH_GPU_BYTES_PER_VERTEX_TARGET",
    "triangle_corners",
]

MAX_MORPH_TARGETS = 256
"""Most morph targets written: WebGL 2 guarantees only 256 layers in an array
texture (``MAX_ARRAY_TEXTURE_LAYERS``), and three.js puts one target in each."""

MORPH_GPU_BYTES_PER_VERTEX_TARGET = 16
"""three.js stores a POSITION-only target as one RGBA float32 texel per vertex."""

MORPH_GPU_BUDGET_BYTES = 2 * 2**30
"""Largest morph texture (vertices x targets x 16 bytes) written: 2 GiB, what a
browser tab can allocate on a mid-range GPU; above it three.js fails to upload it."""

_MM_PER_M = 1000.0
_ARRAY_BUFFER = 34962
_ELEMENT_ARRAY_BUFFER = 34963
_FLOAT = 5126
_UNSIGNED_SHORT = 5123
_UNSIGNED_INT = 5125
_MESHOPT = "EXT_meshopt_compression"
_MARKER_RADIUS_M = 0.0015  # a 3 mm octahedron: the size of a facial marker


def write_gltf(
    path: str | os.PathLike[str],
    mesh: Mesh,
    *,
    targets: np.ndarray | None = None,
    weights: np.ndarray | None = None,
    rate: float,
    target_names: list[str] | tuple[str, ...] | None = None,
    markers: np.ndarray | None = None,
    marker_labels: list[str] | tuple[str, ...] | None = None,
    head_motion: np.ndarray | None = None,
    compress: bool = False,
    progress: bool = False,
    extras: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write a mesh with morph targets and their weights animation as a binary glTF (``.glb``).

    Parameters
    ----------
    path : str or path-like
        The ``.glb`` file to write (atomically: a hidden sibling renamed on success).
    mesh : Mesh
        The rest mesh (mm). Its triangles ``mesh.faces`` are written; face-varying
        UVs (``mesh.uv_indices``) are made per-vertex by splitting vertices along
        UV seams (glTF has per-vertex attributes only); the split is returned
        as ``vertex_source``.
    targets : (r, n, 3) float array, mm, or None
        Morph target offsets from ``mesh.vertices``; default None: no targets.
    weights : (T, r) float array or None
        Weight of each target at each frame: one animation, a LINEAR sampler
        with time ``frame / rate`` s. Needs ``targets``. Default None: no
        weights animation (the targets are still there, at weight 0).
    rate : float
        Frame rate of the take in Hz.
    target_names : sequence of r str, or None
        Names in ``mesh.extras.targetNames`` (the convention three.js and
        Blender read); default ``target_000, target_001, ...``.
    markers : (T, K, 3) float array, mm, or None
        Marker positions in the mesh's frame, NaN in gaps: one node per marker
        with a translation animation (gaps linearly filled, and the marker
        hidden by a STEP scale of 0 while its gap lasts). ``T`` must equal
        ``len(weights)`` when both are given.
    marker_labels : sequence of K str, or None
        Names of the marker nodes; default ``marker_000, ...``.
    head_motion : (T, 4, 4) float array, mm, or None
        Rigid motion per frame (column vectors, translation in mm) of a
        stabilised result: a root node ``Head`` above the face and the markers
        gets it as a translation and rotation animation (LINEAR: rotations are
        slerped between frames), so the face plays where the capture saw it.
    compress : bool, optional
        Compress the buffers with ``EXT_meshopt_compression`` (lossless:
        meshoptimizer's vertex and index codecs, no quantisation), through
        the ``meshopt`` binding; default False. The file then needs a viewer
        with a meshopt decoder (three.js ``GLTFLoader.setMeshoptDecoder``,
        Babylon.js, gltfpack); Blender 5.0.1's importer refuses it.
    progress : bool, optional
        Show a tqdm progress bar over the buffers; default False.
    extras : dict or None
        JSON-serialisable data for ``asset.extras`` (for example the take,
        the error the targets leave, the tool's version).

    Returns
    -------
    info : dict
        ``path`` (str), ``bytes`` (file size), ``buffer_bytes`` (binary data
        before compression), ``n_vertices`` (written, after the seam split),
        ``n_triangles``, ``n_targets``, ``n_frames``, ``n_markers``,
        ``vertex_source`` ((n_written,) int64: the mesh vertex each written
        vertex copies), ``gpu_morph_bytes`` (the three.js morph texture),
        ``compressed`` (bool).

    Raises
    ------
    InputError
        If an array has the wrong shape or non-finite values, the faces are
        not the fan triangulation of the polygons (UVs could not be carried),
        ``extras`` is not JSON, or the targets exceed a viewer limit:
        more than :data:`MAX_MORPH_TARGETS` targets, or a morph texture above
        :data:`MORPH_GPU_BUDGET_BYTES` (write fewer components, or targets on
        a decimated review mesh, :func:`facecap.mesh.review_mesh`). Nothing
        is written then.

    Notes
    -----
    POSITION accessors, the targets' included, carry ``min``/``max`` (glTF 2.0,
    3.7.2.1 requires them). The GLB container (glTF 2.0, section 4) is written
    here rather than by pygltflib, whose ``save_to_bytes`` merges all buffers
    into one and so cannot keep the fallback buffer ``EXT_meshopt_compression``
    needs. Compressed attribute views use meshoptimizer's ``ATTRIBUTES`` mode,
    the weights one row of ``r`` floats per frame when ``4 r <= 256`` bytes
    (the codec predicts each byte from the row before, so frame-to-frame
    coherence compresses); index views use ``TRIANGLES``.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from facecap.structures import Mesh
    >>> tri = Mesh([[0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2]])
    >>> lift = np.zeros((1, 3, 3)); lift[0, :, 2] = 5.0
    >>> out = os.path.join(tempfile.mkdtemp(), "take.glb")
    >>> info = write_gltf(out, tri, targets=lift, weights=[[0.0], [1.0]], rate=30.0)
    >>> info["n_vertices"], info["n_targets"], info["n_frames"]
    (3, 1, 2)
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
    rate_hz = _positive_rate(rate)
    n = mesh.n_vertices
    offsets = _optional_array(targets, "targets", lambda a: a.ndim == 3 and a.shape[1:] == (n, 3),
                              f"(r, {n}, 3) offsets in mm from mesh.vertices")
    r = 0 if offsets is None else offsets.shape[0]
    if offsets is not None and r == 0:
        raise InputError("targets: expected at least one target (pass targets=None for none)")
    if weights is not None and offsets is None:
        raise InputError("weights: given without targets")
    frame_weights = _optional_array(weights, "weights", lambda a: a.ndim == 2 and a.shape[1] == r,
                                    f"(T, {r}) weights, one column per target")
    if frame_weights is not None and frame_weights.shape[0] == 0:
        raise InputError("weights: expected at least one frame")
    marker_xyz = _optional_array(markers, "markers", lambda a: a.ndim == 3 and a.shape[2] == 3 and a.shape[0] > 0,
                                 "(T, K, 3) marker positions in mm", allow_nan=True)
    if marker_xyz is not None and frame_weights is not None and marker_xyz.shape[0] != frame_weights.shape[0]:
        raise InputError(
            f"markers: {marker_xyz.shape[0]} frames, but weights have {frame_weights.shape[0]}: "
            "both animate the same take"
        )
    motion = _optional_array(head_motion, "head_motion", lambda a: a.shape[1:] == (4, 4) and a.shape[0] > 0,
                             "(T, 4, 4) rigid transforms in mm")
    if motion is not None:
        frames_elsewhere = {len(a) for a in (frame_weights, marker_xyz) if a is not None}
        if frames_elsewhere and frames_elsewhere != {motion.shape[0]}:
            raise InputError(f"head_motion: {motion.shape[0]} frames, the weights or markers have {frames_elsewhere}")
        R = motion[:, :3, :3]
        if np.abs(np.einsum("tji,tjk->tik", R, R) - np.eye(3)).max() > 1e-5 or np.any(np.linalg.det(R) <= 0):
            raise InputError("head_motion: expected rigid transforms (rotation and translation only)")
    names = _names(target_names, r, "target_names", "target")
    labels = _names(marker_labels, 0 if marker_xyz is None else marker_xyz.shape[1], "marker_labels", "marker")
    if extras is not None:
        if not isinstance(extras, dict):
            raise InputError(f"extras: expected a dict, got {type(extras).__name__}")
        try:
            json.dumps(extras, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InputError(f"extras: not JSON-serialisable ({exc})") from None

    triangles, vertex_source, uv = _split_uv_seams(mesh)
    n_out = vertex_source.size
    gpu_bytes = n_out * r * MORPH_GPU_BYTES_PER_VERTEX_TARGET
    if r > MAX_MORPH_TARGETS:
        raise InputError(
            f"targets: {r} morph targets, more than the {MAX_MORPH_TARGETS} a WebGL 2 viewer can hold "
            "(three.js puts one target per texture layer); write fewer principal components"
        )
    if gpu_bytes > MORPH_GPU_BUDGET_BYTES:
        raise InputError(
            f"targets: {n_out} vertices x {r} targets x {MORPH_GPU_BYTES_PER_VERTEX_TARGET} bytes = "
            f"{gpu_bytes / 2**30:.2f} GiB of morph texture, above the {MORPH_GPU_BUDGET_BYTES / 2**30:.0f} GiB "
            "a browser viewer can upload; write fewer components or targets on a decimated review mesh "
            "(facecap.mesh.review_mesh)"
        )
    if compress:
        meshopt = _import_meshopt()

    builder = _GlbBuilder(compress=compress)
    n_frames = 0 if frame_weights is None else frame_weights.shape[0]
    if marker_xyz is not None:
        n_frames = marker_xyz.shape[0]
    if motion is not None:
        n_frames = motion.shape[0]
    steps = 2 + r + (1 if n_frames else 0) + (0 if marker_xyz is None else marker_xyz.shape[1])
    from tqdm import tqdm

    with tqdm(total=steps, desc="glTF", unit="buffer", disable=not progress) as bar:
        base_m = (mesh.vertices[vertex_source] / _MM_PER_M).astype(np.float32)
        index_type = _UNSIGNED_SHORT if n_out < 65535 else _UNSIGNED_INT
        index_data = triangles.astype(np.uint16 if index_type == _UNSIGNED_SHORT else np.uint32).ravel()
        attributes = {"POSITION": builder.accessor(base_m, "VEC3", target=_ARRAY_BUFFER, min_max=True)}
        bar.update()
        if uv is not None:
            attributes["TEXCOORD_0"] = builder.accessor(uv, "VEC2", target=_ARRAY_BUFFER)
        primitive: dict[str, Any] = {
            "attributes": attributes,
            "indices": builder.accessor(index_data, "SCALAR", target=_ELEMENT_ARRAY_BUFFER, triangles=True),
            "material": 0,
            "mode": 4,
        }
        bar.update()
        if r:
            primitive["targets"] = []
            for j in range(r):
                offset_m = (offsets[j][vertex_source] / _MM_PER_M).astype(np.float32)
                primitive["targets"].append(
                    {"POSITION": builder.accessor(offset_m, "VEC3", target=_ARRAY_BUFFER, min_max=True)}
                )
                bar.update()
        face_mesh: dict[str, Any] = {"name": "Face", "primitives": [primitive]}
        if r:
            face_mesh["weights"] = [0.0] * r
            face_mesh["extras"] = {"targetNames": names}
        gltf: dict[str, Any] = {
            "asset": {"version": "2.0", "generator": "facecap write_gltf"},
            "scene": 0,
            "scenes": [{"name": "Take", "nodes": [0]}],
            "nodes": [{"name": "Face", "mesh": 0}],
            "meshes": [face_mesh],
            "materials": [{
                "name": "Skin",
                "doubleSided": True,  # a face scan is an open surface, seen from behind at the edges
                "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.7, 0.65, 1.0], "metallicFactor": 0.0,
                                         "roughnessFactor": 0.6},
            }],
        }
        if uv is not None and mesh.texture is not None:  # the scan's colour texture, as the file's base colour
            gltf["images"] = [{"bufferView": builder.raw_view(_png_bytes(mesh.texture)), "mimeType": "image/png"}]
            gltf["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
            gltf["textures"] = [{"sampler": 0, "source": 0}]
            pbr = gltf["materials"][0]["pbrMetallicRoughness"]
            pbr["baseColorFactor"] = [1.0, 1.0, 1.0, 1.0]
            pbr["baseColorTexture"] = {"index": 0, "texCoord": 0}
        if extras is not None:
            gltf["asset"]["extras"] = extras

        channels: list[dict[str, Any]] = []
        samplers: list[dict[str, Any]] = []
        if n_frames:
            times = (np.arange(n_frames, dtype=np.float64) / rate_hz).astype(np.float32)
            if n_frames > 1 and not np.all(np.diff(times) > 0):
                raise InputError(f"rate: {rate_hz} Hz over {n_frames} frames gives frame times float32 cannot tell apart")
            time_accessor = builder.accessor(times, "SCALAR", min_max=True)
            bar.update()
            if frame_weights is not None:
                w = frame_weights.astype(np.float32)
                samplers.append({"input": time_accessor, "output": builder.accessor(w, "SCALAR", rows=True),
                                 "interpolation": "LINEAR"})
                channels.append({"sampler": len(samplers) - 1, "target": {"node": 0, "path": "weights"}})
        if marker_xyz is not None:
            _add_markers(gltf, builder, marker_xyz, labels, time_accessor, samplers, channels, bar)
        if motion is not None:
            _add_head_motion(gltf, builder, motion, time_accessor, samplers, channels)
        if channels:
            gltf["animations"] = [{"name": "Performance", "channels": channels, "samplers": samplers}]
        blob = builder.finish(gltf, meshopt if compress else None)
        glb = _glb_bytes(gltf, blob)

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            for part in glb:
                handle.write(part)
    return {
        "path": os.fspath(path),
        "bytes": Path(os.fspath(path)).stat().st_size,
        "buffer_bytes": builder.raw_bytes,
        "n_vertices": int(n_out),
        "n_triangles": int(triangles.shape[0]),
        "n_targets": int(r),
        "n_frames": int(n_frames),
        "n_markers": 0 if marker_xyz is None else int(marker_xyz.shape[1]),
        "vertex_source": vertex_source,
        "gpu_morph_bytes": int(gpu_bytes),
        "compressed": bool(compress),
    }


# ----------------------------------------------------------------------------- inputs


def _positive_rate(rate: object) -> float:
    try:
        rate_f = float(rate)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        rate_f = float("nan")
    if not math.isfinite(rate_f) or rate_f <= 0:
        raise InputError(f"rate: expected a positive frame rate in Hz, got {rate!r}")
    return rate_f


def _optional_array(value: object, name: str, shape_ok: Any, expected: str, *, allow_nan: bool = False) -> np.ndarray | None:
    if value is None:
        return None
    try:
        arr = np.asarray(value, dtype=np.float64 if not isinstance(value, np.ndarray) else None)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected {expected}, got {type(value).__name__}") from None
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name}: expected {expected}, got an array of {arr.dtype}")
    if not shape_ok(arr):
        raise InputError(f"{name}: expected {expected}, got shape {arr.shape}")
    bad = np.isinf(arr) if allow_nan else ~np.isfinite(arr)
    if bad.any():
        raise InputError(f"{name}: expected finite values, got {'infinity' if allow_nan else 'NaN or infinity'}")
    return arr


def _names(names: object, count: int, argument: str, stem: str) -> list[str]:
    if names is None:
        return [f"{stem}_{j:03d}" for j in range(count)]
    if isinstance(names, str) or not all(isinstance(s, str) for s in names):  # type: ignore[union-attr]
        raise InputError(f"{argument}: expected a sequence of {count} strings")
    out = list(names)  # type: ignore[call-overload]
    if len(out) != count:
        raise InputError(f"{argument}: expected {count} names, got {len(out)}")
    return out


def triangle_corners(mesh: Mesh) -> np.ndarray:
    """Index of each triangle corner into the mesh's corner list (the one ``uv_indices`` follows).

    Parameters
    ----------
    mesh : Mesh
        Triangles ``faces`` and, when it has them, the polygons they fan.

    Returns
    -------
    (m, 3) int64 array
        ``corners[f, k]``: the polygon corner triangle ``f``'s corner ``k`` is
        (``3 f + k`` for a triangle mesh without polygons).

    Raises
    ------
    InputError
        If a polygon has fewer than 3 corners, or the triangles are not the
        fan triangulation of the polygons.
    """
    m = mesh.n_faces
    if mesh.polygon_sizes is None or mesh.polygon_indices is None:
        return np.arange(3 * m, dtype=np.int64).reshape(m, 3)
    sizes = mesh.polygon_sizes
    if np.any(sizes < 3):
        raise InputError("mesh.polygon_sizes: every polygon needs at least 3 corners")
    starts = np.cumsum(sizes) - sizes
    n_tri = sizes - 2
    poly = np.repeat(np.arange(sizes.size), n_tri)
    j = np.arange(poly.size) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    first = starts[poly]
    corners = np.stack([first, first + j, first + j + 1], axis=1)
    if corners.shape != mesh.faces.shape or not np.array_equal(mesh.polygon_indices[corners], mesh.faces):
        raise InputError(
            "mesh.faces: not the fan triangulation of mesh.polygon_indices, so the face-varying UVs "
            "cannot be carried onto the triangles"
        )
    return corners


def _split_uv_seams(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Triangles, ``vertex_source`` and per-vertex glTF UVs, vertices split where UVs are face-varying.

    Each distinct (vertex, UV index) pair at a triangle corner becomes one
    written vertex, ordered by vertex then UV index (so an unsplit mesh keeps
    its order). Vertices that no triangle uses are dropped then. glTF's UV
    origin is the top-left corner, facecap's (OBJ's) the bottom-left: v -> 1 - v.
    """
    n = mesh.n_vertices
    if mesh.uvs is None:
        return mesh.faces, np.arange(n, dtype=np.int64), None
    uvs = np.asarray(mesh.uvs, dtype=np.float64)
    if uvs.ndim != 2 or uvs.shape[1] != 2 or not np.all(np.isfinite(uvs)):
        raise InputError(f"mesh.uvs: expected finite (u, 2) texture coordinates, got shape {uvs.shape}")
    if mesh.uv_indices is None:
        if uvs.shape[0] != n:
            raise InputError(f"mesh.uvs: without uv_indices expected one UV per vertex ({n}), got {uvs.shape[0]}")
        return mesh.faces, np.arange(n, dtype=np.int64), _gltf_uv(uvs)
    corners = triangle_corners(mesh)
    uv_index = np.asarray(mesh.uv_indices, dtype=np.int64)
    n_corners = corners.size if mesh.polygon_sizes is None else int(mesh.polygon_sizes.sum())
    if uv_index.shape != (n_corners,):
        raise InputError(f"mesh.uv_indices: expected one index per polygon corner ({n_corners}), got {uv_index.shape}")
    if uv_index.size and (uv_index.min() < 0 or uv_index.max() >= uvs.shape[0]):
        raise InputError(f"mesh.uv_indices: indices must lie in [0, {uvs.shape[0]})")
    corner_uv = uv_index[corners]
    key = mesh.faces * np.int64(uvs.shape[0]) + corner_uv
    unique_keys, triangles = np.unique(key.ravel(), return_inverse=True)
    vertex_source = unique_keys // uvs.shape[0]
    return triangles.reshape(-1, 3).astype(np.int64), vertex_source, _gltf_uv(uvs[unique_keys % uvs.shape[0]])


def _gltf_uv(uvs: np.ndarray) -> np.ndarray:
    out = np.empty(uvs.shape, dtype=np.float32)
    out[:, 0] = uvs[:, 0]
    out[:, 1] = 1.0 - uvs[:, 1]
    return out


def _import_meshopt() -> Any:
    try:
        import meshopt
    except ImportError:
        raise InputError(
            "compress=True needs the meshopt package (meshoptimizer's encoder): pip install meshopt"
        ) from None
    return meshopt


# ----------------------------------------------------------------------------- markers


def _marker_mesh(builder: "_GlbBuilder") -> dict[str, Any]:
    """A small octahedron for the marker nodes to show."""
    a = _MARKER_RADIUS_M
    V = np.array([[a, 0, 0], [-a, 0, 0], [0, a, 0], [0, -a, 0], [0, 0, a], [0, 0, -a]], dtype=np.float32)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.uint16)
    return {"name": "Marker", "primitives": [{
        "attributes": {"POSITION": builder.accessor(V, "VEC3", target=_ARRAY_BUFFER, min_max=True)},
        "indices": builder.accessor(F.ravel(), "SCALAR", target=_ELEMENT_ARRAY_BUFFER, triangles=True),
        "material": 1, "mode": 4,
    }]}


def _add_markers(gltf: dict[str, Any], builder: "_GlbBuilder", markers: np.ndarray, labels: list[str],
                 time_accessor: int, samplers: list[dict[str, Any]], channels: list[dict[str, Any]], bar: Any) -> None:
    gltf["meshes"].append(_marker_mesh(builder))
    gltf["materials"].append({"name": "Marker", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.45, 0.05, 1.0],
                                                                          "metallicFactor": 0.0}})
    group = len(gltf["nodes"])
    gltf["nodes"].append({"name": "Markers", "children": []})
    gltf["scenes"][0]["nodes"].append(group)
    n_frames, n_markers = markers.shape[:2]
    frames = np.arange(n_frames)
    for k in range(n_markers):
        xyz = markers[:, k]
        seen = np.isfinite(xyz).all(axis=1)
        filled = np.zeros((n_frames, 3))
        if seen.any():
            for c in range(3):  # linear through gaps, held at the ends
                filled[:, c] = np.interp(frames, frames[seen], xyz[seen, c])
        node = len(gltf["nodes"])
        gltf["nodes"].append({"name": labels[k], "mesh": len(gltf["meshes"]) - 1,
                              "translation": [float(v) for v in (filled[0] / _MM_PER_M).astype(np.float32)]})
        if not seen[0]:
            gltf["nodes"][node]["scale"] = [0.0, 0.0, 0.0]
        gltf["nodes"][group]["children"].append(node)
        translation = (filled / _MM_PER_M).astype(np.float32)
        samplers.append({"input": time_accessor, "output": builder.accessor(translation, "VEC3"),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": "translation"}})
        if not seen.all():
            scale = np.repeat(seen.astype(np.float32)[:, None], 3, axis=1)
            samplers.append({"input": time_accessor, "output": builder.accessor(scale, "VEC3"),
                             "interpolation": "STEP"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": "scale"}})
        bar.update()


def _add_head_motion(gltf: dict[str, Any], builder: "_GlbBuilder", motion: np.ndarray, time_accessor: int,
                     samplers: list[dict[str, Any]], channels: list[dict[str, Any]]) -> None:
    """A root node ``Head`` over every node of the scene, animated by the rigid motion (metres, quaternions)."""
    from scipy.spatial.transform import Rotation

    translation = (motion[:, :3, 3] / _MM_PER_M).astype(np.float32)
    quaternions = Rotation.from_matrix(motion[:, :3, :3]).as_quat()  # (x, y, z, w), glTF's order
    # the shorter way round between neighbouring frames: slerp of q and -q differ
    flip = np.cumsum(np.r_[0, (np.sum(quaternions[1:] * quaternions[:-1], axis=1) < 0).astype(int)]) % 2 == 1
    quaternions[flip] *= -1
    quaternions = quaternions.astype(np.float32)
    head = len(gltf["nodes"])
    gltf["nodes"].append({"name": "Head", "children": list(gltf["scenes"][0]["nodes"]),
                          "translation": [float(v) for v in translation[0]],
                          "rotation": [float(v) for v in quaternions[0]]})
    gltf["scenes"][0]["nodes"] = [head]
    for path, values in (("translation", translation), ("rotation", quaternions)):
        samplers.append({"input": time_accessor, "output": builder.accessor(values, "VEC3" if path == "translation" else "VEC4"),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": head, "path": path}})


# ----------------------------------------------------------------------------- container


class _GlbBuilder:
    """Accessors and buffer views over one binary buffer (and a fallback buffer when compressed)."""

    def __init__(self, *, compress: bool) -> None:
        self.compress = compress
        self.accessors: list[dict[str, Any]] = []
        self.views: list[dict[str, Any]] = []
        self.arrays: list[tuple[np.ndarray, str]] = []  # (data as rows, meshopt mode) per view
        self.raw_bytes = 0

    def accessor(self, data: np.ndarray, kind: str, *, target: int | None = None, min_max: bool = False,
                 triangles: bool = False, rows: bool = False) -> int:
        """Add ``data`` as one accessor in its own buffer view; return the accessor's index.

        ``rows``: a 2D array of scalars whose rows compress together (the
        weights, one row per frame); the accessor is its flat sequence.
        """
        data = np.ascontiguousarray(data)
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[kind]
        count = data.size // width
        component = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint16): _UNSIGNED_SHORT,
                     np.dtype(np.uint32): _UNSIGNED_INT}[data.dtype]
        view: dict[str, Any] = {"byteLength": int(data.nbytes)}
        if target is not None:
            view["target"] = target
        self.views.append(view)
        if triangles:
            mode, encoded = "TRIANGLES", data.ravel()
        elif rows and data.ndim == 2 and data.shape[1] * data.itemsize <= 256:
            mode, encoded = "ATTRIBUTES", data  # meshopt's element stride is at most 256 bytes
        else:
            mode, encoded = "ATTRIBUTES", data.reshape(count, width)
        self.arrays.append((encoded, mode))
        accessor: dict[str, Any] = {"bufferView": len(self.views) - 1, "componentType": component,
                                    "count": int(count), "type": kind}
        if min_max:
            flat = data.reshape(count, width)
            accessor["min"] = [float(v) for v in flat.min(axis=0)]
            accessor["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def raw_view(self, payload: bytes) -> int:
        """Add ``payload`` (an encoded image) as a buffer view of its own, never compressed; its index."""
        self.views.append({"byteLength": len(payload)})
        self.arrays.append((np.frombuffer(payload, dtype=np.uint8), "RAW"))
        return len(self.views) - 1

    def finish(self, gltf: dict[str, Any], meshopt: Any | None) -> list[bytes | memoryview]:
        """Lay the views out (4-byte aligned), fill ``gltf``'s buffer tables; return the BIN chunk's parts."""
        parts: list[bytes | memoryview] = []
        offset = 0
        fallback_offset = 0
        for view, (data, mode) in zip(self.views, self.arrays):
            raw = memoryview(data).cast("B")
            if meshopt is None or mode == "RAW":
                view["buffer"] = 0
                view["byteOffset"] = offset
                payload: bytes | memoryview = raw
            else:
                payload = meshopt.encode_gltf_buffer(data, mode)
                view["buffer"] = 1
                view["byteOffset"] = fallback_offset
                fallback_offset += _aligned(len(raw))
                view["extensions"] = {_MESHOPT: {
                    "buffer": 0, "byteOffset": offset, "byteLength": len(payload),
                    "byteStride": int(data.itemsize * (1 if data.ndim == 1 else data.shape[1])),
                    "count": int(data.shape[0]), "mode": mode,
                }}
            parts.append(payload)
            pad = _aligned(len(payload)) - len(payload)
            if pad:
                parts.append(b"\0" * pad)
            offset += len(payload) + pad
            self.raw_bytes += len(raw)
        gltf["accessors"] = self.accessors
        gltf["bufferViews"] = self.views
        gltf["buffers"] = [{"byteLength": offset}]
        if meshopt is not None:
            gltf["buffers"].append({"byteLength": fallback_offset, "extensions": {_MESHOPT: {"fallback": True}}})
            gltf["extensionsUsed"] = [_MESHOPT]
            gltf["extensionsRequired"] = [_MESHOPT]
        return parts


def _png_bytes(texture: np.ndarray) -> bytes:
    """An 8-bit PNG of an RGB texture (16-bit ones rounded to 8: what glTF viewers read)."""
    import cv2

    image = texture if texture.dtype == np.uint8 else np.round(texture / 257.0).astype(np.uint8)
    ok, encoded = cv2.imencode(".png", np.ascontiguousarray(image[:, :, ::-1]))
    if not ok:
        raise InputError("mesh.texture: OpenCV could not encode it as PNG")
    return encoded.tobytes()


def _aligned(size: int) -> int:
    return (size + 3) // 4 * 4


def _glb_bytes(gltf: dict[str, Any], bin_parts: list[bytes | memoryview]) -> list[bytes | memoryview]:
    """The GLB container (glTF 2.0, section 4): header, JSON chunk (space-padded), BIN chunk (zero-padded)."""
    text = json.dumps(gltf, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (_aligned(len(text)) - len(text))
    bin_length = sum(len(p) for p in bin_parts)
    total = 12 + 8 + len(text) + 8 + bin_length
    if total > 2**32 - 1:
        raise InputError(
            f"the file would be {total / 2**30:.1f} GiB, beyond GLB's 4 GiB limit; write fewer targets "
            "or a decimated review mesh"
        )
    return [struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text,
            struct.pack("<I4s", bin_length, b"BIN\0"), *bin_parts]
