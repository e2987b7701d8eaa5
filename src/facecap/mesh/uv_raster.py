"""Which triangle, and where in it, each texel of a square map on a mesh's UVs samples.

A texture map on the scan's UV atlas is filled by asking, for the centre of
every texel, which UV triangle holds it and at which barycentric weights; any
value given at the triangles' corners (a vertex's height, normal or tangent) is
then one weighted sum per texel. The atlas may have seams (a vertex with several
UVs: each side's triangle fills its own texels), faces without UVs (skipped) and
gaps between its islands (empty texels). A renderer's bilinear and mipmap
filtering reads a little past an island's border, so the empty texels next to
an island (``padding`` texels wide) copy the value of their nearest covered
texel, which keeps the background from bleeding in at seams.

Conventions: the UV origin is the map's bottom-left corner and ``v`` points up
(OBJ, USD, Blender, Maya); the image is stored top row first, so texel
``(i, j)`` (row ``i`` from the top, column ``j``) has its centre at
``u = (j + 0.5) / size``, ``v = 1 - (i + 0.5) / size``. glTF's ``v`` points down,
and its writer flips the UVs, so the same image serves both.

Why by hand: each triangle's texels are found by a vectorised scan of its
bounding box (numpy), which handles overlapping and degenerate UV triangles
and 600k triangles at 2048^2 in 3.4 s (one shared core); matplotlib's
``TrapezoidMapTriFinder`` needs a valid triangulation (no overlapping or
duplicate-point triangles, which real atlases have) and took 17 s to build and
6 s to query on the same grid (``benchmarks/bench_detail_maps.py`` times the
set-up). The padding is SciPy's Euclidean distance transform with the nearest
covered texel's index.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray

__all__ = ["UVRaster"]

_CANDIDATES_PER_CHUNK = 1 << 22
"""Bounding-box texels examined at once (memory: a few arrays of this many float64)."""


class UVRaster:
    """The triangle and barycentric weights of every texel of a ``size x size`` map on a UV atlas.

    Built once per mesh and map size; :meth:`sample` then fills a map from
    values at the triangles' corners in one gather and one weighted sum.

    Parameters
    ----------
    uvs : (u, 2) float array
        Texture coordinates, ``[0, 1]^2`` the map (others fall outside it and are clipped away).
    uv_triangles : (m, 3) int array
        Each triangle's corners as indices into ``uvs`` (face-varying UVs already gathered per triangle
        corner); a row with a negative index is a face without UVs and is skipped.
    size : int
        The map's width and height in texels.
    padding : int, default 4
        Empty texels within this distance (texels) of a covered one copy its value (edge padding); 0: none.

    Attributes
    ----------
    size : int
    triangle : (size * size,) int64 array
        The triangle each texel samples (row-major, row 0 the top of the map); -1 for an empty texel.
    weights : (size * size, 3) float64 array
        Barycentric weights of the texel's centre in its triangle (0 for an empty texel).
    covered : (k,) int64 array
        The texels a triangle covers, ascending.
    pad_target, pad_source : (p,) int64 arrays
        Empty texels within ``padding`` of a covered texel, and the covered texel each copies.

    Raises
    ------
    InputError
        Shapes that do not fit, non-finite UVs, indices beyond ``uvs``, a size below 1.

    Notes
    -----
    A texel centre on an edge two triangles share goes to the later triangle; where UV triangles overlap
    (mirrored islands) the later one wins too. Degenerate UV triangles (zero area) cover nothing.

    Examples
    --------
    Two triangles making the unit square cover every texel:

    >>> import numpy as np
    >>> raster = UVRaster(np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]), np.array([[0, 1, 2], [0, 2, 3]]), 4)
    >>> int((raster.triangle >= 0).sum()), float(raster.weights.sum(axis=1).min().round(12))
    (16, 1.0)
    """

    def __init__(self, uvs: Any, uv_triangles: Any, size: int, *, padding: int = 4) -> None:
        UV = np.asarray(uvs, dtype=np.float64)
        T = np.asarray(uv_triangles)
        if UV.ndim != 2 or UV.shape[1] != 2:
            raise InputError(f"uvs: expected a (u, 2) array, got shape {UV.shape}")
        if not np.all(np.isfinite(UV)):
            raise InputError("uvs: expected finite texture coordinates, got NaN or infinity")
        if T.ndim != 2 or T.shape[1] != 3 or not (T.size == 0 or np.issubdtype(T.dtype, np.integer)):
            raise InputError(f"uv_triangles: expected an (m, 3) integer array, got shape {T.shape}, dtype {T.dtype}")
        T = T.astype(np.int64)
        if T.size and T.max() >= UV.shape[0]:
            raise InputError(f"uv_triangles: indices must lie below {UV.shape[0]} (the number of uvs), "
                             f"got {int(T.max())}")
        if int(size) != size or size < 1:
            raise InputError(f"size: expected a positive whole number of texels, got {size!r}")
        if int(padding) != padding or padding < 0:
            raise InputError(f"padding: expected a whole number of texels >= 0, got {padding!r}")
        self.size = int(size)
        self.padding = int(padding)
        n_texels = self.size * self.size
        self.triangle = np.full(n_texels, -1, dtype=np.int64)
        self.weights = np.zeros((n_texels, 3), dtype=np.float64)
        valid = np.flatnonzero(np.all(T >= 0, axis=1))
        if valid.size:
            self._scan(UV, T, valid)
        self.covered = np.flatnonzero(self.triangle >= 0)
        self.pad_target, self.pad_source = self._pad()

    def _scan(self, UV: FloatArray, T: IntArray, valid: IntArray) -> None:
        """Fill ``triangle`` and ``weights`` triangle by triangle (vectorised over bounding-box texels)."""
        s = self.size
        # texel coordinates: column j's centre at x = j, row i's centre at y = i (row 0 at the top, v = 1)
        x = UV[T[valid], 0] * s - 0.5
        y = (1.0 - UV[T[valid], 1]) * s - 0.5
        x0, y0 = x[:, 0], y[:, 0]
        e1x, e1y, e2x, e2y = x[:, 1] - x0, y[:, 1] - y0, x[:, 2] - x0, y[:, 2] - y0
        det = e1x * e2y - e2x * e1y
        scale = np.maximum(np.abs(e1x * e1x + e1y * e1y), np.abs(e2x * e2x + e2y * e2y))
        keep = np.abs(det) > 1e-12 * np.maximum(scale, 1e-300)
        j0 = np.clip(np.ceil(x.min(axis=1)), 0, s).astype(np.int64)
        j1 = np.clip(np.floor(x.max(axis=1)), -1, s - 1).astype(np.int64)
        i0 = np.clip(np.ceil(y.min(axis=1)), 0, s).astype(np.int64)
        i1 = np.clip(np.floor(y.max(axis=1)), -1, s - 1).astype(np.int64)
        width, height = np.maximum(j1 - j0 + 1, 0), np.maximum(i1 - i0 + 1, 0)
        count = np.where(keep, width * height, 0)
        ends = np.cumsum(count)
        starts = ends - count
        lo = 0
        tol = 1e-9
        while lo < valid.size:
            # as many triangles as fit in one chunk of candidates (at least one)
            hi = int(np.searchsorted(ends, starts[lo] + _CANDIDATES_PER_CHUNK, side="right"))
            hi = max(hi, lo + 1)
            k = np.arange(lo, hi)
            c = count[k]
            if c.sum() == 0:
                lo = hi
                continue
            tri = np.repeat(k, c)
            offset = np.arange(int(c.sum())) - np.repeat(starts[k] - starts[lo], c)
            jj = j0[tri] + offset % width[tri]
            ii = i0[tri] + offset // width[tri]
            px, py = jj - x0[tri], ii - y0[tri]
            w1 = (px * e2y[tri] - e2x[tri] * py) / det[tri]
            w2 = (e1x[tri] * py - px * e1y[tri]) / det[tri]
            w0 = 1.0 - w1 - w2
            inside = (w0 >= -tol) & (w1 >= -tol) & (w2 >= -tol)
            texel = ii[inside] * s + jj[inside]
            # later triangles win shared texels: numpy's fancy assignment keeps the last write of a repeated index
            self.triangle[texel] = valid[tri[inside]]
            W = np.clip(np.stack([w0[inside], w1[inside], w2[inside]], axis=1), 0.0, 1.0)
            self.weights[texel] = W / W.sum(axis=1, keepdims=True)
            lo = hi

    def _pad(self) -> tuple[IntArray, IntArray]:
        """Empty texels within ``padding`` of a covered texel and the nearest covered texel each copies."""
        empty = np.array([], dtype=np.int64)
        if self.padding == 0 or self.covered.size == 0 or self.covered.size == self.triangle.size:
            return empty, empty
        from scipy.ndimage import binary_dilation, distance_transform_edt

        s, r = self.size, self.padding
        is_empty = (self.triangle < 0).reshape(s, s)
        near = binary_dilation(~is_empty, structure=np.ones((3, 3), bool), iterations=r) & is_empty
        if not near.any():
            return empty, empty
        # only the band round the islands needs the transform: crop to its bounding box (plus the reach)
        rows, cols = np.nonzero(near)
        a, b = max(rows.min() - r, 0), min(rows.max() + r + 1, s)
        c, d = max(cols.min() - r, 0), min(cols.max() + r + 1, s)
        distance, (ni, nj) = distance_transform_edt(is_empty[a:b, c:d], return_indices=True)
        band = near[a:b, c:d] & (distance <= r + 1e-9)
        li, lj = np.nonzero(band)
        target = (li + a) * s + (lj + c)
        source = (ni[li, lj] + a) * s + (nj[li, lj] + c)
        return target.astype(np.int64), source.astype(np.int64)

    def sample(self, corner_values: Any, *, background: Any = 0.0, out: np.ndarray | None = None) -> np.ndarray:
        """A map of values given at the triangles' corners, interpolated at the texel centres.

        Parameters
        ----------
        corner_values : (m, 3) or (m, 3, c) float array
            Each triangle's value at its three corners (``values[F]`` for values at vertices).
        background : float or (c,) float array, default 0
            The value of empty texels beyond the padding.
        out : (size, size) or (size, size, c) array, optional
            Written in place and returned.

        Returns
        -------
        (size, size) or (size, size, c) array
            float64 unless ``out`` is given.
        """
        values = np.asarray(corner_values, dtype=np.float64)
        if values.ndim not in (2, 3) or values.shape[1] != 3:
            raise InputError(f"corner_values: expected an (m, 3) or (m, 3, c) array, got shape {values.shape}")
        tail = values.shape[2:]
        if out is None:
            out = np.empty((self.size, self.size) + tail, dtype=np.float64)
        flat = out.reshape((self.size * self.size,) + tail)
        flat[...] = background
        t = self.triangle[self.covered]
        w = self.weights[self.covered]
        if values.ndim == 2:
            flat[self.covered] = np.einsum("kc,kc->k", w, values[t])
        else:
            flat[self.covered] = np.einsum("kc,kcd->kd", w, values[t])
        flat[self.pad_target] = flat[self.pad_source]
        return out
