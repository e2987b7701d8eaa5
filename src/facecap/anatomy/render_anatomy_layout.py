"""A review picture of the muscle layout: every muscle drawn over the skin, front and side.

matplotlib's Agg canvas (no display): the skin grey-shaded with back faces
culled, each muscle as a band along its centre curve as wide as the muscle,
one colour per muscle pair, each labelled once per view (its left-side copy).
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from ..errors import InputError
from ..io.atomic_write import atomic_path
from .anatomy_landmarks import face_frame
from .face_anatomy import FaceAnatomy

__all__ = ["render_anatomy_layout"]

_DPI = 100.0
_SKIN = np.array([0.86, 0.82, 0.79])


def _face_frame(anatomy: FaceAnatomy) -> np.ndarray:
    return face_frame(dict(zip(anatomy.landmark_names, anatomy.landmark_points)))


def _view(frame: np.ndarray, which: str) -> np.ndarray:
    """Screen right, screen up and toward-camera rows for the front view or the view from the subject's left."""
    x, y, z = frame
    if which == "front":
        return np.stack([x, y, z])
    return np.stack([-z, y, x])


def _draw_panel(ax, anatomy: FaceAnatomy, R: np.ndarray, side: str, labels: bool) -> None:
    V = anatomy.scan_vertices @ R.T
    F = anatomy.scan_faces
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    visible = n[:, 2] > 0
    n = n[visible] / np.linalg.norm(n[visible], axis=1, keepdims=True)
    tri = tri[visible]
    order = np.argsort(tri[:, :, 2].mean(axis=1))
    shade = 0.3 + 0.7 * np.clip(n @ np.array([0.3, 0.4, 0.87]), 0.0, 1.0)
    colours = np.clip(_SKIN[None] * shade[:, None], 0, 1)
    ax.add_collection(PolyCollection(tri[order, :, :2], facecolors=colours[order], edgecolors="none"))
    lo, hi = V[:, :2].min(axis=0), V[:, :2].max(axis=0)
    pad = 0.04 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    fig = ax.figure
    width_px = ax.get_position().width * fig.get_figwidth() * _DPI
    pt_per_mm = width_px / (hi[0] - lo[0] + 2 * pad) * 72.0 / _DPI
    bases = sorted({name[:-2] if name.endswith(("_L", "_R")) else name for name in anatomy.muscle_names})
    cmap = colormaps["tab20"]
    for k, name in enumerate(anatomy.muscle_names):
        C = anatomy.muscle_curves[k] @ R.T
        lateral = (anatomy.muscle_curves[k] - anatomy.landmark_points.mean(axis=0)) @ _face_frame(anatomy)[0]
        if side == "left" and name.endswith("_R"):
            continue
        base = name[:-2] if name.endswith(("_L", "_R")) else name
        colour = cmap(bases.index(base) % 20)
        ax.plot(C[:, 0], C[:, 1], color=colour, alpha=0.75, solid_capstyle="round",
                linewidth=max(anatomy.muscle_widths_mm[k] * pt_per_mm, 1.0))
        ax.plot(C[:, 0], C[:, 1], color="k", alpha=0.5, linewidth=0.5)
        if labels and not name.endswith("_R") and (lateral.mean() >= -1.0):
            mid = C[len(C) // 3] if anatomy.muscle_rings[k] else C[len(C) // 2]
            ax.annotate(base.replace("_", " "), mid[:2], fontsize=6.5, color="k",
                        xytext=(4, 2), textcoords="offset points")


def render_anatomy_layout(anatomy: FaceAnatomy, path: str | os.PathLike[str], *,
                          size_px: tuple[int, int] = (1800, 1000), title: str | None = None) -> None:
    """Write a PNG of the muscles over the skin: front view and the subject's left side, labelled.

    Parameters
    ----------
    anatomy : FaceAnatomy
        The model (:func:`~facecap.anatomy.build_anatomy` or :func:`~facecap.anatomy.load_anatomy`).
    path : str or path-like
        PNG to write (atomically).
    size_px : (int, int), optional
        Width and height in pixels, default (1800, 1000).
    title : str or None, optional
        Figure title; default names the muscle and tetrahedron counts.

    Raises
    ------
    InputError
        If ``size_px`` is not two sizes of at least 200 pixels, or the
        folder of ``path`` does not exist.
    """
    try:
        W, H = (int(v) for v in size_px)
    except (TypeError, ValueError):
        raise InputError(f"size_px: expected (width, height) in pixels, got {size_px!r}") from None
    if W < 200 or H < 200:
        raise InputError(f"size_px: expected at least 200 x 200 pixels, got {W} x {H}")
    fig = Figure(figsize=(W / _DPI, H / _DPI), dpi=_DPI, facecolor="white")
    frame = _face_frame(anatomy)
    top = 0.93
    for i, side in enumerate(("front", "left")):
        ax = fig.add_axes((0.5 * i, 0.0, 0.5, top))
        _draw_panel(ax, anatomy, _view(frame, side), side, labels=True)
        ax.set_title("front" if side == "front" else "subject's left", fontsize=11)
    fig.suptitle(title or f"{anatomy.n_muscles} muscles over the skin; {anatomy.n_tets:,} tetrahedra "
                 f"(each band as wide as its muscle)", fontsize=13)
    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI, facecolor="white")
