"""Headless PNG plots of per-frame quantities against time (residuals, errors)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import InputError
from ..io.atomic_write import atomic_path

__all__ = ["plot_series", "draw_series"]

_DPI = 100.0


def _as_series(x: Any, T: int, *, name: str) -> np.ndarray:
    try:
        A = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a numeric (T,) or (T, M) array") from None
    if A.ndim not in (1, 2) or A.shape[0] != T:
        raise InputError(f"{name}: expected shape ({T},) or ({T}, M) to match times, got {A.shape}")
    if np.any(np.isinf(A)):
        raise InputError(f"{name}: contains infinite values (use NaN for gaps)")
    return A


def _nan_stats(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-row median, 95th percentile and maximum ignoring NaN (all-NaN rows give NaN).

    As ``np.nanmedian``, ``np.nanpercentile`` (linear interpolation) and ``np.nanmax`` compute them, from
    one sort of each row (NaN sorts last): those take 0.4 s on a 10,000-frame take of 90 markers, this 0.03.
    """
    S = np.sort(A, axis=1)
    count = np.sum(~np.isnan(A), axis=1)
    seen = count > 0
    last = np.maximum(count - 1, 0)
    rows = np.arange(A.shape[0])

    def quantile(q: float) -> np.ndarray:
        position = q * last
        below = np.floor(position).astype(np.int64)
        above = np.minimum(below + 1, last)
        low, high = S[rows, below], S[rows, above]
        value = low + (position - below) * (high - low)
        return np.where(seen, np.where(high == low, low, value), np.nan)

    return quantile(0.5), quantile(0.95), np.where(seen, S[rows, last], np.nan)


def draw_series(ax: Any, t: np.ndarray, curves: Mapping[str, np.ndarray],
                bands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> None:
    """Draw checked series on a matplotlib axes, as :func:`plot_series` draws them.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    t : (T,) float64 array
        x of every sample (s, or any unit of the axes).
    curves : mapping of str to (T,) or (T, M) float64 array
        A (T,) array as a line; a (T, M) array as its per-row median (line), median to 95th
        percentile (band) and maximum (dotted), NaN ignored. Colours ``C0``, ``C1``, ... in order.
    bands : mapping of str to ((T,), (T,)) float64 arrays, optional
        Shaded ``(lower, upper)`` bands, in the colours after the curves'.
    """
    for i, (label, A) in enumerate(curves.items()):
        colour = f"C{i}"
        if A.ndim == 1:
            ax.plot(t, A, color=colour, lw=1.2, label=label)
        else:
            med, p95, mx = _nan_stats(A)
            ax.plot(t, med, color=colour, lw=1.2, label=f"{label} (median)")
            ax.fill_between(t, med, p95, color=colour, alpha=0.25, lw=0, label=f"{label} (to p95)")
            ax.plot(t, mx, color=colour, lw=0.8, ls=":", label=f"{label} (max)")
    for j, (label, (lo_a, hi_a)) in enumerate((bands or {}).items()):
        ax.fill_between(t, lo_a, hi_a, color=f"C{len(curves) + j}", alpha=0.2, lw=0, label=label)


def plot_series(
    times: Any,
    series: Mapping[str, Any],
    path: str | os.PathLike[str],
    *,
    ylabel: str,
    title: str | None = None,
    bands: Mapping[str, tuple[Any, Any]] | None = None,
    xlabel: str = "time (s)",
    size_px: tuple[int, int] = (1200, 500),
    log_y: bool = False,
) -> None:
    """Plot one or more per-frame series against time and save a PNG.

    Parameters
    ----------
    times : (T,) float array, s
        Time of each frame, e.g. ``MarkerSequence.times``.
    series : mapping of str to (T,) or (T, M) float array
        Curves to draw, by legend label (units given by ``ylabel``); NaN marks
        a gap. A (T, M) array (e.g. the residual of each of M markers) is
        summarised per frame: its median as a line, a shaded band from the
        median up to the 95th percentile, and its maximum as a thin dotted line.
    path : str or path-like
        PNG file to write (atomically: a temporary sibling renamed on success).
    ylabel : str
        y-axis label with its unit, e.g. ``'residual (mm)'``.
    title : str or None, optional
        Plot title.
    bands : mapping of str to ((T,) array, (T,) array) or None, optional
        Extra shaded bands ``label -> (lower, upper)``, e.g. a tolerance.
    xlabel : str, optional
        x-axis label, default ``'time (s)'``.
    size_px : (int, int), optional
        Image width and height in pixels, default (1200, 500).
    log_y : bool, optional
        Logarithmic y axis; default False.

    Raises
    ------
    InputError
        If ``series`` is empty, or any series or band does not have T rows
        matching ``times``, or ``times`` is not a finite (T,) array.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> t = np.arange(120) / 60.0
    >>> out = os.path.join(tempfile.mkdtemp(), "err.png")
    >>> plot_series(t, {"mean error": np.abs(np.sin(t))}, out, ylabel="error (mm)")
    >>> os.path.exists(out)
    True
    """
    try:
        t = np.asarray(times, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("times: expected a numeric (T,) array of seconds") from None
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)):
        raise InputError(f"times: expected a finite (T,) array of seconds, got shape {t.shape}")
    T = t.size
    if not series:
        raise InputError("series: expected at least one named (T,) or (T, M) array")
    try:
        w, h = (int(s) for s in size_px)
    except (TypeError, ValueError):
        raise InputError(f"size_px: expected (width, height) in pixels, got {size_px!r}") from None
    if w < 64 or h < 64:
        raise InputError(f"size_px: expected at least 64 x 64 pixels, got {size_px!r}")
    curves = {str(k): _as_series(v, T, name=f"series[{k!r}]") for k, v in series.items()}
    extra = {}
    for k, (lo, hi) in (bands or {}).items():
        lo_a = _as_series(lo, T, name=f"bands[{k!r}] lower")
        hi_a = _as_series(hi, T, name=f"bands[{k!r}] upper")
        if lo_a.ndim != 1 or hi_a.ndim != 1:
            raise InputError(f"bands[{k!r}]: expected (T,) lower and upper arrays")
        extra[str(k)] = (lo_a, hi_a)

    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_series(ax, t, curves, extra)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if log_y:
        ax.set_yscale("log")
    if T > 1:
        ax.set_xlim(t[0], t[-1])
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=9)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI)
