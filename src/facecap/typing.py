"""Array shapes used throughout facecap, stated once.

Glossary of the standard symbols used in signatures:

- ``V`` : (n, 3) float64 vertex positions, mm.
- ``F`` : (m, 3) int64 triangle vertex indices, 0-based.
- ``L`` : (n, n) sparse cotangent Laplacian (positive semi-definite sign).
- ``M`` : (n, n) sparse diagonal mass matrix (Voronoi / mixed areas), mm^2.
- ``B`` : per-marker deformation basis.
- ``W`` : weights (RBF or blendshape).
- ``T`` : frame count; ``M`` in shapes, marker count.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["FloatArray", "IntArray", "BoolArray"]

FloatArray = npt.NDArray[np.float64]
"""Float array; the docstring of each function states its shape and units."""

IntArray = npt.NDArray[np.int64]
"""Integer index array (vertex, face or frame indices), 0-based."""

BoolArray = npt.NDArray[np.bool_]
"""Boolean mask array."""
