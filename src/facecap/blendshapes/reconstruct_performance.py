"""Dense performance from blendshape bases and per-frame NNLS weights (Huang et al. 2011, eq. 12)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, NamedTuple

import numpy as np

from ..errors import InputError
from ..io.result_rig import ResultRig
from ..io.mocap_correspondence import write_mocap_correspondence
from ..io.write_performance import PerformanceWriter
from ..units import mm_per_unit
from ..structures import Mesh
from .nnls_weights import nnls_weights

__all__ = ["BlendWithPose", "blend_weights", "blend_weights_with_head_pose", "write_blended_performance"]

DEFAULT_POSE_ITERATIONS = 4
"""Steps of :func:`blend_weights_with_head_pose` (each removes the remaining rotation to second order)."""

SUM_TO_ONE_WEIGHT_MM2 = 1e4
"""Weight of ``(sum w - 1)^2`` per marker in :func:`blend_weights_with_head_pose`, mm^2: a sum off by 0.01
costs as much as every marker off by 1 mm."""


def blend_weights(basis_markers: np.ndarray, markers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Non-negative blend weights of every frame (eq. 12).

    Parameters
    ----------
    basis_markers : (K, M, 3) float array, mm
        The markers of each basis (the selected frames' markers: after fitting,
        ``D d_i`` equals them, so eq. 12 and eq. 3 use the same matrix).
    markers : (T, M, 3) float array, mm
        Conditioned markers of every frame, in the same frame as the bases.

    Returns
    -------
    weights : (T, K) float64 array, >= 0
    residual_mm : (T,) float64 array
        RMS marker distance of the blended markers to the captured ones.
    """
    Xb = np.asarray(basis_markers, dtype=np.float64)
    X = np.asarray(markers, dtype=np.float64)
    if Xb.ndim != 3 or X.ndim != 3 or Xb.shape[1:] != X.shape[1:]:
        raise InputError(f"markers: expected (T, M, 3) matching the bases' (K, M, 3), got {X.shape} and {Xb.shape}")
    seen = np.all(np.isfinite(X), axis=(0, 2)) & np.all(np.isfinite(Xb), axis=(0, 2))
    if seen.sum() < 3:
        raise InputError("fewer than 3 markers are seen in every frame and every basis")
    A = Xb[:, seen].reshape(Xb.shape[0], -1).T  # (3M, K)
    B = X[:, seen].reshape(X.shape[0], -1).T  # (3M, T)
    weights, residual = nnls_weights(A, B)
    return weights.T, residual / np.sqrt(seen.sum())


class BlendWithPose(NamedTuple):
    """Result of :func:`blend_weights_with_head_pose`.

    Attributes
    ----------
    weights : (T, K) float64 array, >= 0
    residual_mm : (T,) float64 array
        RMS marker distance of the blended markers to the corrected ones.
    rotations : (T, 3, 3) float64 array
        Per-frame rigid correction applied to the markers (``x' = R x + t``),
        on top of the take's stabilisation.
    translations : (T, 3) float64 array, mm
    """

    weights: np.ndarray
    residual_mm: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray


