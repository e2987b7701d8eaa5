"""Vertex displacements from marker displacements by one dense product per batch (the hot path).

A linear large-scale deformer (the thin shell) ends in a per-frame step where
each vertex moves by a fixed weighted sum of the K marker displacements. This
module owns that step.

Why it is built the way it is (measured on the 2-core AVX-512 machine of
``benchmarks/RESULTS.md``, 714k vertices, 90 markers): the product itself is
a GEMM of 0.39 GFLOP per frame, which one core runs at about 60 GFLOP/s in
float32, so the arithmetic alone caps two cores near 300 frames/s; writing
the result in the ``(frames, vertices, 3)`` layout of ``vertices.npy`` costs
another pass over 8.6 MB per frame. Three choices keep both cheap:

- the weights are stored vertex-major, ``(n, K)``, and the product is done in
  blocks of a few hundred vertices, so each block's result stays in the
  core's cache while it is interleaved into the output;
- the interleave (and the rest-shape add, and for int16 the rescale) is one
  compiled loop (numba, releases the GIL), and the blocks are shared by one
  thread per core, each running single-threaded BLAS;
- with ``precision='int16'`` (where Intel MKL is present) the
  weights and displacements are quantised to 16-bit integers and multiplied by
  MKL's int16 GEMM with int32 accumulation, which the AVX-512 VNNI units run
  at about 1.8x the float32 rate. The scales are chosen so the int32 sums
  cannot overflow; the error is bounded (:meth:`BasisProduct.error_bound_mm`)
  and in practice about 1e-4 of the displacement (0.001 mm for 10 mm of
  motion), far below marker noise. ``precision='float32'`` is exact to
  float32 rounding.
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from typing import Literal

import numba
import numpy as np

from .._mkl import CBLAS_FIX_OFFSET, CBLAS_NO_TRANS, CBLAS_ROW_MAJOR, mkl_blas
from .._threads import available_cores
from ..errors import InputError

__all__ = ["BasisProduct", "Precision"]

Precision = Literal["float32", "int16"]

_INT16_MAX = 32767
# Largest sum over markers of |quantised weight| that keeps every int32
# accumulator below 2**31 when each displacement is at most 32767 in magnitude:
# 32767 * (65000 + K/2 rounding) < 2**31 for K < 240.
_INT16_ROW_SUM = 65000
_MAX_MARKERS_INT16 = 240


@numba.njit(nogil=True, fastmath=True)
def _interleave_float32(product, rest, start, out):  # pragma: no cover - compiled
    """out[f, start + i, a] = product[a b + f, i] + rest[start + i, a], for the block's vertices."""
    b = out.shape[0]
    rows = min(product.shape[1], out.shape[1] - start)
    r = rest[start : start + rows].reshape(-1)
    for f in range(b):
        px, py, pz = product[f], product[b + f], product[2 * b + f]
        o = out[f, start : start + rows].reshape(-1)
        for i in range(rows):  # three contiguous reads, one contiguous interleaved write
            o[3 * i] = px[i] + r[3 * i]
            o[3 * i + 1] = py[i] + r[3 * i + 1]
            o[3 * i + 2] = pz[i] + r[3 * i + 2]


@numba.njit(nogil=True, fastmath=True)
def _interleave_int32(product, vertex_scale, row_scale, rest, start, out):  # pragma: no cover - compiled
    """As :func:`_interleave_float32`, rescaling the int32 sums by vertex and by (axis, frame)."""
    b = out.shape[0]
    rows = min(product.shape[1], out.shape[1] - start)
    r = rest[start : start + rows].reshape(-1)
    s = vertex_scale[start : start + rows]
    for f in range(b):
        px, py, pz = product[f], product[b + f], product[2 * b + f]
        cx, cy, cz = row_scale[f], row_scale[b + f], row_scale[2 * b + f]
        o = out[f, start : start + rows].reshape(-1)
        for i in range(rows):
            o[3 * i] = np.float32(px[i]) * (cx * s[i]) + r[3 * i]
            o[3 * i + 1] = np.float32(py[i]) * (cy * s[i]) + r[3 * i + 1]
            o[3 * i + 2] = np.float32(pz[i]) * (cz * s[i]) + r[3 * i + 2]


