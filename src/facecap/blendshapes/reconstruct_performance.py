"""Dense performance from blendshape bases and per-frame NNLS weights (Huang et al. 2011, eq. 12), as a rig."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .nnls_weights import nnls_weights

__all__ = ["BlendWithPose", "blend_weights", "blend_weights_with_head_pose", "BlendRig", "blend_rig"]

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


class BlendRig(NamedTuple):
    """Result of :func:`blend_rig`: the performance as a rest shape plus weighted shapes.

    Attributes
    ----------
    shapes : (K + 1, n, 3) float64 array, mm
        ``d_i - r`` for each basis (moved into the output frame), then ``r - c``.
    coefficients : (T, K + 1) float32 array
        Each frame's weights, then their sum less one.
    """

    shapes: np.ndarray
    coefficients: np.ndarray


def blend_rig(
    rest: np.ndarray,
    bases: np.ndarray,
    weights: np.ndarray,
    *,
    output_from_bases: np.ndarray | None = None,
) -> BlendRig:
    """``m_t = c + sum_i w_t,i (d_i - c)`` as a rig about the rest shape ``r`` (eq. 12 about the bases' centroid).

    ``c`` is the bases' centroid; with weights summing to one this is eq. 12's
    ``sum_i w_t,i d_i``. The rig is ``m_t = r + sum_i w_t,i (d_i - r) + (sum_i w_t,i - 1) (r - c)``,
    the same thing exactly, with the rest shape blendshape clients expect and one
    shape more for the weights' sum.

    Parameters
    ----------
    rest : (n, 3) float array, mm
        The rest shape ``r`` (the template, in the output frame).
    bases : (K, n, 3) float array, mm
        Blendshape bases ``d_i`` (in the markers' frame).
    weights : (T, K) float array
    output_from_bases : (4, 4) float array, optional
        Rigid transform from the bases' frame to the output's. The bases are
        moved by it and blended about their centroid, so weights that do not
        sum to one scale the face about its middle, not about either frame's origin.

    Returns
    -------
    BlendRig

    Raises
    ------
    InputError
        If the bases, the weights and the rest shape do not match.
    """
    R = np.asarray(rest, dtype=np.float64)
    Bs = np.asarray(bases, dtype=np.float32)
    W = np.asarray(weights, dtype=np.float32)
    if Bs.ndim != 3 or Bs.shape[1] != R.shape[0] or W.ndim != 2 or W.shape[1] != Bs.shape[0]:
        raise InputError(f"bases {Bs.shape} and weights {W.shape} do not match a template of {R.shape[0]} vertices")
    # The weights need not sum to one, and a sum of 1 + e scales the blend about the coordinate
    # origin: e times 1.5 m of false translation in a mocap frame (NNLS spends e on each frame's
    # stabilisation error). So the bases are moved into the output frame and blended about their
    # own centroid, where 1 + e scales only the face's shape about its middle.
    B64 = np.asarray(bases, dtype=np.float64)
    if output_from_bases is not None:
        pose = np.asarray(output_from_bases, dtype=np.float64)
        B64 = B64 @ pose[:3, :3].T + pose[:3, 3]
    centre = B64.reshape(-1, 3).mean(axis=0)
    shapes = np.concatenate([B64 - R[None], (R - centre)[None]])
    coefficients = np.concatenate([W, (W.astype(np.float64).sum(axis=1, keepdims=True) - 1.0).astype(np.float32)], axis=1)
    return BlendRig(shapes, coefficients)