def blend_weights_with_head_pose(
    basis_markers: np.ndarray,
    markers: np.ndarray,
    *,
    iterations: int = DEFAULT_POSE_ITERATIONS,
) -> BlendWithPose:
    """Blend weights and each frame's head pose, solved together (eq. 12 with a rigid motion).

    The stabilisation of a take without a head band comes from skin markers
    that move with the expression, so it leaves each frame slightly turned.
    The bases know better: a rigid motion is not in their span (they share
    one head pose), so a frame's markers are fitted by a blend *and* a rigid
    motion, ``min_{R, t, w >= 0} sum_i |R x_i + t - sum_k w_k b_ki|^2``.

    Parameters
    ----------
    basis_markers : (K, M, 3) float array, mm
        The markers of each basis.
    markers : (T, M, 3) float array, mm
        Conditioned (stabilised) markers of every frame, in the bases' frame.
    iterations : int, default 4
        Steps of weights (exact NNLS, all frames at once) then rigid motion
        (Kabsch, all frames at once); see Notes.

    Returns
    -------
    BlendWithPose

    Notes
    -----
    Variable projection: the rigid motions of the bases' mean marker set
    ``c`` span, to first order, ``J = [[-[c_i]x, I]]`` (3M x 6). Projecting
    both the bases and each frame's markers onto the complement of ``J``
    leaves a problem in the weights alone, solved exactly for all frames at
    once (NNLS with a shared matrix), with a row ``sqrt(lambda) (sum w - 1)``
    holding the weights' sum at one as the paper's uncentred markers do
    implicitly (the projection removes the translation that did it). The
    frame's exact rigid motion onto its blend then follows by a Kabsch fit,
    the markers are moved by it, and the step repeats; each step removes the
    remaining rotation to second order, so three or four suffice (the plain
    alternation of the two blocks needs dozens).
    """
    from ..markers.rigid_fit import rigid_fit

    Xb = np.asarray(basis_markers, dtype=np.float64)
    X = np.asarray(markers, dtype=np.float64)
    if Xb.ndim != 3 or X.ndim != 3 or Xb.shape[1:] != X.shape[1:]:
        raise InputError(f"markers: expected (T, M, 3) matching the bases' (K, M, 3), got {X.shape} and {Xb.shape}")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise InputError(f"iterations: expected an integer >= 1, got {iterations!r}")
    seen = np.all(np.isfinite(X), axis=(0, 2)) & np.all(np.isfinite(Xb), axis=(0, 2))
    if seen.sum() < 3:
        raise InputError("fewer than 3 markers are seen in every frame and every basis")
    B = Xb[:, seen]  # (K, m, 3)
    Y = X[:, seen]  # (T, m, 3)
    T, m = Y.shape[0], Y.shape[1]
    centre = B.reshape(-1, 3).mean(axis=0)
    c = B.mean(axis=0) - centre  # mean marker set about its centroid
    J = np.zeros((m, 3, 6))
    J[:, :, 3:] = np.eye(3)
    J[:, 0, 1], J[:, 0, 2] = c[:, 2], -c[:, 1]  # -[c]x: d/dw of w x c
    J[:, 1, 0], J[:, 1, 2] = -c[:, 2], c[:, 0]
    J[:, 2, 0], J[:, 2, 1] = c[:, 1], -c[:, 0]
    Q, _ = np.linalg.qr(J.reshape(3 * m, 6))

    def project(V: np.ndarray) -> np.ndarray:  # (3m, n) -> complement of the rigid motions
        return V - Q @ (Q.T @ V)

    scale = np.sqrt(SUM_TO_ONE_WEIGHT_MM2 * m)
    A = np.vstack([project((B - centre).reshape(B.shape[0], -1).T), np.full((1, B.shape[0]), scale)])
    R = np.tile(np.eye(3), (T, 1, 1))
    t = np.zeros((T, 3))
    Bflat = B.reshape(B.shape[0], -1)
    for _ in range(iterations):
        moved = Y @ np.swapaxes(R, 1, 2) + t[:, None]
        targets = np.vstack([project((moved - centre).reshape(T, -1).T), np.full((1, T), scale)])
        weights = nnls_weights(A, targets).weights.T  # (T, K)
        blended = (weights @ Bflat).reshape(T, m, 3) + (1.0 - weights.sum(axis=1))[:, None, None] * centre
        fit = rigid_fit(Y, blended)
        R, t = fit.rotation, fit.translation
    moved = Y @ np.swapaxes(R, 1, 2) + t[:, None]
    blended = (weights @ Bflat).reshape(T, m, 3) + (1.0 - weights.sum(axis=1))[:, None, None] * centre
    residual = np.sqrt(np.mean(np.sum((moved - blended) ** 2, axis=2), axis=1))
    return BlendWithPose(weights, residual, R, t)


