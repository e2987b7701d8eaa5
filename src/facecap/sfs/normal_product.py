"""The data and smoothness part of one frame's Gauss-Newton normal matrix, applied in one compiled pass.

Conjugate gradients spend nearly all of the solve in this product (``benchmarks/RESULTS.md``, "Fine
detail from video": 96 of 146 s of a window). Per frame it is

``y = G^T q + S^T S x``, ``q_p = sum_c b_cp s_cp``, ``s_c = B_c^T (w_c * (B_c u_c))``, ``u_cp = b_cp . (G x)_p``

with ``G`` the vertex gradient (three sparse matrices on the one-ring's pattern), ``S`` eq. 6's one-ring
operator (the same pattern), ``b`` the linearised shading's sensitivity to the gradient per camera, ``w`` the
observations' weights and ``B_c`` each camera's blur. As scipy products that is a dozen passes over
sparse matrices and as many temporaries a frame; here the gradient, the one-ring and the projection onto
``b`` share one pass over the pattern, the blur and its transpose one pass each, and the transposed
gradient and one-ring one more, split over the cores (numba, BSD-2). Measured on a 140 880-sample window:
see ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba
import numpy as np
import scipy.sparse as sp

from .._threads import available_cores

__all__ = ["OneRingPattern", "FrameNormalProduct", "compile_blur"]


@numba.njit(nogil=True, parallel=True)
def _forward(indptr, indices, gx, gy, gz, s, x, b, u, sx):  # pragma: no cover - compiled
    """u[c, i] = b[c, i] . (G x)_i and sx[i] = (S x)_i, one pass over the pattern."""
    r = indptr.size - 1
    C = b.shape[0]
    for i in numba.prange(r):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            v = x[indices[k]]
            a0 += gx[k] * v
            a1 += gy[k] * v
            a2 += gz[k] * v
            a3 += s[k] * v
        sx[i] = a3
        for c in range(C):
            u[c, i] = b[c, i, 0] * a0 + b[c, i, 1] * a1 + b[c, i, 2] * a2


@numba.njit(nogil=True, parallel=True)
def _blur(indptr, indices, data, u, w, out):  # pragma: no cover - compiled
    """out[i] = w[i] * (B u)_i (w empty: no weight), for one camera."""
    r = indptr.size - 1
    weighted = w.size > 0
    for i in numba.prange(r):
        acc = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            acc += data[k] * u[indices[k]]
        out[i] = acc * w[i] if weighted else acc


@numba.njit(nogil=True, parallel=True)
def _backward(indptr, indices, gx, gy, gz, s, b, v, sx, y):  # pragma: no cover - compiled
    """y[j] = sum_i G_ij^T (sum_c b[c, i] v[c, i]) + (S^T sx)_j over the transposed pattern."""
    r = indptr.size - 1
    C = b.shape[0]
    for j in numba.prange(r):
        acc = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            q0 = 0.0
            q1 = 0.0
            q2 = 0.0
            for c in range(C):
                q0 += b[c, i, 0] * v[c, i]
                q1 += b[c, i, 1] * v[c, i]
                q2 += b[c, i, 2] * v[c, i]
            acc += gx[k] * q0 + gy[k] * q1 + gz[k] * q2 + s[k] * sx[i]
        y[j] = acc


for _kernel in (_forward, _blur, _backward):
    try:  # compiled once per machine and kept; where no cache folder is writable, compiled per process
        _kernel.enable_caching()
    except RuntimeError:
        pass


def _on_pattern(pattern: sp.csr_matrix, matrix: sp.csr_matrix) -> np.ndarray:
    """``matrix``'s values at ``pattern``'s entries (0 where it has none); ``pattern`` holds every entry of it."""
    coo = matrix.tocoo()
    n_cols = pattern.shape[1]
    rows = np.repeat(np.arange(pattern.shape[0], dtype=np.int64), np.diff(pattern.indptr))
    keys = rows * n_cols + pattern.indices
    where = np.searchsorted(keys, coo.row.astype(np.int64) * n_cols + coo.col)
    values = np.zeros(keys.size)
    np.add.at(values, where, coo.data)
    return values


class OneRingPattern:
    """The vertex gradient and eq. 6's one-ring operator on one shared pattern, and its transpose.

    Parameters
    ----------
    gradient : VertexGradient
        (r, r).
    one_ring : (r, r) sparse matrix
        ``S`` (the spatial term is ``k |S h|^2``), already scaled by ``sqrt(k)``.
    """

    def __init__(self, gradient: Any, one_ring: sp.spmatrix) -> None:
        parts = [sp.csr_matrix(m) for m in (gradient.x, gradient.y, gradient.z, one_ring)]
        pattern = sum(abs(m) for m in parts) + sp.identity(parts[0].shape[0], format="csr")
        pattern = sp.csr_matrix(pattern)
        pattern.sum_duplicates()
        pattern.sort_indices()
        transposed = sp.csr_matrix(pattern.T)
        transposed.sort_indices()
        self.forward = (pattern.indptr.astype(np.int64), pattern.indices.astype(np.int32),
                        *(np.ascontiguousarray(_on_pattern(pattern, m)) for m in parts))
        self.backward = (transposed.indptr.astype(np.int64), transposed.indices.astype(np.int32),
                         *(np.ascontiguousarray(_on_pattern(transposed, sp.csr_matrix(m.T))) for m in parts))
        self.size = parts[0].shape[0]


def _compiled_csr(matrix: sp.spmatrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A CSR matrix's arrays for the compiled passes."""
    m = sp.csr_matrix(matrix)
    # 32-bit indices and values: the blur's passes are bound by memory, and its weights need no more
    return m.indptr.astype(np.int64), m.indices.astype(np.int32), m.data.astype(np.float32)


def compile_blur(blur: Sequence[sp.spmatrix]) -> list[tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]]:
    """Each camera's blur and its transpose in the compiled product's layout (made once per frame)."""
    return [(_compiled_csr(m), _compiled_csr(m.T)) for m in blur]


class FrameNormalProduct:
    """``x -> G^T (sum_c b_c B_c^T W_c B_c b_c^T) G x + S^T S x`` for one frame (see the module notes).

    Parameters
    ----------
    pattern : OneRingPattern
    b : (C, r, 3) float array
        The shading's sensitivity to the gradient, per camera (scaled as the image term is).
    weight : (C, r) float array
    blur : result of :func:`compile_blur`, or None
        Each camera's; None: no blur.
    """

    def __init__(self, pattern: OneRingPattern, b: np.ndarray, weight: np.ndarray,
                 blur: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]] | None) -> None:
        numba.set_num_threads(min(available_cores(), numba.config.NUMBA_NUM_THREADS))
        self.pattern = pattern
        self.b = np.ascontiguousarray(b, dtype=np.float64)
        self.weight = np.ascontiguousarray(weight, dtype=np.float64)
        self.blur = blur
        C, r = self.weight.shape
        self._u, self._v, self._sx = np.empty((C, r)), np.empty((C, r)), np.empty(r)
        self._unweighted, self._blurred = np.empty(0), np.empty(r)

    def __call__(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.empty_like(x) if out is None else out
        u, v, sx = self._u, self._v, self._sx
        _forward(*self.pattern.forward, x, self.b, u, sx)
        if self.blur is None:
            np.multiply(u, self.weight, out=v)
        else:
            for c, (forward, transposed) in enumerate(self.blur):
                _blur(*forward, u[c], self.weight[c], self._blurred)
                _blur(*transposed, self._blurred, self._unweighted, v[c])
        _backward(*self.pattern.backward, self.b, v, sx, y)
        return y
