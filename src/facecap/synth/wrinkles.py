"""Ground-truth expression wrinkles: valley curves on the face, and a height field of their own along them.

The truth for the wrinkle layer (Bickel et al. 2007, section 5) must not be
made by the solver it tests, so the cross-section here is deliberately not
the solver's ``S(w, d, p) = d (p/w - 1) exp(-p/w)``: it is a smooth valley with
a bulge on each side, ``h(p) = -d (1 - q^2) exp(-q^2)``, ``q = p / w``
(a Ricker-like "Mexican hat": zero at ``p = w`` like ``S``, bulges
``d e^-2`` high at ``p = sqrt(2) w``, but round at the bottom where ``S``
has a kink).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from .expression_curves import EXPRESSION_PRESETS
from .smoothstep import smoothstep
from ..mesh.resample_polyline import resample_polyline
from ..mesh.nearest_on_polyline import nearest_on_polyline
from ..mesh.vertex_normals import vertex_normals
from ..io.ict_sample import IctSample

__all__ = ["WrinkleCurves", "WrinkledPerformance", "WRINKLE_KINDS", "INFLUENCE_WIDTHS", "WRINKLE_EXPRESSIONS",
           "wrinkle_profile", "place_wrinkles", "wrinkle_curves_on_surface", "wrinkle_activation", "wrinkle_heights", "wrinkle_expression_curves",
           "add_wrinkles", "every_wrinkle_at_once"]

WRINKLE_KINDS = ("forehead", "glabella", "crows_feet", "nasolabial")
"""The wrinkle families :func:`place_wrinkles` can draw."""

INFLUENCE_WIDTHS = 3.0
"""A wrinkle moves the skin up to this many (largest) widths from its valley line, and nothing beyond."""

_CUT_START = 2.5  # q where the profile starts its smooth cut to exactly 0 at INFLUENCE_WIDTHS (|h| < 1 % of d there)
CURVE_POINTS = 48
"""Points per truth curve (uniform in arc length on the rest surface)."""

# kind: (depth range mm, width range mm (the half-width w: valley line to zero crossing), gains {expression: gain})
# sides: 'L' is the subject's left (+x), as in the ICT names
_FAMILIES = {
    "forehead": ((0.5, 0.9), (1.6, 2.2)),
    "glabella": ((0.5, 0.8), (1.4, 1.8)),
    "crows_feet": ((0.3, 0.5), (1.3, 1.6)),
    "nasolabial": ((0.8, 1.2), (2.5, 3.2)),
}
_MIN_WIDTH_FRACTION = 0.6  # a barely active wrinkle is 60 % as wide as a fully active one


def _drivers(kind: str, side: str) -> dict[str, float]:
    """Which expressions make a wrinkle, with gains: activation = clip(sum gain * weight, 0, 1)."""
    if kind == "forehead":  # brow raise: the frontalis folds the forehead skin
        return {"browInnerUp_L": 0.5, "browInnerUp_R": 0.5, "browOuterUp_L": 0.3, "browOuterUp_R": 0.3}
    if kind == "glabella":  # frown: corrugator pulls the inner brows down and together
        return {f"browDown_{side}": 1.0, f"noseSneer_{side}": 0.3}
    if kind == "crows_feet":  # squint and smile: orbicularis oculi
        return {f"eyeSquint_{side}": 0.6, f"cheekSquint_{side}": 0.6, f"mouthSmile_{side}": 0.5}
    return {f"mouthSmile_{side}": 1.0, f"cheekSquint_{side}": 0.3, f"noseSneer_{side}": 0.3}  # nasolabial


@dataclass(frozen=True, eq=False)
class WrinkleCurves:
    """Wrinkle valley lines on a rest surface, and what drives each.

    Attributes
    ----------
    names : tuple of str, length c
        ``forehead_0``, ``glabella_L``, ``crows_feet_R_1``, ``nasolabial_L``, ...
    kinds : tuple of str, length c
        One of :data:`WRINKLE_KINDS` per curve.
    points : (c, k, 3) float64 array, mm
        The valley line on the rest surface, ``k = CURVE_POINTS`` points uniform in arc length.
    faces : (c, k) int64 array
        The triangle of the rest mesh each point lies on.
    barycentric : (c, k, 3) float64 array
        Its barycentric coordinates there (so the curve rides on any frame of the mesh).
    arc_fraction : (c, k) float64 array
        Arc length from the curve's start over its length, in [0, 1].
    gains : (c, e) float64 array
        Activation ``a = clip(weights @ gains.T, 0, 1)`` with ``e`` the expression count.
    max_depth : (c,) float64 array, mm
        Depth of the valley at full activation, mid-curve.
    max_width : (c,) float64 array, mm
        Half-width ``w`` (valley line to the profile's zero crossing) at full activation, mid-curve.
    min_width : (c,) float64 array, mm
        ``w`` as the wrinkle starts to form.
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    points: FloatArray
    faces: IntArray
    barycentric: FloatArray
    arc_fraction: FloatArray
    gains: FloatArray
    max_depth: FloatArray
    max_width: FloatArray
    min_width: FloatArray

    @property
    def n_curves(self) -> int:
        """Number of curves c."""
        return len(self.names)


class WrinkledPerformance(NamedTuple):
    """A performance with its wrinkles, and their truth.

    Attributes
    ----------
    vertices : (T, n, 3) float32 array, mm
        ``large_scale`` plus the wrinkle height along its vertex normals.
    heights : (T, n) float32 array, mm
        The wrinkle height field at each vertex (negative in valleys,
        positive on bulges, exactly 0 outside ``mask``).
    mask : (n,) bool array
        Vertices within :data:`INFLUENCE_WIDTHS` largest widths of a valley line.
    activation : (T, c) float64 array
        Each wrinkle's activation in [0, 1].
    depths : (T, c, k) float64 array, mm
        Valley depth at each curve point (0 where the wrinkle is not formed).
    widths : (T, c, k) float64 array, mm
        Half-width ``w`` at each curve point.
    curve_points : (T, c, k, 3) float32 array, mm
        The valley line on the wrinkled surface: the large-scale point plus
        ``-depth`` along the interpolated normal.
    """

    vertices: np.ndarray
    heights: np.ndarray
    mask: BoolArray
    activation: FloatArray
    depths: FloatArray
    widths: FloatArray
    curve_points: np.ndarray


def wrinkle_profile(distance: FloatArray, depth: FloatArray, width: FloatArray) -> FloatArray:
    """Height of the skin at ``distance`` from a valley line (mm; negative in the valley).

    Parameters
    ----------
    distance : float array, mm
        Unsigned distance from the valley line.
    depth : float array, mm
        Valley depth ``d`` (>= 0), broadcast with ``distance``.
    width : float array, mm
        Half-width ``w`` (> 0): the distance of the zero crossing.

    Returns
    -------
    float64 array, mm

    Notes
    -----
    ``h = -d (1 - q^2) exp(-q^2) c(q)``, ``q = |p| / w``: ``-d`` at the line,
    0 at ``q = 1``, bulges of ``d e^-2`` at ``q = sqrt 2``; ``c`` is 1 up to
    ``q = 2.5`` and falls smoothly (smoothstep) to exactly 0 at ``q = 3``.

    Examples
    --------
    >>> wrinkle_profile(np.array([0.0, 1.0, 3.0]), 0.5, 1.0).round(6).tolist()
    [-0.5, -0.0, 0.0]
    """
    q = np.abs(np.asarray(distance, dtype=np.float64)) / np.asarray(width, dtype=np.float64)
    r = np.clip((q - _CUT_START) / (INFLUENCE_WIDTHS - _CUT_START), 0.0, 1.0)
    cut = 1.0 - r * r * (3.0 - 2.0 * r)
    return -np.asarray(depth, dtype=np.float64) * (1.0 - q * q) * np.exp(-q * q) * cut


def _depth_taper(s: FloatArray) -> FloatArray:
    """Depth along the curve: 0 at the ends, 1 mid-way."""
    return np.sqrt(np.sin(np.pi * np.clip(s, 0.0, 1.0)))


def _width_taper(s: FloatArray) -> FloatArray:
    """Width along the curve: 70 % at the ends, 100 % mid-way."""
    return 0.7 + 0.3 * np.sin(np.pi * np.clip(s, 0.0, 1.0))


def _lift(V: FloatArray, F: IntArray, xy: FloatArray) -> tuple[FloatArray, IntArray, FloatArray]:
    """Points on the surface seen along -z from above each (x, y): positions, triangles, barycentrics."""
    from ..cameras import ray_cast

    origins = np.column_stack([xy, np.full(len(xy), V[:, 2].max() + 100.0)])
    hits = ray_cast(V, F, origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1)))
    if not hits.hit.all():
        raise InputError("place_wrinkles: a wrinkle curve runs off the face (no surface under it)")
    return hits.points, hits.triangle, hits.barycentric


