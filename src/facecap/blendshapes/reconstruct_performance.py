"""Dense performance from blendshape bases and per-frame NNLS weights (Huang et al. 2011, eq. 12)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import InputError
from ..io.write_performance import PerformanceWriter
from ..structures import Mesh
from .nnls_weights import nnls_weights

__all__ = ["blend_weights", "write_blended_performance"]


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


def write_blended_performance(
    out_dir: str | Path,
    template: Mesh,
    bases: np.ndarray,
    weights: np.ndarray,
    *,
    rate: float,
    output_from_bases: np.ndarray | None = None,
    exports: Iterable[str] = (),
    metadata: dict[str, Any] | None = None,
    extra_files: dict[str, Any] | None = None,
    batch_frames: int = 64,
    progress: bool = True,
) -> Path:
    """Stream ``m_t = c + sum_i w_t,i (d_i - c)`` to an output folder like ``facecap animate`` writes.

    ``c`` is the bases' centroid (see ``output_from_bases``); with weights
    summing to one this is eq. 12's ``sum_i w_t,i d_i``.

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
    exports : iterable of {'obj', 'ply', 'usd'}
    metadata : dict, optional
        Added to ``performance.json``.
    extra_files : dict of str to array or str, optional
        Written into the folder before it is moved into place: ``.npy`` names
        get arrays, other names get text.
    batch_frames : int, default 64
    progress : bool, default True

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
    centre64 = B64.reshape(-1, 3).mean(axis=0)
    flat = (B64 - centre64).astype(np.float32).reshape(K, n * 3)  # float32 only once centred
    centre = centre64.astype(np.float32)
    del B64

    def compute(start: int, stop: int, out: np.ndarray) -> None:
        np.matmul(W[start:stop], flat, out=out.reshape(stop - start, n * 3))
        out += centre

    with PerformanceWriter(out_dir, mesh=template, rate=rate, n_frames=T, exports=exports) as writer:
        writer.stream(compute, batch_frames=batch_frames, progress=progress, desc="blend")
        for name, content in (extra_files or {}).items():
            if name.endswith(".npy"):
                np.save(writer.path(name), content)
            else:
                writer.path(name).write_text(str(content))
        return writer.finish({"method": "huang2011-blendshapes", **(metadata or {})})
