"""A result's rig as UsdSkel blend shapes with animated weights (``performance_rig.usdc``).

Layout of the stage::

    /Head              SkelRoot, defaultPrim; time-sampled ``xformOp:transform``
                       with the head motion of a stabilised result
    /Head/Skeleton     Skeleton (no joints: the rig is blend shapes only),
                       ``skel:animationSource`` -> /Head/Animation
    /Head/Animation    SkelAnimation: ``blendShapes`` and time-sampled ``blendShapeWeights``
    /Head/Face         Mesh: the points at all-zero weights, the scan's polygons
                       and UVs, ``skel:blendShapes`` / ``skel:blendShapeTargets``,
                       ``customData["facecap:restWeights"]`` (the weights of the rest shape)
    /Head/Face/s0000.. BlendShape: ``offsets`` and ``pointIndices``

Frame k is time code k at the take's rate, as in ``performance.usdc``; points
are in the result's unit with ``metersPerUnit`` set to match. Every weight
lies in [0, 1] (:mod:`facecap.io.weight_ranges`: Blender clamps to that range),
so the mesh's own points are the shape at all-zero weights; the rest shape is at
``restWeights``.

The thin shell's rig has one scalar weight per marker and vertex, so it
becomes three shapes per marker (that marker moved along x, y and z; see
:meth:`facecap.io.ResultRig.shapes`). A shape's ``pointIndices`` keep only
the vertices it moves by more than its share of ``tolerance`` over the whole
take: the shell's weights decay away from their marker, and the far vertices'
contributions are below float32's resolution of the coordinates. The dropped
contributions add up to at most ``tolerance`` at any vertex and frame (the
bound is written into the layer's documentation and returned).

Those exact shapes cost ``3 K n`` vectors: 2.3 GB at 700k vertices and 90
markers, where the rig itself is 0.26 GB. Given ``principal_targets`` (the
take's first principal components, computed by the caller with
:func:`facecap.deform.principal_targets_from_rig`), the stage holds those
instead, and the error they leave (``principal_error``) is returned and written
into the layer's documentation. :func:`facecap.pipelines.export_result` chooses:
exact up to :data:`USD_EXACT_MAX_BYTES` of shapes, principal components beyond.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..structures import Mesh
from ..units import mm_per_unit
from .atomic_write import atomic_path
from .result_rig import ResultRig
from .usd_material import bind_colour_texture, write_texture_beside
from .weight_ranges import to_unit_range

__all__ = ["write_usd_blendshapes", "DEFAULT_BLENDSHAPE_TOLERANCE_MM", "USD_EXACT_MAX_BYTES", "DEFAULT_USD_COMPONENTS"]

DEFAULT_BLENDSHAPE_TOLERANCE_MM = 1e-4
"""Largest vertex error the dropped far-field shape entries may add up to, mm."""

USD_EXACT_MAX_BYTES = 1 << 30
"""Largest exact set of blend shapes (``12 m n`` bytes) the automatic choice writes; principal components beyond."""

DEFAULT_USD_COMPONENTS = 48
"""Blend shapes of a principal-component USD rig (the size bar at 700k vertices: rig + USD under 1/100 of the frames)."""

_ROOT, _SKELETON, _ANIMATION, _FACE = "/Head", "/Head/Skeleton", "/Head/Animation", "/Head/Face"


def write_usd_blendshapes(
    path: str | os.PathLike[str],
    mesh: Mesh,
    rig: ResultRig,
    *,
    rate: float,
    head_motion: np.ndarray | None = None,
    tolerance_mm: float = DEFAULT_BLENDSHAPE_TOLERANCE_MM,
    principal_targets: np.ndarray | None = None,
    principal_weights: np.ndarray | None = None,
    principal_error: dict[str, Any] | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Write ``rig`` as UsdSkel blend shapes with their weights animated at ``rate``.

    Parameters
    ----------
    path : str or path-like
        A ``.usdc`` (or ``.usda``) file; written under a temporary name and renamed.
    mesh : Mesh
        The scan: polygons and UVs (its vertices are not used: the rig's rest is); its colour
        texture, if any, is written beside the file (``<stem>_color.png``) and bound as a
        UsdPreviewSurface material.
    rig : ResultRig
        In the result's unit (``rig.units``).
    rate : float
        Frame rate, Hz: ``timeCodesPerSecond`` and ``framesPerSecond``.
    head_motion : (T, 4, 4) array, optional
        Head motion per frame (translation in the rig's unit) on ``/Head``.
    tolerance_mm : float, default 1e-4
        Bound on what the dropped far-field entries may add up to (see the module docstring); 0 keeps every entry.
    principal_targets : (m, n, 3) float32 array, mm, optional
        Shapes to write instead of the rig's exact ones: the take's first
        principal components (``targets`` of
        :func:`facecap.deform.principal_targets_from_rig` on ``rig.in_mm()``).
        Converted to the rig's unit and moved into the weights' [0, 1] range
        in place (no copy of what can be 0.4 GB); default None: the exact shapes.
    principal_weights : (T, m) float array, optional
        Their weights per frame; with ``principal_targets``.
    principal_error : dict, optional
        The error they leave, mm (``rms_mm``, ``max_mm`` (None where not
        computed), ...); with ``principal_targets``. Returned and written into
        the layer's documentation.
    progress : bool, default False

    Returns
    -------
    dict
        ``n_shapes``, ``stored_entries`` (shape x vertex entries written),
        ``dense_entries`` (what full shapes would hold), ``error_bound_mm``
        (of the dropped entries), ``principal_components`` (bool) with
        ``error`` (mm: ``rms_mm``, ``max_mm``, ...) when they were used, ``bytes``.

    Raises
    ------
    InputError
        If the mesh and the rig disagree, ``head_motion`` is not (T, 4, 4), the principal
        components are incomplete or do not fit the rig, or the file cannot be written.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

    path = Path(path)
    if path.suffix.lower() not in (".usdc", ".usda", ".usd"):
        raise InputError(f"expected a .usdc, .usda or .usd file name, got {path.name!r}", path=str(path))
    if mesh.n_vertices != rig.n_vertices:
        raise InputError(f"the mesh has {mesh.n_vertices} vertices, the rig {rig.n_vertices}", path=str(path))
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"rate: expected a positive frame rate in Hz, got {rate!r}")
    if head_motion is not None:
        head_motion = np.asarray(head_motion, np.float64)
        if head_motion.shape != (rig.n_frames, 4, 4) or not np.isfinite(head_motion).all():
            raise InputError(f"head_motion: expected finite ({rig.n_frames}, 4, 4), got {head_motion.shape}")
    tolerance = float(tolerance_mm) / mm_per_unit(rig.units)

    principal = principal_targets is not None
    if principal:
        if principal_weights is None or principal_error is None:
            raise InputError("principal_targets: give principal_weights and principal_error with them")
        shapes = np.asarray(principal_targets, dtype=np.float32)  # the caller's: converted and rescaled in place
        weights = np.asarray(principal_weights)
        if (shapes.ndim != 3 or shapes.shape[1:] != (rig.n_vertices, 3)
                or weights.shape != (rig.n_frames, shapes.shape[0])):
            raise InputError(f"principal_targets, principal_weights: expected (m, {rig.n_vertices}, 3) and "
                             f"({rig.n_frames}, m), got {shapes.shape} and {weights.shape}")
        to_mm = np.float32(mm_per_unit(rig.units))
        if to_mm != 1:
            shapes /= to_mm
        names = [f"pc{j:03d}" for j in range(shapes.shape[0])]
        tolerance = 0.0  # principal shapes are dense: nothing to drop
    else:
        shapes, names = rig.shapes()
        weights = rig.shape_weights()
    m, T = shapes.shape[0], rig.n_frames
    # weights in [0, 1]: Blender's USD importer keeps every shape key's range at [0, 1] and clamps
    unit = to_unit_range(shapes, weights, overwrite_targets=principal)
    shapes, weights = unit.targets, unit.weights
    share = tolerance / m if tolerance > 0 else 0.0
    tokens = [_token(name, k) for k, name in enumerate(names)]

    layer = Sdf.Layer.CreateAnonymous(path.name)
    stage = Usd.Stage.Open(layer)
    root = UsdSkel.Root.Define(stage, _ROOT)
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, mm_per_unit(rig.units) / 1000.0)
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(float(T - 1))
    stage.SetTimeCodesPerSecond(float(rate))
    stage.SetFramesPerSecond(float(rate))

    skeleton = UsdSkel.Skeleton.Define(stage, _SKELETON)
    skeleton.CreateJointsAttr(Vt.TokenArray([]))
    animation = UsdSkel.Animation.Define(stage, _ANIMATION)
    animation.CreateJointsAttr(Vt.TokenArray([]))
    animation.CreateBlendShapesAttr(Vt.TokenArray(tokens))
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets([animation.GetPath()])

    face = UsdGeom.Mesh.Define(stage, _FACE)
    sizes, indices = mesh.export_polygons()
    face.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(sizes, np.int32)))
    face.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(indices, np.int32)))
    face.CreateSubdivisionSchemeAttr("none")
    rest = np.ascontiguousarray(rig.rest + unit.base_offset, np.float32)  # the shape at all-zero weights
    face.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rest))
    face.GetPrim().SetCustomDataByKey("facecap:restWeights", Vt.FloatArray.FromNumpy(unit.rest_weights.astype(np.float32)))
    face.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, rest.min(0))), Gf.Vec3f(*map(float, rest.max(0)))]))
    if mesh.uvs is not None:
        face_varying = mesh.uv_indices is not None
        st = UsdGeom.PrimvarsAPI(face).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray,
            UsdGeom.Tokens.faceVarying if face_varying else UsdGeom.Tokens.vertex)
        st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(mesh.uvs, np.float32)))
        if face_varying:
            st.SetIndices(Vt.IntArray.FromNumpy(np.ascontiguousarray(mesh.uv_indices, np.int32)))
    image = write_texture_beside(path, mesh)  # the colour texture, beside the file that names it
    if image is not None:
        bind_colour_texture(stage, _FACE, image.name)
    binding = UsdSkel.BindingAPI.Apply(face.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    binding.CreateBlendShapesAttr(Vt.TokenArray(tokens))

    stored = 0
    targets = []
    for k in tqdm(range(m), desc="USD blend shapes", unit="shape", disable=not progress, leave=False):
        offsets = shapes[k]
        shape = UsdSkel.BlendShape.Define(stage, f"{_FACE}/{tokens[k]}")
        if share > 0:  # only the entries that matter, with their point indices
            keep = np.flatnonzero(np.abs(offsets).max(axis=1) > share)  # its weights lie in [0, 1]
            shape.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(offsets[keep], np.float32)))
            shape.CreatePointIndicesAttr(Vt.IntArray.FromNumpy(keep.astype(np.int32)))
        else:  # every point: no pointIndices (UsdSkel then applies the offsets to all points in order)
            keep = offsets
            shape.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(offsets, np.float32)))
        targets.append(shape.GetPath())
        stored += keep.shape[0]
    binding.CreateBlendShapeTargetsRel().SetTargets(targets)

    weights_attr = animation.CreateBlendShapeWeightsAttr()
    spec_path = weights_attr.GetPath()
    transform_path = None
    if head_motion is not None:
        root_xform = UsdGeom.Xformable(root.GetPrim())
        transform_path = root_xform.AddTransformOp().GetAttr().GetPath()
    with Sdf.ChangeBlock():
        for t in range(T):
            layer.SetTimeSample(spec_path, float(t), Vt.FloatArray.FromNumpy(np.ascontiguousarray(weights[t], np.float32)))
            if transform_path is not None:
                layer.SetTimeSample(transform_path, float(t), Gf.Matrix4d(head_motion[t].T.tolist()))
    bound = share * m if share > 0 else 0.0
    error = None if not principal else {k: (float(v) if isinstance(v, (float, np.floating)) else v)
                                        for k, v in principal_error.items()}
    layer.documentation = (
        f"facecap rig as UsdSkel blend shapes: {m} shapes, {rig.n_vertices} vertices, {T} frames at {rate:g} Hz, "
        f"unit {rig.units}; "
        + (f"far-field entries dropped add up to at most {bound * mm_per_unit(rig.units):.3g} mm" if not principal
           else f"the take's first {m} principal components: error RMS {error['rms_mm']:.3g} mm, "
                f"max {error['max_mm'] if error['max_mm'] is None else round(error['max_mm'], 4)} mm")
    )
    del stage
    with atomic_path(path) as tmp:
        if not layer.Export(str(tmp)):
            raise InputError("could not write the USD file", path=str(path))
    return {
        "n_shapes": m,
        "stored_entries": int(stored),
        "dense_entries": int(m * rig.n_vertices),
        "error_bound_mm": float(bound * mm_per_unit(rig.units)),
        "principal_components": principal,
        **({"error": error} if error is not None else {}),
        "bytes": path.stat().st_size,
    }


def _token(name: str, index: int) -> str:
    """A valid USD prim name (and blend shape token) from a basis name, unique by its index."""
    clean = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return f"s{index:04d}_{clean}"[:64]
