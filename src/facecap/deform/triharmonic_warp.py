"""Mocap-to-scan correspondence space warp (Bickel et al. 2007, section 4.1)."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RBFInterpolator

from ..errors import MarkerError
from ..typing import FloatArray
from ..validate import as_points

__all__ = ["TriharmonicWarp", "check_warp_sources"]

_QUADRATIC_MIN_POINTS = 10  # a trivariate quadratic has 10 coefficients


class TriharmonicWarp:
    """Smooth space warp ``c: R^3 -> R^3`` interpolating marker-to-scan correspondences.

    ``c(x) = sum_i w_i |x - m_i|^3 + q(x)`` with a quadratic polynomial ``q``
    (Bickel et al. 2007, eq. 1), solved so that ``c(m_i) = f_i`` exactly. The
    polynomial reproduces affine motion, so no rigid pre-registration is needed;
    the triharmonic kernel ``r^3`` gives the smoothest (C^2, fairest) interpolant.

    Parameters
    ----------
    sources : (K, 3) float64 array, mm
        Marker positions in mocap space at the rest frame (the RBF centres).
    targets : (K, 3) float64 array, mm
        The corresponding points on the scan (face space).

    Raises
    ------
    MarkerError
        If fewer than 4 markers are given, or they are coplanar (no affine fit).

    Notes
    -----
    With fewer than 10 markers, or markers lying on (or within numerical noise
    of) a quadric surface, the quadratic term is not determined by the markers:
    a sheet of markers on a paraboloid leaves the polynomial free in the
    direction off the surface, and the warp would extrapolate arbitrarily. The
    polynomial then falls back to affine (degree 1), which still reproduces
    rigid and affine motion exactly; ``degree`` records the choice. Solved by
    :class:`scipy.interpolate.RBFInterpolator` with ``kernel='cubic'`` (which is
    ``r^3``) and ``smoothing=0``, i.e. exact interpolation.

    References
    ----------
    .. [1] B. Bickel et al., "Multi-Scale Capture of Facial Geometry and Motion",
       SIGGRAPH 2007, section 4.1.
    .. [2] J. Carr et al., "Reconstruction and representation of 3D objects with
       radial basis functions", SIGGRAPH 2001.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> m = rng.normal(size=(20, 3))
    >>> f = 2.0 * m + [1.0, 2.0, 3.0]          # an affine map is reproduced exactly
    >>> warp = TriharmonicWarp(m, f)
    >>> x = rng.normal(size=(5, 3))
    >>> bool(np.allclose(warp(x), 2.0 * x + [1.0, 2.0, 3.0]))
    True
    """

    def __init__(self, sources: FloatArray, targets: FloatArray) -> None:
        self.sources = check_warp_sources(sources)
        self.targets = as_points(targets, name="targets")
        k = self.sources.shape[0]
        if self.targets.shape[0] != k:
            raise MarkerError(f"targets: expected {k} points to match sources, got {self.targets.shape[0]}")
        self.degree = 2 if k >= _QUADRATIC_MIN_POINTS and _quadratic_is_determined(self.sources) else 1
        try:
            self._rbf = RBFInterpolator(self.sources, self.targets, kernel="cubic", degree=self.degree)
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise MarkerError(f"the correspondence warp could not be solved: {exc}") from None

    def __call__(self, points: FloatArray) -> FloatArray:
        """Warp points from mocap space to face space.

        Parameters
        ----------
        points : (..., 3) float64 array, mm
            NaN rows stay NaN.

        Returns
        -------
        (..., 3) float64 array, mm
        """
        P = np.asarray(points, dtype=np.float64)
        flat = P.reshape(-1, 3)
        out = np.full_like(flat, np.nan)
        ok = np.all(np.isfinite(flat), axis=1)
        if ok.any():
            out[ok] = self._rbf(flat[ok])
        return out.reshape(P.shape)

    def leave_one_out_residuals(self) -> FloatArray:
        """Distance from each target to the warp fitted without that marker.

        A marker whose scan vertex was mis-picked cannot be predicted from its
        neighbours, so its residual stands out.

        Returns
        -------
        (K,) float64 array, mm
        """
        k = self.sources.shape[0]
        residuals = np.full(k, np.nan)
        if k <= 4:
            return residuals
        degree = self.degree if k - 1 >= _QUADRATIC_MIN_POINTS else 1
        keep = np.ones(k, dtype=bool)
        for i in range(k):
            keep[i] = False
            try:
                rbf = RBFInterpolator(self.sources[keep], self.targets[keep], kernel="cubic", degree=degree)
                residuals[i] = float(np.linalg.norm(rbf(self.sources[i : i + 1])[0] - self.targets[i]))
            except (ValueError, np.linalg.LinAlgError):
                pass
            keep[i] = True
        return residuals


def check_warp_sources(sources: FloatArray) -> np.ndarray:
    """The warp's centres as a float64 (K, 3) array, or a :class:`MarkerError` if no 3D warp is defined by them.

    At least 4 markers, not coplanar or collinear: what :class:`TriharmonicWarp`
    checks first, for a caller that wants the error before it has the targets.
    """
    points = as_points(sources, name="sources")
    k = points.shape[0]
    if k < 4:
        raise MarkerError(f"need at least 4 usable markers for the correspondence warp, got {k}")
    centred = points - points.mean(axis=0)
    if np.linalg.matrix_rank(centred, tol=1e-6 * max(np.abs(centred).max(), 1e-12)) < 3:
        raise MarkerError("the rest-frame markers are coplanar or collinear: no 3D warp is defined")
    return points


def _quadratic_is_determined(points: FloatArray, *, rcond: float = 1e-6) -> bool:
    """Whether the 10 quadratic monomials are linearly independent on ``points``."""
    X = points - points.mean(axis=0)
    X = X / max(float(np.abs(X).max()), 1e-300)
    x, y, z = X.T
    P = np.stack([np.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, x * z, y * z], axis=1)
    s = np.linalg.svd(P, compute_uv=False)
    return bool(s[-1] > rcond * s[0])
