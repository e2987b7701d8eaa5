"""Removing the wrinkles a neutral scan already has: multi-scale smoothing (Bickel et al. 2007, section 5.4)."""

from __future__ import annotations

import math
import warnings
from typing import Any, Literal, NamedTuple

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..mesh.factor_spd import Backend, SpdFactor
from ..errors import FacecapWarning, InputError
from ..mesh.laplacian import laplace_operators
from ..mesh.local_frame_details import LocalFrameDetails
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices

__all__ = ["remove_wrinkles", "remove_wrinkles_arrays", "WrinkleRemoval", "DEFAULT_DETAIL_SCALE_MM",
           "DEFAULT_LARGE_SCALE_MM", "DEFAULT_SMOOTHING_STEPS"]

DEFAULT_DETAIL_SCALE_MM = 0.5
"""Default ``detail_scale_mm``: the width (heat-kernel standard deviation, mm) of the smoothing
that splits fine details (pores, fine lines) off the surface before the wrinkles are removed."""

DEFAULT_LARGE_SCALE_MM = 3.0
"""Default ``large_scale_mm``: the length (mm) of the bi-Laplacian smoothing that makes the large-scale
reference whose curvature the wrinkle-free patch keeps (None: the paper's plain steady state)."""

DEFAULT_SMOOTHING_STEPS = 3
"""Implicit Laplacian smoothing steps (Desbrun et al. 1999) that make up the detail smoothing."""

DetailSmoothing = Literal["laplacian", "bilaplacian"]

# Relative to the mean triangle area: anything smaller has no usable cotangents (as in the thin shell).
_DEGENERATE_AREA = 1e-10
# Rings outside the changed vertices that the bi-Laplacian reads: two (C1 continuity), plus one
# so that their Laplacians are complete in the cut-out patch.
_BILAPLACIAN_RINGS = 3
# The detail smoothing is carried this many kernel widths beyond those rings, so the smoothed
# surface the bi-Laplacian takes as boundary is the same as a smoothing of the whole mesh.
_SMOOTHING_REACH = 3.0


class WrinkleRemoval(NamedTuple):
    """A scan without its medium-scale wrinkles, and the layers it was made from.

    Attributes
    ----------
    vertices : (n, 3) float64 array, mm
        The result: ``base`` plus the fine details in the base's local frames
        on the changed vertices, the input exactly everywhere else.
    base : (n, 3) float64 array, mm
        The smooth surface under the details: the bi-Laplacian patch on the
        changed vertices, the detail-smoothed scan around them (the patch's
        boundary), the input beyond.
    fine_details : (n, 3) float64 array, mm
        Scan minus its detail-smoothed copy (world axes), zero where the
        smoothing did not reach.
    changed : (n,) bool array
        The vertices solved for (the region without the mesh's open
        boundaries and without closed pieces that nothing outside the region holds).
    """

    vertices: FloatArray
    base: FloatArray
    fine_details: FloatArray
    changed: BoolArray


def _as_region_mask(region_mask: Any, n: int) -> BoolArray:
    if region_mask is None:
        return np.ones(n, dtype=bool)
    mask = np.asarray(region_mask)
    if mask.dtype != np.bool_:
        raise InputError(f"region_mask: expected a boolean vertex mask, got dtype {mask.dtype}")
    if mask.ndim != 1 or mask.shape[0] != n:
        raise InputError(f"region_mask: expected one value per vertex of the mesh (length {n}), got shape {mask.shape}")
    return mask


def _usable_faces(V: FloatArray, F: IntArray) -> IntArray:
    """Triangles with three distinct corners and a usable area (degenerate ones have infinite cotangents)."""
    area2 = igl.doublearea(V, F)
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    return F[~repeated & (area2 > _DEGENERATE_AREA * max(float(np.mean(area2)), 1e-300))]


