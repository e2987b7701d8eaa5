"""Per-vertex mean curvature from local quadric (height-field) fits (Cazals & Pouget 2003)."""

from __future__ import annotations

from typing import Any, Literal

import igl
import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices
from .median_edge_length import median_edge_length

__all__ = ["mean_curvature", "DEFAULT_FEATURE_THRESHOLD"]

DEFAULT_FEATURE_THRESHOLD = 0.05
"""Huang et al. 2011 (section 6.2): mean curvatures below 0.05 (here 1/mm) are set to zero."""

_CHUNK = 8192  # vertices per batched least-squares block: bounds memory at ~chunk * k * 6 floats


def mean_curvature(
    V: Any,
    F: Any,
    *,
    radius_mm: float | None = None,
    threshold: float = DEFAULT_FEATURE_THRESHOLD,
    threshold_mode: Literal["hard", "soft"] = "hard",
    max_neighbours: int = 32,
    neighbours: Any = None,
) -> FloatArray:
    """Mean curvature of each vertex from a quadric fitted to the vertices within a radius.

    For every vertex a local frame is built from its normal; the neighbours
    within ``radius_mm`` (at most ``max_neighbours``, nearest first, and only
    those whose normal faces the same side) are written as heights over the
    tangent plane and fitted in the least-squares sense by
    ``z = a x^2 + b x y + c y^2 + d x + e y + f``; the mean curvature of that
    height field at the vertex is returned. Values whose magnitude is below
    ``threshold`` are set to zero (the paper's noise threshold); with
    ``threshold_mode='soft'`` the others are moved towards zero by the
    threshold too, which keeps the feature continuous.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangles (used for the vertex normals only).
    radius_mm : float or None, default None
        Radius of the neighbourhood fitted around each vertex, mm. None takes
        2.5 times the median edge length (about 20 neighbours on a regular
        mesh).
    threshold : float, default 0.05
        Magnitudes ``|H| < threshold`` (1/mm) become 0; 0 keeps every value.
        Huang et al. use 0.05 to remove noise from the features.
    threshold_mode : {'hard', 'soft'}, default 'hard'
        ``'hard'``: ``H`` where ``|H| >= threshold``, else 0 (the paper's
        wording). ``'soft'``: ``sign(H) max(|H| - threshold, 0)``, the same
        zero set without the jump at the threshold (images of it have no
        artificial edges for an optical flow to latch onto).
    max_neighbours : int, default 32
        At most this many nearest vertices inside the radius enter a fit
        (a fixed-size, masked neighbourhood keeps the fits batched).
    neighbours : (n, k) int64 array, optional
        Candidate neighbours of every vertex, padded with -1 (or ``n``), for
        instance the k-NN lists of the same mesh in a nearby pose: skips the
        k-NN search; candidates farther than ``radius_mm`` are still left out.
        Entries outside ``[0, n)`` are padding.
        Default: the ``max_neighbours`` nearest vertices (a k-d tree search).

    Returns
    -------
    H : (n,) float64 array, 1/mm
        Mean curvature ``(k1 + k2) / 2``, positive where the surface bends away
        from its normals (everywhere on a sphere with outward normals, on a
        bump of a face whose normals point out of the face), negative in
        concavities (a furrow). 0 where fewer than 6 neighbours were found.

    Raises
    ------
    MeshError
        If ``V`` or ``F`` is malformed.
    InputError
        If ``radius_mm``, ``threshold``, ``threshold_mode``, ``max_neighbours``
        or ``neighbours`` is out of range.

    Notes
    -----
    In the local frame ``(t1, t2, n)`` of vertex ``i`` the Monge patch
    ``z(x, y)`` has mean curvature

    .. math:: H = -\\frac{(1 + z_y^2) z_{xx} - 2 z_x z_y z_{xy} + (1 + z_x^2) z_{yy}}
                         {2 (1 + z_x^2 + z_y^2)^{3/2}}

    at the origin, with ``z_xx = 2a``, ``z_xy = b``, ``z_yy = 2c``,
    ``z_x = d``, ``z_y = e``; the minus sign gives the convention above.
    The linear and constant terms absorb a slightly wrong vertex normal, as in
    Cazals & Pouget's fit [1]_. Neighbourhoods come from
    :meth:`scipy.spatial.cKDTree.query` (Euclidean, not geodesic), so the
    normal test is what keeps the other lip or eyelid out of a fit. This is
    the geometry feature ``G`` of Huang et al. [2]_, section 6.2.

    References
    ----------
    .. [1] F. Cazals, M. Pouget, "Estimating differential quantities using
       polynomial fitting of osculating jets", SGP 2003.
    .. [2] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture and
       3D scanning for high-fidelity facial performance acquisition", ACM
       SIGGRAPH 2011.

    Examples
    --------
    >>> import numpy as np
    >>> x, y = np.meshgrid(np.linspace(-5, 5, 21), np.linspace(-5, 5, 21))
    >>> V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    >>> a = (np.arange(20)[:, None] * 21 + np.arange(20)[None]).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 21], 1), np.stack([a + 1, a + 22, a + 21], 1)])
    >>> float(np.abs(mean_curvature(V, F, threshold=0.0)).max()) < 1e-9
    True
    """
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    thr = as_positive(threshold, name="threshold", allow_zero=True)
    if threshold_mode not in ("hard", "soft"):
        raise InputError(f"threshold_mode: expected 'hard' or 'soft', got {threshold_mode!r}")
    if isinstance(max_neighbours, bool) or not isinstance(max_neighbours, (int, np.integer)) or max_neighbours < 6:
        raise InputError(f"max_neighbours: expected an integer >= 6, got {max_neighbours!r}")
    if radius_mm is None:
        radius = 2.5 * median_edge_length(V, F)
        if not radius > 0:
            raise InputError("radius_mm: the mesh's median edge length is zero; give radius_mm explicitly")
    else:
        radius = as_positive(radius_mm, name="radius_mm")

    n = V.shape[0]
    k = int(min(max_neighbours, n))
    N = igl.per_vertex_normals(V, F)
    bad_normal = ~np.all(np.isfinite(N), axis=1) | (np.linalg.norm(N, axis=1) < 0.5)
    N[bad_normal] = 0.0
    if neighbours is None:
        _, idx = cKDTree(V).query(V, k=k, distance_upper_bound=radius)
        idx = idx.reshape(n, -1)
    else:
        idx = np.asarray(neighbours)
        if idx.ndim != 2 or idx.shape[0] != n or not np.issubdtype(idx.dtype, np.integer):
            raise InputError(f"neighbours: expected an ({n}, k) integer array, got {idx.shape} {idx.dtype}")
    H = np.zeros(n)
    for start in range(0, n, _CHUNK):
        rows = np.arange(start, min(start + _CHUNK, n))
        H[rows] = _fit_chunk(V, N, idx[rows], rows, radius)
    H[bad_normal] = 0.0
    if threshold_mode == "soft":
        H = np.sign(H) * np.maximum(np.abs(H) - thr, 0.0)
    elif thr > 0:
        H[np.abs(H) < thr] = 0.0
    return H