for _kernel in (_interleave_float32, _interleave_int32):
    try:  # compiled once per machine and kept; where no cache folder is writable, compiled per process
        _kernel.enable_caching()
    except RuntimeError:
        pass


class BasisProduct:
    """Apply fixed per-vertex marker weights to batches of marker displacements.

    Parameters
    ----------
    weights : (n, K) float array
        Row ``i`` holds vertex ``i``'s weight for each of the K markers, so a
        frame's vertex displacements are ``weights @ d`` for marker
        displacements ``d`` (K, 3).
    precision : {'float32', 'int16'}, default 'float32'
        Arithmetic of the product. ``'float32'``: float32 GEMM, exact to
        float32 rounding. ``'int16'``: 16-bit fixed point with int32 sums on
        MKL's integer GEMM (needs MKL and K <= 240), faster on AVX-512 VNNI
        machines, error bounded by :meth:`error_bound_mm` (in practice about
        1e-4 of the displacement).
    workers : int, optional
        Threads sharing the vertex blocks. Default: the cores this process may
        run on.
    block_vertices : int, default 1024
        Vertices per block. A block's product, ``(3 b, block_vertices)``, should
        stay in one core's L2 cache for the batch sizes used.
    vertex_rows : (n,) int array, optional
        Vertex ``i`` takes row ``vertex_rows[i]`` of ``weights`` (e.g. welded
        duplicates sharing one row), without an (n, K) copy being made.

    Raises
    ------
    InputError
        If ``weights`` is not a finite (n, K) array, or ``'int16'`` is asked
        for where MKL is absent or K > 240.

    Notes
    -----
    The weights are stored in blocks, ``(n_blocks, K, block_vertices)``, each
    contiguous. Per batch of b frames the marker displacements become
    ``X (3 b, K)`` with rows ordered (axis, frame); block j's product
    ``X @ W_j`` is ``(3 b, block_vertices)``, whose three rows for frame f are
    read contiguously while vertex positions are written contiguously into
    ``out[f]``.

    Examples
    --------
    >>> W = np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    >>> product = BasisProduct(W, precision="float32")
    >>> d = np.array([[[0.0, 0.0, 2.0], [0.0, 0.0, 4.0]]], np.float32)  # one frame, K = 2
    >>> out = np.empty((1, 3, 3), np.float32)
    >>> product.apply_into(d, np.zeros((3, 3), np.float32), out)[0, :, 2].tolist()
    [2.0, 3.0, 4.0]
    """

    def __init__(
        self,
        weights: np.ndarray,
        *,
        precision: Precision = "float32",
        workers: int | None = None,
        block_vertices: int = 1024,
        vertex_rows: np.ndarray | None = None,
    ) -> None:
        W = np.asarray(weights)
        if W.ndim != 2 or W.shape[0] == 0 or W.shape[1] == 0:
            raise InputError(f"weights: expected an (n, K) array, got shape {W.shape}")
        if not np.isfinite(W).all():
            raise InputError("weights: contain NaN or infinite values")
        if vertex_rows is not None:
            vertex_rows = np.asarray(vertex_rows)
            if vertex_rows.ndim != 1 or vertex_rows.size == 0 or not np.issubdtype(vertex_rows.dtype, np.integer) \
                    or vertex_rows.min() < 0 or vertex_rows.max() >= W.shape[0]:
                raise InputError(f"vertex_rows: expected a non-empty (n,) array of rows of weights (0..{W.shape[0] - 1})")
        rows_of = (lambda lo, hi: W[lo:hi]) if vertex_rows is None else (lambda lo, hi: W[vertex_rows[lo:hi]])
        if precision not in ("float32", "int16"):
            raise InputError(f"precision: expected 'float32' or 'int16', got {precision!r}")
        if int(block_vertices) < 1:
            raise InputError(f"block_vertices: expected a positive integer, got {block_vertices}")
        n, K = (W.shape[0] if vertex_rows is None else vertex_rows.size), W.shape[1]
        self._mkl = mkl_blas()
        if precision == "int16" and self._mkl is None:
            raise InputError("precision='int16' needs Intel MKL (the 'mkl' wheel), which did not load here")
        elif precision == "int16" and K > _MAX_MARKERS_INT16:
            raise InputError(f"precision='int16' supports at most {_MAX_MARKERS_INT16} markers, got {K}")
        self.precision: str = precision
        self.backend: str = "mkl" if self._mkl is not None else "numpy"
        # Without MKL, numpy's BLAS threads itself: one worker avoids cores x BLAS threads.
        default_workers = available_cores() if self._mkl is not None else 1
        self.workers = max(1, int(workers)) if workers is not None else default_workers
        self.n_vertices, self.n_markers = int(n), int(K)
        self.block_vertices = rows = int(min(block_vertices, n))
        n_blocks = -(-n // rows)

        self._blocks = np.zeros((n_blocks, K, rows), dtype=np.float32 if precision == "float32" else np.int16)
        if precision == "float32":
            self._vertex_scale = None
            self._relative_error = 0.0
            for j in range(n_blocks):
                part = rows_of(j * rows, (j + 1) * rows)
                self._blocks[j, :, : part.shape[0]] = part.T
        else:
            self._vertex_scale = np.empty(n, np.float32)
            worst = 0.0
            for j in range(n_blocks):  # block by block: no full-size float64 temporaries
                part = np.asarray(rows_of(j * rows, (j + 1) * rows), dtype=np.float64)
                abs_max = np.abs(part).max(axis=1)
                abs_sum = np.abs(part).sum(axis=1)
                # Per-vertex scale: each weight fits int16 and the row's |sum| keeps int32 sums safe.
                with np.errstate(divide="ignore"):
                    scale = np.where(abs_max > 0, np.minimum(_INT16_MAX / abs_max, _INT16_ROW_SUM / abs_sum), 1.0)
                q = np.clip(np.rint(part * scale[:, None]), -_INT16_MAX, _INT16_MAX)
                self._blocks[j, :, : part.shape[0]] = q.T
                self._vertex_scale[j * rows : j * rows + part.shape[0]] = 1.0 / scale
                # Error per mm of the largest displacement d: sum_k |q_k/s - w_k| |d_k| (weight
                # rounding) + sum_k |q_k|/s |e_k| with |e_k| <= d/(2*32767) (displacement rounding).
                dequantised = q / scale[:, None]
                rows_bound = np.abs(dequantised - part).sum(axis=1) + np.abs(dequantised).sum(axis=1) / (2 * _INT16_MAX)
                worst = max(worst, float(rows_bound.max()))
            self._relative_error = worst
        self._zero_offset = np.zeros(1, np.int32)

    def error_bound_mm(self, max_displacement_mm: float) -> float:
        """Worst-case difference from the exact product (before float32 rounding).

        Parameters
        ----------
        max_displacement_mm : float
            The largest marker displacement component in the batch, mm.

        Returns
        -------
        float, mm
            0 for ``precision='float32'``.
        """
        return self._relative_error * float(max_displacement_mm)

    def dense_weights(self) -> np.ndarray:
        """The weights as (n, K) float32 (dequantised for int16)."""
        W = self._blocks.transpose(0, 2, 1).reshape(-1, self.n_markers)[: self.n_vertices].astype(np.float32, copy=False)
        if self._vertex_scale is not None:
            W *= self._vertex_scale[:, None]
        return W

    def weight_rows(self, vertices: np.ndarray) -> np.ndarray:
        """The weights of a few vertices as (k, K) float32 (dequantised for int16), without a full copy.

        Parameters
        ----------
        vertices : (k,) int array
            Vertex indices in ``0 .. n - 1``.
        """
        v = np.asarray(vertices)
        if v.ndim != 1 or not np.issubdtype(v.dtype, np.integer) or (v.size and (v.min() < 0 or v.max() >= self.n_vertices)):
            raise InputError(f"vertices: expected a (k,) array of vertex indices 0..{self.n_vertices - 1}")
        rows = self.block_vertices
        W = self._blocks[v // rows, :, v % rows].astype(np.float32)
        if self._vertex_scale is not None:
            W *= self._vertex_scale[v][:, None]
        return W

    def apply_into(self, marker_displacements: np.ndarray, rest: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Write ``rest + weights @ d`` for every frame of a batch into ``out``.

        Parameters
        ----------
        marker_displacements : (b, K, 3) float array, mm
        rest : (n, 3) float32 array
            Added to every frame.
        out : (b, n, 3) float32 array, C-contiguous
            Written in place and returned.

        Returns
        -------
        (b, n, 3) float32 array
            ``out``.
        """
        D = np.asarray(marker_displacements, dtype=np.float32)
        n, K = self.n_vertices, self.n_markers
        if D.ndim != 3 or D.shape[1:] != (K, 3):
            raise InputError(f"marker_displacements: expected (b, {K}, 3), got {D.shape}")
        b = D.shape[0]
        if out.shape != (b, n, 3) or out.dtype != np.float32 or not out.flags.c_contiguous:
            raise InputError(f"out: expected a C-contiguous float32 ({b}, {n}, 3) array, got {out.dtype} {out.shape}")
        rest = np.ascontiguousarray(rest, dtype=np.float32)
        if rest.shape != (n, 3):
            raise InputError(f"rest: expected ({n}, 3), got {rest.shape}")
        if b == 0:
            return out
        X = np.ascontiguousarray(D.transpose(2, 0, 1).reshape(3 * b, K))  # rows (axis, frame)
        if not np.isfinite(X).all():
            raise InputError("marker_displacements: contain NaN or infinite values (fill the gaps first)")
        if self._vertex_scale is None:
            row_scale = None
        else:
            peak = np.abs(X).max(axis=1).astype(np.float64)
            scale = np.where(peak > 1e-30, peak / _INT16_MAX, 1.0)
            X = np.clip(np.rint(X / scale[:, None]), -_INT16_MAX, _INT16_MAX).astype(np.int16)
            row_scale = scale.astype(np.float32)

        rows, n_blocks = self.block_vertices, self._blocks.shape[0]
        next_block = itertools.count()  # shared by the workers: next() is atomic under the GIL

        def work() -> None:
            # one core per worker (the workers are the parallelism); restored, since
            # with one worker this runs in the caller's thread, where PARDISO may run next
            previous = self._mkl.set_num_threads_local(1) if self._mkl is not None else None
            try:
                product = np.empty((3 * b, rows), np.float32 if row_scale is None else np.int32)
                while (j := next(next_block)) < n_blocks:
                    self._block_product(j, X, product)
                    if row_scale is None:
                        _interleave_float32(product, rest, j * rows, out)
                    else:
                        _interleave_int32(product, self._vertex_scale, row_scale, rest, j * rows, out)
            finally:
                if previous is not None:
                    self._mkl.set_num_threads_local(previous)

        workers = min(self.workers, n_blocks)
        if workers == 1:
            work()
        else:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                for future in [pool.submit(work) for _ in range(workers)]:
                    future.result()
        return out

    def _block_product(self, j: int, X: np.ndarray, product: np.ndarray) -> None:
        """``product = X @ blocks[j]``: (3 b, K) @ (K, block_vertices)."""
        block, mkl = self._blocks[j], self._mkl
        m, K = X.shape
        rows = block.shape[1]
        if mkl is None:
            np.matmul(X, block, out=product)
        elif self._vertex_scale is None:
            mkl.sgemm(CBLAS_ROW_MAJOR, CBLAS_NO_TRANS, CBLAS_NO_TRANS, m, rows, K, 1.0,
                      X.ctypes.data, K, block.ctypes.data, rows, 0.0, product.ctypes.data, rows)
        else:
            mkl.gemm_s16s16s32(CBLAS_ROW_MAJOR, CBLAS_NO_TRANS, CBLAS_NO_TRANS, CBLAS_FIX_OFFSET, m, rows, K, 1.0,
                               X.ctypes.data, K, 0, block.ctypes.data, rows, 0, 0.0, product.ctypes.data, rows,
                               self._zero_offset.ctypes.data)
