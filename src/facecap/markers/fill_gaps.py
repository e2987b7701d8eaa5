"""Fill occlusion gaps in marker trajectories: splines for short gaps, neighbour motion for long ones."""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator

from ..errors import InputError
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_marker_positions, as_positive
from .rigid_fit import rigid_fit

__all__ = ["FilledMarkers", "fill_gaps"]

_DEFAULT_GAP_S = 0.1
_DEFAULT_GAP_FRAMES = 10
_DISTANCE_SAMPLE_FRAMES = 128


class FilledMarkers(NamedTuple):
    """Result of :func:`fill_gaps`.

    Attributes
    ----------
    positions : (T, M, 3) float64 array, mm
        The take with gaps filled; samples that were present are returned
        unchanged, bit for bit. Samples that could not be filled stay NaN.
    filled_mask : (T, M) bool array
        True where a missing sample was filled.
    unfilled_mask : (T, M) bool array
        True where a sample is still missing (for instance a marker never
        seen at all, or a frame where too few neighbours were visible).
    """

    positions: FloatArray
    filled_mask: BoolArray
    unfilled_mask: BoolArray


def _runs(missing: BoolArray) -> tuple[IntArray, IntArray, IntArray]:
    """Runs of True along axis 0 of a (T, M) mask: (marker, start, stop) with stop exclusive."""
    T, M = missing.shape
    pad = np.zeros((M, T + 2), dtype=np.int8)
    pad[:, 1:-1] = missing.T
    step = np.diff(pad, axis=1)
    m_start, start = np.nonzero(step == 1)
    _, stop = np.nonzero(step == -1)
    return m_start.astype(np.int64), start.astype(np.int64), stop.astype(np.int64)


def _ranges(start: IntArray, stop: IntArray) -> tuple[IntArray, IntArray]:
    """Concatenated ``arange(start[g], stop[g])`` for every g, and the run index of each entry."""
    lengths = stop - start
    run = np.repeat(np.arange(start.size), lengths)
    offsets = np.arange(run.size) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return start[run] + offsets, run


def _frame_distances(X: FloatArray) -> FloatArray:
    """(F, M, M) distances between the markers of each frame of ``X`` (F, M, 3); NaN if missing."""
    Y = np.ascontiguousarray(X.transpose(2, 0, 1))  # per component: contiguous planes, 4x faster
    D = np.zeros((X.shape[0], X.shape[1], X.shape[1]))
    for c in range(3):
        d = Y[c][:, :, None] - Y[c][:, None, :]
        d *= d
        D += d
    return np.sqrt(D, out=D)


def _median_distances(P: FloatArray, missing: BoolArray) -> FloatArray:
    """(M, M) median over frames of the distance between markers; inf if never seen together.

    The median is taken over up to 128 evenly spaced frames plus the first
    and last frame each marker is seen in, so every seen marker takes part.
    """
    T, M = missing.shape
    seen = ~missing
    frames = [np.linspace(0, T - 1, min(T, _DISTANCE_SAMPLE_FRAMES)).round().astype(np.int64)]
    any_seen = seen.any(axis=0)
    frames.append(np.argmax(seen, axis=0)[any_seen])
    frames.append((T - 1 - np.argmax(seen[::-1], axis=0))[any_seen])
    sample = np.unique(np.concatenate(frames))
    D = np.empty((sample.size, M, M))
    for lo in range(0, sample.size, 32):  # chunks keep the (chunk, M, M, 3) difference small
        X = P[sample[lo : lo + 32]]
        D[lo : lo + 32] = _frame_distances(X)
    count = np.count_nonzero(~np.isnan(D), axis=0)
    D = np.where(count[None] > 0, D, 0.0)
    med = np.nanmedian(D, axis=0)
    return np.where(count > 0, med, np.inf)


