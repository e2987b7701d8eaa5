"""Image values as floats, and the sRGB transfer curve both ways.

Footage is read as stored (:func:`~facecap.cameras.read_image`,
:func:`~facecap.cameras.open_footage`); a stage that computes with intensities
says which it wants: :func:`image_to_float` keeps the file's encoding (sRGB
for 8-bit PNG/JPEG and ordinary video), :func:`srgb_to_linear` decodes it to
linear light (what a shading model such as Lo et al.'s Phong fit needs).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["image_to_float", "srgb_to_linear", "linear_to_srgb"]


def image_to_float(image: Any) -> np.ndarray:
    """Scale an image to float32: integers divided by their type's maximum, floats kept.

    Parameters
    ----------
    image : array
        ``uint8`` (/255), ``uint16`` (/65535), or a float type (returned as float32, unscaled).

    Returns
    -------
    (same shape) float32 array
        In [0, 1] for integer input; the encoding (sRGB or linear) is unchanged.

    Raises
    ------
    InputError
        For other dtypes (bool, signed or wider integers).

    Examples
    --------
    >>> import numpy as np
    >>> image_to_float(np.array([0, 255], dtype=np.uint8)).tolist()
    [0.0, 1.0]
    """
    A = np.asarray(image)
    if A.dtype == np.uint8 or A.dtype == np.uint16:
        return A.astype(np.float32) / np.float32(np.iinfo(A.dtype).max)
    if np.issubdtype(A.dtype, np.floating):
        return A.astype(np.float32, copy=False)
    raise InputError(f"image: expected uint8, uint16 or float values, got {A.dtype}")


def _float_of(values: Any) -> np.ndarray:
    """``values`` as float64 where they are float64 (a computation's), float32 otherwise (an image's)."""
    A = np.asarray(values)
    return A if A.dtype == np.float64 else A.astype(np.float32)


def srgb_to_linear(values: Any) -> np.ndarray:
    """Decode sRGB-encoded values in [0, 1] to linear light (IEC 61966-2-1).

    Parameters
    ----------
    values : array of float in [0, 1]

    Returns
    -------
    (same shape) float array
        float64 for float64 values, float32 for any other (an image's).

    Notes
    -----
    ``c / 12.92`` for ``c <= 0.04045``, else ``((c + 0.055) / 1.055) ** 2.4``.
    """
    c = _float_of(values)
    t = c.dtype.type
    return np.where(c <= 0.04045, c / t(12.92), ((c + t(0.055)) / t(1.055)) ** t(2.4)).astype(c.dtype)


def linear_to_srgb(values: Any) -> np.ndarray:
    """Encode linear values in [0, 1] as sRGB (the inverse of :func:`srgb_to_linear`).

    Returns float64 for float64 values, float32 for any other.

    Notes
    -----
    ``12.92 c`` for ``c <= 0.0031308``, else ``1.055 c ** (1 / 2.4) - 0.055``.
    """
    c = _float_of(values)
    t = c.dtype.type
    positive = np.maximum(c, 0)
    return np.where(c <= 0.0031308, t(12.92) * c, t(1.055) * positive ** t(1 / 2.4) - t(0.055)).astype(c.dtype)
