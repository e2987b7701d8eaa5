"""Unwrap a face onto a cylinder around its vertical axis: pixels, rasterisation, look-ups."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_points, as_vertices

__all__ = ["cylindrical_map", "CylindricalMap", "TriangleRaster"]

_INSIDE_EPS = 1e-9  # barycentric slack: pixel centres on a shared edge belong to both triangles


@dataclass(frozen=True, eq=False)
class TriangleRaster:
    """Which triangle covers each pixel of a :class:`CylindricalMap` image, and where.

    Attributes
    ----------
    face : (h, w) int64 array
        Triangle covering each pixel centre, -1 where none does.
    barycentric : (h, w, 3) float64 array
        Barycentric coordinates of each pixel centre in its triangle (0 where
        ``face`` is -1).
    pixels : (n, 2) float64 array, px
        Image position ``(u, v)`` of every vertex (column, row).
    F : (m, 3) int64 array
        The rasterised triangles.
    """

    face: IntArray
    barycentric: FloatArray
    pixels: FloatArray
    F: IntArray

    @property
    def covered(self) -> np.ndarray:
        """(h, w) bool: pixels covered by a triangle."""
        return self.face >= 0

    def interpolate(self, values: Any, *, fill: float = 0.0) -> FloatArray:
        """Image of per-vertex values, linearly interpolated over the triangles.

        Parameters
        ----------
        values : (n,) or (n, c) float64 array
            One value (or c channels) per vertex.
        fill : float, default 0.0
            Value of uncovered pixels.

        Returns
        -------
        image : (h, w) or (h, w, c) float64 array
        """
        X = np.asarray(values, dtype=np.float64)
        if X.shape[:1] != (self.pixels.shape[0],) or X.ndim not in (1, 2):
            n = self.pixels.shape[0]
            raise InputError(f"values: expected ({n},) or ({n}, c), got {X.shape}")
        covered = self.face >= 0
        corners = self.F[np.where(covered, self.face, 0)]           # (h, w, 3)
        if X.ndim == 1:
            image = np.einsum("hwk,hwk->hw", self.barycentric, X[corners])
            image[~covered] = fill
        else:
            image = np.einsum("hwk,hwkc->hwc", self.barycentric, X[corners])
            image[~covered] = fill
        return image

    def locate(self, uv: Any) -> tuple[IntArray, FloatArray, np.ndarray]:
        """Triangle and barycentric coordinates of arbitrary image points.

        The triangle covering the nearest pixel centre is tried first, then
        those covering the 3 x 3 pixels around. A point in none of them
        (outside the mesh, or in a triangle thinner than a pixel) gets the
        candidate it is closest to (largest smallest barycentric coordinate),
        with its barycentric coordinates clipped to the triangle, so the
        surface point it names always lies on the mesh.

        Parameters
        ----------
        uv : (k, 2) float64 array, px
            Image points ``(column, row)``.

        Returns
        -------
        face : (k,) int64 array
            Triangle of each point, -1 where no triangle is near.
        barycentric : (k, 3) float64 array
            Barycentric coordinates in ``face`` (non-negative, summing to 1).
        inside : (k,) bool array
            True where the point lies inside the triangle returned.
        """
        P = as_points(uv, name="uv", dim=2)
        h, w = self.face.shape
        col = np.clip(np.rint(P[:, 0]).astype(np.int64), 0, w - 1)
        row = np.clip(np.rint(P[:, 1]).astype(np.int64), 0, h - 1)
        face = self.face[row, col]
        bary = np.zeros((P.shape[0], 3))
        inside = np.zeros(P.shape[0], dtype=bool)
        has = face >= 0
        bary[has] = _barycentric(self.pixels[self.F[face[has]]], P[has])
        inside[has] = bary[has].min(axis=1) >= -_INSIDE_EPS
        # the rest: try the triangles of the 3 x 3 pixels around, else the closest of them
        rest = np.flatnonzero(~inside)
        if rest.size:
            dr, dc = np.divmod(np.arange(9), 3)
            rr = np.clip(row[rest, None] + dr[None] - 1, 0, h - 1)
            cc = np.clip(col[rest, None] + dc[None] - 1, 0, w - 1)
            cand = self.face[rr, cc]                                # (r, 9)
            ok = cand >= 0
            b9 = _barycentric(self.pixels[self.F[np.where(ok, cand, 0)]], P[rest, None, :])  # (r, 9, 3)
            score = b9.min(axis=2)
            score = np.where(ok & np.isfinite(score), score, -np.inf)
            best = np.argmax(score, axis=1)
            k = np.arange(rest.size)
            found = np.isfinite(score[k, best])
            face[rest] = np.where(found, cand[k, best], -1)
            bary[rest] = np.where(found[:, None], b9[k, best], 0.0)
            inside[rest] = found & (score[k, best] >= -_INSIDE_EPS)
        bary = np.clip(bary, 0.0, None)
        bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
        bary[face < 0] = 0.0
        return face, bary, inside

    def surface_points(self, uv: Any, V: Any) -> tuple[FloatArray, np.ndarray]:
        """3D points of the mesh under image points: the inverse of the map.

        Parameters
        ----------
        uv : (k, 2) float64 array, px
            Image points ``(column, row)``.
        V : (n, 3) float64 array, mm
            Vertex positions of the rasterised mesh (the map's ``F`` indexes them).

        Returns
        -------
        points : (k, 3) float64 array, mm
            Points on the mesh surface (see :meth:`locate` for points off the mesh).
        found : (k,) bool array
            False where no triangle was near; ``points`` is NaN there.
        """
        Vv = as_vertices(V, name="V")
        if Vv.shape[0] != self.pixels.shape[0]:
            raise InputError(f"V: expected {self.pixels.shape[0]} vertices, got {Vv.shape[0]}")
        face, bary, _ = self.locate(uv)
        found = face >= 0
        points = np.einsum("kc,kcj->kj", bary, Vv[self.F[np.where(found, face, 0)]])
        points[~found] = np.nan
        return points, found


@dataclass(frozen=True, eq=False)
class CylindricalMap:
    """A cylinder around a face's vertical axis, unrolled into an image.

    A point ``P`` goes to angle ``theta = atan2((P - c) . side, (P - c) . forward)``
    around the axis and height ``h = (P - c) . axis``; the image column is
    ``u = u0 + radius_mm * theta * px_per_mm`` (arc length on the cylinder) and
    the row ``v = v0 - h * px_per_mm`` (rows go down), so one pixel is about
    ``1 / px_per_mm`` mm in both directions at the cylinder's radius. Pixel
    ``(row, column)`` has its centre at ``(u, v) = (column, row)``.

    Attributes
    ----------
    axis, forward, side : (3,) float64 arrays
        Orthonormal frame: the cylinder's axis (up), the direction the face
        looks (``theta = 0``, the seam of the unwrap is behind the head) and
        ``axis x forward``.
    centre : (3,) float64 array, mm
        A point on the axis.
    radius_mm : float
        Cylinder radius used to turn angles into arc lengths.
    px_per_mm : float
        Image scale.
    origin : (2,) float64 array, px
        ``(u0, v0)``.
    shape : tuple of int
        Image ``(height, width)`` in pixels.
    pixels : (n, 2) float64 array, px
        ``project`` of the vertices the map was fitted to.
    """

    axis: FloatArray
    forward: FloatArray
    side: FloatArray
    centre: FloatArray
    radius_mm: float
    px_per_mm: float
    origin: FloatArray
    shape: tuple[int, int]
    pixels: FloatArray

    def project(self, P: Any) -> FloatArray:
        """Image position ``(u, v)`` (column, row; px) of 3D points (k, 3) mm."""
        X = as_points(P, name="P") - self.centre
        theta = np.arctan2(X @ self.side, X @ self.forward)
        h = X @ self.axis
        return np.stack([self.origin[0] + self.radius_mm * self.px_per_mm * theta,
                         self.origin[1] - self.px_per_mm * h], axis=1)

    def rasterise(self, F: Any, *, pixels: Any = None) -> TriangleRaster:
        """Scan-convert triangles into the image: the triangle and barycentrics of each pixel.

        Parameters
        ----------
        F : (m, 3) int64 array
            Triangles indexing ``pixels``.
        pixels : (n, 2) float64 array, px, optional
            Vertex image positions (``project`` of another mesh with the same
            map, say); default the map's own ``pixels``.

        Returns
        -------
        TriangleRaster

        Notes
        -----
        A pixel belongs to a triangle when its centre has barycentric
        coordinates ``>= -1e-9``. Each triangle's bounding box is scanned
        in compiled code (numba: 0.06 s for 152k triangles on a 713 x 1175
        image, where numpy batches of equal box size took 0.33-0.35 s; the
        same pixels and barycentrics, bit for bit). The map is meant to be one-to-one
        on a face; where triangles fold over (the map reverses their
        orientation: under the chin, inside a nostril) a consistently oriented
        triangle wins the pixel; among equals, the lowest-numbered one.
        """
        uv = self.pixels if pixels is None else as_points(pixels, name="pixels", dim=2)
        Fa = as_faces(F, uv.shape[0], name="F")
        h, w = self.shape
        face = np.full((h, w), -1, dtype=np.int64)
        bary = np.zeros((h, w, 3))
        T = uv[Fa]                                                   # (m, 3, 2)
        e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
        den = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]              # twice the signed area
        major = 1.0 if (den > 0).sum() >= (den < 0).sum() else -1.0
        lo = np.maximum(np.ceil(T.min(axis=1)).astype(np.int64), 0)
        hi = np.minimum(np.floor(T.max(axis=1)).astype(np.int64), [w - 1, h - 1])
        ext = hi - lo + 1
        keep = (ext.min(axis=1) > 0) & (np.abs(den) > 1e-12)
        safe = np.where(keep, den, 1.0)
        # barycentric coordinates as affine functions of the pixel position relative to corner 0
        a1, b1 = e2[:, 1] / safe, -e2[:, 0] / safe
        a2, b2 = -e1[:, 1] / safe, e1[:, 0] / safe
        # one triangle per pixel: consistently oriented ones beat folded ones, then the lower index wins
        folded = den * major <= 0
        _scan_convert(T[:, 0], lo, hi, a1, b1, a2, b2, keep, folded, face, bary)
        return TriangleRaster(face=face, barycentric=bary, pixels=uv, F=Fa)

    def sample(self, image: Any, uv: Any, *, fill: float = np.nan) -> FloatArray:
        """Bilinear look-up of an image at arbitrary points.

        Parameters
        ----------
        image : (h, w) or (h, w, c) float array
            An image of this map's shape.
        uv : (k, 2) float64 array, px
            Points ``(column, row)``; pixel centres are at integer positions.
        fill : float, default NaN
            Value returned for points outside the image.

        Returns
        -------
        values : (k,) or (k, c) float64 array
        """
        img = np.asarray(image, dtype=np.float64)
        if img.shape[:2] != self.shape or img.ndim not in (2, 3):
            raise InputError(f"image: expected shape {self.shape} (+ channels), got {img.shape}")
        P = as_points(uv, name="uv", dim=2)
        h, w = self.shape
        x, y = P[:, 0], P[:, 1]
        outside = (x < 0) | (y < 0) | (x > w - 1) | (y > h - 1)
        x0 = np.clip(np.floor(x), 0, max(w - 2, 0)).astype(np.int64)
        y0 = np.clip(np.floor(y), 0, max(h - 2, 0)).astype(np.int64)
        x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
        fx, fy = np.clip(x - x0, 0, 1), np.clip(y - y0, 0, 1)
        if img.ndim == 3:
            fx, fy = fx[:, None], fy[:, None]
        out = ((1 - fy) * ((1 - fx) * img[y0, x0] + fx * img[y0, x1])
               + fy * ((1 - fx) * img[y1, x0] + fx * img[y1, x1]))
        out[outside] = fill
        return out


def cylindrical_map(
    V: Any,
    *,
    axis: Any = (0.0, 1.0, 0.0),
    forward: Any = (0.0, 0.0, 1.0),
    centre: Any = None,
    size_px: int = 512,
    margin_px: int = 4,
) -> CylindricalMap:
    """Fit a cylindrical unwrap of a face to an image of a given size.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertices of the face (a registered mesh, the template).
    axis : (3,) float array, default (0, 1, 0)
        The face's vertical (up) direction; normalised.
    forward : (3,) float array, default (0, 0, 1)
        The direction the face looks; its component perpendicular to
        ``axis`` is the angle origin, so the unwrap's seam falls behind the head.
    centre : (3,) float array, mm, optional
        A point on the cylinder's axis. Default: the median centre of
        least-squares circles through 8 horizontal bands of the vertices (those
        that fit their band, convex towards ``forward``, radius between a
        quarter of and 20 face widths), or, if fewer than 2 bands give one (a
        flat sheet), a point two face-widths behind the centroid.
    size_px : int, default 512
        Pixels along the longer side of the image.
    margin_px : int, default 4
        Empty pixels kept around the face.

    Returns
    -------
    CylindricalMap
        The map, with ``pixels`` (n, 2) the image position of every vertex.

    Raises
    ------
    InputError
        If ``axis`` and ``forward`` are parallel or zero, or sizes are invalid.

    Notes
    -----
    Huang et al. 2011 (section 6.2) project the face onto a cylinder and
    unfold it into an image, "a one-to-one mapping between the image space
    and the mesh surface" on which mean-curvature images are registered by
    optical flow. The arc length ``radius * theta`` makes pixels roughly
    square on the face.

    Examples
    --------
    >>> import numpy as np
    >>> theta, h = np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-40, 40, 5))
    >>> V = np.stack([80 * np.sin(theta.ravel()), h.ravel(), 80 * np.cos(theta.ravel())], 1)
    >>> cmap = cylindrical_map(V, centre=(0, 0, 0), size_px=100)
    >>> bool(np.allclose(np.diff(cmap.pixels[:5, 0]), np.diff(cmap.pixels[:5, 0])[0]))
    True
    """
    Vv = as_vertices(V, name="V")
    a = _unit(axis, "axis")
    f0 = as_points(np.reshape(np.asarray(forward, dtype=np.float64), (1, 3)), name="forward")[0]
    f = f0 - (f0 @ a) * a
    if np.linalg.norm(f) < 1e-9 * max(np.linalg.norm(f0), 1e-300):
        raise InputError("forward: must not be parallel to axis (or zero)")
    f = f / np.linalg.norm(f)
    s = np.cross(a, f)
    if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) or size_px < 8:
        raise InputError(f"size_px: expected an integer >= 8, got {size_px!r}")
    if (isinstance(margin_px, bool) or not isinstance(margin_px, (int, np.integer))
            or not 0 <= 2 * margin_px < size_px - 2):
        raise InputError(f"margin_px: expected an integer in [0, size_px / 2 - 1), got {margin_px!r}")
    mean = Vv.mean(axis=0)
    xs, xf = (Vv - mean) @ s, (Vv - mean) @ f
    width = max(float(np.ptp(xs)), float(np.ptp(xf)), 1e-9)
    if centre is None:
        c = _fit_axis(xs, xf, (Vv - mean) @ a, width)
        c3 = mean + c[0] * s + c[1] * f
    else:
        c3 = as_points(np.reshape(np.asarray(centre, dtype=np.float64), (1, 3)), name="centre")[0]
    X = Vv - c3
    radius = float(np.median(np.hypot(X @ s, X @ f)))
    if not radius > 0:
        raise InputError("centre: the vertices lie on the cylinder's axis")
    theta = np.arctan2(X @ s, X @ f)
    h = X @ a
    arc = radius * theta
    extent = max(float(np.ptp(arc)), float(np.ptp(h)), 1e-9)
    px_per_mm = (size_px - 1 - 2 * margin_px) / extent
    width_px = int(np.ceil(np.ptp(arc) * px_per_mm)) + 1 + 2 * margin_px
    height_px = int(np.ceil(np.ptp(h) * px_per_mm)) + 1 + 2 * margin_px
    origin = np.array([margin_px - arc.min() * px_per_mm, margin_px + h.max() * px_per_mm])
    pixels = np.stack([origin[0] + px_per_mm * arc, origin[1] - px_per_mm * h], axis=1)
    return CylindricalMap(axis=a, forward=f, side=s, centre=c3, radius_mm=radius, px_per_mm=px_per_mm,
                          origin=origin, shape=(height_px, width_px), pixels=pixels)


def _unit(x: Any, name: str) -> FloatArray:
    v = as_points(np.reshape(np.asarray(x, dtype=np.float64), (1, 3)), name=name)[0]
    norm = float(np.linalg.norm(v))
    if norm == 0:
        raise InputError(f"{name}: expected a non-zero direction")
    return v / norm


def _fit_axis(xs: FloatArray, xf: FloatArray, h: FloatArray, width: float) -> FloatArray:
    """Centre (side, forward) of the cylinder through the face's horizontal profiles, or a fallback.

    The vertices are cut into 8 bands of height; a least-squares circle
    (Kasa) is fitted to each band seen along the axis and kept if the band
    roughly lies on it (RMS radial residual under 15 % of its radius: a face
    is no circle), it is convex towards ``forward`` and its radius is between
    a quarter of and 20 face widths. The median of the kept centres is the
    axis if at least 2 bands give one; otherwise (a flat or tilted sheet)
    the axis goes two widths behind the centroid.
    """
    edges = np.quantile(h, np.linspace(0.0, 1.0, 9))
    band = np.clip(np.searchsorted(edges, h, side="right") - 1, 0, 7)
    centres = []
    for b in range(8):
        sel = band == b
        if sel.sum() < 10:
            continue
        x, y = xs[sel], xf[sel]
        A = np.stack([2 * x, 2 * y, np.ones_like(x)], axis=1)
        (cs, cf, c0), *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
        r2 = c0 + cs * cs + cf * cf
        if not (np.isfinite(r2) and r2 > 0):
            continue
        r = np.sqrt(r2)
        rms = np.sqrt(np.mean((np.hypot(x - cs, y - cf) - r) ** 2))
        if rms < 0.15 * r and cf < 0 and 0.25 * width < r < 20 * width:
            centres.append((cs, cf))
    if len(centres) >= 2:
        return np.median(np.asarray(centres), axis=0)
    return np.array([0.0, -2.0 * width])


def _barycentric(T: FloatArray, q: FloatArray) -> FloatArray:
    """Barycentric coordinates of points ``q`` (..., 2) in 2D triangles ``T`` (..., 3, 2)."""
    a, b, c = T[..., 0, :], T[..., 1, :], T[..., 2, :]
    v0, v1, v2 = b - a, c - a, q - a
    den = v0[..., 0] * v1[..., 1] - v1[..., 0] * v0[..., 1]
    den = np.where(np.abs(den) > 1e-300, den, np.nan)  # degenerate triangles contain nothing
    l1 = (v2[..., 0] * v1[..., 1] - v1[..., 0] * v2[..., 1]) / den
    l2 = (v0[..., 0] * v2[..., 1] - v2[..., 0] * v0[..., 1]) / den
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


@numba.njit(cache=True, nogil=True)
def _scan_convert(corner: np.ndarray, lo: np.ndarray, hi: np.ndarray, a1: np.ndarray, b1: np.ndarray,
                  a2: np.ndarray, b2: np.ndarray, keep: np.ndarray, folded: np.ndarray, face: np.ndarray,
                  bary: np.ndarray) -> None:  # pragma: no cover - compiled; tested through rasterise
    """Fill ``face`` and ``bary`` (set to -1 and 0) triangle by triangle, in index order: a pixel goes to
    the first consistently oriented triangle covering it, else to the first folded one."""
    best = np.zeros(face.shape, np.int8)  # 0: free, 1: a folded triangle holds it, 2: a consistent one
    for t in range(corner.shape[0]):
        if not keep[t]:
            continue
        claim = 1 if folded[t] else 2
        for py in range(lo[t, 1], hi[t, 1] + 1):
            dy = py - corner[t, 1]
            for px in range(lo[t, 0], hi[t, 0] + 1):
                if best[py, px] >= claim:
                    continue
                dx = px - corner[t, 0]
                l1 = a1[t] * dx + b1[t] * dy
                l2 = a2[t] * dx + b2[t] * dy
                if l1 >= -_INSIDE_EPS and l2 >= -_INSIDE_EPS and l1 + l2 <= 1.0 + _INSIDE_EPS:
                    best[py, px] = claim
                    face[py, px] = t
                    bary[py, px, 0] = 1.0 - l1 - l2
                    bary[py, px, 1] = l1
                    bary[py, px, 2] = l2
