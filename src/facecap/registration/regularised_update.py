"""The update of eq. 11 (Huang et al. 2011): a mesh moved by a displacement field, Laplacian-regularised, back onto its scan."""

from __future__ import annotations

from typing import Any, Sequence

import igl
import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..mesh.factor_spd import Backend, SpdFactor
from ..mesh.laplacian import laplace_operators
from ..mesh.vertex_normals import face_normals
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices

__all__ = ["regularised_update"]

_MAX_BACKTRACKS = 1  # re-solves without the update around triangles it flipped
_MAX_REVERTS = 50  # then rounds of putting the vertices of flipped triangles back
_MAX_COT_WEIGHT = 10.0  # cotangent weights of good triangles are below 2


def regularised_update(
    V: Any,
    F: Any,
    dv: Any,
    confidence: Any,
    scan: Mesh,
    on_scan: Any,
    *,
    alpha: float = 1.0,
    constraints: Sequence[tuple[int, Any]] = (),
    constraint_weight: float = 100.0,
    scan_tree: Any = None,
    backend: Backend = "auto",
    factor: SpdFactor | None = None,
) -> FloatArray:
    """Move a mesh lying on a scan by a displacement field, smoothly, and put it back on the scan (eq. 11).

    The new vertices minimise
    ``sum_j c_j |v'_j - v_j - dv_j|^2 + alpha |L v' - L v|^2`` (plus a pull
    of each constrained vertex to its point), so the displacements are
    followed where they are trusted and carried by the Laplacian where they
    are not; the vertices on the scan are then put on their closest scan
    points. Where that would flip triangles, the displacement is dropped
    around them and the update solved again; triangles that still flip get
    their vertices put back where they were.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        The mesh now, on (or near) ``scan``.
    F : (m, 3) int64 array
        Its triangles.
    dv : (n, 3) float64 array, mm
        Wanted displacement of every vertex (0 where nothing is known).
    confidence : (n,) float64 array
        ``c_j >= 0``, the weight of each vertex's data term (1 in the paper;
        0 leaves a vertex to the Laplacian).
    scan : Mesh
        The surface the mesh lies on (triangles), mm.
    on_scan : (n,) bool array
        Vertices put back onto the scan after the solve (the others, over
        holes or beyond its border, stay where the solve puts them).
    alpha : float, default 1.0
        Laplacian weight (the paper's value), >= 0.
    constraints : sequence of (int, (3,) float array), default ()
        ``(j, p)``: vertex ``j`` pulled to the point ``p`` (mm) with weight
        ``constraint_weight`` in the data term; a vertex may appear more than once.
    constraint_weight : float, default 100.0
        Weight of each constraint relative to a data term of confidence 1, >= 0.
    scan_tree : igl.AABB, optional
        The scan's closest-point tree, ``init(scan.vertices, scan.faces)``
        already called (a caller updating many times builds it once);
        default built here.
    backend : {'auto', 'pardiso', 'scipy'}
        Sparse solver (:class:`~facecap.mesh.factor_spd.SpdFactor`).
    factor : SpdFactor, optional
        A factor to re-use (:meth:`~facecap.mesh.factor_spd.SpdFactor.refactor`) instead of
        factoring anew: a caller updating the same mesh many times keeps one, so that the
        system's analysis, the same for every update, runs once. It is left holding this
        update's system; the caller frees it. Default: a factor of this call's own, freed.

    Returns
    -------
    (n, 3) float64 array, mm
        The updated vertices, with no triangle turned over relative to ``V``
        (triangles of ``V`` with no area are not checked).

    Raises
    ------
    InputError
        If shapes disagree, a weight is negative or not finite, or a
        constraint names a vertex out of range or a point that is not a
        finite (3,) point.
    MeshError
        If ``V`` is not finite or ``F`` indexes outside it.

    Notes
    -----
    Eq. 11 of Huang et al. [1]_ with per-vertex confidences ``c_j``
    (``diag(c) + alpha L^T L`` is factorised once per call): ``L`` is the
    cotangent Laplacian of ``V`` (:func:`~facecap.mesh.laplacian.laplace_operators`)
    over its triangles with area, its edge weights clipped to +-10 so that
    slivers cannot make the system singular (good triangles' weights are
    below 2). A translation of the whole mesh (``dv`` constant) is followed
    exactly: ``L`` annihilates it. Triangles flipped by the solve and snap
    (their normal turned against the one in ``V``) lose the displacement of
    their vertices and two rings around, once; then, up to 50 times, the
    vertices of those still flipped and one ring are put back to ``V``; if
    any still flips, ``V`` is returned.

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture and
       3D scanning for high-fidelity facial performance acquisition", ACM
       SIGGRAPH 2011, section 6.2, eq. 11.

    Examples
    --------
    A patch of a plane slid along the plane by 0.3 mm follows exactly:

    >>> import numpy as np
    >>> from facecap.structures import Mesh
    >>> x, y = np.meshgrid(np.linspace(-5, 5, 11), np.linspace(-5, 5, 11))
    >>> V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    >>> a = (np.arange(10)[:, None] * 11 + np.arange(10)[None]).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 11], 1), np.stack([a + 1, a + 12, a + 11], 1)])
    >>> plane = Mesh(3 * V, F)
    >>> W = regularised_update(V, F, np.tile([0.3, 0.0, 0.0], (121, 1)), np.ones(121), plane,
    ...                        np.ones(121, dtype=bool), backend="scipy")
    >>> bool(np.allclose(W, V + [0.3, 0.0, 0.0]))
    True
    """
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    n = V.shape[0]
    dv = _as_array(dv, (n, 3), "dv")
    confidence = _as_array(confidence, (n,), "confidence")
    if np.any(confidence < 0):
        raise InputError("confidence: expected weights >= 0")
    on_scan = np.asarray(on_scan)
    if on_scan.shape != (n,) or on_scan.dtype != np.bool_:
        raise InputError(f"on_scan: expected a ({n},) bool array, got {on_scan.shape} {on_scan.dtype}")
    if not isinstance(scan, Mesh):
        raise InputError(f"scan: expected a facecap Mesh, got {type(scan).__name__}")
    alpha = as_positive(alpha, name="alpha", allow_zero=True)
    weight = as_positive(constraint_weight, name="constraint_weight", allow_zero=True)
    pulls = []
    for c, (j, p) in enumerate(constraints):
        if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= j < n:
            raise InputError(f"constraints[{c}]: vertex must be an integer in [0, {n}), got {j!r}")
        pulls.append((j, _as_array(p, (3,), f"constraints[{c}] point")))
    if scan_tree is None:
        scan_tree = igl.AABB()
        scan_tree.init(scan.vertices, scan.faces)
    return _update(V, F, dv, confidence, alpha, pulls, weight, scan_tree, (scan.vertices, scan.faces), on_scan,
                   backend, factor)