def _fit_chunk(V: FloatArray, N: FloatArray, idx: np.ndarray, centre: IntArray, radius: float) -> FloatArray:
    """Mean curvature of the vertices ``centre`` from their padded candidate lists ``idx``."""
    n = V.shape[0]
    valid = (idx >= 0) & (idx < n)
    idx = np.where(valid, idx, centre[:, None])
    nrm = N[centre]                                            # (c, 3)
    # tangent frame: t1 = normalise(n x e) for the axis e least aligned with n
    helper = np.zeros_like(nrm)
    helper[np.arange(nrm.shape[0]), np.argmin(np.abs(nrm), axis=1)] = 1.0
    t1 = np.cross(nrm, helper)
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    t2 = np.cross(nrm, t1)
    frame = np.stack([t1, t2, nrm], axis=2)                    # (c, 3, 3): columns t1, t2, n
    D = (V[idx] - V[centre][:, None, :]) * (1.0 / radius)     # (c, k, 3), dimensionless
    local = np.matmul(D, frame)                                # (c, k, 3) in (t1, t2, n)
    valid &= np.einsum("ckj,ckj->ck", D, D) <= 1.0             # inside the radius
    valid &= np.matmul(N[idx], nrm[:, :, None])[:, :, 0] > 0.0  # same side of the surface only
    local[~valid] = 0.0                                        # a zero row adds only to the count
    x, y, z = (np.ascontiguousarray(local[:, :, j]) for j in range(3))
    # normal equations of the 6-term fit from the 15 moments of (x, y) and the 6 of z
    xx, xy, yy = x * x, x * y, y * y

    def total(a: np.ndarray) -> np.ndarray:
        return a.sum(axis=1)

    m = {
        "": valid.sum(axis=1).astype(np.float64), "x": total(x), "y": total(y),
        "xx": total(xx), "xy": total(xy), "yy": total(yy),
        "xxx": total(xx * x), "xxy": total(xx * y), "xyy": total(xy * y), "yyy": total(yy * y),
        "xxxx": total(xx * xx), "xxxy": total(xx * xy), "xxyy": total(xx * yy),
        "xyyy": total(xy * yy), "yyyy": total(yy * yy),
    }
    basis = ("xx", "xy", "yy", "x", "y", "")
    M = np.stack([np.stack([m["".join(sorted(p + q))] for q in basis], axis=1) for p in basis], axis=1)
    rhs = np.stack([total(xx * z), total(xy * z), total(yy * z), total(x * z), total(y * z), total(z)], axis=1)
    ridge = 1e-9 * np.trace(M, axis1=1, axis2=2) + 1e-12
    M += ridge[:, None, None] * np.eye(6)
    coef = np.linalg.solve(M, rhs[:, :, None])[:, :, 0]
    a, b, c, d, e = coef[:, 0], coef[:, 1], coef[:, 2], coef[:, 3], coef[:, 4]
    g = 1.0 + d * d + e * e
    H = -((1.0 + e * e) * 2 * a - 2 * d * e * b + (1.0 + d * d) * 2 * c) / (2.0 * g**1.5)
    H /= radius
    H[m[""] < 6] = 0.0
    return H
