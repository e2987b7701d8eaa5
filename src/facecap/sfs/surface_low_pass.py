"""A low-pass filter on a surface: what varies slowly across the skin, kept; fine detail, removed.

The image term of the height solve is divided by a smooth gain first: the ratio of
what the cameras saw to what the base surface with the rest frame's reflectance
predicts, low-passed over the skin. It takes out what shading of fine detail is
not (a flush that reddens a cheek, the lights' calibration error, the exposure,
the layer below's own tilt over centimetres) and leaves the lines. One implicit
heat step ``(M + tau L) u = M f`` (cotangent Laplacian ``L``, Voronoi mass ``M``)
with ``tau = sigma^2 / 2``, factorised once per mesh; weights enter as a
normalised convolution, ``smooth(w f) / smooth(w)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..mesh.factor_spd import SpdFactor
from ..mesh.laplacian import laplace_operators
from ..typing import FloatArray
from ..validate import as_faces, as_vertices

__all__ = ["SurfaceLowPass"]


class SurfaceLowPass:
    """Smooth values given at a mesh's vertices over a length ``sigma_mm``.

    Parameters
    ----------
    V : (n, 3) float array, mm
    F : (m, 3) int array
    sigma_mm : float
        About the standard deviation of the Gaussian the step resembles.
    backend : str, default 'auto'
        :class:`~facecap.mesh.factor_spd.SpdFactor`'s.

    Examples
    --------
    A constant passes unchanged:

    >>> import numpy as np
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]); F = np.array([[0, 1, 2], [1, 3, 2]])
    >>> SurfaceLowPass(V, F, 2.0)(np.full(4, 3.0)).round(12).tolist()
    [3.0, 3.0, 3.0, 3.0]
    """

    def __init__(self, V: Any, F: Any, sigma_mm: float, *, backend: str = "auto") -> None:
        V = as_vertices(V, name="V")
        F = as_faces(F, V.shape[0], name="F")
        if not np.isfinite(sigma_mm) or sigma_mm <= 0:
            raise InputError(f"sigma_mm: expected a positive length, got {sigma_mm!r}")
        ops = laplace_operators(V, F)
        self.mass = np.maximum(ops.mass, 1e-12)
        self.sigma_mm = float(sigma_mm)
        system = sp.diags(self.mass) + (0.5 * self.sigma_mm ** 2) * ops.L
        self._factor = SpdFactor(sp.csr_matrix(system), backend=backend)  # type: ignore[arg-type]

    def __call__(self, values: Any, weights: Any = None) -> FloatArray:
        """(n,) or (n, k): the smoothed values (weighted: ``smooth(w f) / smooth(w)``, NaN where no weight reaches)."""
        f = np.asarray(values, dtype=np.float64)
        column = f.ndim == 1
        F2 = f[:, None] if column else f
        if weights is None:
            out = self._factor.solve(self.mass[:, None] * F2)
        else:
            w = np.asarray(weights, dtype=np.float64).reshape(-1, 1)
            both = self._factor.solve(np.hstack([self.mass[:, None] * w * np.nan_to_num(F2), self.mass[:, None] * w]))
            top, bottom = both[:, :-1], both[:, -1:]
            out = np.where(bottom > 1e-9 * max(float(bottom.max()), 1e-300), top / np.maximum(bottom, 1e-300), np.nan)
        return out[:, 0] if column else out