def _as_array(x: Any, shape: tuple[int, ...], name: str) -> FloatArray:
    """``x`` as a finite float64 array of the given shape, or InputError."""
    try:
        A = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a numeric {shape} array ({exc})") from None
    if A.shape != shape or not np.all(np.isfinite(A)):
        raise InputError(f"{name}: expected a finite {shape} array, got shape {A.shape}")
    return A


def _update(V: FloatArray, F: IntArray, dv: FloatArray, confidence: FloatArray, alpha: float,
            constraints: list[tuple[int, FloatArray]], weight: float, tree: Any, scan: tuple[FloatArray, IntArray],
            on_scan: BoolArray, backend: Backend, kept: SpdFactor | None) -> FloatArray:
    """Eq. 11 (confidence-weighted) plus constraints, then back onto the scan, without flipping triangles."""
    n = V.shape[0]
    before = face_normals(V, F)
    area = np.linalg.norm(before, axis=1)
    sound = area > 1e-12 * max(float(np.median(area)), 1e-300)
    L = _clamped_laplacian(V, F[sound], n)
    LtL = (L.T @ L).tocsr()
    diag = confidence.copy()
    extra = np.zeros((n, 3))
    for j, p in constraints:
        diag[j] += weight
        extra[j] += weight * p
    A = (sp.diags(diag) + alpha * LtL).tocsr()
    if kept is None:
        factor = SpdFactor(A, backend=backend)
    else:
        factor = kept
        factor.refactor(A)
    base = alpha * (LtL @ V) + extra
    step = np.ones(n)
    vertex_faces = sp.csr_matrix((np.ones(F.size), (F.ravel(), np.repeat(np.arange(F.shape[0]), 3))),
                                 shape=(n, F.shape[0]))
    try:
        for attempt in range(_MAX_BACKTRACKS + 1):
            W = _snap(factor.solve(base + confidence[:, None] * (V + step[:, None] * dv)), tree, scan, on_scan)
            flipped = sound & (np.einsum("ij,ij->i", before, face_normals(W, F)) < 0)
            if not flipped.any():
                return W
            # drop the update around the flipped triangles (their vertices and two rings) and solve again
            ring = vertex_faces[:, flipped].sum(axis=1).A1 > 0
            for _ in range(2):
                ring = (vertex_faces @ (vertex_faces[ring].sum(axis=0).A1 > 0)) > 0
            step[ring] = 0.0
    finally:
        if kept is None:
            factor.free()
    # still flipped: put those triangles' vertices (and one ring) back where they were, until none is
    for _ in range(_MAX_REVERTS):
        stuck = vertex_faces[:, flipped].sum(axis=1).A1 > 0
        stuck = (vertex_faces @ (vertex_faces[stuck].sum(axis=0).A1 > 0)) > 0
        W[stuck] = V[stuck]
        touched = np.flatnonzero(vertex_faces[stuck].sum(axis=0).A1 > 0)
        flipped = np.zeros(F.shape[0], dtype=bool)
        flipped[touched] = sound[touched] & (np.einsum("ij,ij->i", before[touched], face_normals(W, F[touched])) < 0)
        if not flipped.any():
            return W
    return V


def _clamped_laplacian(V: FloatArray, F: IntArray, n: int) -> sp.csr_matrix:
    """Cotangent Laplacian with edge weights clipped to +-_MAX_COT_WEIGHT (slivers would make eq. 11 singular)."""
    if F.shape[0] == 0:
        return sp.csr_matrix((n, n))
    L = laplace_operators(V, F).L.tocoo()
    off = L.row != L.col
    w = np.clip(-L.data[off], -_MAX_COT_WEIGHT, _MAX_COT_WEIGHT)
    rows, cols = L.row[off], L.col[off]
    W = sp.csr_matrix((w, (rows, cols)), shape=(n, n))
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def _snap(W: FloatArray, tree: Any, scan: tuple[FloatArray, IntArray], on_scan: BoolArray) -> FloatArray:
    """Vertices that were on the scan go to their closest scan point."""
    _, _, cp = tree.squared_distance(scan[0], scan[1], W)
    return np.where(on_scan[:, None], cp, W)
