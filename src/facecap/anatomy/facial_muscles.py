"""The facial muscles as procedural volumes between origin and insertion, embedded in the tetrahedra.

Each muscle is a centre curve built from the named skin landmarks
(:mod:`.anatomy_landmarks`) and laid into the soft tissue at a fraction of the
local tissue depth (1 = on the bone, 0 = at the skin), with an elliptic cross
section (a width in the tissue sheet, a thickness across it). Linear muscles
run from their origin (on bone, or on fascia for the risorius and platysma)
to their insertion in the skin; the sphincters (orbicularis oris and oculi)
are closed rings with circumferential fibres. As in Sifakis et al. 2005, sec. 3,
the muscles are not meshed: each tetrahedron of the one soft-tissue mesh
stores the fraction of its volume inside each muscle (from sample points in
the tetrahedron) and one fibre direction per muscle (the curve's tangent).
The origin and insertion of every muscle, in words, are in ``docs/anatomy.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.resample_polyline import resample_polyline
from ..typing import FloatArray, IntArray
from .anatomy_landmarks import AnatomyLandmarks

__all__ = ["MUSCLE_NAMES", "MuscleFields", "MuscleSpec", "facial_muscles", "muscle_specs"]

CURVE_SAMPLES = 64
"""Points of each stored centre curve (uniform in arc length)."""
SAMPLES_PER_TET = 27
"""Sample points per tetrahedron for the volume fractions (fixed, seeded uniform barycentric points)."""
_SPACING_MM = 0.5
"""Spacing of the dense centre curve used for the inside test."""

Point = Callable[[Callable[[str], FloatArray]], FloatArray]


@dataclass(frozen=True)
class MuscleSpec:
    """One muscle: control points (landmark recipes), depths, cross-section.

    Attributes
    ----------
    name : str
    points : tuple of callables
        Each maps a landmark lookup (name -> face-frame point, mm) to a
        face-frame point; origin first, insertion last. For a ring, the
        points go once round (the curve is closed).
    depths : tuple of float
        Depth of each control point as a fraction of the local tissue
        thickness (0 skin, 1 bone).
    width_mm, thickness_mm : float
        Full extent of the elliptic cross-section in the tissue sheet and across it.
    ring : bool
        Closed sphincter (circumferential fibres) rather than origin-insertion.
    """

    name: str
    points: tuple[Point, ...]
    depths: tuple[float, ...]
    width_mm: float
    thickness_mm: float
    ring: bool = False


def _mix(a: str, b: str, t: float, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> Point:
    return lambda p: (1 - t) * p(a) + t * p(b) + np.array([dx, dy, dz])


def _at(a: str, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> Point:
    return lambda p: p(a) + np.array([dx, dy, dz])


def _ring(centre: Point, half_width: Callable, up: float, down: float, n: int = 16) -> tuple[Point, ...]:
    """Points round an ellipse in the face plane (x, y), starting lateral on the subject's left."""
    def point(k: int) -> Point:
        a = 2 * np.pi * k / n
        return lambda p: centre(p) + np.array([half_width(p) * np.cos(a), (up if np.sin(a) > 0 else down) * np.sin(a), 0.0])
    return tuple(point(k) for k in range(n))


