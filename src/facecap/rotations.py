"""Rotations: the nearest one to a matrix that drifted from a rotation (a blend of two, a solved frame)."""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .typing import FloatArray

__all__ = ["nearest_rotation"]


def nearest_rotation(M: FloatArray) -> FloatArray:
    """The proper rotation nearest to each 3 x 3 matrix in the Frobenius norm (the polar factor, det +1).

    Parameters
    ----------
    M : (..., 3, 3) float array
        One matrix or a stack: a linear blend of rotations, a deformation gradient, a matrix that
        drifted by round-off.

    Returns
    -------
    (..., 3, 3) float64 array
        ``U diag(1, 1, d) V^T`` from the SVD ``M = U S V^T``, with ``d = sign(det(U V^T))`` (``+1`` where
        that determinant is 0), so a reflection is never returned.

    Raises
    ------
    InputError
        If ``M`` is not (..., 3, 3) or holds a value that is not finite.

    Notes
    -----
    Of all rotations ``R``, this one minimises ``||R - M||_F`` (Higham 1988); for ``M`` a rotation it is
    ``M`` itself, to round-off.

    Examples
    --------
    >>> import numpy as np
    >>> c, s = np.cos(0.3), np.sin(0.3)
    >>> R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    >>> bool(np.allclose(nearest_rotation(1.1 * R), R))
    True
    """
    A = np.asarray(M, dtype=np.float64)
    if A.ndim < 2 or A.shape[-2:] != (3, 3):
        raise InputError(f"expected (..., 3, 3) matrices, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise InputError("expected finite matrices, got NaN or infinity")
    U, _, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= np.where(d == 0, 1.0, d)[..., None]
    return U @ Vt
