"""Points spaced evenly in arc length along a polyline, with values carried along it."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["ResampledPolyline", "resample_polyline"]


class ResampledPolyline(NamedTuple):
    """A polyline resampled by :func:`resample_polyline`."""

    points: FloatArray
    """(count, d) float64: evenly spaced in arc length, the first and last points kept."""
    values: list[FloatArray]
    """Each given value interpolated at them, (count,) each."""
    arc: FloatArray
    """(count,) float64: the arc length at each, from 0 to the polyline's length."""


def resample_polyline(points: FloatArray, count: int, values: Sequence[FloatArray] = ()) -> ResampledPolyline:
    """``count`` points evenly spaced in arc length along a polyline, and values carried with them.

    Parameters
    ----------
    points : (m, d) float array
        The polyline's vertices in order (any dimension: image pixels, mm).
    count : int
        Points wanted, at least 2.
    values : sequence of (m,) float arrays, optional
        Per-vertex values (a width, a depth) to interpolate linearly in arc length.

    Returns
    -------
    ResampledPolyline

    Raises
    ------
    InputError
        If ``points`` is not (m, d) with m >= 2, a value is not (m,), or ``count`` < 2.

    Notes
    -----
    A point at arc length ``s`` lies on the segment that holds ``s``, linearly between its ends; a
    polyline of zero length gives ``count`` copies of its first point.

    Examples
    --------
    >>> line = resample_polyline(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]]), 4, [np.array([0.0, 1.0, 3.0])])
    >>> line.points.tolist(), line.values[0].tolist()
    ([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 2.0]], [0.0, 1.0, 2.0, 3.0])
    """
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[0] < 2:
        raise InputError(f"points: expected an (m, d) polyline with m >= 2, got shape {P.shape}")
    if int(count) != count or count < 2:
        raise InputError(f"count: expected an integer >= 2, got {count!r}")
    along = [np.asarray(v, dtype=np.float64) for v in values]
    if any(v.shape != (P.shape[0],) for v in along):
        raise InputError(f"values: expected ({P.shape[0]},) arrays, one value per vertex")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    u = np.linspace(0.0, s[-1], int(count))
    resampled = np.stack([np.interp(u, s, P[:, c]) for c in range(P.shape[1])], axis=1)
    return ResampledPolyline(resampled, [np.interp(u, s, v) for v in along], u)
