"""The picture ``facecap calibrate-light`` writes beside ``lights.json``: what it found in each camera's image."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["draw_light_check"]

_OUTLINE = (60, 220, 60)  # RGB: the outline found in the image
_SPHERE = (60, 160, 255)  # the fitted sphere's own outline, projected
_HIGHLIGHT = (255, 40, 40)
_PANEL_WIDTH = 640


def _display(image: Any) -> np.ndarray:
    """Any image as (H, W, 3) uint8 for drawing: 16-bit and float as linear light, shown through sRGB."""
    from ..cameras.image_to_float import image_to_float, linear_to_srgb

    A = np.asarray(image)
    if A.ndim == 3:
        A = A[:, :, :3]
    if A.dtype != np.uint8:
        A = np.rint(np.clip(linear_to_srgb(np.clip(image_to_float(A), 0.0, 1.0)), 0.0, 1.0) * 255).astype(np.uint8)
    if A.ndim == 2:
        A = np.repeat(A[:, :, None], 3, axis=2)
    return np.ascontiguousarray(A)


def draw_light_check(first_images: Sequence[Any], cameras: Sequence[Any], calibration: Any) -> np.ndarray:
    """Each camera's first image with the outlines and highlights found in every frame, side by side.

    Parameters
    ----------
    first_images : sequence of (H, W) or (H, W, 3) arrays
        One image per camera (its first frame), as stored.
    cameras : sequence of Camera
    calibration : LightCalibration
        :func:`facecap.cameras.calibrate_light`'s result.

    Returns
    -------
    (H, W, 3) uint8 array
        RGB: the outline fitted in each image (green), the fitted sphere projected back (blue: it
        should lie on the green), each highlight (a red cross) and the camera's name; panels
        scaled to 640 px wide.
    """
    import cv2

    panels = []
    for c, (image, camera) in enumerate(zip(first_images, cameras)):
        panel = _display(image).copy()
        scale = _PANEL_WIDTH / panel.shape[1]
        panel = cv2.resize(panel, (_PANEL_WIDTH, int(round(panel.shape[0] * scale))), interpolation=cv2.INTER_AREA
                           if scale < 1 else cv2.INTER_LINEAR)
        shift = 4
        for f in range(calibration.outlines.shape[0]):
            cu, cv, a, b, angle = calibration.outlines[f, c]
            centre = (int(round((cu + 0.5) * scale * (1 << shift) - 0.5 * (1 << shift))),
                      int(round((cv + 0.5) * scale * (1 << shift) - 0.5 * (1 << shift))))
            axes = (int(round(a / 2 * scale * (1 << shift))), int(round(b / 2 * scale * (1 << shift))))
            cv2.ellipse(panel, centre, axes, float(angle), 0, 360, _OUTLINE, 1, cv2.LINE_AA, shift)
            # the fitted sphere's silhouette: points on its tangent cone from this camera, projected
            C = calibration.sphere_centres[f]
            radius = float(np.linalg.norm(calibration.ray_origins[f * len(cameras) + c] - C))
            axis = C - camera.centre
            distance = float(np.linalg.norm(axis))
            axis /= distance
            e1 = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(axis, e1)
            t = np.linspace(0, 2 * np.pi, 181)
            ring = radius * np.sqrt(1 - (radius / distance) ** 2)
            rim = (C - axis * radius ** 2 / distance + ring * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2))
            pixels = (camera.project(rim).pixels + 0.5) * scale - 0.5
            cv2.polylines(panel, [np.rint(pixels * (1 << shift)).astype(np.int32)], True, _SPHERE, 1, cv2.LINE_AA,
                          shift)
            hu, hv = (calibration.highlights[f, c] + 0.5) * scale - 0.5
            cv2.drawMarker(panel, (int(round(hu)), int(round(hv))), _HIGHLIGHT, cv2.MARKER_CROSS, 12, 1, cv2.LINE_AA)
        cv2.putText(panel, camera.name, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
        panels.append(panel)
    height = max(p.shape[0] for p in panels)
    padded = [np.pad(p, ((0, height - p.shape[0]), (0, 0), (0, 0))) for p in panels]
    return np.concatenate(padded, axis=1)
