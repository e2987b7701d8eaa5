"""Markers in the footage: small discs where the markers project, drawn into a linear image."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["draw_markers"]


def draw_markers(image: FloatArray, centres_px: FloatArray, radii_px: FloatArray, radiance: FloatArray) -> FloatArray:
    """Paint anti-aliased discs into an image (a copy).

    Parameters
    ----------
    image : (H, W, 3) float array
        Linear radiance.
    centres_px : (k, 2) float array
        Disc centres ``(u, v)``, px, OpenCV convention (the top-left pixel's centre at (0, 0)).
    radii_px : (k,) float array
        Radii, px.
    radiance : (k, 3) float array
        Each disc's radiance.

    Returns
    -------
    (H, W, 3) float32 array

    Notes
    -----
    A pixel's coverage is ``clip(r + 0.5 - d, 0, 1)`` for the distance ``d`` from its centre to
    the disc's (a one-pixel ramp at the edge); ``I = (1 - c) I + c L``. Discs off the image are skipped.

    Examples
    --------
    >>> out = draw_markers(np.zeros((9, 9, 3)), np.array([[4.0, 4.0]]), np.array([2.0]), np.ones((1, 3)))
    >>> float(out[4, 4, 0]), float(out[4, 6, 0]), float(out[4, 7, 0]), float(out[0, 0, 0])
    (1.0, 0.5, 0.0, 0.0)
    """
    out = np.array(image, dtype=np.float32)
    C = np.asarray(centres_px, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii_px, dtype=np.float64).reshape(-1)
    L = np.asarray(radiance, dtype=np.float64).reshape(-1, 3)
    if out.ndim != 3 or out.shape[2] != 3 or r.shape[0] != C.shape[0] or L.shape[0] != C.shape[0]:
        raise InputError(f"draw_markers: expected an (H, W, 3) image and k centres, radii and radiances; got "
                         f"{out.shape}, {C.shape}, {r.shape}, {L.shape}")
    H, W = out.shape[:2]
    for (u, v), radius, colour in zip(C, r, L):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        u0, u1 = max(int(np.floor(u - radius - 1)), 0), min(int(np.ceil(u + radius + 1)), W - 1)
        v0, v1 = max(int(np.floor(v - radius - 1)), 0), min(int(np.ceil(v + radius + 1)), H - 1)
        if u0 > u1 or v0 > v1:
            continue
        uu, vv = np.meshgrid(np.arange(u0, u1 + 1), np.arange(v0, v1 + 1))
        cover = np.clip(radius + 0.5 - np.hypot(uu - u, vv - v), 0.0, 1.0)[..., None]
        patch = out[v0 : v1 + 1, u0 : u1 + 1]
        out[v0 : v1 + 1, u0 : u1 + 1] = (1.0 - cover) * patch + cover * colour
    return out