def muscle_specs() -> tuple[MuscleSpec, ...]:
    """The 36 muscles (17 pairs, the procerus and the orbicularis oris), subject's left first."""
    specs: list[MuscleSpec] = []
    for S, s in (("L", 1.0), ("R", -1.0)):
        def m(name: str, points: tuple[Point, ...], depths: tuple[float, ...], w: float, h: float) -> None:
            specs.append(MuscleSpec(f"{name}_{S}", points, depths, w, h))
        m("frontalis", (_at(f"frontal_eminence_{S}", 0, 16), _at(f"supraorbital_{S}", 0, -2)), (0.75, 0.3), 24, 3.5)
        m("corrugator_supercilii", (_mix("glabella", f"brow_inner_{S}", 0.6, 0, -5), _mix(f"brow_inner_{S}", f"supraorbital_{S}", 0.8, 0, 3)),
          (0.9, 0.3), 7, 3.5)
        m("levator_labii_superioris_alaeque_nasi", (_mix("nasion", f"endocanthion_{S}", 0.55, 0, -4), _at(f"alare_{S}", s * 2, -4)),
          (0.85, 0.3), 6, 3.5)
        m("levator_labii_superioris", (_at(f"suborbital_{S}", -s * 2, -4), _mix(f"alare_{S}", f"cheilion_{S}", 0.5, 0, -3)),
          (0.9, 0.3), 10, 3.5)
        m("zygomaticus_minor", (_mix(f"zygomatic_{S}", f"suborbital_{S}", 0.35), _mix(f"cheilion_{S}", "labrale_superius", 0.3, 0, 4)),
          (0.9, 0.3), 6, 3.5)
        m("zygomaticus_major", (_mix(f"zygomatic_{S}", f"zygomatic_arch_{S}", 0.4), _at(f"cheilion_{S}", s * 5)),
          (0.9, 0.35), 8, 4)
        m("risorius", (_mix(f"occlusal_line_{S}", f"gonion_{S}", 0.6), _at(f"cheilion_{S}", s * 4)), (0.4, 0.3), 6, 3.5)
        m("levator_anguli_oris", (_mix(f"alare_{S}", f"zygomatic_{S}", 0.4, 0, -3), _at(f"cheilion_{S}", s * 3, 3)),
          (0.95, 0.45), 6, 3.5)
        m("depressor_anguli_oris", (_mix(f"mandible_border_{S}", f"sub_m2_{S}", 0.35, 0, 3), _at(f"cheilion_{S}", s * 3, -3)),
          (0.9, 0.3), 10, 3.5)
        m("depressor_labii_inferioris", (_mix(f"mandible_border_{S}", "pogonion", 0.5), _mix("labrale_inferius", f"cheilion_{S}", 0.45, 0, -3)),
          (0.9, 0.3), 8, 3.5)
        m("mentalis", (_at("supramentale", s * 5), _at("pogonion", s * 7, -3)), (0.9, 0.3), 6, 3.5)
        m("buccinator", (_mix(f"occlusal_line_{S}", f"gonion_{S}", 0.45), _at(f"cheilion_{S}", s * 6)), (0.95, 0.6), 14, 3.5)
        m("platysma", (_at(f"mandible_border_{S}", s * 8, -14), _mix(f"cheilion_{S}", f"mandible_border_{S}", 0.55, s * 4)),
          (0.5, 0.3), 22, 3.5)
        m("masseter", (_at(f"zygomatic_arch_{S}", 0, -4), _at(f"gonion_{S}", 0, 5)), (0.9, 0.9), 18, 5)
        m("temporalis", (_at(f"temple_{S}", 0, 8), _at(f"zygomatic_arch_{S}", 0, 2), _mix(f"zygomatic_arch_{S}", f"occlusal_line_{S}", 0.3, 0, -8)),
          (0.9, 0.95, 0.95), 16, 5)
        m("nasalis", (_mix(f"alare_{S}", "subnasale", 0.15, s * 3, -1), _at("rhinion", s * 4, -4)), (0.9, 0.3), 6, 3.5)
        eye_centre = _mix(f"exocanthion_{S}", f"endocanthion_{S}", 0.5)
        half = lambda p, S=S: 0.5 * abs(p(f"exocanthion_{S}")[0] - p(f"endocanthion_{S}")[0]) + 10.0
        specs.append(MuscleSpec(f"orbicularis_oculi_{S}", _ring(eye_centre, half, 17.0, 14.0), (0.35,) * 16, 10, 3.5, ring=True))
    specs.append(MuscleSpec("procerus", (_mix("nasion", "rhinion", 0.5), _at("glabella", 0, 8)), (0.9, 0.3), 9, 3.5))
    mouth_half = lambda p: 0.5 * abs(p("cheilion_L")[0] - p("cheilion_R")[0]) + 3.0
    specs.append(MuscleSpec("orbicularis_oris", _ring(_at("stomion"), mouth_half, 12.0, 13.0), (0.4,) * 16, 9, 4.5, ring=True))
    # subject's left and right of each pair side by side, then the two unpaired muscles
    paired = [sp for sp in specs if sp.name.endswith(("_L", "_R"))]
    order = sorted(range(len(paired)), key=lambda i: (i % (len(paired) // 2), i // (len(paired) // 2)))
    return tuple(paired[i] for i in order) + tuple(sp for sp in specs if not sp.name.endswith(("_L", "_R")))


MUSCLE_NAMES: tuple[str, ...] = tuple(sp.name for sp in muscle_specs())
"""The muscle names, in the order of the per-tetrahedron arrays."""


class MuscleFields(NamedTuple):
    """Per-tetrahedron muscle data.

    Attributes
    ----------
    names : tuple of str
        Muscle names (:data:`MUSCLE_NAMES`).
    fractions : (m, k) float64 array in [0, 1]
        Volume fraction of each tetrahedron inside each muscle.
    fibres : (m, k, 3) float64 array
        Unit fibre direction per tetrahedron and muscle (origin to insertion,
        or round the ring); zero where the fraction is zero.
    curves : (k, 64, 3) float64 array, mm
        Each muscle's centre curve, uniform in arc length, origin first
        (rings: closed, first point repeated last).
    rings : (k,) bool array
        Which muscles are sphincters.
    widths_mm, thicknesses_mm : (k,) float64 arrays, mm
        Cross-section extents.
    """

    names: tuple[str, ...]
    fractions: FloatArray
    fibres: FloatArray
    curves: FloatArray
    rings: np.ndarray
    widths_mm: FloatArray
    thicknesses_mm: FloatArray


def _sample_weights(count: int = SAMPLES_PER_TET) -> FloatArray:
    """Fixed barycentric sample points, uniform in a tetrahedron (seeded, so every build agrees).

    A flat Dirichlet(1, 1, 1, 1) draw is the uniform distribution on the
    simplex; a fixed seed makes the fractions reproducible bit for bit.
    """
    return np.random.default_rng(20050731).dirichlet(np.ones(4), size=count)


def _centre_curve(spec: MuscleSpec, lm: AnatomyLandmarks, skin: FloatArray, normals: FloatArray,
                  depth: FloatArray, tree: cKDTree) -> tuple[FloatArray, FloatArray]:
    """Dense centre curve (mm) and the skin normal at each of its points."""
    lookup = lambda name: lm.local(lm.point(name))
    local = np.array([f(lookup) for f in spec.points])
    ctrl = local @ lm.frame + lm.origin
    d = np.asarray(spec.depths, dtype=np.float64)
    if spec.ring:
        ctrl = np.concatenate([ctrl, ctrl[:1]])
        d = np.concatenate([d, d[:1]])
    length = np.cumsum(np.linalg.norm(np.diff(ctrl, axis=0), axis=1))[-1]
    P, (frac,), _ = resample_polyline(ctrl, max(int(length / _SPACING_MM), 8), [d])
    _, v = tree.query(P)
    n = normals[v]
    on_skin = P - np.einsum("ij,ij->i", P - skin[v], n)[:, None] * n
    C = on_skin - (frac * depth[v])[:, None] * n
    # nearest-vertex lookups make the curve step at the vertex spacing: a moving average smooths it
    k = 9
    if C.shape[0] > 2 * k:
        pad = np.concatenate([C[-k:], C, C[:k]]) if spec.ring else np.concatenate([np.repeat(C[:1], k, 0), C, np.repeat(C[-1:], k, 0)])
        kernel = np.ones(2 * k + 1) / (2 * k + 1)
        Cs = np.stack([np.convolve(pad[:, j], kernel, mode="valid") for j in range(3)], axis=1)
        if not spec.ring:
            Cs[0], Cs[-1] = C[0], C[-1]
        C = Cs
    return C, n


def facial_muscles(X: FloatArray, T: IntArray, landmarks: AnatomyLandmarks, skin: FloatArray,
                   normals: FloatArray, depth: FloatArray, *, specs: tuple[MuscleSpec, ...] | None = None) -> MuscleFields:
    """Volume fractions and fibre directions of the facial muscles in a tetrahedral mesh.

    Parameters
    ----------
    X : (N, 3) float64 array, mm
        Tetrahedral mesh nodes.
    T : (M, 4) int64 array
        Tetrahedra.
    landmarks : AnatomyLandmarks
        The scan's named landmarks.
    skin : (s, 3) float64 array, mm
        Meshed skin vertices.
    normals : (s, 3) float64 array
        Unit inward-offset normals at them (outward from the face).
    depth : (s,) float64 array, mm
        Soft-tissue depth (skin to bone along ``-normals``) at them.
    specs : tuple of MuscleSpec, optional
        Default :func:`muscle_specs`.

    Returns
    -------
    MuscleFields

    Notes
    -----
    A sample point ``p`` is inside a muscle when, with ``c`` the nearest
    point of the dense centre curve, ``t`` its unit tangent, ``n`` the skin
    normal there and ``b = t x n``: ``|(p - c) . t| <= 0.5 mm`` (not beyond
    the ends) and ``((p - c) . b / (w/2))^2 + ((p - c) . n / (h/2))^2 <= 1``.
    The fraction is the share of the tetrahedron's 27 sample points inside
    (exact for a tetrahedron wholly in or out, 1/27 resolution on the
    boundary; seeded uniform points); the fibre is the normalised sum of the tangents at the inside points.
    """
    specs = muscle_specs() if specs is None else specs
    tree = cKDTree(skin)
    B = _sample_weights()
    corners = X[T]  # (M, 4, 3)
    samples = np.einsum("sc,mcd->msd", B, corners)  # (M, S, 3)
    centroids = corners.mean(axis=1)
    reach = np.sqrt(np.max(np.sum((corners - centroids[:, None]) ** 2, axis=2), axis=1))
    M, k = T.shape[0], len(specs)
    fractions = np.zeros((M, k))
    fibres = np.zeros((M, k, 3))
    curves = np.zeros((k, CURVE_SAMPLES, 3))
    for j, spec in enumerate(specs):
        C, n = _centre_curve(spec, landmarks, skin, normals, depth, tree)
        curves[j] = resample_polyline(C, CURVE_SAMPLES).points
        t = np.gradient(C, axis=0)
        if spec.ring:
            t[0] = t[-1] = C[1] - C[-2]
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        b = np.cross(t, n)
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        nn = np.cross(b, t)
        half = 0.5 * max(spec.width_mm, spec.thickness_mm)
        near = cKDTree(C).query(centroids, distance_upper_bound=half + reach.max())[0] <= half + reach
        cand = np.flatnonzero(near)
        if cand.size == 0:
            continue
        P = samples[cand].reshape(-1, 3)
        _, ci = cKDTree(C).query(P)
        r = P - C[ci]
        along = np.abs(np.einsum("ij,ij->i", r, t[ci]))
        if spec.ring:
            along[:] = 0.0
        inside = (along <= _SPACING_MM) & (
            (np.einsum("ij,ij->i", r, b[ci]) / (0.5 * spec.width_mm)) ** 2
            + (np.einsum("ij,ij->i", r, nn[ci]) / (0.5 * spec.thickness_mm)) ** 2 <= 1.0
        )
        inside = inside.reshape(cand.size, -1)
        fractions[cand, j] = inside.mean(axis=1)
        tan = (t[ci] * inside.reshape(-1, 1)).reshape(cand.size, -1, 3).sum(axis=1)
        norm = np.linalg.norm(tan, axis=1)
        ok = norm > 0
        fibres[cand[ok], j] = tan[ok] / norm[ok, None]
    return MuscleFields(
        tuple(sp.name for sp in specs), fractions, fibres, curves,
        np.array([sp.ring for sp in specs]), np.array([sp.width_mm for sp in specs], dtype=np.float64),
        np.array([sp.thickness_mm for sp in specs], dtype=np.float64),
    )
