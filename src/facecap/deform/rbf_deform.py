"""Deformation of a whole scan by a triharmonic RBF warp alone: the baseline the shell must beat."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RBFInterpolator

from ..errors import MarkerError
from ..typing import FloatArray
from ..validate import as_points, as_vertices

__all__ = ["rbf_deformation_basis"]


def rbf_deformation_basis(V: FloatArray, centres: FloatArray) -> np.ndarray:
    """Linear map from marker displacements to vertex displacements by an r^3 RBF warp.

    The warp of Bickel et al. 2007, eq. 1 (``r^3`` kernel plus a quadratic
    polynomial), interpolating the marker displacements at ``centres`` and
    evaluated at every vertex. Because the interpolant is linear in the data,
    one fit with identity data gives the whole map: vertex displacements are
    ``basis.T @ d`` for marker displacements ``d`` (K, 3). This is the
    "warp alone" deformation (also the large-scale step of Lo et al.) that
    the thin shell is compared against; unlike the shell it cannot separate
    the lips or eyelids, since it is smooth across gaps in the surface.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Points to deform (the scan's vertices).
    centres : (K, 3) float64 array, mm
        Marker positions on the scan.

    Returns
    -------
    basis : (K, n) float32 array

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> c = rng.normal(size=(12, 3)); V = rng.normal(size=(30, 3))
    >>> B = rbf_deformation_basis(V, c)
    >>> bool(np.allclose(B.T @ np.ones((12, 3)), 1.0, atol=1e-4))   # translations are kept
    True
    """
    V = as_vertices(V)
    centres = as_points(centres, name="centres")
    k = centres.shape[0]
    if k < 4:
        raise MarkerError(f"need at least 4 markers for an RBF deformation, got {k}")
    degree = 2 if k >= 10 else 1
    rbf = RBFInterpolator(centres, np.eye(k), kernel="cubic", degree=degree)
    out = np.empty((k, V.shape[0]), dtype=np.float32)
    chunk = 65536
    for start in range(0, V.shape[0], chunk):
        out[:, start : start + chunk] = rbf(V[start : start + chunk]).T
    return out
