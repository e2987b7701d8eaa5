"""Where each marker sits on the template, read from the bases that colour put in the template's material."""

from __future__ import annotations

from typing import Any, NamedTuple

import igl
import numpy as np

from ..errors import InputError
from ..typing import BoolArray, FloatArray, IntArray

__all__ = ["MarkerPlaces", "marker_places_from_bases"]

_NEAR_MM = 1.0  # a skin point farther than this from a basis is off what the basis covers: not counted


class MarkerPlaces(NamedTuple):
    """Result of :func:`marker_places_from_bases`.

    Attributes
    ----------
    vertices, weights : (M, 3) int64 / float64 arrays
        The template triangle (its corners) and barycentric weights of each marker's place.
    found : (M,) bool array
        Markers with a place (their skin point on at least one basis).
    points : (M, 3) float64 array, mm
        The places on the template's rest surface (NaN where not found).
    """

    vertices: IntArray
    weights: FloatArray
    found: BoolArray
    points: FloatArray

    def moved_mm(self, rest: FloatArray, vertices: IntArray, weights: FloatArray) -> FloatArray:
        """(M,) distance from the places ``vertices, weights`` on ``rest`` to these (NaN where not found)."""
        old = np.einsum("mj,mjc->mc", weights, rest[np.maximum(vertices, 0)])
        return np.where(self.found, np.linalg.norm(self.points - old, axis=1), np.nan)


def marker_places_from_bases(bases: Any, faces: Any, rest: Any, skin_points: Any, landed: Any) -> MarkerPlaces:
    """Each marker's place on the template as the median of its skin points carried back by the bases.

    A basis registered onto its scan, and slid along it until the skin's colour matches the template's,
    holds the template's material: the point of a basis nearest a marker's skin point on that scan lies
    in some template triangle at some barycentric weights, and those weights on the template's rest
    surface are where the marker sits. The median over the bases (per coordinate, then the nearest
    point of the rest surface) is robust to the odd basis that slid.

    Parameters
    ----------
    bases : (K, n, 3) float array, mm
        Registered bases in the template's topology (same frame as ``skin_points``).
    faces : (m, 3) int array
        The template's triangles.
    rest : (n, 3) float array, mm
        The template's own surface (the material).
    skin_points : (K, M, 3) float array, mm
        The skin under each marker on each scan.
    landed : (K, M) bool array
        Which skin points are real (the marker landed on that scan).

    Returns
    -------
    MarkerPlaces

    Raises
    ------
    InputError
        If the shapes do not agree.
    """
    B = np.asarray(bases, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    R = np.asarray(rest, dtype=np.float64)
    S = np.asarray(skin_points, dtype=np.float64)
    L = np.asarray(landed, dtype=bool)
    if B.ndim != 3 or B.shape[1:] != R.shape or S.shape[0] != B.shape[0] or S.shape[2] != 3 or L.shape != S.shape[:2]:
        raise InputError(f"bases (K, n, 3), rest (n, 3), skin_points (K, M, 3), landed (K, M) expected, "
                         f"got {B.shape}, {R.shape}, {S.shape}, {L.shape}")
    K, M = S.shape[:2]
    material = np.full((K, M, 3), np.nan)
    for k in range(K):
        use = np.flatnonzero(L[k] & np.all(np.isfinite(S[k]), axis=1))
        if use.size == 0:
            continue
        sq, tri, closest = igl.point_mesh_squared_distance(S[k, use], B[k], F)
        corners = F[tri]
        bary = igl.barycentric_coordinates(np.ascontiguousarray(closest),
                                           *(np.ascontiguousarray(B[k][corners[:, j]]) for j in range(3)))
        near = np.sqrt(sq) <= _NEAR_MM
        material[k, use[near]] = np.einsum("pj,pjc->pc", bary[near], R[corners[near]])
    found = np.any(np.isfinite(material[:, :, 0]), axis=0)
    points = np.full((M, 3), np.nan)
    vertices = np.full((M, 3), -1, dtype=np.int64)
    weights = np.zeros((M, 3))
    if found.any():
        median = np.nanmedian(material[:, found], axis=0)
        _, tri, on_rest = igl.point_mesh_squared_distance(median, R, F)
        corners = F[tri]
        w = igl.barycentric_coordinates(np.ascontiguousarray(on_rest),
                                        *(np.ascontiguousarray(R[corners[:, j]]) for j in range(3)))
        points[found], vertices[found], weights[found] = on_rest, corners, np.clip(w, 0.0, 1.0)
        weights[found] /= weights[found].sum(axis=1, keepdims=True)
    return MarkerPlaces(vertices, weights, found, points)