def _family_curves(kind: str, V: FloatArray, landmarks: IntArray, forehead_top: float, rng: np.random.Generator
                   ) -> list[tuple[str, str, FloatArray]]:
    """(name, side, (m, 2) xy polyline) for each curve of a family, from the 68 landmarks."""
    L = V[landmarks]
    out = []
    brow_top = float(L[17:27, 1].max())
    if kind == "forehead":
        # between the brow hair and the hairline (the top of the sample's forehead region)
        low, high = brow_top + 11.0, forehead_top - 3.0
        count = int(rng.integers(2, 5))
        spacing = rng.uniform(8.5, 10.5)
        count = max(1, min(count, int((high - low) // 8.0) + 1))
        if count > 1:
            spacing = min(spacing, (high - low) / (count - 1))
        for i in range(count):
            half = rng.uniform(30.0, 38.0) - 3.0 * i
            x = np.linspace(-half, half, 40)
            y0 = low + spacing * i
            wobble = rng.uniform(0.3, 0.8) * np.sin(2 * np.pi * x / rng.uniform(40, 70) + rng.uniform(0, 2 * np.pi))
            y = y0 - rng.uniform(0.002, 0.006) * x * x + wobble
            out.append((f"forehead_{i}", "", np.column_stack([x, y])))
        return out
    for side, sign in (("L", 1.0), ("R", -1.0)):
        if kind == "glabella":
            x0 = sign * rng.uniform(4.5, 6.5)
            y = np.linspace(brow_top - 8.0, brow_top + 6.0, 20)
            x = x0 + sign * 1.5 * (y - y[0]) / (y[-1] - y[0])
            out.append((f"glabella_{side}", side, np.column_stack([x, y])))
        elif kind == "crows_feet":
            corner = L[45 if sign > 0 else 36, :2]
            count = int(rng.integers(2, 4))
            fan = np.array([-28.0, 0.0, 28.0])[:count] + (8.0 if count == 2 else 0.0)  # two lines: centred
            angles = np.deg2rad(fan + rng.uniform(-5, 5, count))
            for j, a in enumerate(angles):
                direction = np.array([sign * np.cos(a), np.sin(a)])
                start = corner + direction * rng.uniform(6.0, 8.0)
                t = np.linspace(0.0, rng.uniform(10.0, 14.0), 20)[:, None]
                out.append((f"crows_feet_{side}_{j}", side, start + t * direction))
        elif kind == "nasolabial":
            ala, corner = L[35 if sign > 0 else 31, :2], L[54 if sign > 0 else 48, :2]
            a = ala + np.array([sign * rng.uniform(4.0, 6.0), rng.uniform(0.0, 3.0)])
            b = corner + np.array([sign * rng.uniform(5.0, 8.0), -rng.uniform(6.0, 10.0)])
            bow = np.array([sign * rng.uniform(3.0, 5.0), 0.0])
            t = np.linspace(0.0, 1.0, 30)[:, None]
            mid = 0.5 * (a + b) + bow
            out.append((f"nasolabial_{side}", side, (1 - t) ** 2 * a + 2 * t * (1 - t) * mid + t * t * b))
    return out


def place_wrinkles(
    scan: Mesh,
    sample: IctSample,
    *,
    kinds: Sequence[str] = WRINKLE_KINDS,
    seed: int = 0,
) -> WrinkleCurves:
    """Draw wrinkle valley lines on a face of ICT topology, from its landmarks.

    Forehead lines (2-4, between the brows and the top of the sample's
    forehead region, 8.5-10.5 mm apart or closer to fit), glabella (frown) lines (one each
    side of the midline between the brows), crow's feet (2-3 each side,
    fanning out from the outer eye corner) and nasolabial folds (nose wing
    to outside the mouth corner), each with a seeded depth, width and shape.

    Parameters
    ----------
    scan : Mesh
        The rest face (mm), of ICT topology or subdivided from it with its
        original vertices first (:func:`~facecap.synth.wrinkle_scan.subdivide_scan`).
    sample : IctSample
        Gives the landmarks and the expression names the drivers refer to.
    kinds : sequence of {'forehead', 'glabella', 'crows_feet', 'nasolabial'}, default all
    seed : int, default 0

    Returns
    -------
    WrinkleCurves

    Raises
    ------
    InputError
        If a kind is unknown or a curve runs off the face.

    Notes
    -----
    Each curve is drawn in the frontal (x, y) plane of the ICT frame and
    dropped along -z onto the surface (Embree ray casting). Its activation
    ``a(t) = clip(sum_e gain_e weight_e(t), 0, 1)`` comes from the
    expressions that make it: brow raise (forehead), brow down (glabella),
    eye and cheek squint and smile (crow's feet), smile (nasolabial).
    Depth ``d = a d_max sqrt(sin(pi s))`` and width
    ``w = (w_min + a (w_max - w_min)) (0.7 + 0.3 sin(pi s))`` along the arc
    fraction ``s``.
    """
    kinds = tuple(kinds)
    bad = [k for k in kinds if k not in WRINKLE_KINDS]
    if bad or not kinds:
        raise InputError(f"kinds: expected some of {WRINKLE_KINDS}, got {list(kinds)}")
    n_landmark_max = int(sample.landmarks.max())
    if scan.n_vertices <= n_landmark_max:
        raise InputError(f"scan: {scan.n_vertices} vertices; expected the ICT topology (or a subdivision of it)")
    rng = np.random.default_rng(seed)
    index = {s: i for i, s in enumerate(sample.expression_names)}
    V = scan.vertices
    n = sample.n_vertices
    centre_forehead = (sample.region_labels == sample.region_names.index("forehead")) & (np.abs(V[:n, 0]) < 20.0)
    forehead_top = float(V[:n][centre_forehead, 1].max())
    rows: list[tuple[str, str, FloatArray]] = []
    kind_of: list[str] = []
    for kind in WRINKLE_KINDS:
        if kind in kinds:
            curves = _family_curves(kind, V, sample.landmarks, forehead_top, rng)
            rows += curves
            kind_of += [kind] * len(curves)
    gains = np.zeros((len(rows), len(sample.expression_names)))
    depth, width = np.zeros(len(rows)), np.zeros(len(rows))
    for i, ((name, side, _), kind) in enumerate(zip(rows, kind_of)):
        for expr, g in _drivers(kind, side).items():
            gains[i, index[expr]] = g
        (d_lo, d_hi), (w_lo, w_hi) = _FAMILIES[kind]
        depth[i], width[i] = rng.uniform(d_lo, d_hi), rng.uniform(w_lo, w_hi)
    return wrinkle_curves_on_surface(scan, [r[2] for r in rows], names=tuple(r[0] for r in rows),
                                     kinds=tuple(kind_of), gains=gains, max_depth=depth, max_width=width,
                                     min_width=_MIN_WIDTH_FRACTION * width)


def wrinkle_curves_on_surface(
    scan: Mesh,
    polylines: Sequence[FloatArray],
    *,
    names: Sequence[str],
    kinds: Sequence[str],
    gains: FloatArray,
    max_depth: FloatArray,
    max_width: FloatArray,
    min_width: FloatArray,
) -> WrinkleCurves:
    """Wrinkle lines drawn in the frontal plane, dropped onto the surface, as :class:`WrinkleCurves`.

    Parameters
    ----------
    scan : Mesh
        The rest surface (mm, the ICT frame: z out of the face).
    polylines : sequence of (m_i, 2) float arrays, mm
        Each line in the frontal (x, y) plane; resampled to :data:`CURVE_POINTS` points uniform
        in arc length and dropped along -z onto the surface (Embree).
    names, kinds : sequences of str, length c
    gains : (c, e) float array
        Activation ``clip(weights @ gains.T, 0, 1)``.
    max_depth, max_width, min_width : (c,) float arrays, mm
        See :class:`WrinkleCurves`.

    Returns
    -------
    WrinkleCurves

    Raises
    ------
    InputError
        If a line runs off the face.
    """
    V, F = scan.vertices, scan.faces
    c, k = len(polylines), CURVE_POINTS
    xy = np.stack([resample_polyline(np.asarray(P, dtype=np.float64), k).points for P in polylines])
    pts, faces, bary = _lift(V, F, xy.reshape(-1, 2))
    pts, faces, bary = pts.reshape(c, k, 3), faces.reshape(c, k), bary.reshape(c, k, 3)
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=2)
    arc = np.concatenate([np.zeros((c, 1)), np.cumsum(seg, axis=1)], axis=1)
    arc /= arc[:, -1:]
    return WrinkleCurves(names=tuple(names), kinds=tuple(kinds), points=pts, faces=faces, barycentric=bary,
                         arc_fraction=arc, gains=np.asarray(gains, dtype=np.float64),
                         max_depth=np.asarray(max_depth, dtype=np.float64),
                         max_width=np.asarray(max_width, dtype=np.float64),
                         min_width=np.asarray(min_width, dtype=np.float64))


WRINKLE_EXPRESSIONS: dict[str, dict[str, float]] = {
    "brow_raise": EXPRESSION_PRESETS["surprise"],
    "frown": EXPRESSION_PRESETS["anger"],
    "smile": EXPRESSION_PRESETS["smile"],
    "squint": {"eyeSquint_L": 0.9, "eyeSquint_R": 0.9, "cheekSquint_L": 0.6, "cheekSquint_R": 0.6,
               "browDown_L": 0.2, "browDown_R": 0.2},
}
"""The expressions that make the generated wrinkles (brow raise, frown, smile, squint), as blendshape weights."""


def wrinkle_expression_curves(n_frames: int, names: Sequence[str], *, rate: float, seed: int = 0,
                              intensity: tuple[float, float] = (0.6, 1.0)) -> FloatArray:
    """(T, len(names)) weights playing every :data:`WRINKLE_EXPRESSIONS` entry in turn, in a seeded order.

    Each expression eases in (C2, 0.3-0.6 s), holds 0.2-0.6 s and eases out
    (0.3-0.6 s) at an intensity drawn from ``intensity``; the next starts as
    the last eases out; the order is reshuffled each round. Frame 0 is
    neutral (the scan), after a 0.2 s lead-in.

    Examples
    --------
    >>> W = wrinkle_expression_curves(100, ["browInnerUp_L", "mouthSmile_L"], rate=50.0)
    >>> W.shape, float(W[0].max()), bool(W[:, 0].max() > 0.5)
    ((100, 2), 0.0, True)
    """
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames: expected an integer >= 1, got {n_frames!r}")
    rng = np.random.default_rng(seed)
    t = np.arange(int(n_frames)) / float(rate)
    index = {s: i for i, s in enumerate(names)}
    out = np.zeros((t.size, len(names)))
    at = 0.2
    keys = list(WRINKLE_EXPRESSIONS)
    while True:
        for key in rng.permutation(keys):
            ramp_in, hold, ramp_out = rng.uniform(0.3, 0.6), rng.uniform(0.2, 0.6), rng.uniform(0.3, 0.6)
            envelope = smoothstep((t - at) / ramp_in) * (1.0 - smoothstep((t - at - ramp_in - hold) / ramp_out))
            scale = rng.uniform(*intensity)
            for shape, weight in WRINKLE_EXPRESSIONS[str(key)].items():
                if shape in index:
                    out[:, index[shape]] += scale * weight * envelope
            at += ramp_in + hold
        if at > t[-1]:
            break
    out[0] = 0.0
    return np.clip(out, 0.0, 1.0)


def every_wrinkle_at_once(n_frames: int, names: Sequence[str], *, from_frame: int = 3, weight: float = 0.6
                          ) -> FloatArray:
    """(T, len(names)) weights: neutral, then every :data:`WRINKLE_EXPRESSIONS` entry at once from ``from_frame``.

    The short takes of the tests and the demo: every wrinkle formed in one video frame.

    Examples
    --------
    >>> W = every_wrinkle_at_once(9, ["browInnerUp_L", "mouthSmile_L"])
    >>> float(W[2].max()), bool(W[3:].min() > 0)
    (0.0, True)
    """
    out = np.zeros((int(n_frames), len(names)))
    index = {s: i for i, s in enumerate(names)}
    for expression in WRINKLE_EXPRESSIONS.values():
        for shape, gain in expression.items():
            if shape in index:
                out[from_frame:, index[shape]] += weight * gain
    return np.clip(out, 0.0, 1.0)


def wrinkle_activation(curves: WrinkleCurves, weights: FloatArray) -> FloatArray:
    """(T, c) activation in [0, 1] of each wrinkle from the expression weights (T, e)."""
    W = np.asarray(weights, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != curves.gains.shape[1]:
        raise InputError(f"weights: expected shape (T, {curves.gains.shape[1]}), got {W.shape}")
    return np.clip(W @ curves.gains.T, 0.0, 1.0)


def _influence(curves: WrinkleCurves, rest: FloatArray) -> list[tuple[IntArray, FloatArray, FloatArray]]:
    """Per curve: the vertices within its influence, their distance to the valley line and arc fraction."""
    out = []
    for i in range(curves.n_curves):
        P = curves.points[i]
        reach = INFLUENCE_WIDTHS * curves.max_width[i]
        lo, hi = P.min(axis=0) - reach, P.max(axis=0) + reach
        box = np.flatnonzero(np.all((rest >= lo) & (rest <= hi), axis=1))
        dist, s = nearest_on_polyline(rest[box], P, curves.arc_fraction[i])
        keep = dist < reach
        out.append((box[keep], dist[keep], s[keep]))
    return out


def wrinkle_heights(curves: WrinkleCurves, rest: FloatArray, activation: FloatArray, *,
                    profile: Callable[[FloatArray, FloatArray, FloatArray], FloatArray] = wrinkle_profile,
                    ) -> tuple[BoolArray, IntArray, FloatArray]:
    """The wrinkles' heights at points of the rest surface, for each frame's activations.

    Parameters
    ----------
    curves : WrinkleCurves
    rest : (n, 3) float array, mm
        Points on the rest surface the curves lie on (any mesh's vertices: the scan's, or a
        finer one of the same surface).
    activation : (T, c) float array
        Each wrinkle's activation per frame (:func:`wrinkle_activation`).
    profile : callable, default :func:`wrinkle_profile`
        ``profile(distance, depth, width)`` (mm, broadcasting): the cross-section, exactly 0
        beyond :data:`INFLUENCE_WIDTHS` widths.

    Returns
    -------
    mask : (n,) bool array
        The points within some wrinkle's influence (elsewhere the height is exactly 0).
    moving : (k,) int64 array
        ``flatnonzero(mask)``.
    heights : (T, k) float64 array, mm
        Along the surface normal at ``moving`` (negative in the valleys).
    """
    a = np.asarray(activation, dtype=np.float64)
    peak_width = curves.min_width[None] + a * (curves.max_width - curves.min_width)[None]  # (T, c)
    n = rest.shape[0]
    influence = _influence(curves, rest)
    mask = np.zeros(n, dtype=bool)
    for idx, _, _ in influence:
        mask[idx] = True
    moving = np.flatnonzero(mask)
    column = np.full(n, -1, dtype=np.int64)
    column[moving] = np.arange(moving.size)
    local = np.zeros((a.shape[0], moving.size))  # heights on the mask only: the rest is exactly 0
    for i, (idx, dist, s) in enumerate(influence):
        d = a[:, i : i + 1] * curves.max_depth[i] * _depth_taper(s)[None]
        w = peak_width[:, i : i + 1] * _width_taper(s)[None]
        local[:, column[idx]] += profile(dist[None], d, w)
    return mask, moving, local


def add_wrinkles(
    large_scale: np.ndarray,
    faces: IntArray,
    curves: WrinkleCurves,
    weights: FloatArray,
    *,
    rest: FloatArray | None = None,
    batch_frames: int = 16,
    profile: Callable[[FloatArray, FloatArray, FloatArray], FloatArray] = wrinkle_profile,
) -> WrinkledPerformance:
    """Add the wrinkles to a performance: heights along each frame's vertex normals.

    Parameters
    ----------
    large_scale : (T, n, 3) float array, mm
        The performance without wrinkles (the mesh the curves were placed on, animated).
    faces : (m, 3) int64 array
    curves : WrinkleCurves
        From :func:`place_wrinkles` on the rest mesh.
    weights : (T, e) float array
        The expression weights of the take (they set each wrinkle's activation).
    rest : (n, 3) float array, mm, optional
        The rest surface the curves lie on, where distances are measured
        (the wrinkles ride with the skin). Default: ``large_scale[0]``.
    batch_frames : int, default 16
        Frames per block of the normal computation (bounds memory).
    profile : callable, default :func:`wrinkle_profile`
        The cross-section (see :func:`wrinkle_heights`).

    Returns
    -------
    WrinkledPerformance

    Raises
    ------
    InputError
        If the shapes disagree.

    Notes
    -----
    ``vertices[t, v] = large_scale[t, v] + sum_c h_c(t, v) n_t(v)``, with
    ``h_c = wrinkle_profile(p_c(v), d_c(t, s_c(v)), w_c(t, s_c(v)))`` for the
    distance ``p_c`` from vertex ``v`` to curve ``c`` on the rest surface and
    the arc fraction ``s_c`` of the nearest curve point, and ``n_t`` the
    area-weighted vertex normal of ``large_scale[t]``. The wrinkles are finer
    than the markers: markers come from the large scale.
    """
    X = np.asarray(large_scale)
    if X.ndim != 3 or X.shape[2] != 3:
        raise InputError(f"large_scale: expected shape (T, n, 3), got {X.shape}")
    T, n = X.shape[:2]
    W = np.asarray(weights, dtype=np.float64)
    if W.shape[0] != T:
        raise InputError(f"weights: {W.shape[0]} frames for a performance of {T}")
    rest = X[0].astype(np.float64) if rest is None else np.asarray(rest, dtype=np.float64)
    if rest.shape != (n, 3):
        raise InputError(f"rest: expected shape ({n}, 3), got {rest.shape}")
    a = wrinkle_activation(curves, W)  # (T, c)
    peak_width = curves.min_width[None] + a * (curves.max_width - curves.min_width)[None]  # (T, c)
    mask, moving, local = wrinkle_heights(curves, rest, a, profile=profile)
    heights = np.zeros((T, n), dtype=np.float32)
    heights[:, moving] = local
    vertices = np.array(X, dtype=np.float32)
    s_pts = curves.arc_fraction
    depths = a[:, :, None] * curves.max_depth[None, :, None] * _depth_taper(s_pts)[None]
    widths = peak_width[:, :, None] * _width_taper(s_pts)[None]
    c, k = curves.faces.shape
    corner = faces[curves.faces.ravel()]  # (c k, 3)
    curve_points = np.empty((T, c, k, 3), dtype=np.float32)
    for t0 in range(0, T, batch_frames):
        block = X[t0 : t0 + batch_frames].astype(np.float64)
        if moving.size:
            N = vertex_normals(block, faces, moving)
            lift = heights[t0 : t0 + batch_frames, moving, None] * N
            vertices[t0 : t0 + batch_frames, moving] += lift.astype(np.float32)
        # the valley line on the wrinkled surface: large-scale point, minus the depth along the smooth normal
        Nc = vertex_normals(block, faces, np.unique(corner))
        row = np.full(n, -1)
        row[np.unique(corner)] = np.arange(np.unique(corner).size)
        b = curves.barycentric.reshape(-1, 3)
        base = np.einsum("tqjd,qj->tqd", block[:, corner], b)
        normal = np.einsum("tqjd,qj->tqd", Nc[:, row[corner]], b)
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        dep = depths[t0 : t0 + batch_frames].reshape(block.shape[0], -1)
        curve_points[t0 : t0 + batch_frames] = (base - dep[..., None] * normal).reshape(-1, c, k, 3)
    return WrinkledPerformance(vertices=vertices, heights=heights, mask=mask, activation=a, depths=depths,
                               widths=widths, curve_points=curve_points)
