"""The picture ``facecap map`` writes: the scan from the front with every marker's place, labelled."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import InputError
from ..io.atomic_write import atomic_path
from ..validate import as_faces, as_points, as_vertices
from .render_mesh import as_size_px, draw_mesh

__all__ = ["plot_marker_map", "MARKER_MAP_COLORS"]

MARKER_MAP_COLORS: dict[str, str] = {"placed": "#1f5fbf", "check": "#e07b00", "not placed": "#c8102e"}
"""Colour of each kind of marker in the picture: placed, placed but to be checked (ambiguous or uncertain),
not placed (drawn where the fitted marker centre is)."""

_DPI = 100.0


def plot_marker_map(
    V: Any,
    F: Any,
    points: Any,
    labels: Sequence[str],
    kinds: Sequence[str],
    path: str | os.PathLike[str],
    *,
    forward: Any,
    up: Any,
    title: str | None = None,
    size_px: tuple[int, int] = (1000, 1150),
) -> Figure:
    """Draw the scan seen from the front with each marker's place and label, and save a PNG.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Scan vertices.
    F : (m, 3) int64 array
        Scan triangles, counter-clockwise seen from outside (as drawn: a scan
        wound the other way should be passed with its triangles reversed).
    points : (M, 3) float64 array, mm
        Where to draw each marker: its place on the skin, or for a marker not
        placed, its fitted centre; NaN rows are not drawn.
    labels : sequence of str, length M
        Marker labels, written beside the points.
    kinds : sequence of str, length M
        Each marker's kind, a key of :data:`MARKER_MAP_COLORS`: ``'placed'``,
        ``'check'`` (placed, ambiguous or uncertain) or ``'not placed'``.
    path : str or path-like
        PNG file to write (atomically: a temporary sibling renamed on success).
    forward : (3,) float array
        The direction the face looks, in scan coordinates: the camera looks back along it.
    up : (3,) float array
        Roughly up on the picture (made perpendicular to ``forward``).
    title : str or None, optional
        Title over the picture.
    size_px : (int, int), optional
        Image width and height in pixels, default (1000, 1150).

    Returns
    -------
    matplotlib.figure.Figure
        The figure as saved; its axes hold one scatter per kind present
        (``gid`` the kind) and one text per drawn label.

    Raises
    ------
    InputError
        If the arrays disagree in length, a kind is unknown, the view vectors
        are parallel or zero, or ``size_px`` is not two sizes of at least 16 pixels
        (MeshError for the mesh).
    """
    Vc = as_vertices(V, name="V")
    Fc = as_faces(F, Vc.shape[0], name="F")
    P = as_points(points, name="points", allow_nan=True)
    if len(labels) != P.shape[0] or len(kinds) != P.shape[0]:
        raise InputError(f"labels, kinds: expected {P.shape[0]} each to match points, got {len(labels)} and "
                         f"{len(kinds)}")
    unknown = sorted(set(kinds) - set(MARKER_MAP_COLORS))
    if unknown:
        raise InputError(f"kinds: expected values in {sorted(MARKER_MAP_COLORS)}, got {unknown}")
    w, h = as_size_px(size_px)
    toward = np.asarray(forward, dtype=np.float64).reshape(3)
    vertical = np.asarray(up, dtype=np.float64).reshape(3)
    if not np.linalg.norm(toward) > 0:
        raise InputError("forward: expected a non-zero vector")
    toward = toward / np.linalg.norm(toward)
    vertical = vertical - (vertical @ toward) * toward
    if not np.linalg.norm(vertical) > 1e-9:
        raise InputError("up: expected a vector not parallel to forward")
    vertical /= np.linalg.norm(vertical)
    screen = np.stack([np.cross(vertical, toward), vertical, toward])  # rows: right, up, toward the camera

    title_px = 50 if title else 0
    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI, facecolor="white")
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0 - title_px / h))
    draw_mesh(ax, Vc @ screen.T, Fc, view="front", aspect_px=w / (h - title_px))
    shown = np.isfinite(P).all(axis=1)
    xy = P @ screen[:2].T
    kind_array = np.asarray(kinds, dtype=object)
    names = {"placed": "placed", "check": "placed, to check (ambiguous or uncertain)", "not placed": "not placed"}
    for kind, colour in MARKER_MAP_COLORS.items():
        rows = shown & (kind_array == kind)
        if rows.any():
            ax.scatter(xy[rows, 0], xy[rows, 1], s=22 if kind != "not placed" else 40, c=colour,
                       marker="o" if kind != "not placed" else "x", linewidths=1.5, zorder=3, gid=kind,
                       label=f"{names[kind]}: {int(rows.sum())}")
    for i in np.flatnonzero(shown):
        ax.annotate(labels[i], xy[i], xytext=(3, 3), textcoords="offset points", fontsize=7,
                    color=MARKER_MAP_COLORS[kinds[i]], zorder=4)
    if shown.any():
        ax.legend(loc="lower left", fontsize=9, frameon=False)
    if title:
        fig.text(0.5, 1.0 - 0.5 * title_px / h, title, ha="center", va="center", fontsize=13)
    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI, facecolor="white")
    return fig