def _open_boundary_vertices(F: IntArray, n: int) -> BoolArray:
    """Vertices on an edge that only one triangle has (eyes, mouth, neck of a face scan)."""
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key, count = np.unique(edges[:, 0] * np.int64(n) + edges[:, 1], return_counts=True)  # 1-D: fast
    single = key[count == 1]
    on = np.zeros(n, dtype=bool)
    on[single // n] = True
    on[single % n] = True
    return on


def _ring_distance(adjacency: sp.csr_matrix, seed: BoolArray, rings: int) -> IntArray:
    """Graph distance in edges from ``seed`` (0 on it), up to ``rings``; ``rings + 1`` beyond."""
    distance = np.full(seed.shape[0], rings + 1, dtype=np.int64)
    distance[seed] = 0
    reached = seed.copy()
    for ring in range(1, rings + 1):
        grown = (adjacency @ reached.astype(np.float64)) > 0
        new = grown & ~reached
        distance[new] = ring
        reached |= new
    return distance


def _implicit_smoothing(X: FloatArray, L: sp.csr_matrix, mass: FloatArray, moving: BoolArray, length: float, *,
                        order: int, steps: int, backend: Backend,
                        bilaplacian: sp.csr_matrix | None = None) -> FloatArray:
    """``steps`` implicit steps ``(M + length^(2 order) / (c steps) K) X_k+1 = M X_k``, ``X`` fixed off ``moving``.

    ``K = L`` (``order=1``, ``c = 2``: the heat equation run for ``length^2 / 2``, a Gaussian of
    standard deviation ``length``) or ``K = L M^-1 L`` (``order=2``, ``c = 1``: a wave of
    wavenumber ``k`` kept by ``(1 + (length k)^4 / steps)^-steps``).
    """
    if order == 1:
        K, tau = L, length**2 / (2.0 * steps)
    else:
        K = bilaplacian if bilaplacian is not None else (L @ sp.diags(1.0 / mass) @ L).tocsr()
        tau = length**4 / steps
    mi, fi = np.flatnonzero(moving), np.flatnonzero(~moving)
    factor = SpdFactor((sp.diags(mass[mi]) + tau * K[mi][:, mi]).tocsr(), backend=backend)
    from_fixed = tau * (K[mi][:, fi] @ X[fi])
    out = X.copy()
    for _ in range(steps):
        out[mi] = factor.solve(mass[mi, None] * out[mi] - from_fixed)
    factor.free()
    return out


def remove_wrinkles_arrays(
    V: Any,
    F: Any,
    region_mask: Any = None,
    *,
    detail_scale_mm: float = DEFAULT_DETAIL_SCALE_MM,
    large_scale_mm: float | None = DEFAULT_LARGE_SCALE_MM,
    smoothing_steps: int = DEFAULT_SMOOTHING_STEPS,
    detail_smoothing: DetailSmoothing = "laplacian",
    backend: Backend = "auto",
) -> WrinkleRemoval:
    """Remove the medium-scale wrinkles of a scan in a region, keeping its fine details.

    The three steps of Bickel et al. 2007, section 5.4, on the vertices of
    ``region_mask``:

    1. fine details ``D = V - S``, with ``S`` a small amount of implicit
       Laplacian smoothing of the scan (Desbrun et al. 1999), stored in the
       local frames of ``S`` (Kobbelt et al. 1999);
    2. the wrinkles eliminated by the steady state of bi-Laplacian smoothing:
       ``L M^-1 L x = L M^-1 L R`` on the region, with the two rings of ``S``
       around it fixed, so the smooth patch meets the rest
       tangent-continuously; ``R`` is a large-scale reference (``S`` smoothed
       at ``large_scale_mm``) whose curvature the patch keeps; with
       ``large_scale_mm=None`` there is none, the paper's ``L M^-1 L x = 0``;
    3. the details added back in the local frames of the new patch.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        The neutral scan.
    F : (m, 3) int64 array
        Its triangles (consistently oriented).
    region_mask : (n,) bool array, optional
        The vertices to smooth (the wrinkle regions). Default: every vertex,
        which suits a mesh that is itself a wrinkle region cut from a scan;
        on a whole face it would flatten the nose and lips too, since the
        bi-Laplacian patch keeps only what its boundary holds. Vertices
        outside the mask are returned unchanged, bit for bit.
    detail_scale_mm : float, default :data:`DEFAULT_DETAIL_SCALE_MM` (0.5)
        Width of the detail smoothing, mm: the standard deviation ``sigma``
        of the heat kernel it approximates. Features much narrower than it
        (pores, fine lines) are kept as details; features much wider
        (the wrinkles, half-widths 1.3-3 mm) stay in the surface the
        bi-Laplacian replaces and are removed. 0 keeps no details (the
        bi-Laplacian patch alone). See Notes for the choice.
    large_scale_mm : float or None, default :data:`DEFAULT_LARGE_SCALE_MM` (3.0)
        Length ``s`` (mm) of the bi-Laplacian smoothing that makes the
        large-scale reference: shapes much wider than ``s`` (the brow, the
        forehead's curve) are kept inside the region, shapes narrower are
        removed. None: the paper's plain steady state, which keeps only what
        the region's boundary implies (exact for a quadric-like patch, but it
        flattens or bulges the face's own shape as the region grows: a smooth
        generated forehead region 40 mm tall moved 0.06 mm RMS, against
        0.02 mm with the reference). See Notes.
    smoothing_steps : int, default :data:`DEFAULT_SMOOTHING_STEPS` (3)
        Implicit steps the detail smoothing is split into (more steps: closer
        to the heat kernel's sharper fall-off between scales).
    detail_smoothing : {'laplacian', 'bilaplacian'}, default 'laplacian'
        The detail smoothing's operator: ``'laplacian'``, the paper's (and
        Desbrun et al.'s) implicit Laplacian smoothing; ``'bilaplacian'``,
        the same implicit scheme with ``L M^-1 L`` and ``tau = sigma^4 /
        steps``, a sharper split between scales (a wave kept by
        ``(1 + (sigma k)^4 / steps)^-steps``): measured on the generated
        forehead, the same wrinkle residual with 0.99 instead of 0.76
        correlation of the kept detail with the truth (see the docs).
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
        Sparse factorisation, see :class:`~facecap.mesh.factor_spd.SpdFactor`.

    Returns
    -------
    WrinkleRemoval
        ``vertices`` (the result) and the layers behind it.

    Raises
    ------
    MeshError
        If ``V`` or ``F`` is malformed.
    InputError
        If ``region_mask`` is not a boolean mask with one value per vertex,
        or an option is out of range.

    Warns
    -----
    FacecapWarning
        If a closed piece lies entirely in the region (nothing fixes it: it is
        left as it is), or nothing in the region can change.

    Notes
    -----
    The (Laplacian) smoothing solves ``(M + tau L) S_{k+1} = M S_k`` ``smoothing_steps``
    times with ``tau = sigma^2 / (2 steps)`` (``L`` the cotangent Laplacian
    and ``M`` the mixed Voronoi mass of the scan, :func:`~facecap.mesh.laplace_operators`):
    an implicit integration of the heat equation for time ``sigma^2 / 2``,
    which keeps a surface wave of wavenumber ``k`` (1/mm) by
    ``(1 + tau k^2)^-steps``, close to ``exp(-sigma^2 k^2 / 2)``. The
    details are ``1 -`` that: at the default 0.5 mm and 3 steps, about 65 %
    of a ripple 2 mm long (the finest a 1 mm mesh holds), 3-5 % of a wave
    ``2 pi w`` long for a wrinkle of half-width ``w`` = 1.5-2 mm, and up to
    ``2 sigma^2 / w^2`` (12-22 %) of the depth at a valley's round bottom
    (measured on generated wrinkles: about 9 % of their height comes back
    with the details). A larger ``sigma`` keeps more of the fine details
    and also more of the wrinkles (they come back with the details); it
    cannot keep a detail the mesh does not resolve. Vertices of the mesh's
    open boundaries (eyes, mouth, neck) stay fixed in the smoothing.

    The bi-Laplacian system (the Euler-Lagrange equation of the thin-plate
    energy, eq. 4 of the paper with ``ks = 0``) uses the operators of ``S``.
    With ``large_scale_mm=None`` its steady state ``L M^-1 L x = 0`` depends
    only on the fixed rings around the region: it removes everything inside
    that the boundary does not imply, the face's own shape included, and
    that loss grows with the region's size (about as its width to the
    fourth power; measured on the generated face, it dominates the residual).
    A departure, by measurement: the reference
    ``R = (M + s^4 L M^-1 L)^-1 M S`` (one implicit step of bi-Laplacian
    smoothing; a surface wave of wavenumber ``k`` kept by
    ``1 / (1 + (s k)^4)``) carries the large scale, and the patch solves
    ``L M^-1 L (x - R) = 0`` with ``x = S`` on the rings: the thin plate
    fills in only the difference from the reference. At ``s = 3`` mm a
    wrinkle of half-width 2 mm (``k`` about ``1 / w``) is 17 % in ``R`` and
    a shape 30 mm across 86 %. The region's vertices on an open boundary of
    the mesh, and the ring inside them, are fixed too: nothing would hold
    them otherwise.

    Units: every length is mm (a :class:`~facecap.structures.Mesh` read from a
    file in cm or m is converted to mm on reading, so the same defaults mean the
    same physical scale). Arrays in another unit need ``detail_scale_mm``
    and ``large_scale_mm`` in that unit (0.05 and 0.3 for cm); the
    bi-Laplacian steady state itself has no length in it.

    Only the region, its rings and the smoothing's reach are cut out and
    solved, so the cost follows the region, not the mesh. UV-seam duplicates
    are welded for the solve (a duplicate changes only if all its copies are
    in the region).

    References
    ----------
    .. [1] B. Bickel et al., "Multi-Scale Capture of Facial Geometry and
       Motion", SIGGRAPH 2007, section 5.4.
    .. [2] M. Desbrun, M. Meyer, P. Schroeder, A. Barr, "Implicit Fairing of
       Irregular Meshes using Diffusion and Curvature Flow", SIGGRAPH 1999.
    .. [3] L. Kobbelt, J. Vorsatz, H.-P. Seidel, "Multiresolution hierarchies
       on unstructured triangle meshes", Computational Geometry 14, 1999.

    Examples
    --------
    A valley 0.4 mm deep (half-width 2 mm) across a gently curved 30 x 30 mm
    grid (0.5 mm spacing) is removed; the vertices outside the region do not move.

    >>> x, y = np.meshgrid(np.arange(61.0) * 0.5, np.arange(61.0) * 0.5)
    >>> V = np.stack([x.ravel(), y.ravel(), (x.ravel() - 15) ** 2 / 100], 1)
    >>> q = (V[:, 1] - 15) / 2.0
    >>> valley = -0.4 * (1 - q**2) * np.exp(-q**2) * np.exp(-((V[:, 0] - 15) / 6) ** 4)
    >>> a = (np.arange(60)[:, None] * 61 + np.arange(60)[None]).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 62], 1), np.stack([a, a + 62, a + 61], 1)])
    >>> region = (np.abs(q) < 3) & (np.abs(V[:, 0] - 15) < 11)
    >>> scan = V + np.outer(valley, [0, 0, 1])
    >>> out = remove_wrinkles_arrays(scan, F, region, large_scale_mm=None)
    >>> float(np.abs(out.base[:, 2] - V[:, 2]).max()) < 0.01  # the smooth patch: the valley is gone
    True
    >>> float(np.abs(out.vertices[:, 2] - V[:, 2]).max()) < 0.05  # with the details: its part under 0.5 mm
    True
    >>> bool(np.array_equal(out.vertices[~region], scan[~region]))
    True
    """
    V = as_vertices(V)
    F = as_faces(F, V.shape[0])
    n = V.shape[0]
    mask = _as_region_mask(region_mask, n)
    sigma = as_positive(detail_scale_mm, name="detail_scale_mm", allow_zero=True)
    large_scale = None if large_scale_mm is None else as_positive(large_scale_mm, name="large_scale_mm")
    if isinstance(smoothing_steps, bool) or not isinstance(smoothing_steps, (int, np.integer)) or smoothing_steps < 1:
        raise InputError(f"smoothing_steps: expected an integer >= 1, got {smoothing_steps!r}")
    if detail_smoothing not in ("laplacian", "bilaplacian"):
        raise InputError(f"detail_smoothing: expected 'laplacian' or 'bilaplacian', got {detail_smoothing!r}")
    unchanged = WrinkleRemoval(vertices=V.copy(), base=V.copy(), fine_details=np.zeros_like(V),
                               changed=np.zeros(n, dtype=bool))

    # One vertex per position across UV seams, or each seam would act as an open boundary.
    Vw, Fw, welded_index = weld_duplicate_vertices(V, F)
    nw = Vw.shape[0]
    region = np.ones(nw, dtype=bool)
    np.logical_and.at(region, welded_index, mask)  # every copy must be in the region
    Fs = _usable_faces(Vw, Fw)
    referenced = np.zeros(nw, dtype=bool)
    referenced[Fs.ravel()] = True
    E = igl.edges(Fs)
    adjacency = sp.csr_matrix((np.ones(2 * E.shape[0]), (E.ravel(), E[:, ::-1].ravel())), shape=(nw, nw))
    open_boundary = _open_boundary_vertices(Fs, nw)
    pinned = _ring_distance(adjacency, open_boundary, 1) <= 1

    free = region & referenced & ~pinned
    # A closed piece wholly inside the region touches no fixed vertex: its system is singular.
    n_parts, part = connected_components(adjacency[free][:, free], directed=False)
    held = np.zeros(n_parts, dtype=bool)
    touches_fixed = (adjacency[free][:, ~free] @ np.ones(int((~free).sum()))) > 0
    held[part[touches_fixed]] = True
    if not held.all():
        loose = np.flatnonzero(free)[~held[part]]
        warnings.warn(f"{loose.size} vertices of the region lie on closed pieces wholly inside it; "
                      "nothing outside holds them, so they are left as they are", FacecapWarning, stacklevel=2)
        free[loose] = False
        if not free.any():
            return unchanged
    if not free.any():
        warnings.warn("remove_wrinkles: no vertex of the region can change (it is empty or all on the "
                      "mesh's open boundaries); the scan is returned unchanged", FacecapWarning, stacklevel=2)
        return unchanged

    # Cut out the region, the rings the bi-Laplacian reads and the smoothings' reach.
    edge_length = np.linalg.norm(Vw[E[:, 0]] - Vw[E[:, 1]], axis=1)
    near = free[E[:, 0]] | free[E[:, 1]]
    spacing = float(np.median(edge_length[near]))
    reach = _BILAPLACIAN_RINGS + math.ceil(_SMOOTHING_REACH * sigma / spacing)
    if detail_smoothing == "bilaplacian":  # its stencil reaches one ring further
        reach += 1
    if large_scale is not None:  # the reference's bi-Laplacian stencil (2 rings) must be complete too
        reach += 2 + math.ceil(_SMOOTHING_REACH * large_scale / spacing)
    distance = _ring_distance(adjacency, free, reach)
    support = np.flatnonzero(distance <= reach)
    local = np.full(nw, -1, dtype=np.int64)
    local[support] = np.arange(support.size)
    Fp = local[Fs[np.all(distance[Fs] <= reach, axis=1)]]
    Vp = Vw[support]
    free_p = free[support]
    distance_p = distance[support]
    open_p = open_boundary[support]

    # Step 1: the fine details, scan minus a little implicit Laplacian smoothing. Fixed: the
    # vertices whose stencil the cut does not hold whole (1 ring for L, 2 for L M^-1 L) and the
    # open boundaries.
    Sp = Vp.copy()
    if sigma > 0:
        ops = laplace_operators(Vp, Fp)
        order = 1 if detail_smoothing == "laplacian" else 2
        Sp = _implicit_smoothing(Vp, ops.L.tocsr(), ops.mass, (distance_p <= reach - order) & ~open_p,
                                 sigma, order=order, steps=smoothing_steps, backend=backend)
    details = LocalFrameDetails.encode(Vp, Sp, Fp)

    # Step 2: the steady state of bi-Laplacian smoothing, the rings around the region fixed,
    # with the bi-Laplacian of the large-scale reference as its source.
    ops = laplace_operators(Sp, Fp)
    L = ops.L.tocsr()
    bilaplacian = (L @ sp.diags(1.0 / ops.mass) @ L).tocsr()
    source = np.zeros_like(Sp)
    if large_scale is not None:
        # the reference: one implicit step of bi-Laplacian smoothing, (M + s^4 L M^-1 L) R = M S
        reference = _implicit_smoothing(Sp, L, ops.mass, (distance_p <= reach - 2) & ~open_p, large_scale,
                                        order=2, steps=1, backend=backend, bilaplacian=bilaplacian)
        source = bilaplacian @ reference
    fr, kn = np.flatnonzero(free_p), np.flatnonzero(~free_p)
    factor = SpdFactor(bilaplacian[fr][:, fr].tocsr(), backend=backend)
    Bp = Sp.copy()
    Bp[fr] = factor.solve(source[fr] - bilaplacian[fr][:, kn] @ Sp[kn])
    factor.free()

    # Step 3: the details back, in the local frames of the smooth patch.
    Rp = details.add_to(Bp)

    changed = free[welded_index]
    out = V.copy()
    out[changed] = Rp[local[welded_index[changed]]]
    in_support = local[welded_index] >= 0
    base = V.copy()
    base[in_support] = Bp[local[welded_index[in_support]]]
    fine = np.zeros_like(V)
    fine[in_support] = (Vp - Sp)[local[welded_index[in_support]]]
    return WrinkleRemoval(vertices=out, base=base, fine_details=fine, changed=changed)


def remove_wrinkles(
    mesh: Mesh,
    region_mask: Any = None,
    *,
    detail_scale_mm: float = DEFAULT_DETAIL_SCALE_MM,
    large_scale_mm: float | None = DEFAULT_LARGE_SCALE_MM,
    smoothing_steps: int = DEFAULT_SMOOTHING_STEPS,
    detail_smoothing: DetailSmoothing = "laplacian",
    backend: Backend = "auto",
) -> Mesh:
    """The scan without the wrinkles it already has in ``region_mask`` (Bickel et al. 2007, 5.4).

    Run on the neutral scan before wrinkles are synthesised (section 5.3), so
    that wrinkles already in the scan are not detected and amplified.

    Parameters
    ----------
    mesh : Mesh
        The neutral scan (mm).
    region_mask : (n,) bool array, optional
        The wrinkle regions (for a generated case, ``truth.npz``'s
        ``wrinkle_mask``); default every vertex.
    detail_scale_mm, large_scale_mm, smoothing_steps, detail_smoothing, backend
        See :func:`remove_wrinkles_arrays`.

    Returns
    -------
    Mesh
        The same mesh (topology, UVs, polygons, units) with new vertex
        positions; outside the region they are the input's, exactly.

    Raises
    ------
    InputError
        As :func:`remove_wrinkles_arrays`.
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
    result = remove_wrinkles_arrays(mesh.vertices, mesh.faces, region_mask, detail_scale_mm=detail_scale_mm,
                                    large_scale_mm=large_scale_mm, smoothing_steps=smoothing_steps,
                                    detail_smoothing=detail_smoothing, backend=backend)
    return mesh.with_vertices(result.vertices)
