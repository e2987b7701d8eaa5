"""Which vertices a rasterised unwrap shows: those with one of their own triangles on a pixel next to them."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..typing import BoolArray
from .cylindrical_map import TriangleRaster

__all__ = ["visible_in_raster"]


def visible_in_raster(raster: TriangleRaster) -> BoolArray:
    """Vertices the image sees: one of their own triangles covers a pixel next to them.

    Where the unwrap folds over (under the chin, inside a nostril, a lip
    curled over the other) the pixels go to one layer's triangles; the
    vertices of the layer underneath are not seen, and a flow in the image
    says nothing about them. A vertex counts as seen when a triangle it is a
    corner of covers one of the 3 x 3 pixels around its own pixel (its
    position rounded, clipped to the image).

    Parameters
    ----------
    raster : TriangleRaster
        The mesh's triangles rasterised into the image
        (:meth:`CylindricalMap.rasterise`), with ``pixels`` the (n, 2) image
        positions of its vertices.

    Returns
    -------
    (n,) bool array
        True where vertex ``j`` is seen.

    Raises
    ------
    InputError
        If ``raster`` is not a :class:`TriangleRaster`.

    Examples
    --------
    One triangle a few pixels wide: all its corners are seen.

    >>> import numpy as np
    >>> from facecap.registration.cylindrical_map import cylindrical_map
    >>> V = np.array([[-5.0, 0, 50], [5, 0, 50], [0, 8, 50]])
    >>> raster = cylindrical_map(V, centre=(0, 0, 0), size_px=32).rasterise(np.array([[0, 1, 2]]))
    >>> visible_in_raster(raster).tolist()
    [True, True, True]
    """
    if not isinstance(raster, TriangleRaster):
        raise InputError(f"raster: expected a TriangleRaster, got {type(raster).__name__}")
    pixels = raster.pixels
    h, w = raster.face.shape
    col = np.clip(np.rint(pixels[:, 0]).astype(np.int64), 0, w - 1)
    row = np.clip(np.rint(pixels[:, 1]).astype(np.int64), 0, h - 1)
    dr, dc = np.divmod(np.arange(9), 3)
    cand = raster.face[np.clip(row[:, None] + dr - 1, 0, h - 1), np.clip(col[:, None] + dc - 1, 0, w - 1)]
    corners = raster.F[np.where(cand >= 0, cand, 0)]                    # (n, 9, 3)
    own = (corners == np.arange(pixels.shape[0])[:, None, None]).any(axis=2) & (cand >= 0)
    return own.any(axis=1)
