"""Benchmark meshes, markers and marker motion built from the ICT-FaceKit neutral face.

Not part of the package: used by ``benchmarks/bench_thin_shell.py``. Everything
here is deterministic (no RNG in the meshes, a seeded local RNG for the motion),
so every subprocess of a benchmark run rebuilds exactly the same inputs.

Meshes (all from ``/work/shared/data/ict_face/generic_neutral_mesh.obj``, read
with :func:`facecap.io.read_mesh.read_mesh` in cm -> mm, quads fan-triangulated):

=====  ==========================================================  ==========
case   construction                                                 vertices
=====  ==========================================================  ==========
100k   narrow face area (vertices 0-6705, polygons 0-6559),          105,550
       ``igl.upsample`` 2 levels
300k   face + head/neck (vertices 0-11247, polygons 0-11143),        ~300,000
       ``igl.upsample`` 3 levels, then cropped to the triangles
       whose three corners lie within a sphere around the centroid
       of the narrow-face base vertices (radius found by bisection
       for 300,000 vertices), unreferenced vertices dropped
700k   face + head/neck (vertices 0-11247, polygons 0-11143),        714,062
       ``igl.upsample`` 3 levels
=====  ==========================================================  ==========

``igl.upsample`` splits every edge at its midpoint (no smoothing), roughly 4x
vertices per level, and keeps the original vertices first.
"""

from __future__ import annotations

import os
from functools import lru_cache
from typing import NamedTuple

import igl
import numpy as np

ICT_OBJ = os.environ.get("FACECAP_ICT_OBJ", "/work/shared/data/ict_face/generic_neutral_mesh.obj")

CASES = ("100k", "300k", "700k")

# (last vertex, last polygon) of the ICT regions used (README of the ICT data, 0-based inclusive)
_NARROW_FACE = (6705, 6559)
_FACE_AND_HEAD = (11247, 11143)
_CROP_TARGET_300K = 300_000


class BenchMesh(NamedTuple):
    """A benchmark mesh. ``V`` (n, 3) float64 mm, ``F`` (m, 3) int64, ``description`` str."""

    V: np.ndarray
    F: np.ndarray
    description: str


@lru_cache(maxsize=1)
def _ict_triangles() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ICT neutral in mm: vertices, triangles, and the polygon each triangle came from."""
    from facecap.io.read_mesh import read_mesh

    mesh = read_mesh(ICT_OBJ, unit="cm")
    sizes = mesh.polygon_sizes
    polygon_of_triangle = np.repeat(np.arange(sizes.size), sizes - 2)
    if polygon_of_triangle.size != mesh.n_faces:
        raise RuntimeError("ICT mesh: fan triangulation does not match the polygon sizes")
    return mesh.vertices, mesh.faces, polygon_of_triangle


def _region(last_vertex: int, last_polygon: int) -> tuple[np.ndarray, np.ndarray]:
    V, F, poly = _ict_triangles()
    Fr = F[poly <= last_polygon]
    if int(Fr.max()) > last_vertex:
        raise RuntimeError("ICT region: polygons refer to vertices outside the region")
    return np.ascontiguousarray(V[: last_vertex + 1]), np.ascontiguousarray(Fr)


def _crop_sphere(V: np.ndarray, F: np.ndarray, centre: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Keep triangles with all corners within radius r of ``centre``, r chosen for ~target vertices."""
    dist = np.linalg.norm(V - centre, axis=1)
    tri_far = dist[F].max(axis=1)

    def count(r: float) -> int:
        used = np.zeros(V.shape[0], dtype=bool)
        used[F[tri_far <= r].ravel()] = True
        return int(used.sum())

    lo, hi = 0.0, float(dist.max())
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        k = count(mid)
        if k == target:
            hi = mid
            break
        if k < target:
            lo = mid
        else:
            hi = mid
    Fk = F[tri_far <= hi]
    used = np.unique(Fk)
    remap = np.full(V.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return np.ascontiguousarray(V[used]), np.ascontiguousarray(remap[Fk]), hi


def _largest_piece(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest edge-connected piece (the crop may leave islands)."""
    from facecap.mesh.connected_pieces import connected_pieces

    _, labels = connected_pieces(F, V.shape[0])
    big = np.argmax(np.bincount(labels))
    keep_f = labels[F[:, 0]] == big
    Fk = F[keep_f]
    used = np.unique(Fk)
    remap = np.full(V.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return np.ascontiguousarray(V[used]), np.ascontiguousarray(remap[Fk])


@lru_cache(maxsize=1)
def bench_mesh(case: str) -> BenchMesh:
    """Build the benchmark mesh for ``case`` in {'100k', '300k', '700k'} (see module docstring)."""
    if case == "100k":
        V, F = _region(*_NARROW_FACE)
        V, F = igl.upsample(V, F, 2)
        desc = "ICT narrow face (v 0-6705, poly 0-6559), igl.upsample x2"
    elif case == "700k":
        V, F = _region(*_FACE_AND_HEAD)
        V, F = igl.upsample(V, F, 3)
        desc = "ICT face+head/neck (v 0-11247, poly 0-11143), igl.upsample x3"
    elif case == "300k":
        V0, F0 = _region(*_FACE_AND_HEAD)
        centre = V0[: _NARROW_FACE[0] + 1].mean(axis=0)
        V, F = igl.upsample(V0, F0, 3)
        V, F, radius = _crop_sphere(V, F, centre, _CROP_TARGET_300K)
        V, F = _largest_piece(V, F)
        desc = (
            "ICT face+head/neck, igl.upsample x3, cropped to triangles within "
            f"{radius:.1f} mm of the narrow-face centroid, largest piece"
        )
    else:
        raise ValueError(f"case: expected one of {CASES}, got {case!r}")
    return BenchMesh(np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64), desc)


def farthest_point_markers(V: np.ndarray, n_markers: int, *, start: int | None = None) -> np.ndarray:
    """Farthest point sampling of ``n_markers`` vertices (Euclidean), seeded at the vertex nearest the centroid.

    Returns
    -------
    (n_markers,) int64 array of distinct vertex indices.
    """
    if start is None:
        start = int(np.argmin(np.linalg.norm(V - V.mean(axis=0), axis=1)))
    chosen = np.empty(n_markers, dtype=np.int64)
    chosen[0] = start
    d = np.linalg.norm(V - V[start], axis=1)
    for k in range(1, n_markers):
        chosen[k] = int(np.argmax(d))
        np.minimum(d, np.linalg.norm(V - V[chosen[k]], axis=1), out=d)
    return chosen


def smooth_marker_motion(
    n_frames: int, n_markers: int, *, amplitude_mm: float = 3.0, rate_hz: float = 60.0, seed: int = 0
) -> np.ndarray:
    """Smooth random marker displacements: a sum of 4 sinusoids (0.1-2 Hz) per marker and axis.

    Returns
    -------
    (n_frames, n_markers, 3) float64 array, mm; RMS about ``amplitude_mm / 2`` per axis.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames)[:, None, None, None] / rate_hz
    freq = rng.uniform(0.1, 2.0, size=(1, n_markers, 3, 4))
    phase = rng.uniform(0, 2 * np.pi, size=(1, n_markers, 3, 4))
    weight = rng.uniform(0.5, 1.0, size=(1, n_markers, 3, 4))
    weight /= weight.sum(axis=3, keepdims=True)
    out = np.zeros((n_frames, n_markers, 3))
    for j in range(4):  # loop over the 4 terms keeps memory at one (T, K, 3) array
        out += weight[..., j] * np.sin(2 * np.pi * freq[..., j] * t[..., 0] + phase[..., j])
    return amplitude_mm * out
