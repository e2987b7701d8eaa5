"""Dense optical flow between two feature images (OpenCV's DIS or Farneback), for the fine-scale registrations."""

from __future__ import annotations

from typing import Any, Literal

import cv2
import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["optical_flow"]

Flow = Literal["farneback", "dis"]
"""The dense flows :func:`optical_flow` runs."""


def optical_flow(prev: Any, nxt: Any, *, method: Flow = "dis") -> FloatArray:
    """Dense flow from one feature image to another: where each pixel's content lies in the second.

    The images hold features scaled to about ``[-1, 1]`` (curvature over its
    99th percentile, band-passed colour), mapped to grey levels
    ``128 + 127 x`` (clipped to 0..255), the range OpenCV's flows are tuned
    for.

    Parameters
    ----------
    prev, nxt : (h, w) float64 arrays
        The two images, features of about unit scale (values beyond +-1 are clipped).
    method : {'dis', 'farneback'}, default 'dis'
        ``'dis'``: Dense Inverse Search with variational refinement
        (``cv2.DISOpticalFlow``, medium preset, down to full resolution) on the
        8-bit images (rounded). ``'farneback'``: Farneback's polynomial
        expansion (``cv2.calcOpticalFlowFarneback``: pyramid scale 0.5, up to 4
        levels with the coarsest at least 8 pixels, 15-pixel windows, 3
        iterations, degree-5 neighbourhoods of sigma 1.1, Gaussian window) on
        the float images.

    Returns
    -------
    flow : (h, w, 2) float64 array, px
        ``(du, dv)`` per pixel (column, row offsets) with
        ``prev(x) ~ nxt(x + flow(x))``.

    Raises
    ------
    InputError
        If the images are not two-dimensional arrays of the same shape, or
        ``method`` is unknown.

    References
    ----------
    .. [1] T. Kroeger, R. Timofte, D. Dai, L. Van Gool, "Fast optical flow using
       dense inverse search", ECCV 2016.
    .. [2] G. Farneback, "Two-frame motion estimation based on polynomial
       expansion", SCIA 2003.

    Examples
    --------
    A pattern moved 2 pixels to the right:

    >>> import numpy as np
    >>> y, x = np.mgrid[0:64, 0:64].astype(float)
    >>> pattern = lambda x, y: 0.5 * np.sin(x / 4.0) * np.cos(y / 5.0)
    >>> flow = optical_flow(pattern(x, y), pattern(x - 2.0, y))
    >>> bool(np.allclose(np.median(flow[16:48, 16:48], axis=(0, 1)), [2.0, 0.0], atol=0.1))
    True
    """
    a = np.asarray(prev, dtype=np.float64)
    b = np.asarray(nxt, dtype=np.float64)
    if a.ndim != 2 or a.shape != b.shape:
        raise InputError(f"prev, nxt: expected two (h, w) images of the same shape, got {a.shape} and {b.shape}")
    if method == "dis":
        return _flow_dis(a, b)
    if method == "farneback":
        return _flow_farneback(a, b)
    raise InputError(f"method: expected 'dis' or 'farneback', got {method!r}")


def _to_image(x: FloatArray) -> FloatArray:
    """Features scaled to about [-1, 1] mapped to 0..255 around 128 (the range both OpenCV flows expect)."""
    return np.clip(128.0 + 127.0 * x, 0.0, 255.0)


def _flow_farneback(prev: FloatArray, nxt: FloatArray) -> FloatArray:
    """(h, w, 2) Farneback flow: prev(x) ~ nxt(x + flow(x))."""
    a = np.ascontiguousarray(_to_image(prev), dtype=np.float32)
    b = np.ascontiguousarray(_to_image(nxt), dtype=np.float32)
    levels = int(max(1, min(4, np.floor(np.log2(max(min(a.shape), 2) / 8.0)))))
    return cv2.calcOpticalFlowFarneback(a, b, None, 0.5, levels, 15, 3, 5, 1.1,
                                        cv2.OPTFLOW_FARNEBACK_GAUSSIAN).astype(np.float64)


def _flow_dis(prev: FloatArray, nxt: FloatArray) -> FloatArray:
    """(h, w, 2) DIS flow (OpenCV, medium preset at full resolution): prev(x) ~ nxt(x + flow(x))."""
    a = np.ascontiguousarray(np.rint(_to_image(prev)), dtype=np.uint8)
    b = np.ascontiguousarray(np.rint(_to_image(nxt)), dtype=np.uint8)
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setFinestScale(0)
    return dis.calc(a, b, None).astype(np.float64)
