"""Every frame of a take solved for muscle activations and bone frames, each warm-started from the one before."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from .muscle_solver import MuscleFrame, MuscleSolver

__all__ = ["MuscleTake", "solve_muscles"]


@dataclass(frozen=True, eq=False)
class MuscleTake:
    """A solved take, frame-major arrays.

    Attributes
    ----------
    activations : (T, k) float64 array
    cranium, mandible : (T, 3, 4) float64 arrays, mm
    jaw_pose : (T, 3) float64 array
        ``(opening_rad, slide_left_mm, slide_right_mm)`` per frame.
    skin : (T, n_scan, 3) float64 array, mm
        The scan's vertices per frame, world.
    marker_residuals : (T, M) float64 array, mm
        NaN where a marker is missing.
    rms_mm : (T,) float64 array
    flags : tuple of tuple of str
        Per frame (:class:`MuscleFrame`).
    frames : tuple of MuscleFrame
        Everything else per frame (nodes, timings, iterations, constraint violations).
    """

    activations: FloatArray
    cranium: FloatArray
    mandible: FloatArray
    jaw_pose: FloatArray
    skin: FloatArray
    marker_residuals: FloatArray
    rms_mm: FloatArray
    flags: tuple[tuple[str, ...], ...]
    frames: tuple[MuscleFrame, ...]


def solve_muscles(anatomy: Any, marker_vertices: Any, rest_markers: Any, markers: Any, *,
                  previous: MuscleFrame | None = None, **options: Any) -> MuscleTake:
    """Solve a take frame by frame (:class:`MuscleSolver`, ``options`` go there).

    Parameters
    ----------
    anatomy : FaceAnatomy
    marker_vertices : (M,) int array
    rest_markers : (M, 3) float64 array, mm
    markers : (T, M, 3) float64 array, mm
        The take, world coordinates; NaN for missing markers.
    previous : MuscleFrame, optional
        A solved frame to start the first one from (a chunk of a longer take).

    Returns
    -------
    MuscleTake

    Raises
    ------
    InputError
        A take of the wrong shape, or what :class:`MuscleSolver` raises.
    """
    take = np.asarray(markers, dtype=np.float64)
    if take.ndim != 3 or take.shape[2] != 3 or take.shape[0] == 0:
        raise InputError(f"markers: expected shape (T, M, 3) with T >= 1, got {take.shape}")
    solver = MuscleSolver(anatomy, marker_vertices, rest_markers, **options)
    frames = []
    for t in range(take.shape[0]):
        previous = solver.solve_frame(take[t], previous)
        frames.append(previous)
    return MuscleTake(
        activations=np.stack([f.activations for f in frames]),
        cranium=np.stack([f.cranium for f in frames]),
        mandible=np.stack([f.mandible for f in frames]),
        jaw_pose=np.stack([f.jaw_pose for f in frames]),
        skin=np.stack([f.skin for f in frames]),
        marker_residuals=np.stack([f.marker_residuals for f in frames]),
        rms_mm=np.array([f.rms_mm for f in frames]),
        flags=tuple(f.flags for f in frames),
        frames=tuple(frames),
    )
