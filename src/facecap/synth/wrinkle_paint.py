"""Paint on the wrinkles, as the actor wears it for the wrinkle cameras: distinct diffuse colours on the valleys."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..mesh.nearest_on_polyline import nearest_on_polyline
from ..typing import FloatArray, IntArray
from .wrinkles import WrinkleCurves

__all__ = ["PAINT_COLORS", "PAINT_HALF_WIDTH", "PaintedSkin", "paint_wrinkles"]

PAINT_COLORS = (
    (0.08, 0.22, 0.62),  # blue
    (0.10, 0.50, 0.16),  # green
    (0.70, 0.66, 0.06),  # yellow
    (0.55, 0.10, 0.50),  # magenta
    (0.06, 0.50, 0.55),  # teal
)
"""Linear RGB reflectances of the paints: saturated, far from skin (no reds or oranges), bright enough
that a valley's self-shadowing reads above the sensor noise."""

PAINT_HALF_WIDTH = 2.0
"""A stripe covers the valley and its bulges: this many (largest) widths each side of the valley line."""


class PaintedSkin(NamedTuple):
    """The albedo with paint, and which paint went where.

    Attributes
    ----------
    albedo : (n, 3) float64 array
        Linear RGB reflectance: the paint's on painted vertices, the skin's elsewhere.
    stripe : (n,) int64 array
        Index of the curve whose stripe covers each vertex, -1 for bare skin.
    curve_colors : (c, 3) float64 array
        Each curve's paint (linear RGB), one of :data:`PAINT_COLORS`.
    color_index : (c,) int64 array
        Index into :data:`PAINT_COLORS` of each curve's paint.
    """

    albedo: FloatArray
    stripe: IntArray
    curve_colors: FloatArray
    color_index: IntArray


def _stripes(curves: WrinkleCurves, rest: FloatArray) -> tuple[IntArray, FloatArray]:
    """Per vertex: the curve whose stripe it is in (nearest in widths), and that distance over the width."""
    n = rest.shape[0]
    best = np.full(n, np.inf)
    owner = np.full(n, -1, dtype=np.int64)
    for i in range(curves.n_curves):
        P = curves.points[i]
        reach = PAINT_HALF_WIDTH * curves.max_width[i]
        lo, hi = P.min(axis=0) - reach, P.max(axis=0) + reach
        box = np.flatnonzero(np.all((rest >= lo) & (rest <= hi), axis=1))
        dist, _ = nearest_on_polyline(rest[box], P, curves.arc_fraction[i])
        rel = dist / curves.max_width[i]
        take = (rel <= PAINT_HALF_WIDTH) & (rel < best[box])
        best[box[take]] = rel[take]
        owner[box[take]] = i
    return owner, best


def paint_wrinkles(curves: WrinkleCurves, rest: FloatArray, skin: FloatArray) -> PaintedSkin:
    """Paint a stripe on each wrinkle, neighbouring wrinkles in different colours.

    Parameters
    ----------
    curves : WrinkleCurves
    rest : (n, 3) float array, mm
        The rest surface the curves lie on (the paint rides with the skin).
    skin : (n, 3) float array
        The skin's linear albedo, e.g. from :func:`~facecap.synth.skin_albedo.skin_albedo`.

    Returns
    -------
    PaintedSkin

    Raises
    ------
    InputError
        If the shapes disagree.

    Notes
    -----
    Vertices within ``PAINT_HALF_WIDTH * max_width`` of a valley line take
    its paint (the nearest line, in widths, where stripes meet). Colours are
    given greedily in curve order: each curve takes the first paint that no
    curve within ``2 * PAINT_HALF_WIDTH`` widths plus 10 mm of it already has,
    so wrinkles a tracker could confuse never share a colour.
    """
    rest = np.asarray(rest, dtype=np.float64)
    skin = np.asarray(skin, dtype=np.float64)
    if rest.ndim != 2 or rest.shape[1] != 3 or skin.shape != rest.shape:
        raise InputError(f"rest, skin: expected two (n, 3) arrays, got {rest.shape} and {skin.shape}")
    c = curves.n_curves
    color_index = np.zeros(c, dtype=np.int64)
    for i in range(c):
        taken = set()
        for j in range(i):
            gap = np.linalg.norm(curves.points[i][:, None] - curves.points[j][None], axis=2).min()
            if gap < PAINT_HALF_WIDTH * (curves.max_width[i] + curves.max_width[j]) + 10.0:
                taken.add(int(color_index[j]))
        free = [k for k in range(len(PAINT_COLORS)) if k not in taken]
        color_index[i] = free[0] if free else i % len(PAINT_COLORS)
    palette = np.asarray(PAINT_COLORS, dtype=np.float64)
    curve_colors = palette[color_index]
    owner, _ = _stripes(curves, rest)
    albedo = skin.copy()
    painted = owner >= 0
    albedo[painted] = curve_colors[owner[painted]]
    return PaintedSkin(albedo=albedo, stripe=owner, curve_colors=curve_colors, color_index=color_index)