def fill_gaps(
    positions: FloatArray,
    *,
    max_interp_gap: int | None = None,
    rate: float | None = None,
    n_neighbours: int = 6,
    interpolation: Literal["cubic", "pchip"] = "cubic",
) -> FilledMarkers:
    """Fill the gaps (NaN samples) of a marker take.

    Short interior gaps are interpolated with a cubic spline through the
    marker's own visible samples. Longer gaps, and gaps at the start or end
    of the take, are filled by carrying the marker with the rigid motion of
    its nearest visible neighbours, with the seam blended so the filled
    stretch meets the visible samples at both ends without a jump.

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        Marker positions; NaN marks a missing sample (a row with any NaN
        coordinate is treated as missing as a whole).
    max_interp_gap : int or None, optional
        Longest interior gap, in frames, filled by spline interpolation.
        None (default) means 0.1 s worth of frames, ``round(0.1 * rate)``,
        or 10 frames when ``rate`` is not given. 0.1 s is short against the
        time scale of facial motion (expressions change over 0.2-1 s), so a
        cubic through the samples around such a gap follows the curve to
        well under a tenth of a millimetre; over longer gaps a spline can
        overshoot, and the neighbours' motion is the better witness.
        0 sends every gap to the neighbour method.
    rate : float or None, optional
        Frame rate in Hz, used only for the default of ``max_interp_gap``.
    n_neighbours : int, optional
        Number of neighbours, nearest first, whose rigid motion carries a
        marker through a long gap; default 6. At least 3 must be visible in
        both the gap frame and the reference frame. Six is a compromise
        between locality (faces deform: far markers move differently) and
        robustness to noise and to neighbours' own gaps.
    interpolation : {'cubic', 'pchip'}, optional
        Spline for the short gaps: ``'cubic'`` (default,
        :class:`scipy.interpolate.CubicSpline`, C2 and the most accurate on
        smooth motion) or ``'pchip'`` (:class:`scipy.interpolate.PchipInterpolator`,
        shape-preserving, never overshoots the samples around the gap).

    Returns
    -------
    FilledMarkers
        ``positions`` (T, M, 3) mm, ``filled_mask`` (T, M) and
        ``unfilled_mask`` (T, M).

    Raises
    ------
    MarkerError
        If ``positions`` is not a (T, M, 3) array or holds infinite values.
    InputError
        If ``max_interp_gap``, ``rate``, ``n_neighbours`` or
        ``interpolation`` are out of range.

    Notes
    -----
    Long gaps. Neighbours are ranked by their median distance to the marker
    over the take (the rest configuration, independent of head motion;
    sampled on up to 128 evenly spaced frames plus the first and last frame
    each marker is seen in). For
    a gap of marker ``i`` over frames ``a..b``, the reference frame is
    ``r = a - 1`` (or ``r = b + 1`` for a gap at the start of the take).
    For each frame ``t`` the rigid motion ``(R_t, c_t)`` mapping the
    ``n_neighbours`` nearest markers visible at both ``r`` and ``t`` from
    frame ``r`` to frame ``t`` is fitted with :func:`rigid_fit`, and

    ``m_i(t) = R_t q_i(t) + c_t``,

    where ``q_i`` is the marker in the reference frame's coordinates. At
    ``r`` it is ``m_i(r)``; at the other end ``e = b + 1`` it is
    ``q_e = R_e^T (m_i(e) - c_e)``, and ``q_i(t)`` is interpolated linearly
    between the two, so the offset between the carried marker and the
    observed one is spread across the gap in the neighbours' moving frame
    and the fill joins both ends exactly. Gaps at the start or end of the
    take have one visible end and keep ``q_i`` constant. Under rigid motion
    the fill is exact. Frames where fewer than 3 usable neighbours are
    visible stay NaN.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(50.0)
    >>> P = np.stack([np.c_[np.sin(t / 10), t, 0 * t]], axis=1)  # (50, 1, 3)
    >>> P[20:24] = np.nan
    >>> out = fill_gaps(P, max_interp_gap=5)
    >>> bool(out.filled_mask[20:24, 0].all()), bool(out.unfilled_mask.any())
    (True, False)
    """
    P = as_marker_positions(positions, name="positions").copy()
    T, M, _ = P.shape
    if rate is not None:
        rate = as_positive(rate, name="rate")
    if max_interp_gap is None:
        max_gap = max(1, round(_DEFAULT_GAP_S * rate)) if rate is not None else _DEFAULT_GAP_FRAMES
    else:
        if isinstance(max_interp_gap, bool) or not isinstance(max_interp_gap, (int, np.integer)):
            raise InputError(
                f"max_interp_gap: expected an integer number of frames, got {max_interp_gap!r}"
            )
        if max_interp_gap < 0:
            raise InputError(f"max_interp_gap: expected >= 0 frames, got {max_interp_gap}")
        max_gap = int(max_interp_gap)
    is_int = isinstance(n_neighbours, (int, np.integer)) and not isinstance(n_neighbours, bool)
    if not is_int or n_neighbours < 3:
        raise InputError(f"n_neighbours: expected an integer >= 3, got {n_neighbours!r}")
    if interpolation not in ("cubic", "pchip"):
        raise InputError(f"interpolation: expected 'cubic' or 'pchip', got {interpolation!r}")

    missing = np.isnan(P).any(axis=2)
    P[missing] = np.nan
    g_marker, g_start, g_stop = _runs(missing)
    interior = (g_start > 0) & (g_stop < T)
    short = interior & (g_stop - g_start <= max_gap)
    never_seen = (g_start == 0) & (g_stop == T)
    long_ = ~short & ~never_seen

    out = P.copy()
    spline = CubicSpline if interpolation == "cubic" else PchipInterpolator
    for i in np.unique(g_marker[short]):
        mine = short & (g_marker == i)
        frames, _ = _ranges(g_start[mine], g_stop[mine])
        x = np.flatnonzero(~missing[:, i])
        out[frames, i] = spline(x.astype(np.float64), P[x, i], axis=0)(frames.astype(np.float64))

    if np.any(long_):
        D = _median_distances(P, missing)
        k = int(n_neighbours)
        for i in np.unique(g_marker[long_]):
            mine = long_ & (g_marker == i)
            start, stop = g_start[mine], g_stop[mine]
            ref = np.where(start > 0, start - 1, stop)
            two_sided = (start > 0) & (stop < T)
            frames, run = _ranges(start, stop)
            ends = stop[two_sided]
            # fit the gap frames and the far end of each two-sided gap in one batch
            all_frames = np.concatenate([frames, ends])
            all_refs = np.concatenate([ref[run], ref[two_sided]])

            order = np.argsort(D[i], kind="stable")
            cand = order[(order != i) & np.isfinite(D[i, order])]
            if cand.size < 3:
                continue
            usable = ~missing[all_frames][:, cand] & ~missing[all_refs][:, cand]
            chosen = usable & (np.cumsum(usable, axis=1) <= k)
            kk = min(k, cand.size)
            slot = np.argsort(~chosen, axis=1, kind="stable")[:, :kk]
            nbr = cand[slot]
            w = np.take_along_axis(chosen, slot, axis=1).astype(np.float64)
            src = P[all_refs[:, None], nbr]
            dst = P[all_frames[:, None], nbr]
            fit = rigid_fit(src, dst, weights=w)

            n_f = frames.size
            R, c = fit.rotation[:n_f], fit.translation[:n_f]
            q_ref = P[ref, i]  # (G, 3) marker at each gap's reference frame
            q_far = q_ref.copy()
            Re, ce = fit.rotation[n_f:], fit.translation[n_f:]
            q_e = np.einsum("gji,gj->gi", Re, P[ends, i] - ce)
            q_far[two_sided] = np.where(np.isnan(q_e), q_ref[two_sided], q_e)
            span = np.where(two_sided, stop - ref, 1).astype(np.float64)
            s = np.where(two_sided[run], (frames - ref[run]) / span[run], 0.0)
            q = q_ref[run] + s[:, None] * (q_far[run] - q_ref[run])
            out[frames, i] = np.einsum("fij,fj->fi", R, q) + c

    unfilled = np.isnan(out).any(axis=2)
    out[unfilled] = np.nan
    return FilledMarkers(positions=out, filled_mask=missing & ~unfilled, unfilled_mask=unfilled)
