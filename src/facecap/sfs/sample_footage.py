"""Footage onto the skin (Lo et al. 3.2, "warped to the neutral face"): what each camera saw at each sample.

Every sample (a vertex of the layer below, carried into the mocap frame) is
projected into each camera through its lens model and the linear image is read
there (bilinear, the luminance of the colour: the shading's scalar). A camera's
observation counts with a weight: 0 where the sample is hidden, outside the
image or clipped (a highlight the sensor could not hold), rising from 0 to 1 as
the view turns from grazing to frontal, since a grazing view squeezes the skin
into few pixels and its shading into the next sample's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["FootageSamples", "sample_footage", "luminance", "LUMINANCE", "CLIPPED_LEVEL"]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance of linear RGB: the scalar the shading is solved on (a grey image is used as it is)."""

CLIPPED_LEVEL = 0.98
"""A pixel at or above this share of full scale in any channel is taken as clipped."""

GRAZING_COS = (0.25, 0.6)
"""The view's cosine with the normal over which an observation's weight rises from 0 to 1 (76 to 53 degrees)."""


class FootageSamples(NamedTuple):
    """What the cameras saw at the samples of one frame.

    Attributes
    ----------
    intensity : (C, r) float64 array
        Linear luminance (0 where unseen).
    weight : (C, r) float64 array
        In [0, 1]; 0 where the camera does not see the sample or it is clipped.
    to_eye : (C, r, 3) float64 array
        Unit directions from each sample toward each camera's centre.
    clipped : (C, r) bool array
        Seen, but clipped.
    pixels : (C, r, 2) float64 array, px
        Where each sample projects (NaN where the camera does not see it).
    """

    intensity: FloatArray
    weight: FloatArray
    to_eye: FloatArray
    clipped: np.ndarray
    pixels: FloatArray


def luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) float32: the Rec. 709 luminance of a linear colour image (a grey image as it is)."""
    if image.ndim == 2:
        return image.astype(np.float32)
    if image.ndim == 3 and image.shape[2] >= 3:
        return (image[..., :3].astype(np.float32) @ LUMINANCE.astype(np.float32)).astype(np.float32)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[..., 0].astype(np.float32)
    raise InputError(f"image: expected (H, W) or (H, W, 3), got shape {image.shape}")


def sample_footage(images: Sequence[np.ndarray], cameras: Sequence[Any], points: FloatArray, normals: FloatArray,
                   visible: Sequence[np.ndarray], *, pixels: Sequence[Any] | None = None) -> FootageSamples:
    """Read each camera's linear image at each sample.

    Parameters
    ----------
    images : sequence of (H, W) or (H, W, 3) float arrays
        Linear images (1 = full scale), one per camera.
    cameras : sequence of facecap.cameras.Camera
    points : (r, 3) float array, mm
        The samples in the mocap frame.
    normals : (r, 3) float array
        Their unit normals.
    visible : sequence of (r,) bool arrays
        Whether each camera sees each sample (:meth:`facecap.cameras.RayCaster.visible`).
    pixels : sequence of (r, 2) float arrays or None, optional
        Per camera, where to read each sample instead of where it projects (:func:`~facecap.sfs.follow_skin`);
        None for a camera: its projection.

    Returns
    -------
    FootageSamples
    """
    import cv2

    X = np.asarray(points, dtype=np.float64)
    N = np.asarray(normals, dtype=np.float64)
    C, r = len(cameras), X.shape[0]
    if len(images) != C or len(visible) != C or (pixels is not None and len(pixels) != C):
        raise InputError(f"expected one image, one visibility (and one pixel array if any) per camera ({C})")
    intensity = np.zeros((C, r))
    weight = np.zeros((C, r))
    clipped = np.zeros((C, r), dtype=bool)
    to_eye = np.empty((C, r, 3))
    where = np.full((C, r, 2), np.nan)
    for c, (image, camera) in enumerate(zip(images, cameras)):
        image = np.asarray(image)
        if image.shape[:2] != (camera.height, camera.width):
            raise InputError(f"camera {camera.name!r}: image {image.shape[1]}x{image.shape[0]}, calibration "
                             f"{camera.width}x{camera.height}")
        offset = camera.centre - X
        to_eye[c] = offset / np.linalg.norm(offset, axis=1, keepdims=True)
        seen = np.asarray(visible[c], dtype=bool)
        if not seen.any():
            continue
        if pixels is not None and pixels[c] is not None:
            at = np.asarray(pixels[c], dtype=np.float32)[seen]
        else:
            at = camera.project(X[seen]).pixels.astype(np.float32)
        grey = luminance(image)
        peak = image.max(axis=2) if image.ndim == 3 else image
        # a pixel is clipped when any of the four it is read from is: dilate the clipped mask by one
        hot = cv2.dilate((peak >= CLIPPED_LEVEL).astype(np.uint8), np.ones((2, 2), np.uint8)).astype(np.float32)
        # OpenCV's remap takes maps under 32767 a side: the samples laid out in rows of 1024
        k = at.shape[0]
        rows_needed = -(-k // 1024)
        padded = np.zeros((rows_needed * 1024, 2), dtype=np.float32)
        padded[:k] = at
        map_x = padded[:, 0].reshape(rows_needed, 1024)
        map_y = padded[:, 1].reshape(rows_needed, 1024)
        value = cv2.remap(grey, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0).ravel()[:k]
        near_hot = cv2.remap(hot, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                             borderValue=0).ravel()[:k]
        rows = np.flatnonzero(seen)
        where[c, rows] = at
        intensity[c, rows] = value
        cos = np.sum(N[rows] * to_eye[c, rows], axis=1)
        lo, hi = GRAZING_COS
        s = np.clip((cos - lo) / (hi - lo), 0.0, 1.0)
        w = s * s * (3.0 - 2.0 * s)
        is_hot = near_hot > 0
        clipped[c, rows] = is_hot
        weight[c, rows] = np.where(is_hot, 0.0, w)
    return FootageSamples(intensity, weight, to_eye, clipped, where)
