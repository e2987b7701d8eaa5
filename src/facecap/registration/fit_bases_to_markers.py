"""Registered scans deformed to match their frame's markers exactly (Huang et al. 2011, section 7)."""

from __future__ import annotations

import numpy as np

from ..deform.thin_shell import DEFAULT_KB_MM2, DEFAULT_KS, ThinShellSolver
from ..errors import InputError
from ..typing import FloatArray, IntArray

__all__ = ["fit_bases_to_markers"]


def fit_bases_to_markers(
    registered: FloatArray,
    F: IntArray,
    marker_vertices: IntArray,
    marker_weights: FloatArray,
    frame_markers: FloatArray,
    *,
    ks: float = DEFAULT_KS,
    kb: float = DEFAULT_KB_MM2,
) -> tuple[np.ndarray, np.ndarray]:
    """Deform each registered scan so its markers land exactly on its frame's markers.

    A scan is a static expression performed again for the scanner: it is
    close to, but not exactly, the expression of the mocap frame it was chosen
    for. The paper deforms each registered scan with a Laplacian deformation so
    that the markers match; facecap uses the same linear thin shell as the
    large-scale step (Bickel 2007, eq. 4), factored once on the first basis
    (all bases share the template's topology and are close in shape) and
    applied to each basis as ``d_i = B^T (x_i - C d_i)``.

    Parameters
    ----------
    registered : (K, n, 3) float array, mm
        Registered scans in the template topology, in the markers' frame.
    F : (m, 3) int64 array
        Template triangles.
    marker_vertices : (M, 3) int64 array
        Template vertices of the triangle each marker sits on.
    marker_weights : (M, 3) float64 array
        Barycentric weights of each marker.
    frame_markers : (K, M, 3) float array, mm
        The markers of each basis's mocap frame.
    ks, kb : float
        Thin-shell stiffness (see :class:`~facecap.deform.thin_shell.ThinShellSolver`).

    Returns
    -------
    bases : (K, n, 3) float64 array, mm
        Bases whose markers equal ``frame_markers`` (at the constrained vertices).
    marker_change_mm : (K, M) float64 array
        How far each basis's markers had to move.
    """
    R = np.asarray(registered, dtype=np.float64)
    X = np.asarray(frame_markers, dtype=np.float64)
    mv = np.asarray(marker_vertices, dtype=np.int64)
    mw = np.asarray(marker_weights, dtype=np.float64)
    if R.ndim != 3 or R.shape[2] != 3:
        raise InputError(f"registered: expected (K, n, 3), got {R.shape}")
    if X.shape != (R.shape[0], mv.shape[0], 3) or mw.shape != mv.shape:
        raise InputError(
            f"frame_markers: expected ({R.shape[0]}, {mv.shape[0]}, 3) with (M, 3) marker vertices and weights, "
            f"got {X.shape}, {mv.shape}, {mw.shape}"
        )
    constrained = mv[np.arange(mv.shape[0]), np.argmax(mw, axis=1)]
    solver = ThinShellSolver(R[0], F, constrained, ks=ks, kb=kb)
    on_basis = np.einsum("mj,kmjc->kmc", mw, R[:, mv])  # (K, M, 3) markers on each basis
    change = X - on_basis
    bases = R + solver.displacements(change).astype(np.float64)
    return bases, np.linalg.norm(change, axis=2)
