"""The scan plan as a picture: the error against the number of scans (Huang et al. 2011, Fig. 8), and the chosen frames."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..errors import InputError
from ..io.atomic_write import atomic_path
from .render_mesh import as_size_px

__all__ = ["plot_scan_selection"]

_DPI = 100.0


def plot_scan_selection(plan: Any, path: str | os.PathLike[str], *, title: str | None = None,
                        size_px: tuple[int, int] = (1400, 820)) -> Figure:
    """Plot which frames a scan plan chose and how well they rebuild the take, and save a PNG.

    Two panels. Top, Huang et al.'s Fig. 8: the marker reconstruction error after each
    added scan (all frames' RMS, and the worst frame's, which the stopping rule compares with
    the tolerance), one point per scan on whole-number ticks, each point labelled with the
    take frame that scan adds. Bottom: every frame's reconstruction error with all the scans,
    over the take, with a line at each chosen frame (numbered in the order chosen), so one
    sees where the scans sit in the performance and which stretches they explain least.

    Parameters
    ----------
    plan : facecap.blendshapes.ScanPlan
        The plan (:func:`~facecap.blendshapes.select_scan_frames`): ``frames`` (K,) int,
        ``error_after_each`` and ``worst_frame_after_each`` (K,) mm, ``per_frame_residual``
        (T,) mm, ``tolerance_mm``, ``tolerance``, ``diagonal_mm``, ``rate`` (Hz or None),
        ``first_frame``.
    path : str or path-like
        PNG file to write (atomically: a temporary sibling renamed on success).
    title : str or None, optional
        Title over both panels; default ``'Scans needed for T frames (tolerance x% of D mm)'``.
    size_px : (int, int), optional
        Image width and height in pixels, default (1400, 820).

    Returns
    -------
    matplotlib.figure.Figure
        The figure as saved: ``axes[0]`` the error per number of scans, ``axes[1]`` the
        take, whose chosen-frame lines are the ``LineCollection`` with gid ``'chosen_frames'``.

    Raises
    ------
    InputError
        If the plan's arrays disagree in length, a chosen frame is outside the take, or
        ``size_px`` is not two sizes of at least 16 pixels.
    """
    frames = np.asarray(plan.frames, dtype=np.int64).reshape(-1)
    error = np.asarray(plan.error_after_each, dtype=np.float64).reshape(-1)
    worst = np.asarray(plan.worst_frame_after_each, dtype=np.float64).reshape(-1)
    residual = np.asarray(plan.per_frame_residual, dtype=np.float64).reshape(-1)
    K, T = frames.size, residual.size
    if K == 0 or error.size != K or worst.size != K:
        raise InputError(f"plan: expected K >= 1 frames with K errors after each, got {K} frames, "
                         f"{error.size} and {worst.size} errors")
    if T == 0 or frames.min() < 0 or frames.max() >= T:
        raise InputError(f"plan: chosen frames {frames.tolist()} are not all within the take's {T} frames")
    w, h = as_size_px(size_px)

    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, gridspec_kw={"height_ratios": [3, 2]})
    counts = np.arange(1, K + 1)
    top.plot(counts, error, "o-", color="C0", lw=1.4, ms=5, label="all frames (RMS over frames and markers)")
    top.plot(counts, worst, "s-", color="C1", lw=1.4, ms=5,
             label="worst frame (RMS over its markers): the stopping rule")
    top.axhline(plan.tolerance_mm, color="C2", ls="--", lw=1.2,
                label=f"tolerance {plan.tolerance_mm:.2f} mm ({100 * plan.tolerance:.2g}% of the "
                      f"{plan.diagonal_mm:.0f} mm marker diagonal)")
    for k, (frame, y) in enumerate(zip(frames, worst), start=1):
        top.annotate(f"+ frame {frame}", (k, y), textcoords="offset points", xytext=(6, 6), fontsize=9, color="C1")
    top.set_xlim(0.5, K + 0.5)
    top.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
    top.set_xlabel("number of scanned expressions (each point adds the frame named beside it)")
    top.set_ylabel("marker reconstruction error (mm)")
    top.set_ylim(0.0, 1.15 * max(float(worst.max()), float(plan.tolerance_mm)))
    top.grid(True, alpha=0.3)
    top.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)

    x = np.arange(T)
    bottom.plot(x, residual, color="C0", lw=1.0, label=f"each frame, rebuilt from the {K} scans (RMS over markers)")
    bottom.axhline(plan.tolerance_mm, color="C2", ls="--", lw=1.2, label="tolerance")
    y_top = 1.25 * max(float(np.nanmax(residual)) if np.isfinite(residual).any() else 0.0, float(plan.tolerance_mm))
    chosen = bottom.vlines(frames, 0.0, y_top, colors="C3", lw=1.2, label="chosen frames (in the order chosen)")
    chosen.set_gid("chosen_frames")
    # labels in up to three rows, so that frames chosen close together do not print over each other
    level, last = {}, None
    for k in np.argsort(frames, kind="stable"):
        close = last is not None and frames[k] - frames[last] < 0.07 * T
        level[k] = (level[last] + 1) % 3 if close else 0
        last = k
    for k, frame in enumerate(frames):
        bottom.annotate(f"#{k + 1}: {frame}", (frame, y_top), textcoords="offset points",
                        xytext=(3, -12 - 13 * level[k]), fontsize=9, color="C3")
    bottom.set_xlim(-0.5, T - 0.5)
    bottom.set_ylim(0.0, y_top * 1.08)
    bottom.xaxis.set_major_locator(MaxNLocator(integer=True))
    rate = getattr(plan, "rate", None)
    where = f" at {rate:g} Hz" if rate else ""
    bottom.set_xlabel(f"take frame (0-based{where}; the plan's 'frames')")
    bottom.set_ylabel("error (mm)")
    bottom.grid(True, alpha=0.3)
    bottom.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9)

    if title is None:
        title = (f"Scans needed for {T} frames (tolerance {100 * plan.tolerance:.2g}% of {plan.diagonal_mm:.0f} mm): "
                 f"frames {', '.join(map(str, frames.tolist()))}")
    fig.suptitle(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI)
    return fig
