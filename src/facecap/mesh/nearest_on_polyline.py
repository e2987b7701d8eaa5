"""The nearest point of a polyline to each of many points, and where along the line it lies."""

from __future__ import annotations

import numpy as np

from ..typing import FloatArray

__all__ = ["nearest_on_polyline"]


def nearest_on_polyline(points: FloatArray, line: FloatArray, arc: FloatArray | None = None
                        ) -> tuple[FloatArray, FloatArray]:
    """Distance from each point to a polyline, and the arc position of its nearest point (foot).

    Each point's foot is the closest point of the closest segment (ties: the first segment);
    its position along the line is interpolated linearly in ``arc`` over that segment.

    Parameters
    ----------
    points : (p, d) float64 array, mm
        The points (``d`` is 3 for the face, any for the function).
    line : (k, d) float64 array, mm
        The polyline's vertices in order, ``k >= 2``. A segment of zero length counts as a point.
    arc : (k,) float64 array, optional
        A value at each vertex of ``line`` to interpolate at the feet (the generator's curves
        pass their arc fractions, 0 to 1). Default: the arc length from the first vertex, mm.

    Returns
    -------
    distance : (p,) float64 array, mm
        Euclidean distance from each point to the polyline.
    position : (p,) float64 array
        ``arc`` at each point's foot (mm along the line by default).

    Notes
    -----
    Dense over (p, k - 1) pairs: meant for short lines (a wrinkle's, tens of vertices) and the
    points near them. The generator's truth wrinkles and the wrinkle layer's snapping both use it.

    Examples
    --------
    >>> line = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]])
    >>> distance, position = nearest_on_polyline(np.array([[4.0, 3.0, 0.0], [12.0, 6.0, 0.0]]), line)
    >>> distance.tolist(), position.tolist()
    ([3.0, 2.0], [4.0, 16.0])
    """
    A, B = line[:-1], line[1:]
    AB = B - A
    squared_length = np.einsum("kd,kd->k", AB, AB)
    t = np.einsum("pkd,kd->pk", points[:, None, :] - A[None], AB) / np.maximum(squared_length, 1e-300)
    t = np.clip(t, 0.0, 1.0)
    foot = A[None] + t[..., None] * AB[None]
    d2 = np.einsum("pkd,pkd->pk", points[:, None, :] - foot, points[:, None, :] - foot)
    j = np.argmin(d2, axis=1)
    rows = np.arange(points.shape[0])
    if arc is None:
        step = np.sqrt(squared_length)
        start = np.concatenate([[0.0], np.cumsum(step)])[:-1]
    else:
        start, step = arc[:-1], arc[1:] - arc[:-1]
    return np.sqrt(d2[rows, j]), start[j] + t[rows, j] * step[j]
