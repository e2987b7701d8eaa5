"""Where each sample's skin point is in a frame's image: the layer below's projection refined by optical flow.

Lo et al. warp every frame "to the neutral face" (3.2) so that a pixel of the solve is the same
skin point in every frame. The layer below places the skin a few tenths of a millimetre off and
slides along it as the expression changes (0.3-0.5 mm on the generator's takes, 1.3-1.9 mm on an
independent case), about two pixels at 0.2 mm a pixel: enough to move a freckle or a mole's edge
under a sample, which the solve then reads as shading, and to put a line's shading on the wrong
vertex. So each camera's frame is aligned to its rest frame (where the albedo was measured) by
dense optical flow (OpenCV's DIS, Kroeger et al. 2016, with its patch mean normalisation: the
expression changes the shading), started from the motion the layer below predicts; a sample is
then read where its rest-frame pixel flows to. Where the flow disagrees with the prediction by more
than a limit (a shadow's edge or a specular highlight moving, the flow lost on a marker), the
prediction is kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["follow_skin", "FLOW_LIMIT_PX"]

FLOW_LIMIT_PX = 4.0
"""The largest correction of the layer below's projection that is trusted, pixels (about 0.8 mm at the
generator's 0.2 mm a pixel; the layer below slides 0.3-0.5 mm there)."""

_BLOCK = 8


def _encoded(grey: np.ndarray) -> np.ndarray:
    """Linear luminance as 8 bits, gamma-encoded so that the flow weighs dark skin as the eye does."""
    return np.clip(np.sqrt(np.clip(grey, 0.0, 1.0)) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _dense_guess(shape: tuple[int, int], at: FloatArray, motion: FloatArray) -> np.ndarray:
    """(H, W, 2) float32: the samples' motion averaged in 8-pixel blocks, spread to the blocks without samples."""
    import cv2

    H, W = shape
    bh, bw = -(-H // _BLOCK), -(-W // _BLOCK)
    cell = (np.clip(at[:, 1] // _BLOCK, 0, bh - 1).astype(np.int64) * bw
            + np.clip(at[:, 0] // _BLOCK, 0, bw - 1).astype(np.int64))
    count = np.bincount(cell, minlength=bh * bw)
    guess = np.zeros((bh * bw, 2), dtype=np.float32)
    if count.any():
        for k in range(2):
            guess[:, k] = np.bincount(cell, weights=motion[:, k], minlength=bh * bw) / np.maximum(count, 1)
        empty = count == 0
        if empty.any():  # the nearest block with samples (the face's own motion beyond its outline)
            from scipy.ndimage import distance_transform_edt

            nearest = distance_transform_edt(empty.reshape(bh, bw), return_distances=False, return_indices=True)
            flat = (nearest[0] * bw + nearest[1]).ravel()
            guess = guess[flat]
    coarse = guess.reshape(bh, bw, 2)
    return np.ascontiguousarray(cv2.resize(coarse, (bw * _BLOCK, bh * _BLOCK), interpolation=cv2.INTER_LINEAR)[:H, :W])


def follow_skin(rest_grey: Any, grey: Any, rest_pixels: Any, predicted_pixels: Any, *,
                limit_px: float = FLOW_LIMIT_PX) -> tuple[FloatArray, np.ndarray]:
    """Where the samples' rest-frame skin points are in another frame of the same camera.

    Parameters
    ----------
    rest_grey, grey : (H, W) float arrays
        The rest frame's and this frame's linear luminance.
    rest_pixels : (k, 2) float array, px
        Where the samples were read in the rest frame.
    predicted_pixels : (k, 2) float array, px
        Where the layer below puts them in this frame.
    limit_px : float, default :data:`FLOW_LIMIT_PX`
        Corrections larger than this are not trusted (the prediction is kept there).

    Returns
    -------
    pixels : (k, 2) float64 array, px
        Where to read the samples in this frame.
    followed : (k,) bool array
        Whether the flow's position was used (False: the prediction was kept).

    Examples
    --------
    A textured image moved by 3 pixels, predicted unmoved, is followed:

    >>> rng = np.random.default_rng(0)
    >>> import cv2
    >>> rest = cv2.GaussianBlur(rng.uniform(0.1, 0.9, (120, 160)).astype(np.float32), (0, 0), 2.0)
    >>> moved = np.roll(rest, 3, axis=1).astype(np.float32)  # 3 px to the right
    >>> at = np.c_[rng.uniform(30, 130, 50), rng.uniform(30, 90, 50)]
    >>> pixels, followed = follow_skin(rest, moved, at, at)
    >>> bool(followed.all()), round(float(np.median(pixels[:, 0] - at[:, 0])), 1)
    (True, 3.0)
    """
    import cv2

    rest_grey = np.asarray(rest_grey, dtype=np.float32)
    grey = np.asarray(grey, dtype=np.float32)
    P0 = np.asarray(rest_pixels, dtype=np.float64)
    PA = np.asarray(predicted_pixels, dtype=np.float64)
    if rest_grey.ndim != 2 or rest_grey.shape != grey.shape:
        raise InputError(f"images: expected two (H, W) images of one size, got {rest_grey.shape} and {grey.shape}")
    if P0.ndim != 2 or P0.shape[1] != 2 or P0.shape != PA.shape:
        raise InputError(f"pixels: expected two (k, 2) arrays, got {P0.shape} and {PA.shape}")
    if not np.isfinite(limit_px) or limit_px < 0:
        raise InputError(f"limit_px: expected a length >= 0, got {limit_px!r}")
    if P0.shape[0] == 0:
        return PA.copy(), np.zeros(0, dtype=bool)
    flow = _dense_guess(grey.shape, P0, PA - P0)
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setUseMeanNormalization(True)
    flow = dis.calc(_encoded(rest_grey), _encoded(grey), flow)
    # the flow at each rest pixel (bilinear), in rows of 1024 (OpenCV's maps stay under 32767 a side)
    k = P0.shape[0]
    rows = -(-k // 1024)
    padded = np.zeros((rows * 1024, 2), dtype=np.float32)
    padded[:k] = P0
    map_x, map_y = padded[:, 0].reshape(rows, 1024), padded[:, 1].reshape(rows, 1024)
    moved = np.stack([cv2.remap(flow[..., i], map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
                      .ravel()[:k] for i in range(2)], axis=1)
    pixels = P0 + moved
    followed = np.all(np.isfinite(pixels), axis=1) & (np.linalg.norm(pixels - PA, axis=1) <= limit_px)
    return np.where(followed[:, None], pixels, PA), followed
