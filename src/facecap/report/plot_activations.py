"""Muscle activations over a take, with the frames the solve flagged and the marker residual that flagged them."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import InputError
from ..io.atomic_write import atomic_path
from .plot_series import draw_series
from .render_mesh import as_size_px

__all__ = ["plot_activations"]

_DPI = 100.0
_NAMED = 8
"""Muscles drawn by name (the most active); the others as one median-to-p95 band."""


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges where ``mask`` is True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def plot_activations(times: Any, activations: Any, names: Sequence[str], path: str | os.PathLike[str], *,
                     flagged: Any = None, max_residual_mm: Any = None, flag_residual_mm: float | None = None,
                     title: str | None = None, caption: str | None = None,
                     size_px: tuple[int, int] = (1200, 720)) -> Figure:
    """Plot muscle activations against time and save a PNG.

    The eight most active muscles (highest mean activation over the take) are drawn by name and
    the others summarised (median to 95th percentile, and their maximum); the activation bound 1 (full activation: the solve
    keeps every activation in [0, 1]) is drawn as a line, so a curve lying on it reads as
    "this muscle at its strongest, and the markers asked for more". With ``max_residual_mm``
    a second panel shows each frame's largest marker residual against ``flag_residual_mm``;
    frames in ``flagged`` are shaded in both panels.

    Parameters
    ----------
    times : (T,) float array, s
    activations : (T, k) float array
        Activations in [0, 1] (``activations.csv`` without its frame column).
    names : sequence of k str
        Muscle names.
    path : str or path-like
        PNG file to write (atomically).
    flagged : (T,) bool array, optional
        Frames the solve flagged (shaded, labelled "flagged").
    max_residual_mm : (T,) float array, mm, optional
        Largest marker residual of each frame (NaN: not solved); adds the lower panel.
    flag_residual_mm : float, optional
        The residual above which a frame is flagged ``large_residual`` (a dashed line).
    title : str or None, optional
        Title; default ``'muscle activations'``.
    caption : str or None, optional
        Text under the plot (what the frames are, why the curves look as they do); lines split
        at ``\\n`` and wrapped to the picture's width.
    size_px : (int, int), optional
        Image size, default (1200, 720) (with a caption, 20 px more per caption line as wrapped).

    Returns
    -------
    matplotlib.figure.Figure
        The figure as saved; ``axes[0]`` the activations (its line with gid
        ``'activation_bound'`` at 1), ``axes[1]`` the residual panel when drawn.

    Raises
    ------
    InputError
        If the shapes disagree, an activation is not finite, or ``size_px`` is not two sizes of at
        least 16 pixels.
    """
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    A = np.asarray(activations, dtype=np.float64)
    T = t.size
    if A.ndim != 2 or A.shape[0] != T or A.shape[1] != len(names) or T == 0:
        raise InputError(f"activations: expected shape ({T}, {len(names)}) to match times and names, got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise InputError("activations: expected finite values")
    flags = None if flagged is None else np.asarray(flagged, dtype=bool).reshape(-1)
    if flags is not None and flags.size != T:
        raise InputError(f"flagged: expected {T} values, got {flags.size}")
    residual = None if max_residual_mm is None else np.asarray(max_residual_mm, dtype=np.float64).reshape(-1)
    if residual is not None and residual.size != T:
        raise InputError(f"max_residual_mm: expected {T} values, got {residual.size}")
    w, h = as_size_px(size_px)
    # each caption line wrapped to the picture's width (10 pt text: at most about 7.8 px a character)
    lines = [part for line in (caption.splitlines() if caption else [])
             for part in (textwrap.wrap(line, width=int(w / 7.8)) or [""])]
    h += 20 * len(lines)

    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.3]}) if residual is not None \
        else [fig.subplots()]
    ax = axes[0]
    order = np.argsort(-A.mean(axis=0), kind="stable")  # the mean: many may touch the bound, fewer stay there
    series = {names[i]: A[:, i] for i in order[:_NAMED]}
    if A.shape[1] > _NAMED:
        series[f"the other {A.shape[1] - _NAMED} muscles"] = A[:, order[_NAMED:]]
    draw_series(ax, t, series)
    ax.axhline(1.0, color="k", ls="--", lw=0.9, gid="activation_bound", label="1 = full activation (the bound)")
    ax.set_ylim(-0.03, 1.08)
    ax.set_ylabel("activation (0 relaxed, 1 full)")
    dt = float(np.median(np.diff(t))) if T > 1 else 1.0
    for axis in axes:
        for k, (lo, hi) in enumerate(_runs(flags) if flags is not None else []):
            axis.axvspan(t[lo] - 0.5 * dt, t[hi - 1] + 0.5 * dt, color="tab:gray", alpha=0.15, lw=0, zorder=0,
                         label=f"flagged ({int(flags.sum())} of {T} frames)" if k == 0 and axis is ax else None)
        axis.grid(True, alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8.5)
    if residual is not None:
        low = axes[1]
        low.plot(t, residual, color="C3", lw=1.2, label="largest marker residual")
        if flag_residual_mm is not None:
            low.axhline(flag_residual_mm, color="k", ls="--", lw=0.9,
                        label=f"{flag_residual_mm:g} mm: above it a frame is flagged large_residual")
        low.set_ylabel("marker residual (mm)")
        low.set_ylim(0.0, None)
        low.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8.5)
    axes[-1].set_xlabel("time (s)")
    if T > 1:
        axes[-1].set_xlim(t[0], t[-1])
    fig.suptitle(title or "muscle activations")
    bottom = (20 * len(lines) + 6) / h if lines else 0.0
    if lines:
        fig.text(0.5, 0.5 * bottom + 2 / h, "\n".join(lines), ha="center", va="center", fontsize=10, linespacing=1.3)
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI)
    return fig
