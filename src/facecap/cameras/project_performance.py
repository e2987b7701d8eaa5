"""A performance projected into a camera's view: pixels, depth and visibility of every vertex in every frame."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError
from ..typing import BoolArray, FloatArray
from ..validate import as_faces
from .camera import Camera
from .ray_cast import DEFAULT_OCCLUSION_TOLERANCE_MM, RayCaster

__all__ = ["PerformanceProjection", "project_performance"]


class PerformanceProjection(NamedTuple):
    """Every vertex of every frame in one camera.

    Attributes
    ----------
    pixels : (T, n, 2) float64 array, px
    depth : (T, n) float64 array, mm
        Along the optical axis (camera z).
    visible : (T, n) bool array
        In front of the camera and inside the image, and, when faces were
        given, not hidden by the frame's own mesh.
    """

    pixels: FloatArray
    depth: FloatArray
    visible: BoolArray


def project_performance(vertices: Any, camera: Camera, *, faces: Any = None,
                        tolerance_mm: float = DEFAULT_OCCLUSION_TOLERANCE_MM,
                        progress: bool = False) -> PerformanceProjection:
    """Project a performance into a camera, with per-frame occlusion if the faces are given.

    Parameters
    ----------
    vertices : (T, n, 3) or (n, 3) array, mm
        The performance in the mocap frame (a single frame is taken as T = 1).
    camera : Camera
    faces : (m, 3) int64 array or None, default None
        Triangles; with them each frame's visibility also tests occlusion
        by that frame's mesh (one Embree build per frame: ~1 s at 700k
        vertices, 10-100 ms at 9k). Without them, ``visible`` is in front and inside the image.
    tolerance_mm : float, default 0.01
        See :meth:`RayCaster.visible`.
    progress : bool, default False
        Show a tqdm progress bar over the frames (occlusion only).

    Returns
    -------
    PerformanceProjection

    Raises
    ------
    InputError
        On a wrong shape, non-finite vertices, or faces out of range.
    """
    try:
        X = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"vertices: expected a numeric (T, n, 3) array ({exc})") from None
    if X.ndim == 2:
        X = X[None]
    if X.ndim != 3 or X.shape[2] != 3 or X.shape[1] == 0:
        raise InputError(f"vertices: expected shape (T, n, 3), got {np.shape(vertices)}")
    if not np.all(np.isfinite(X)):
        raise InputError("vertices: contains NaN or infinite values")
    projection = camera.project(X)
    visible = projection.in_image
    if faces is not None:
        F = as_faces(faces, X.shape[1], name="faces")
        visible = np.zeros(X.shape[:2], dtype=bool)
        for t in tqdm(range(X.shape[0]), unit="frame", desc="occlusion", disable=not progress, leave=False):
            visible[t] = RayCaster(X[t], F).visible(X[t], camera, tolerance_mm=tolerance_mm)
    return PerformanceProjection(projection.pixels, projection.depth, visible)
