"""Dense per-vertex error of a solved performance against ground truth."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from ..errors import InputError
from ..mesh.vertex_normals import vertex_normals
from ..validate import as_faces
from ..typing import FloatArray

__all__ = ["evaluate_performance", "DenseError", "RegionError"]

# Quantiles come from histograms whose bins are the float32 numbers with the low
# mantissa bits dropped: log-spaced bins obtained by a bit shift (no log()).
# Keeping 13 mantissa bits gives bins 2**-13 (0.012 %) wide in relative terms;
# the per-region histograms keep 10 bits (0.1 %), so that 20+ of them stay small.
_HIST_LO = 1e-6
_HIST_HI = 1e6
_SHIFT_ALL = 23 - 13
_SHIFT_REGION = 23 - 10
# Upper bound on frames x vertices handled at once (keeps each chunk ~100-200 MB).
_MAX_CHUNK_SAMPLES = 1 << 23


class _LogBins:
    """Bins of non-negative float32 values: 0 underflow (< 1e-6), then log bins, last overflow (> 1e6)."""

    def __init__(self, shift: int) -> None:
        self.shift = shift
        self.base = int(np.array(_HIST_LO, dtype=np.float32).view(np.int32)) >> shift
        top = int(np.array(_HIST_HI, dtype=np.float32).view(np.int32)) >> shift
        self.n_bins = top - self.base + 2

    def index(self, err32: np.ndarray) -> np.ndarray:
        """Bin of each value of a non-negative float32 array (same shape, int32)."""
        idx = (err32.view(np.int32) >> self.shift) - (self.base - 1)
        np.clip(idx, 0, self.n_bins - 1, out=idx)
        return idx

    def edges(self, b: int) -> tuple[float, float]:
        """Lower and upper value of log bin ``b`` (1 .. n_bins - 2)."""
        code = np.array([b - 1 + self.base, b + self.base], dtype=np.int32) << self.shift
        lo, hi = code.view(np.float32).astype(np.float64)
        return float(lo), float(hi)

    def quantile(self, counts: np.ndarray, q: float, vmin: float, vmax: float) -> float:
        """Quantile ``q`` (numpy's 'linear' rank ``q (N-1)``) from the bin ``counts``.

        Each order statistic is placed inside its bin by its rank among the
        bin's values (uniform spread); the result is within one bin of the
        exact value and clamped to ``[vmin, vmax]`` (exact for a constant).
        """
        total = int(counts.sum())
        if total == 0:
            return float("nan")
        rank = q * (total - 1)
        cum = np.cumsum(counts)
        out = []
        for r in (np.floor(rank), np.ceil(rank)):
            b = int(np.searchsorted(cum, r, side="right"))
            before = int(cum[b - 1]) if b > 0 else 0
            frac = (r - before + 0.5) / counts[b]
            if b == 0:
                lo, hi = vmin, min(_HIST_LO, vmax)
            elif b == self.n_bins - 1:
                lo, hi = max(_HIST_HI, vmin), vmax
            else:
                lo, hi = self.edges(b)
            out.append(lo + frac * (hi - lo))
        w = rank - np.floor(rank)
        v = (1.0 - w) * out[0] + w * out[1]
        return float(min(max(v, vmin), vmax))


_BINS_ALL = _LogBins(_SHIFT_ALL)
_BINS_REGION = _LogBins(_SHIFT_REGION)


@dataclass(frozen=True)
class RegionError:
    """Error statistics over the vertices of one region, all frames.

    Parameters
    ----------
    n_vertices : int
        Vertices in the region (after ``vertex_mask``).
    mean_mm, p95_mm, max_mm : float
        Mean, 95th percentile and maximum Euclidean error, mm.
    """

    n_vertices: int
    mean_mm: float
    p95_mm: float
    max_mm: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary of the fields."""
        return {
            "n_vertices": int(self.n_vertices),
            "mean_mm": float(self.mean_mm),
            "p95_mm": float(self.p95_mm),
            "max_mm": float(self.max_mm),
        }


@dataclass(frozen=True, eq=False)
class DenseError:
    """Per-vertex Euclidean error of a performance against ground truth.

    The summary statistics run over every (frame, vertex) pair of the
    evaluated vertices (those in ``vertex_mask``).

    Parameters
    ----------
    mean_mm, median_mm, p95_mm, max_mm : float
        Mean, median, 95th percentile and maximum error, mm.
    diagonal_mm : float
        Bounding-box diagonal of the truth's first frame (all vertices), mm;
        the ``*_pct`` properties are relative to it.
    max_frame, max_vertex : int
        Where the maximum error occurs.
    per_frame_mean_mm, per_frame_max_mm : (T,) float64 array, mm
        Mean and maximum error of each frame.
    per_vertex_mean_mm : (n,) float64 array, mm
        Mean error of each vertex over all frames (every vertex, masked or not,
        so that it can be painted on the mesh).
    regions : mapping of str to RegionError
        Statistics per named region; empty when no regions were given.
    n_frames, n_vertices : int
        Frames T and evaluated vertices (after the mask).
    across_mean_mm, along_mean_mm : float or None
        With the faces given: the mean of each error's part across the skin (its component along
        the truth's vertex normal, absolute; for errors small against the surface's curvature,
        the distance to the true surface) and of its length along the skin (the rest), over the
        same samples as ``mean_mm``; None without faces.
    """

    mean_mm: float
    median_mm: float
    p95_mm: float
    max_mm: float
    diagonal_mm: float
    max_frame: int
    max_vertex: int
    per_frame_mean_mm: FloatArray = field(repr=False)
    per_frame_max_mm: FloatArray = field(repr=False)
    per_vertex_mean_mm: FloatArray = field(repr=False)
    regions: Mapping[str, RegionError] = field(default_factory=dict)
    n_frames: int = 0
    n_vertices: int = 0
    across_mean_mm: float | None = None
    along_mean_mm: float | None = None

    def _pct(self, value_mm: float) -> float:
        return 100.0 * value_mm / self.diagonal_mm if self.diagonal_mm > 0 else float("nan")

    @property
    def mean_pct(self) -> float:
        """Mean error as a percentage of ``diagonal_mm``."""
        return self._pct(self.mean_mm)

    @property
    def median_pct(self) -> float:
        """Median error as a percentage of ``diagonal_mm``."""
        return self._pct(self.median_mm)

    @property
    def p95_pct(self) -> float:
        """95th-percentile error as a percentage of ``diagonal_mm``."""
        return self._pct(self.p95_mm)

    @property
    def max_pct(self) -> float:
        """Maximum error as a percentage of ``diagonal_mm``."""
        return self._pct(self.max_mm)

    def to_dict(self, *, per_vertex: bool = False) -> dict[str, Any]:
        """JSON-ready dictionary (plain floats, ints and lists).

        Parameters
        ----------
        per_vertex : bool, optional
            Include ``per_vertex_mean_mm`` (n numbers); default False.
        """

        def num(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        out: dict[str, Any] = {
            "n_frames": int(self.n_frames),
            "n_vertices": int(self.n_vertices),
            "diagonal_mm": num(self.diagonal_mm),
            "mean_mm": num(self.mean_mm),
            "median_mm": num(self.median_mm),
            "p95_mm": num(self.p95_mm),
            "max_mm": num(self.max_mm),
            "mean_pct": num(self.mean_pct),
            "median_pct": num(self.median_pct),
            "p95_pct": num(self.p95_pct),
            "max_pct": num(self.max_pct),
            "max_frame": int(self.max_frame),
            "max_vertex": int(self.max_vertex),
            "per_frame_mean_mm": [num(x) for x in self.per_frame_mean_mm],
            "per_frame_max_mm": [num(x) for x in self.per_frame_max_mm],
            "regions": {k: r.to_dict() for k, r in self.regions.items()},
        }
        if self.across_mean_mm is not None:
            out["across_mean_mm"] = num(self.across_mean_mm)
            out["along_mean_mm"] = num(self.along_mean_mm)
        if per_vertex:
            out["per_vertex_mean_mm"] = [num(x) for x in self.per_vertex_mean_mm]
        return out


def _as_frames(X: Any, *, name: str) -> np.ndarray:
    """View ``X`` as (T, n, 3) without copying (memmaps stay memmaps)."""
    A = X if isinstance(X, np.ndarray) else np.asarray(X)
    if not (np.issubdtype(A.dtype, np.floating) or np.issubdtype(A.dtype, np.integer)):
        raise InputError(f"{name}: expected a numeric (T, n, 3) array, got dtype {A.dtype}")
    if A.ndim == 2:
        A = A[None]
    if A.ndim != 3 or A.shape[2] != 3 or A.shape[0] < 1 or A.shape[1] < 1:
        raise InputError(f"{name}: expected shape (T, n, 3) or (n, 3), got {np.shape(X)}")
    return A


def evaluate_performance(
    result_vertices: Any,
    truth_vertices: Any,
    *,
    region_labels: Any = None,
    region_names: Sequence[str] | None = None,
    vertex_mask: Any = None,
    chunk_frames: int = 256,
    faces: Any = None,
) -> DenseError:
    """Per-vertex Euclidean error of a solved performance against ground truth.

    Parameters
    ----------
    result_vertices : (T, n, 3) float array, mm
        Solved vertex positions; may be a read-only ``np.memmap`` (float32 or
        float64) of many GB: it is read ``chunk_frames`` frames at a time.
        A single frame (n, 3) is accepted as T = 1.
    truth_vertices : (T, n, 3) float array, mm
        Ground-truth positions, same shape (may also be a memmap).
    region_labels : (n,) int array or None, optional
        Region of each vertex (0, 1, ...); negative labels belong to no region.
        Default None: no per-region statistics.
    region_names : sequence of str or None, optional
        Name of each region label (``region_names[k]`` names label k).
        Default None: ``'region_<k>'``.
    vertex_mask : (n,) bool array or None, optional
        Vertices included in the statistics (e.g. excluding eyeballs).
        Default None: every vertex.
    faces : (m, 3) int array or None, optional
        The mesh's triangles: each error is then also split across the skin (along the truth's
        vertex normals) and along it (``across_mean_mm``, ``along_mean_mm``).
    chunk_frames : int, optional
        Most frames read at once; default 256. It is further capped so that a
        chunk holds at most ~8 million vertex samples (~100-200 MB per array).

    Returns
    -------
    DenseError
        Summary (mean, median, p95, max, also as % of the truth's frame-0
        bounding-box diagonal), per-frame mean/max, per-vertex mean and
        per-region mean/p95/max.

    Raises
    ------
    InputError
        If the shapes differ or are not (T, n, 3), an array holds NaN or
        infinite values, or the labels/mask/names do not fit n vertices.

    Notes
    -----
    The error of vertex i at frame t is :math:`e_{ti} = \\|x_{ti} - y_{ti}\\|_2`.
    Differences are taken in float32 when both arrays are float32 (the
    correctly rounded difference of the stored values: ~1e-7 relative error)
    and in float64 otherwise; sums are accumulated in float64. Means and
    maxima are therefore exact to that precision. The median and p95 come
    from histograms with log-spaced bins (float32 values with their low
    mantissa bits dropped) between 1e-6 and 1e6 mm: bins 2^-13 (0.012 %)
    wide for the overall statistics and 2^-10 (0.1 %) for the regions, so
    they lie within one bin of numpy's ``'linear'`` percentile while memory
    stays independent of T. They are clamped to the exact minimum and
    maximum, so a constant error is reported exactly.

    Examples
    --------
    >>> import numpy as np
    >>> truth = np.zeros((4, 10, 3))
    >>> res = evaluate_performance(truth + [3.0, 4.0, 0.0], truth)
    >>> res.mean_mm, res.median_mm, res.p95_mm, res.max_mm
    (5.0, 5.0, 5.0, 5.0)
    """
    R = _as_frames(result_vertices, name="result_vertices")
    G = _as_frames(truth_vertices, name="truth_vertices")
    if R.shape != G.shape:
        raise InputError(
            f"result_vertices and truth_vertices: expected the same shape, got {R.shape} and {G.shape}"
        )
    T, n, _ = R.shape
    try:
        chunk = int(chunk_frames)
    except (TypeError, ValueError):
        raise InputError(f"chunk_frames: expected a positive integer, got {chunk_frames!r}") from None
    if chunk < 1:
        raise InputError(f"chunk_frames: expected a positive integer, got {chunk_frames!r}")
    chunk = max(1, min(chunk, _MAX_CHUNK_SAMPLES // n))

    if vertex_mask is None:
        mask = np.ones(n, dtype=bool)
    else:
        mask = np.asarray(vertex_mask)
        if mask.shape != (n,) or mask.dtype != np.bool_:
            raise InputError(
                f"vertex_mask: expected a ({n},) bool array, got shape {mask.shape} dtype {mask.dtype}"
            )
    n_eval = int(mask.sum())
    if n_eval == 0:
        raise InputError("vertex_mask: selects no vertices")
    all_vertices = n_eval == n
    eval_idx = None if all_vertices else np.flatnonzero(mask)

    # Regions, expressed on the evaluated vertices.
    names: list[str] = []
    reg = None
    if region_labels is not None:
        labels = np.asarray(region_labels)
        if labels.shape != (n,) or not np.issubdtype(labels.dtype, np.integer):
            raise InputError(
                f"region_labels: expected a ({n},) integer array, got shape {labels.shape} dtype {labels.dtype}"
            )
        n_labels = int(labels.max()) + 1 if labels.size and labels.max() >= 0 else 0
        if region_names is None:
            names = [f"region_{k}" for k in range(n_labels)]
        else:
            names = [str(s) for s in region_names]
            if len(names) < n_labels:
                raise InputError(
                    f"region_names: expected a name for each of {n_labels} labels, got {len(names)}"
                )
            if len(set(names)) != len(names):
                raise InputError("region_names: names must be unique")
        reg = labels[mask].astype(np.int64)
    elif region_names is not None:
        raise InputError("region_names: given without region_labels")
    n_reg = len(names)
    if reg is not None:
        reg_valid = reg >= 0
        rv = reg[reg_valid]
        reg_sizes = np.bincount(rv, minlength=n_reg)[:n_reg]
        # Evaluated vertices grouped by region, for max/min by reduceat.
        reg_order = np.argsort(rv, kind="stable")
        reg_present = np.flatnonzero(reg_sizes)
        reg_starts = np.concatenate([[0], np.cumsum(reg_sizes)[:-1]])[reg_present]

    # Truth frame 0 bounding-box diagonal, all vertices.
    g0 = np.asarray(G[0], dtype=np.float64)
    if not np.all(np.isfinite(g0)):
        raise InputError("truth_vertices: frame 0 contains NaN or infinite values")
    diagonal = float(np.linalg.norm(g0.max(axis=0) - g0.min(axis=0)))
    del g0

    # float32 arithmetic when both inputs are float32 (exact differences of the
    # stored values, ~1e-7 relative error), float64 otherwise; sums in float64.
    work = np.float32 if (R.dtype == np.float32 and G.dtype == np.float32) else np.float64
    hist = np.zeros(_BINS_ALL.n_bins, dtype=np.int64)
    nb_reg = _BINS_REGION.n_bins
    reg_hist = np.zeros(n_reg * nb_reg, dtype=np.int64) if n_reg else None
    reg_index_dtype = np.int32 if n_reg * nb_reg < 2**31 else np.int64
    reg_sum = np.zeros(n_reg)
    reg_max = np.full(n_reg, -np.inf)
    reg_min = np.full(n_reg, np.inf)
    per_frame_mean = np.empty(T)
    per_frame_max = np.empty(T)
    vertex_sum = np.zeros(n)
    total_sum = 0.0
    across_sum = along_sum = 0.0
    F = None if faces is None else as_faces(faces, n, name="faces")
    gmin, gmax = np.inf, -np.inf
    max_frame = max_vertex = 0

    for t0 in range(0, T, chunk):
        t1 = min(T, t0 + chunk)
        diff = np.subtract(np.asarray(R[t0:t1]), np.asarray(G[t0:t1]), dtype=work)
        err = np.sqrt(np.einsum("tij,tij->ti", diff, diff))  # (k, n)
        if F is not None and np.all(np.isfinite(err)):
            # a vertex in no (or only degenerate) triangles has no normal: its whole error counts as along
            normals = np.nan_to_num(vertex_normals(np.asarray(G[t0:t1], dtype=np.float64), F))
            across = np.abs(np.einsum("tij,tij->ti", diff, normals))
            along = np.sqrt(np.maximum(err.astype(np.float64) ** 2 - across**2, 0.0))
            across_sum += float(across[:, eval_idx].sum()) if not all_vertices else float(across.sum())
            along_sum += float(along[:, eval_idx].sum()) if not all_vertices else float(along.sum())
        del diff
        if not np.all(np.isfinite(err)):
            bad_t, bad_i = np.argwhere(~np.isfinite(err))[0]
            which = (
                "result_vertices"
                if not np.all(np.isfinite(np.asarray(R[t0 + bad_t, bad_i])))
                else "truth_vertices"
            )
            raise InputError(
                f"{which}: NaN or infinite value at frame {t0 + bad_t}, vertex {bad_i}"
            )
        vertex_sum += err.sum(axis=0, dtype=np.float64)
        e = err if all_vertices else err[:, eval_idx]
        del err
        per_frame_mean[t0:t1] = e.mean(axis=1, dtype=np.float64)
        per_frame_max[t0:t1] = e.max(axis=1)
        total_sum += float(per_frame_mean[t0:t1].sum() * n_eval)
        cmax = float(per_frame_max[t0:t1].max())
        if cmax > gmax:
            gmax = cmax
            flat = int(np.argmax(e))
            max_frame = t0 + flat // e.shape[1]
            col = flat % e.shape[1]
            max_vertex = int(col if all_vertices else eval_idx[col])
        gmin = min(gmin, float(e.min()))
        e32 = e if e.dtype == np.float32 else e.astype(np.float32)
        hist += np.bincount(_BINS_ALL.index(e32).ravel(), minlength=_BINS_ALL.n_bins)
        if n_reg and reg_present.size:
            ev = e[:, reg_valid]
            bins = _BINS_REGION.index(e32[:, reg_valid]).astype(reg_index_dtype, copy=False)
            bins += (rv * nb_reg).astype(reg_index_dtype)[None, :]
            reg_hist += np.bincount(bins.ravel(), minlength=n_reg * nb_reg)
            del bins
            reg_sum += np.bincount(rv, weights=ev.sum(axis=0, dtype=np.float64), minlength=n_reg)[:n_reg]
            vmax = ev.max(axis=0)[reg_order]
            vmin = ev.min(axis=0)[reg_order]
            reg_max[reg_present] = np.maximum(reg_max[reg_present], np.maximum.reduceat(vmax, reg_starts))
            reg_min[reg_present] = np.minimum(reg_min[reg_present], np.minimum.reduceat(vmin, reg_starts))
            del ev
        del e, e32

    n_samples = T * n_eval
    regions: dict[str, RegionError] = {}
    for k, name in enumerate(names):
        size = int(reg_sizes[k])
        if size == 0:
            continue
        h = reg_hist[k * nb_reg:(k + 1) * nb_reg]
        regions[name] = RegionError(
            n_vertices=size,
            mean_mm=float(reg_sum[k] / (size * T)),
            p95_mm=_BINS_REGION.quantile(h, 0.95, float(reg_min[k]), float(reg_max[k])),
            max_mm=float(reg_max[k]),
        )

    return DenseError(
        mean_mm=total_sum / n_samples,
        median_mm=_BINS_ALL.quantile(hist, 0.5, gmin, gmax),
        p95_mm=_BINS_ALL.quantile(hist, 0.95, gmin, gmax),
        max_mm=gmax,
        diagonal_mm=diagonal,
        max_frame=int(max_frame),
        max_vertex=int(max_vertex),
        per_frame_mean_mm=per_frame_mean,
        per_frame_max_mm=per_frame_max,
        per_vertex_mean_mm=vertex_sum / T,
        regions=MappingProxyType(regions),
        n_frames=T,
        n_vertices=n_eval,
        across_mean_mm=None if F is None else across_sum / n_samples,
        along_mean_mm=None if F is None else along_sum / n_samples,
    )
