"""A take's rest frame and head-stabilised motion, as :func:`~facecap.registration.find_marker_map` takes them.

The rest frame averaged with its neighbours (a marker missing there filled from the gap-filled take),
and at most :data:`MAX_MOTION_FRAMES` frames of the take, head-stabilised onto it: the directions the
markers may follow back to a scan's expression. ``facecap map`` and ``facecap info map.json --scan
--markers`` prepare a take this way.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import FacecapWarning, MarkerError
from ..markers.condition_take import condition_take
from ..markers.prepare_take import DEFAULT_REST_AVERAGE_S, rest_average
from ..structures import MarkerSequence
from ..typing import FloatArray

__all__ = ["rest_markers_of", "MAX_MOTION_FRAMES"]

MAX_MOTION_FRAMES = 1200
"""Frames of the take (evenly spaced, the rest frame among them) whose motion gives the directions the
markers may follow back to the scan's expression; more add time, not directions."""


def rest_markers_of(take: MarkerSequence, rest_frame: int) -> tuple[FloatArray, FloatArray]:
    """The take's rest-frame markers and its head-stabilised motion, as :func:`find_marker_map` takes them.

    Parameters
    ----------
    take : MarkerSequence
        The take, every marker.
    rest_frame : int
        The frame whose expression is nearest the scan's.

    Returns
    -------
    rest : (M, 3) float64 array, mm
        The rest frame averaged with its neighbours (each moved rigidly onto it:
        :func:`~facecap.markers.prepare_take.rest_average`, the half-width
        ``animate`` uses); a marker missing there is taken from the gap-filled
        take, NaN if it cannot be filled.
    motion : (T', M, 3) float64 array, mm
        At most :data:`MAX_MOTION_FRAMES` frames, evenly spaced and holding the
        rest frame, gap-filled and head-stabilised onto the rest frame
        (:func:`~facecap.markers.condition_take`, ``stabilize=True``, unfiltered).

    Raises
    ------
    MarkerError
        If ``rest_frame`` is outside the take.
    """
    T = take.n_frames
    if not (isinstance(rest_frame, (int, np.integer)) and 0 <= rest_frame < T):
        raise MarkerError(f"--rest-frame {rest_frame} is outside the take (0..{T - 1})", path=take.source_path)
    stride = max(1, int(np.ceil(T / MAX_MOTION_FRAMES)))
    frames = np.arange(rest_frame % stride, T, stride)
    sampled = MarkerSequence(take.positions[frames], take.labels, rate=take.rate / stride,
                             source_unit=take.source_unit, source_path=take.source_path)
    with warnings.catch_warnings():  # "left unstabilised" is news for animate, not for a map: a still head is fine
        warnings.simplefilter("ignore", FacecapWarning)
        conditioned = condition_take(sampled, rest_frame=rest_frame // stride, stabilize=True, smooth=False)
    motion = conditioned.positions
    rest = rest_average(take.positions, rest_frame, DEFAULT_REST_AVERAGE_S * take.rate)
    missing = ~np.isfinite(rest).all(axis=1)
    rest[missing] = motion[rest_frame // stride, missing]
    return rest, motion
