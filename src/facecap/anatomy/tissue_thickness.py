"""Facial soft-tissue thickness at landmarks (forensic tissue-depth tables) and over the skin.

The numbers are the mean soft-tissue depths, in mm, of adult White males of
normal build from the tissue-depth table of Rhine & Campbell (1980), the table
used in forensic facial reconstruction (see ``docs/anatomy.md`` for the
landmark definitions and the caveats). Between the landmarks the thickness is
the harmonic interpolation over the skin surface (``L t = 0`` with the
landmark values fixed), which is smooth, stays within the range of the
landmark values (maximum principle), and needs no tuning.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError
from ..mesh import laplace_operators
from ..typing import FloatArray

__all__ = ["TISSUE_DEPTH_MM", "MIN_TISSUE_MM", "tissue_thickness"]

TISSUE_DEPTH_MM: dict[str, float] = {
    # midline
    "mid_forehead": 4.25,       # frontal region, same as the frontal eminence
    "supraglabella": 4.25,
    "glabella": 5.25,
    "nasion": 6.50,
    "rhinion": 3.00,            # end of the nasal bones
    "mid_philtrum": 10.00,
    "labrale_superius": 9.75,   # upper lip margin
    "labrale_inferius": 10.00,  # lower lip margin
    "supramentale": 10.75,      # chin-lip fold
    "pogonion": 11.25,          # mental eminence
    "menton": 7.25,             # beneath the chin
    # bilateral (applied to _L and _R)
    "frontal_eminence": 4.25,
    "supraorbital": 8.25,
    "suborbital": 5.75,
    "lateral_orbit": 10.00,
    "zygomatic": 12.25,         # inferior malar
    "zygomatic_arch": 7.25,     # midway along the arch
    "supraglenoid": 8.50,
    "gonion": 11.50,
    "supra_m2": 22.00,
    "occlusal_line": 18.25,
    "sub_m2": 16.00,
}
"""Soft-tissue depth (mm) at each landmark that the forensic table lists; bilateral names without the side."""

MIN_TISSUE_MM = 3.0
"""Thinnest soft tissue allowed anywhere (eyelids, nose, rim): keeps every tetrahedron layer non-degenerate."""


def landmark_depth(name: str) -> float | None:
    """Table depth of a named landmark (``'gonion_L'`` -> the 'gonion' entry), or None."""
    if name in TISSUE_DEPTH_MM:
        return TISSUE_DEPTH_MM[name]
    base = name[:-2] if name.endswith(("_L", "_R")) else name
    return TISSUE_DEPTH_MM.get(base)


def tissue_thickness(V: FloatArray, F: Any, vertices: Any, depths: Any) -> FloatArray:
    """Harmonic interpolation of landmark depths over a triangle mesh.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Skin vertices.
    F : (m, 3) int64 array
        Skin triangles (one connected piece).
    vertices : (k,) int array
        Vertices with a known depth (distinct).
    depths : (k,) float array, mm
        The depth at each of them.

    Returns
    -------
    (n,) float64 array, mm
        Thickness at every vertex: ``depths`` at ``vertices``, the discrete
        harmonic function with those values elsewhere (Neumann boundary).

    Raises
    ------
    InputError
        If the indices are out of range or repeated, or the depths not positive.

    Notes
    -----
    Solves ``L_uu t_u = -L_uk t_k`` with the cotangent Laplacian ``L``; by the
    discrete maximum principle (on meshes without badly obtuse triangles) the
    result lies between the smallest and largest landmark depth.
    """
    idx = np.asarray(vertices, dtype=np.int64)
    d = np.asarray(depths, dtype=np.float64)
    n = V.shape[0]
    if idx.ndim != 1 or idx.shape != d.shape or idx.size == 0:
        raise InputError(f"vertices, depths: expected two (k,) arrays, got {idx.shape} and {d.shape}")
    if idx.min() < 0 or idx.max() >= n or np.unique(idx).size != idx.size:
        raise InputError("vertices: expected distinct vertex indices in range")
    if not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise InputError("depths: expected positive finite depths (mm)")
    L = laplace_operators(V, F).L.tocsr()
    known = np.zeros(n, dtype=bool)
    known[idx] = True
    free = np.flatnonzero(~known)
    t = np.zeros(n)
    t[idx] = d
    if free.size:
        Luu = L[free][:, free]
        rhs = -(L[free][:, idx] @ d)
        # a tiny diagonal shift keeps pieces without a landmark solvable (they get 0, then the floor)
        t[free] = spla.spsolve((Luu + 1e-12 * sp.identity(free.size)).tocsc(), rhs)
    return t