def write_blended_performance(
    out_dir: str | Path,
    template: Mesh,
    bases: np.ndarray,
    weights: np.ndarray,
    *,
    rate: float,
    output_from_bases: np.ndarray | None = None,
    head_motion: np.ndarray | None = None,
    exports: Iterable[str] = (),
    metadata: dict[str, Any] | None = None,
    extra_files: dict[str, Any] | None = None,
    correspondence: dict[str, Any] | None = None,
    batch_frames: int = 64,
    write_vertices: bool = True,
    rig_precision: str = "float32",
    export_options: dict[str, Any] | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Write ``m_t = c + sum_i w_t,i (d_i - c)`` to an output folder like ``facecap animate`` writes.

    ``c`` is the bases' centroid (see ``output_from_bases``); with weights
    summing to one this is eq. 12's ``sum_i w_t,i d_i``. The result is a rig
    (``rig/``, :class:`~facecap.io.ResultRig`) about the template ``r``:
    ``m_t = r + sum_i w_t,i (d_i - r) + (sum_i w_t,i - 1) (r - c)``, the same
    thing exactly, with the template as the rest shape blendshape clients
    expect and one shape more for the weights' sum. ``vertices.npy`` is
    evaluated from it.

    Parameters
    ----------
    out_dir : str or Path
    template : Mesh
        Topology, UVs and unit of the output.
    bases : (K, n, 3) float array, mm
        Blendshape bases (in the markers' frame).
    weights : (T, K) float array
    rate : float
        Frame rate, Hz.
    output_from_bases : (4, 4) float array, optional
        Rigid transform from the bases' frame to the output's (the template's
        own coordinates). The bases are moved by it and blended about their
        centroid, so weights that do not sum to one scale the face about its
        middle, not about either frame's origin.
    head_motion : (T, 4, 4) float array, optional
        The head's rigid motion per frame in the output frame (mm), as
        ``facecap animate`` writes it: saved as ``head_motion.npy`` (in the
        template's unit) and carried by the USD export as the mesh's
        transform. The vertices stay stabilised.
    exports : iterable of str
        See :data:`facecap.io.EXPORT_FORMATS`.
    metadata : dict, optional
        Added to ``performance.json``.
    extra_files : dict of str to array or str, optional
        Written into the folder before it is moved into place: ``.npy`` names
        get arrays, other names get text.
    correspondence : dict, optional
        The map from the output's face back into the capture's frame, written as
        ``correspondence.npz``: the arguments of
        :func:`~facecap.io.write_mocap_correspondence` (``mocap_points``,
        ``face_points``, ``labels``, ``mocap_from_stabilized``: (K, 3) mm points,
        K labels, (T, 4, 4) mm transforms).
    batch_frames : int, default 64
    write_vertices : bool, default True
        Write ``vertices.npy`` besides the rig.
    rig_precision : {'float32', 'int16'}, default 'float32'
        Storage of the rig's shapes.
    export_options : dict, optional
        Passed to :func:`facecap.io.export_result`.
    progress : bool, default True
    overwrite : bool, default False
        Replace an earlier result in ``out_dir`` (:class:`~facecap.io.PerformanceWriter`).

    Returns
    -------
    Path
        The finished folder.
    """
    Bs = np.asarray(bases, dtype=np.float32)
    W = np.asarray(weights, dtype=np.float32)
    if Bs.ndim != 3 or Bs.shape[1] != template.n_vertices or W.ndim != 2 or W.shape[1] != Bs.shape[0]:
        raise InputError(f"bases {Bs.shape} and weights {W.shape} do not match a template of {template.n_vertices} vertices")
    K, n, _ = Bs.shape
    T = W.shape[0]
    # The weights need not sum to one, and a sum of 1 + e scales the blend about the coordinate
    # origin: e times 1.5 m of false translation in a mocap frame (NNLS spends e on each frame's
    # stabilisation error). So the bases are moved into the output frame and blended about their
    # own centroid, where 1 + e scales only the face's shape about its middle.
    B64 = np.asarray(bases, dtype=np.float64)
    if output_from_bases is not None:
        pose = np.asarray(output_from_bases, dtype=np.float64)
        B64 = B64 @ pose[:3, :3].T + pose[:3, 3]
    centre = B64.reshape(-1, 3).mean(axis=0)
    rest = template.vertices.astype(np.float64)
    to_unit = 1.0 / mm_per_unit(template.source_unit)
    shapes = np.concatenate([B64 - rest[None], (rest - centre)[None]]).astype(np.float32) * np.float32(to_unit)
    coefficients = np.concatenate([W, (W.astype(np.float64).sum(axis=1, keepdims=True) - 1.0).astype(np.float32)], axis=1)
    del B64
    rig = ResultRig((rest * to_unit).astype(np.float32), shapes, coefficients, units=template.source_unit,
                    names=tuple(f"basis_{k}" for k in range(K)) + ("weight_sum",))

    pose = None
    if head_motion is not None:
        pose = np.asarray(head_motion, dtype=np.float64)
        if pose.shape != (T, 4, 4) or not np.all(np.isfinite(pose)):
            raise InputError(f"head_motion: expected finite ({T}, 4, 4) transforms, got {pose.shape}")
    with PerformanceWriter(out_dir, mesh=template, rate=rate, n_frames=T, exports=exports, vertices=write_vertices,
                           overwrite=overwrite,
                           export_options={"progress": progress, **(export_options or {})}) as writer:
        writer.write_rig(rig, precision=rig_precision)
        if writer.needs_frames:
            writer.stream_rig(batch_frames=batch_frames, head_pose=pose, progress=progress, desc="blend")
        if pose is not None:
            in_unit = pose.copy()
            in_unit[:, :3, 3] = template.to_source_unit(in_unit[:, :3, 3])
            np.save(writer.path("head_motion.npy"), in_unit)
        if correspondence is not None:
            write_mocap_correspondence(writer.path("correspondence.npz"), **correspondence)
        for name, content in (extra_files or {}).items():
            if name.endswith(".npy"):
                np.save(writer.path(name), content)
            else:
                writer.path(name).write_text(str(content))
        return writer.finish({"method": "huang2011-blendshapes", "stabilized": pose is not None, **(metadata or {})})
