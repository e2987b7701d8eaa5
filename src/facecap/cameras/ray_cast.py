"""The point of a mesh each ray (each pixel of a camera) hits first, and which points a camera sees.

Ray casting is Intel Embree's, through ``embreex`` (the binding trimesh
uses): a 1384x1038 frame against the 714k-vertex benchmark face is 0.2 s of
Embree (7M rays/s on this shared 2-core machine) and 0.6 s with the float64
refinement (docs/cameras.md has the figures; Open3D's ``RaycastingScene``, also
Embree, was 2x faster per call but is a 400 MB wheel with a dozen web and
notebook dependencies). Embree works in
float32; each hit is refined in float64 against its triangle, so the points,
barycentric coordinates and distances are exact to float64 rounding for the
triangle Embree found.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_vertices
from .camera import Camera

__all__ = ["RayCaster", "RayHits", "ray_cast"]

_NUDGE_RAD = 1e-6  # far above float32's 6e-8, far below a pixel's 4e-4 rad
_SLIP_MM = 1e-3  # a nudged hit this much nearer means the original ray passed through the surface

LIGHT_RAY_OFFSET_MM = 0.005
"""Shadow rays start this far above the surface (:meth:`RayCaster.lit`)."""

DEFAULT_OCCLUSION_TOLERANCE_MM = 0.01
"""A surface closer than this in front of a point does not hide it (float32 rounding of Embree, ~1e-4 mm)."""


class RayHits(NamedTuple):
    """The first surface point along each ray.

    Attributes
    ----------
    triangle : (...) int64 array
        Index into ``F`` of the triangle hit, -1 where the ray hits nothing.
    barycentric : (..., 3) float64 array
        Weights of the triangle's corners ``F[triangle]`` (sum 1, each in
        [0, 1]); NaN for misses.
    points : (..., 3) float64 array, mm
        ``barycentric @ V[F[triangle]]``; NaN for misses.
    distance : (...) float64 array, mm
        Distance along the (unit) ray to the point; inf for misses.
    normals : (..., 3) float64 array
        Unit normal of the triangle hit, by the winding of ``F``
        (counter-clockwise seen from the side it points to); NaN for misses.
    """

    triangle: IntArray
    barycentric: FloatArray
    points: FloatArray
    distance: FloatArray
    normals: FloatArray

    @property
    def hit(self) -> BoolArray:
        """(...) bool: the ray hit the mesh."""
        return self.triangle >= 0


def _as_rays(origins: Any, directions: Any) -> tuple[FloatArray, FloatArray, tuple[int, ...]]:
    try:
        D = np.asarray(directions, dtype=np.float64)
        O = np.asarray(origins, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"rays: expected numeric (..., 3) origins and directions ({exc})") from None
    if D.ndim < 1 or D.shape[-1] != 3:
        raise InputError(f"directions: expected shape (..., 3), got {D.shape}")
    try:
        O = np.broadcast_to(O, D.shape)
    except ValueError:
        raise InputError(f"origins: shape {O.shape} does not broadcast to the directions' {D.shape}") from None
    shape = D.shape[:-1]
    O = np.ascontiguousarray(O.reshape(-1, 3))
    D = D.reshape(-1, 3)
    if not (np.all(np.isfinite(O)) and np.all(np.isfinite(D))):
        raise InputError("rays: origins and directions must be finite")
    length = np.linalg.norm(D, axis=1)
    if np.any(length == 0):
        raise InputError("directions: a ray has zero length")
    return O, D / length[:, None], shape


class RayCaster:
    """Embree's acceleration structure over one mesh, built once, then cast against cheaply.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions (one frame of a performance).
    F : (m, 3) int64 array
        Triangles.

    Notes
    -----
    Build once per frame (the deformed mesh): about 1 s for 1.4M triangles,
    0.15 s for 210k, 10-100 ms for the 18k-triangle ICT sample. The mesh is stored shifted to its
    bounding-box centre so that Embree's float32 keeps about 1e-5 mm at face scale.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [10, 0, 0], [0, 10, 0]]); F = np.array([[0, 1, 2]])
    >>> hits = RayCaster(V, F).cast([[2.0, 3.0, 5.0]], [[0.0, 0.0, -1.0]])
    >>> hits.triangle.tolist(), hits.points.round(12).tolist(), hits.distance.tolist()
    ([0], [[2.0, 3.0, 0.0]], [5.0])
    """

    def __init__(self, V: Any, F: Any) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.V = as_vertices(V)
        self.F = as_faces(F, self.V.shape[0])
        self._shift = (self.V.min(axis=0) + self.V.max(axis=0)) / 2
        self._scene = rtcore_scene.EmbreeScene(robust=True)
        TriangleMesh(scene=self._scene, vertices=(self.V - self._shift).astype(np.float32),
                     indices=self.F.astype(np.int32))

    def cast(self, origins: Any, directions: Any, *, robust: bool = False) -> RayHits:
        """The first point of the mesh along each ray.

        Parameters
        ----------
        origins : (..., 3) or (3,) array, mm
            Ray origins (broadcast against ``directions``).
        directions : (..., 3) array
            Ray directions (normalised here).
        robust : bool, default False
            Also cast three copies of each ray turned by 1e-6 rad (0.6 um at
            600 mm) and keep the nearest surface they find, refined against the
            original ray. For rays aimed exactly at vertices or edges (projected
            vertices, edge midpoints), which Embree's float32 test lets through
            the mesh about 1-3% of the time (measured on the ICT face and an
            icosphere, Embree's robust mode on); generic pixel rays showed no
            hole in 446k pixels. Costs 4x.

        Returns
        -------
        RayHits
            Shaped like the rays.
        """
        O, D, shape = _as_rays(origins, directions)
        k = O.shape[0]
        triangle = np.full(k, -1, dtype=np.int64)
        barycentric = np.full((k, 3), np.nan)
        points = np.full((k, 3), np.nan)
        distance = np.full(k, np.inf)
        normals = np.full((k, 3), np.nan)
        if k:
            ids = self._first_triangles(O, D, robust)
            hit = ids >= 0
            rows = np.flatnonzero(hit)
            bary, point, t, n = self._refine(O[rows], D[rows], ids[rows])
            triangle[rows] = ids[rows]
            barycentric[rows] = bary
            points[rows] = point
            distance[rows] = t
            normals[rows] = n
        return RayHits(triangle.reshape(shape), barycentric.reshape(shape + (3,)), points.reshape(shape + (3,)),
                       distance.reshape(shape), normals.reshape(shape + (3,)))

    def _first_triangles(self, O: FloatArray, D: FloatArray, robust: bool) -> IntArray:
        """Embree's first triangle along each ray (-1 for none); with ``robust``, the nearest of four nudged casts."""
        shifted = (O - self._shift).astype(np.float32)
        found = self._scene.run(shifted, D.astype(np.float32), output=1)
        ids = np.asarray(found["primID"], dtype=np.int64)
        if not robust:
            return ids
        distance = np.where(ids >= 0, np.asarray(found["tfar"], dtype=np.float64), np.inf)
        helper = np.where(np.abs(D[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        a = _cross(D, helper)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = _cross(D, a)
        for nudge in (a, b, -(a + b) / np.sqrt(2)):
            turned = D + _NUDGE_RAD * nudge
            again = self._scene.run(shifted, turned.astype(np.float32), output=1)
            other = np.asarray(again["primID"], dtype=np.int64)
            other_distance = np.where(other >= 0, np.asarray(again["tfar"], dtype=np.float64), np.inf)
            # a nudged ray replaces a miss, or a hit behind a nearer surface (the original slipped through it)
            take = (other >= 0) & ((ids < 0) | (other_distance < distance - _SLIP_MM))
            ids[take] = other[take]
            distance[take] = other_distance[take]
        return ids

    def _refine(self, O: FloatArray, D: FloatArray, ids: IntArray
                ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Moller-Trumbore in float64 on the triangles Embree found: barycentric, point, distance, unit normal."""
        corners = self.V[self.F[ids]]  # (k, 3 corners, 3)
        a = corners[:, 0]
        e1 = corners[:, 1] - a
        e2 = corners[:, 2] - a
        p = _cross(D, e2)
        s = O - a
        q = _cross(s, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / (e1 * p).sum(axis=1)
            u = (s * p).sum(axis=1) * inv
            v = (D * q).sum(axis=1) * inv
        # a ray in the triangle's plane (det 0) or float32 rounding just outside the triangle: clamp onto it
        bad = ~(np.isfinite(u) & np.isfinite(v))
        u[bad] = v[bad] = 1 / 3
        bary = np.empty((ids.size, 3))
        bary[:, 0] = 1 - u - v
        bary[:, 1] = u
        bary[:, 2] = v
        np.clip(bary, 0, None, out=bary)
        bary /= bary.sum(axis=1, keepdims=True)
        point = a + bary[:, 1:2] * e1 + bary[:, 2:] * e2
        t = ((point - O) * D).sum(axis=1)
        n = _cross(e1, e2)
        n /= np.sqrt((n * n).sum(axis=1))[:, None]
        return bary, point, t, n

    def cast_pixels(self, camera: Camera, pixels: Any, *, robust: bool = False) -> RayHits:
        """The mesh point each pixel of ``camera`` sees (lens distortion included).

        Parameters
        ----------
        camera : Camera
        pixels : (..., 2) array, px
            Pixel positions ``(u, v)``, e.g. ``camera.pixel_grid()`` for every pixel.
        robust : bool, default False
            See :meth:`cast` (for pixels that are projections of vertices).

        Returns
        -------
        RayHits
            ``distance`` is along the ray from the camera centre; the depth
            (along the optical axis) is ``camera.to_camera_frame(hits.points)[..., 2]``.

        Notes
        -----
        A camera's rays do not change from frame to frame: for a whole
        performance compute ``rays = camera.pixel_rays(pixels)`` once (0.4-0.8 s
        for 1384x1038, OpenCV's iterative undistortion) and call
        ``cast(rays.origins, rays.directions)`` on each frame's caster.
        """
        rays = camera.pixel_rays(pixels)
        return self.cast(rays.origins, rays.directions, robust=robust)

    def visible(self, points: Any, camera: Camera, *,
                tolerance_mm: float = DEFAULT_OCCLUSION_TOLERANCE_MM) -> BoolArray:
        """Whether ``camera`` sees each point: in front, inside the image, and no surface in between.

        Parameters
        ----------
        points : (..., 3) array, mm
            Points on (or near) the mesh, typically its vertices.
        camera : Camera
        tolerance_mm : float, default 0.01
            A surface less than this in front of a point does not hide it.

        Returns
        -------
        (...) bool array

        Notes
        -----
        One Embree occlusion ray per point, from the camera centre to the point
        stopping ``tolerance_mm`` short. At grazing incidence (the silhouette,
        where the surface is within a few degrees of the ray) float32 rounding
        decides, and a point there may come out either way; tests compare with
        a float64 brute force everywhere else.
        """
        X = np.asarray(points, dtype=np.float64)
        projection = camera.project(X)
        shape = X.shape[:-1]
        flat = X.reshape(-1, 3)
        inside = projection.in_image.reshape(-1)
        rows = np.flatnonzero(inside)
        visible = np.zeros(flat.shape[0], dtype=bool)
        if rows.size:
            centre = camera.centre
            ray = flat[rows] - centre
            length = np.linalg.norm(ray, axis=1)
            origins = np.broadcast_to((centre - self._shift).astype(np.float32), (rows.size, 3)).copy()
            directions = (ray / length[:, None]).astype(np.float32)
            reach = np.maximum(length - tolerance_mm, 0).astype(np.float32)
            occluded = np.asarray(self._scene.run(origins, directions, dists=reach, query="OCCLUDED")) >= 0
            visible[rows] = ~occluded
        return visible.reshape(shape)

    def lit(self, points: Any, light: Any, *, normals: Any = None, offset_mm: float = LIGHT_RAY_OFFSET_MM) -> BoolArray:
        """Whether each point sees ``light``: no surface between it and the light (a cast shadow otherwise).

        Parameters
        ----------
        points : (..., 3) array, mm
            Points on the mesh, typically its vertices.
        light : Light
            :class:`facecap.cameras.Light` (point, spot or directional).
        normals : (..., 3) array, optional
            The surface's unit normals at the points: each ray starts ``offset_mm`` above the surface
            along it, so that a point is not shadowed by its own triangles (a point facing away from the
            light is still reported lit here: the cosine term, not this one, darkens it).
        offset_mm : float, default 0.005
            Far below any wrinkle, far above Embree's float32 rounding at face scale (about 1e-5 mm).

        Returns
        -------
        (...) bool array
            False where a surface lies between the point and the light.
        """
        X = np.asarray(points, dtype=np.float64)
        shape = X.shape[:-1]
        flat = X.reshape(-1, 3)
        if normals is not None:
            flat = flat + float(offset_mm) * np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        to_light, _ = light.arriving(flat)
        reach = light.distance_to(flat)
        reach = np.where(np.isfinite(reach), reach - float(offset_mm), np.float32(1e30))
        good = np.all(np.isfinite(to_light), axis=1)
        lit = np.ones(flat.shape[0], dtype=bool)
        rows = np.flatnonzero(good)
        if rows.size:
            occluded = np.asarray(self._scene.run((flat[rows] - self._shift).astype(np.float32),
                                                  to_light[rows].astype(np.float32),
                                                  dists=np.maximum(reach[rows], 0).astype(np.float32),
                                                  query="OCCLUDED")) >= 0
            lit[rows] = ~occluded
        return lit.reshape(shape)

    def visible_vertices(self, camera: Camera, *, tolerance_mm: float = DEFAULT_OCCLUSION_TOLERANCE_MM) -> BoolArray:
        """(n,) bool: the vertices ``camera`` sees (:meth:`visible` of ``V``)."""
        return self.visible(self.V, camera, tolerance_mm=tolerance_mm)


def _cross(x: FloatArray, y: FloatArray) -> FloatArray:
    """Row-wise cross product of (k, 3) arrays (np.cross is several times slower on long arrays)."""
    out = np.empty_like(x)
    out[:, 0] = x[:, 1] * y[:, 2] - x[:, 2] * y[:, 1]
    out[:, 1] = x[:, 2] * y[:, 0] - x[:, 0] * y[:, 2]
    out[:, 2] = x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0]
    return out


def ray_cast(V: Any, F: Any, origins: Any, directions: Any, *, robust: bool = False) -> RayHits:
    """One-shot :meth:`RayCaster.cast`: the first point of the mesh ``(V, F)`` along each ray.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
    F : (m, 3) int64 array
    origins : (..., 3) or (3,) array, mm
    directions : (..., 3) array
    robust : bool, default False
        See :meth:`RayCaster.cast`.

    Returns
    -------
    RayHits
    """
    return RayCaster(V, F).cast(origins, directions, robust=robust)
