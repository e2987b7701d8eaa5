"""The detail layer as texture maps on the scan's UVs: a displacement map and a tangent-space normal map per frame.

The detail is heights ``h`` (mm) along the base surface's vertex normals at the
region's vertices. Both maps interpolate per-vertex quantities at the texel
centres (:class:`~facecap.mesh.UVRaster`), so they hold the detail at the
mesh's own resolution, ready for a renderer or a lower-resolution mesh:

- the **displacement map**: ``h`` in mm (0 outside the region), float32;
- the **tangent-space normal map**: the detailed normal
  ``n = normalize(N - P grad h)`` (section 3.2 of Lo et al.; ``N`` the base
  vertex normal, ``P = I - N N^T``, ``grad`` :func:`~facecap.sfs.vertex_gradient`
  on the base surface) in each texel's tangent frame, encoded ``(n + 1) / 2``
  in uint16 RGB. Outside the detail the map is flat, ``(0.5, 0.5, 1.0)``.

Both are relative to the **base surface** (the layer below the detail): the base
plus the displacement map is the detailed surface, the base shaded with the
normal map shows the detail.

The tangent frame is MikkTSpace-like, OpenGL convention (+Y up in UV, as
Blender, Maya, USD's UsdPreviewSurface and glTF expect): a tangent per
triangle corner, ``dP/du`` of each triangle (its UV parameterisation), area-weighted
over the triangles that share the corner's vertex and UV (so a UV seam keeps two
tangents), interpolated at the texel, made orthogonal to the interpolated normal
(Gram-Schmidt), and the bitangent ``B = sign N x T`` with ``sign`` the
triangle's UV handedness (MikkTSpace's ``bitangent = sign * cross(normal, tangent)``).
A renderer's own MikkTSpace weights the corners by angle, not area: the two frames
differ at second order in the mesh's curvature.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from ..validate import as_faces, as_vertices

__all__ = ["DetailMaps", "FLAT_NORMAL", "FLAT_ENCODED"]

FLAT_NORMAL = np.array([0.0, 0.0, 1.0])
"""The tangent-space normal of a texel without detail (encoded ``(0.5, 0.5, 1.0)``)."""

FLAT_ENCODED = np.array([32768, 32768, 65535], dtype=np.uint16)
""":data:`FLAT_NORMAL` as the 16-bit normal map stores it: ``round((n + 1) / 2 * 65535)``."""


_TEXELS_PER_CHUNK = 1 << 17
"""Texels whose normals are computed at once (float32 temporaries that stay in cache)."""


def _dot(A: FloatArray, B: FloatArray) -> FloatArray:
    return np.einsum("kd,kd->k", A, B)


def _gather_corners(G: np.ndarray, values: FloatArray, n: int) -> FloatArray:
    """(n, 3): the sum at each vertex of the (m, 3, 3) values its triangles give their corners."""
    flat = values.reshape(-1, 3)
    return np.stack([np.bincount(G.ravel(), weights=flat[:, c], minlength=n) for c in range(3)], axis=1)


def _unit(X: FloatArray) -> FloatArray:
    length = np.sqrt(_dot(X, X))[:, None]
    return X / np.where(length > 0, length, 1.0)


class DetailMaps:
    """Displacement and tangent-space normal maps of the detail, set up once per mesh and map size.

    Parameters
    ----------
    uvs : (u, 2) float array
        Texture coordinates (origin bottom-left, ``v`` up).
    uv_triangles : (m, 3) int array
        Each triangle's corners as indices into ``uvs``, aligned with ``F``; a row with a negative index is a
        face without UVs (skipped).
    F : (m, 3) int array
        The triangles (vertex indices).
    region : (r,) int array
        The vertices the heights are given at (:func:`~facecap.sfs.select_detail_region`'s).
    size : int
        The maps' width and height in texels.
    padding : int, default 4
        Edge padding in texels (:class:`~facecap.mesh.UVRaster`).

    Attributes
    ----------
    raster : facecap.mesh.UVRaster
    active : (k,) int64 array
        The covered (or padded) texels whose triangle has a vertex in the region: the only texels that change
        from frame to frame.

    Raises
    ------
    InputError
        Shapes that do not fit, indices out of range.

    Examples
    --------
    A height ramp on a flat square: the displacement map is the ramp, the normal map tilts against it.

    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]])
    >>> F = np.array([[0, 1, 2], [0, 2, 3]]); UV = V[:, :2] / 10
    >>> maps = DetailMaps(UV, F, F, np.arange(4), 4)
    >>> h = 0.1 * V[:, 0]
    >>> maps.displacement(h)[0].round(3).tolist()
    [0.125, 0.375, 0.625, 0.875]
    >>> ((maps.tangent_normals(V, h)[0, 0] * np.sqrt(1.01)).round(6) + 0.0).tolist()
    [-0.1, 0.0, 1.0]
    """

    def __init__(self, uvs: Any, uv_triangles: Any, F: Any, region: Any, size: int, *, padding: int = 4) -> None:
        from ..mesh.uv_raster import UVRaster

        T = np.asarray(uv_triangles)
        faces = np.asarray(F)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise InputError(f"F: expected an (m, 3) array, got shape {faces.shape}")
        if T.shape != faces.shape:
            raise InputError(f"uv_triangles: expected one row per triangle {faces.shape}, got shape {T.shape}")
        self.region = np.asarray(region, dtype=np.int64).ravel()
        if self.region.size and self.region.min() < 0:
            raise InputError("region: expected vertex indices >= 0")
        n = max(int(faces.max()) + 1 if faces.size else 0, int(self.region.max()) + 1 if self.region.size else 0)
        self.n_vertices_min = n
        self.F = as_faces(faces, n, name="F")
        self.uv_triangles = T.astype(np.int64)
        self.uvs = np.asarray(uvs, dtype=np.float64)
        self.raster = UVRaster(self.uvs, self.uv_triangles, size, padding=padding)
        self.size = self.raster.size
        in_region = np.zeros(n, bool)
        in_region[self.region] = True
        touched = in_region[self.F].any(axis=1)  # triangles with a vertex in the region
        covered = self.raster.covered
        self._covered_active = covered[touched[self.raster.triangle[covered]]]
        self._triangles = self.raster.triangle[self._covered_active]
        self._weights = self.raster.weights[self._covered_active]
        # the frame-dependent part works on the vertices the active texels interpolate and their one-ring
        self._vertices = np.unique(self.F[np.unique(self._triangles)])
        near = np.zeros(n, bool)
        near[self._vertices] = True
        self._ring = np.flatnonzero(near[self.F].any(axis=1))  # every triangle round those vertices
        self._ring_vertices = np.unique(self.F[self._ring])
        local = np.full(n, -1, dtype=np.int64)
        local[self._ring_vertices] = np.arange(self._ring_vertices.size)
        self._ring_F = local[self.F[self._ring]]
        self._rows = local[self._vertices]  # the texels' vertices among the ring's
        in_ring = local[self.region] >= 0
        self._region_pick = np.flatnonzero(in_ring)  # region vertices in the ring ...
        self._region_cols = local[self.region[in_ring]]  # ... and where they sit in it
        where = np.full(n, -1, dtype=np.int64)
        where[self._vertices] = np.arange(self._vertices.size)
        self._texel_corners = where[self.F[self._triangles]]  # (k, 3) among _vertices
        self._region_at_vertices = where[self.region]  # -1: a region vertex no texel uses
        # tangents live at the (vertex, UV) corners of the ring's triangles, so a UV seam keeps one a side
        uvt = self.uv_triangles[self._ring]
        st = self.uvs[np.where(uvt >= 0, uvt, 0)]
        self._ring_d1, self._ring_d2 = st[:, 1] - st[:, 0], st[:, 2] - st[:, 0]
        det = self._ring_d1[:, 0] * self._ring_d2[:, 1] - self._ring_d2[:, 0] * self._ring_d1[:, 1]
        self._ring_ok = np.all(uvt >= 0, axis=1) & (np.abs(det) > 1e-14)
        self._ring_det = np.where(self._ring_ok, det, 1.0)
        n_uv = max(self.uvs.shape[0], 1)
        keys, inverse = np.unique((self._ring_F * n_uv + np.where(uvt >= 0, uvt, 0)).ravel(), return_inverse=True)
        self._corner_key, self._n_keys = inverse.ravel(), keys.size
        in_ring = np.searchsorted(self._ring, self._triangles)
        texel_keys = self._corner_key.reshape(-1, 3)[in_ring]
        used_keys, texel_keys = np.unique(texel_keys, return_inverse=True)
        self._used_keys, self._texel_keys = used_keys, texel_keys.reshape(-1, 3)
        self._key_vertex = where[self._ring_vertices[keys[used_keys] // n_uv]]  # the key's vertex among _vertices
        # MikkTSpace's sign: the bitangent is sign * N x T; for a consistently wound mesh it is the UV winding's
        self._texel_sign = np.where(det[in_ring] < 0, -1.0, 1.0).astype(np.float32)
        # the padded texels that copy an active texel
        active_mask = np.zeros(self.size * self.size, bool)
        active_mask[self._covered_active] = True
        copies = active_mask[self.raster.pad_source]
        self._pad_target = self.raster.pad_target[copies]
        self._pad_source = self.raster.pad_source[copies]
        self.active = np.concatenate([self._covered_active, self._pad_target])

    def _heights(self, heights: Any) -> FloatArray:
        h = np.asarray(heights, dtype=np.float64)
        if h.shape != self.region.shape:
            raise InputError(f"heights: expected one height per region vertex {self.region.shape}, got {h.shape}")
        if not np.all(np.isfinite(h)):
            raise InputError("heights: expected finite values, got NaN or infinity")
        return h

    def displacement(self, heights: Any) -> np.ndarray:
        """The displacement map: the heights interpolated at the texel centres.

        Parameters
        ----------
        heights : (r,) float array, mm
            Along the base surface's vertex normals, at ``region``.

        Returns
        -------
        (size, size) float32 array, mm
            0 where the detail is not (outside the region, empty texels); row 0 the top of the map (``v = 1``).
        """
        h = self._heights(heights)
        at = np.zeros(self._vertices.size)
        used = self._region_at_vertices >= 0
        at[self._region_at_vertices[used]] = h[used]
        out = np.zeros(self.size * self.size, dtype=np.float32)
        out[self._covered_active] = np.einsum("kc,kc->k", self._weights, at[self._texel_corners])
        out[self._pad_target] = out[self._pad_source]
        return out.reshape(self.size, self.size)

    def tangent_normals(self, V: Any, heights: Any) -> np.ndarray:
        """The detailed normal in each texel's tangent frame (unit vectors, float).

        Parameters
        ----------
        V : (n, 3) float array, mm
            The base surface at this frame.
        heights : (r,) float array, mm

        Returns
        -------
        (size, size, 3) float32 array
            ``(x, y, z)``: along the tangent (``+u``), the bitangent (``+v``) and the normal; ``(0, 0, 1)`` where
            there is no detail. Computed in float32 (the 16-bit map's step is 3e-5).
        """
        out = np.zeros((self.size * self.size, 3), dtype=np.float32)
        out[:, 2] = 1.0
        out[self._covered_active] = self._active_normals(V, heights)
        out[self._pad_target] = out[self._pad_source]
        return out.reshape(self.size, self.size, 3)

    def normal_map(self, V: Any, heights: Any) -> np.ndarray:
        """The tangent-space normal map, encoded ``(n + 1) / 2`` in 16 bits.

        Parameters
        ----------
        V : (n, 3) float array, mm
            The base surface at this frame.
        heights : (r,) float array, mm

        Returns
        -------
        (size, size, 3) uint16 array
            RGB = tangent (+u), bitangent (+v, OpenGL convention), normal; ``(32768, 32768, 65535)`` without
            detail.
        """
        encoded = np.round((self._active_normals(V, heights) + 1.0) * (65535.0 / 2.0)).clip(0, 65535)
        out = np.empty((self.size * self.size, 3), dtype=np.uint16)
        out[:] = FLAT_ENCODED
        out[self._covered_active] = encoded
        out[self._pad_target] = out[self._pad_source]
        return out.reshape(self.size, self.size, 3)

    def _active_normals(self, V: Any, heights: Any) -> FloatArray:
        """(k, 3) float32: the tangent-space detailed normal at the active covered texels."""
        X = as_vertices(V, name="V")
        if X.shape[0] < self.n_vertices_min:
            raise InputError(f"V: expected the mesh's vertices (at least {self.n_vertices_min}), got {X.shape[0]}")
        h = self._heights(heights)
        if self._covered_active.size == 0:
            return np.zeros((0, 3), dtype=np.float32)
        P = X[self._ring_vertices]
        G = self._ring_F
        # base normals (area-weighted, as the frame stage's) and the detailed normals at the texels' vertices
        e1, e2 = P[G[:, 1]] - P[G[:, 0]], P[G[:, 2]] - P[G[:, 0]]
        fn = np.cross(e1, e2)
        N = _unit(_gather_corners(G, fn[:, None, :].repeat(3, axis=1), P.shape[0])[self._rows])
        # the vertex gradient of the heights (vertex_gradient's: each triangle's piecewise-linear gradient,
        # area-weighted at the vertices) computed directly, since only one function is wanted per frame:
        # area * grad_f = sum_i h_i (n_f x e_i) / 2, e_i the edge opposite corner i, counter-clockwise
        h_ring = np.zeros(P.shape[0])
        h_ring[self._region_cols] = h[self._region_pick]
        unit_fn = _unit(fn)
        opposite = np.stack([P[G[:, 2]] - P[G[:, 1]], P[G[:, 0]] - P[G[:, 2]], e1], axis=1)
        area_grad = 0.5 * np.einsum("fk,fkd->fd", h_ring[G], np.cross(unit_fn[:, None, :], opposite))
        area = 0.5 * np.sqrt(_dot(fn, fn))
        total = np.bincount(G.ravel(), weights=np.repeat(area, 3), minlength=P.shape[0])[self._rows]
        grad = _gather_corners(G, area_grad[:, None, :].repeat(3, axis=1), P.shape[0])[self._rows]
        grad /= np.maximum(total, 1e-300)[:, None]
        grad -= _dot(grad, N)[:, None] * N
        detailed = _unit(N - grad)
        # dP/du of each triangle (its UV parameterisation), area-weighted over the (vertex, UV) corners
        d1, d2 = self._ring_d1, self._ring_d2
        T = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) / self._ring_det[:, None]
        Tw = _unit(T) * (area * self._ring_ok)[:, None]
        per_corner = np.repeat(Tw, 3, axis=0)
        tangent = np.stack([np.bincount(self._corner_key, weights=per_corner[:, c], minlength=self._n_keys)
                            for c in range(3)], axis=1)[self._used_keys]
        corner = np.concatenate([N[self._key_vertex], detailed[self._key_vertex], tangent], axis=1)
        corner = corner.astype(np.float32)
        out = np.empty((self._texel_keys.shape[0], 3), dtype=np.float32)
        w = self._weights.astype(np.float32)
        for lo in range(0, out.shape[0], _TEXELS_PER_CHUNK):
            hi = min(lo + _TEXELS_PER_CHUNK, out.shape[0])
            k3, wk = self._texel_keys[lo:hi], w[lo:hi]
            q = wk[:, 0:1] * corner[k3[:, 0]] + wk[:, 1:2] * corner[k3[:, 1]] + wk[:, 2:3] * corner[k3[:, 2]]
            n_t, d_t, t_t = _unit(q[:, 0:3]), _unit(q[:, 3:6]), q[:, 6:9]
            t_t = _unit(t_t - _dot(t_t, n_t)[:, None] * n_t)
            b_t = self._texel_sign[lo:hi, None] * np.cross(n_t, t_t)
            out[lo:hi, 0], out[lo:hi, 1], out[lo:hi, 2] = _dot(d_t, t_t), _dot(d_t, b_t), _dot(d_t, n_t)
        return out
