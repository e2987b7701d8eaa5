"""Rigid iterative closest point: move a point set (markers or a mesh's vertices) onto a surface."""

from __future__ import annotations

import itertools
from typing import NamedTuple

import igl
import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..errors import InputError, MeshError, SolverError
from ..markers.rigid_fit import rigid_fit
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_points, as_positive, as_rigid_transform, as_vertices

__all__ = ["IcpResult", "rigid_icp", "rigid_icp_to_surface", "ClosestPointSurface", "check_surface_units",
           "trimmed_inliers"]

_METHODS = ("point_to_plane", "point_to_point")


class IcpResult(NamedTuple):
    """A rigid motion ``x -> rotation @ x + translation`` found by :func:`rigid_icp`.

    Attributes
    ----------
    rotation : (3, 3) float64 array
        Proper rotation (det +1).
    translation : (3,) float64 array, mm
        Translation.
    rms : float
        Root-mean-square residual of the inlier pairs at the final pose, mm:
        the distance of each moved point to the surface, less the offset.
    iterations : int
        Iterations run from the final start.
    converged : bool
        True if the last update moved no inlier by more than the tolerance.
    distances : (k,) float64 array, mm
        Distance from each moved source point to the target surface; NaN
        for NaN source rows.
    inliers : (k,) bool array
        The pairs used in the last update: finite, not on the target's
        boundary (when rejected) and within the trimmed fraction.
    """

    rotation: FloatArray
    translation: FloatArray
    rms: float
    iterations: int
    converged: bool
    distances: FloatArray
    inliers: BoolArray

    @property
    def matrix(self) -> FloatArray:
        """(4, 4) float64 homogeneous matrix of the motion."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.rotation, self.translation
        return T

    def apply(self, points: FloatArray) -> FloatArray:
        """Move (..., 3) points (mm) by this motion."""
        return np.asarray(points, dtype=np.float64) @ self.rotation.T + self.translation


class ClosestPointSurface:
    """A target triangle mesh with its closest-point trees, built once for many ICP runs.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertices.
    F : (m, 3) int64 array
        Triangles.
    reject_boundary : bool
        Keep a tree of the boundary edges, so that closest points on the
        boundary (holes, the cropped rim) can be told apart.

    Raises
    ------
    MeshError
        If the arrays are malformed or a face index is out of range.

    Notes
    -----
    Building it (libigl's AABB tree, vertex normals, boundary edges) is the
    expensive part of a rigid fit on a dense scan (about 0.8 s for 150k
    vertices); :func:`rigid_icp_to_surface` reuses it.
    """

    def __init__(self, V: FloatArray, F: IntArray, *, reject_boundary: bool) -> None:
        V = as_vertices(V, name="V")
        F = as_faces(F, V.shape[0], name="F")
        self.V, self.F = V, F
        self.tree = igl.AABB()
        self.tree.init(V, F)
        self.vertex_normals = igl.per_vertex_normals(V, F)
        self.boundary = _boundary_edges(F) if reject_boundary else np.zeros((0, 2), dtype=np.int64)
        if self.boundary.shape[0]:
            self.boundary_tree = igl.AABB()
            self.boundary_tree.init(V, self.boundary)
        # nearest-vertex search for the coarse starts, on at most ~2000 vertices (a KD-tree query far
        # from a dense surface visits many leaves), with a rim flag per vertex
        used = np.unique(F)
        self.used = used[:: max(1, used.size // 2000)]
        self.kdtree = cKDTree(V[self.used])
        self.rim_vertex = np.zeros(V.shape[0], dtype=bool)
        self.rim_vertex[self.boundary.ravel()] = True

    def nearest_vertex(self, Y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """Like :meth:`closest` but to the nearest vertex (a KD-tree query), for the coarse starts."""
        d, j = self.kdtree.query(Y)
        v = self.used[j]
        return d**2, self.vertex_normals[v], self.V[v], self.rim_vertex[v]

    def closest(self, Y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """Squared distances, unit normals and closest points on the surface, and rim flags.

        The normal at a closest point interpolates the vertex normals of its triangle, so the
        point-to-plane energy is smooth across edges (face normals make ICP cycle between faces).
        """
        sq, I, C = self.tree.squared_distance(self.V, self.F, Y)
        n = interpolated_normals(C, self.F[I], self.V, self.vertex_normals)
        on_rim = np.zeros(Y.shape[0], dtype=bool)
        if self.boundary.shape[0]:
            sq_rim, _, _ = self.boundary_tree.squared_distance(self.V, self.boundary, Y)
            d, d_rim = np.sqrt(sq), np.sqrt(sq_rim)
            on_rim = d_rim - d <= 1e-6 * (1.0 + d)
        return sq, n, C, on_rim


def interpolated_normals(points: FloatArray, corners: IntArray, V: FloatArray, vertex_normals: FloatArray) -> FloatArray:
    """Unit normals at points on triangles ``corners`` (k, 3): the corners' vertex normals, barycentrically mixed.

    A row whose mix vanishes (degenerate triangle, opposed normals) is NaN: no normal, pair unusable.
    """
    L = igl.barycentric_coordinates(points, V[corners[:, 0]], V[corners[:, 1]], V[corners[:, 2]])
    n = np.einsum("kc,kcd->kd", np.clip(np.nan_to_num(L), 0.0, 1.0), vertex_normals[corners])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 1e-9, n / np.maximum(length, 1e-300), np.nan)


def _boundary_edges(F: IntArray) -> IntArray:
    """(b, 2) edges used by exactly one triangle, in the triangles' winding (libigl)."""
    return np.ascontiguousarray(igl.boundary_facets(F)[0], dtype=np.int64)


def _surface_moments(V: FloatArray, F: IntArray) -> tuple[FloatArray, FloatArray]:
    """Area-weighted centroid (3,) and covariance (3, 3) of a triangle mesh (face centroids)."""
    a = 0.5 * igl.doublearea(V, F)
    if a.sum() <= 0:
        raise MeshError("target_F: the target mesh has zero area")
    C = V[F].mean(axis=1)
    w = a / a.sum()
    c0 = w @ C
    X = C - c0
    return c0, (X * w[:, None]).T @ X


def check_surface_units(
    P: FloatArray, V: FloatArray, F: IntArray, tolerance: float, *, points: str = "source_points",
    surface: str = "target_V",
) -> None:
    """Raise if a surface looks to be in other units than the points to be fitted to it.

    Compares sizes: the points' RMS distance from their centroid against the surface's, taken
    over its area (the square root of the trace of its triangles' area-weighted covariance). A file in cm read
    as mm comes out at x0.1, in m at x0.001.

    Parameters
    ----------
    P : (p, 3) float64 array, mm
        The points (finite).
    V : (n, 3) float64 array, mm
    F : (m, 3) int64 array
        The surface.
    tolerance : float
        The largest relative difference of the two sizes allowed: the ratio must lie in
        ``[1 / (1 + tolerance), 1 + tolerance]``. Either size 0 passes.
    points, surface : str
        The arguments' names in the message.

    Raises
    ------
    MeshError
        If the sizes differ by more than ``tolerance``; the message says how to convert.
    """
    Pc = P - P.mean(axis=0)
    size_points = float(np.sqrt((Pc**2).sum(axis=1).mean()))
    _, cov = _surface_moments(V, F)
    size_surface = float(np.sqrt(np.trace(cov)))
    if size_points == 0 or size_surface == 0:
        return
    ratio = size_surface / size_points
    if not 1.0 / (1.0 + tolerance) <= ratio <= 1.0 + tolerance:
        raise MeshError(
            f"{surface}: the scan appears to be in other units than {points}: its RMS radius is "
            f"{size_surface:.4g} mm against {size_points:.4g} mm for the points (x{ratio:.3g}; a file in cm "
            f"read as mm gives x0.1, in m x0.001). Convert it to mm when reading it "
            f"(read_mesh(path, unit=...)), or pass size_tolerance=None if the two really differ in size "
            f"by more than {100 * tolerance:.0f}%"
        )


def _proper_axis_maps() -> list[FloatArray]:
    """The 24 rotations that map the coordinate axes onto signed coordinate axes."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            G = np.zeros((3, 3))
            G[np.arange(3), perm] = signs
            if np.linalg.det(G) > 0:
                out.append(G)
    return out


def trimmed_inliers(residual: FloatArray, usable: BoolArray, trim: float) -> BoolArray:
    """The ``trim`` fraction of the usable pairs with the smallest ``|residual|`` (at least 3).

    The inliers of one trimmed ICP step: ``ceil(trim * u)`` of the ``u`` usable pairs, at least
    three (a rigid fit's minimum) and at most all of them; ties keep the earlier pair.

    Parameters
    ----------
    residual : (p,) float64 array, mm
        Each pair's signed residual.
    usable : (p,) bool array
        Pairs allowed to be inliers.
    trim : float
        Fraction in (0, 1] of the usable pairs to keep.

    Returns
    -------
    (p,) bool array
        The inliers, a subset of ``usable``.

    Examples
    --------
    >>> trimmed_inliers(np.array([0.5, -0.1, 3.0, 0.2, -2.0]), np.ones(5, bool), 0.5).tolist()
    [True, True, False, True, False]
    """
    idx = np.flatnonzero(usable)
    keep = min(idx.size, max(3, int(np.ceil(trim * idx.size))))
    mask = np.zeros(residual.shape[0], dtype=bool)
    if keep:
        mask[idx[np.argsort(np.abs(residual[idx]), kind="stable")[:keep]]] = True
    return mask


def _iterate(
    X: FloatArray,
    surface: ClosestPointSurface,
    R: FloatArray,
    t: FloatArray,
    *,
    method: str,
    offset_mm: float,
    trim: float,
    max_iterations: int,
    tolerance_mm: float,
    coarse: bool = False,
) -> tuple[FloatArray, FloatArray, int, bool]:
    """ICP iterations from (R, t); returns the final (R, t), iteration count and convergence.

    An update that raises the trimmed mean squared residual is halved instead of taken (a
    backtracking line search), which stops the two-cycles a point between two surface sheets
    can cause. ``coarse`` pairs each point with the nearest target vertex instead of the
    closest surface point.
    """
    closest = surface.nearest_vertex if coarse else surface.closest
    converged = False
    it = 0
    best_energy = np.inf
    base = (R, t)  # the pose the pending update starts from
    update = (np.zeros(3), np.zeros(3), np.zeros(3))  # rotation vector, centre, translation
    for it in range(1, max_iterations + 1):
        Y = X @ R.T + t
        sq, n, C, on_rim = closest(Y)
        if method == "point_to_plane":
            residual = np.einsum("kd,kd->k", Y - C, n) - offset_mm
        else:
            Q = C + offset_mm * n
            residual = np.linalg.norm(Y - Q, axis=1)
        usable = ~on_rim & np.all(np.isfinite(n), axis=1)
        inl = trimmed_inliers(residual, usable, trim)
        if inl.sum() < 3:
            raise SolverError(
                "rigid_icp: fewer than 3 source points have a closest point inside the target surface; "
                "give a better init"
            )
        energy = float(np.mean(residual[inl] ** 2))
        if energy > best_energy:
            # worse than where the last update started: go half as far from there
            w, y0, tau = update
            update = (0.5 * w, y0, 0.5 * tau)
        else:
            best_energy = energy
            base = (R, t)
            if method == "point_to_plane":
                y0 = Y[inl].mean(axis=0)
                A = np.concatenate([np.cross(Y[inl] - y0, n[inl]), n[inl]], axis=1)
                x, *_ = np.linalg.lstsq(A, -residual[inl], rcond=None)
                update = (x[:3], y0, x[3:])
            else:
                fit = rigid_fit(Y[inl], Q[inl])
                y0 = Y[inl].mean(axis=0)
                update = (Rotation.from_matrix(fit.rotation).as_rotvec(), y0,
                          fit.rotation @ y0 + fit.translation - y0)
        w, y0, tau = update
        dR = Rotation.from_rotvec(w).as_matrix()
        dt = y0 - dR @ y0 + tau
        R, t = dR @ base[0], dR @ base[1] + dt
        Y0 = X @ base[0].T + base[1]
        step = float(np.max(np.linalg.norm(Y0[inl] @ dR.T + dt - Y0[inl], axis=1)))
        if step < tolerance_mm:
            converged = True
            break
    return R, t, it, converged


def _global_start(X: FloatArray, surface: ClosestPointSurface, options: dict[str, float]) -> tuple[FloatArray, FloatArray]:
    """A starting pose without a guess: principal axes matched 24 ways, the best few refined coarsely."""
    c_t, cov_t = _surface_moments(surface.V, surface.F)
    _, U_t = np.linalg.eigh(cov_t)
    c_s = X.mean(axis=0)
    _, U_s = np.linalg.eigh(np.cov((X - c_s).T))
    sample = X[:: max(1, X.shape[0] // 500)]
    candidates = []
    for G in _proper_axis_maps():
        R0 = U_t @ G @ U_s.T
        if np.linalg.det(R0) < 0:  # U_s and U_t of opposite handedness: flip the least-spread axis
            R0 = U_t @ (G * np.array([1.0, 1.0, -1.0])) @ U_s.T
        try:
            R1, t1, _, _ = _iterate(sample, surface, R0, c_t - R0 @ c_s, method="point_to_point",
                                    max_iterations=6, coarse=True, **options)
        except SolverError:  # this start leaves too few points over the surface
            continue
        candidates.append((_score(sample, surface, R1, t1, **options), R1, t1))
    if not candidates:
        raise SolverError("rigid_icp: no start from the principal axes reaches the target surface; pass init")
    candidates.sort(key=lambda c: c[0])
    best: tuple[float, FloatArray, FloatArray] = candidates[0]
    for _, R0, t0 in candidates[:4]:
        try:
            R1, t1, _, _ = _iterate(sample, surface, R0, t0, method="point_to_point", max_iterations=20,
                                    coarse=True, **options)
        except SolverError:
            continue
        score = _score(sample, surface, R1, t1, **options)
        if score < best[0]:
            best = (score, R1, t1)
    return best[1], best[2]


def rigid_icp(
    source_points: FloatArray,
    target_V: FloatArray,
    target_F: IntArray,
    *,
    init: FloatArray | None = None,
    max_iterations: int = 50,
    trim: float = 0.9,
    method: str = "point_to_plane",
    offset_mm: float = 0.0,
    reject_boundary: bool = True,
    tolerance_mm: float = 1e-4,
    size_tolerance: float | None = 1.0,
) -> IcpResult:
    """Rigidly move a point set onto a triangle surface by trimmed iterative closest points.

    Each iteration finds the closest point of every moved source point on
    the target, drops pairs whose closest point lies on the target's boundary
    (holes, the cropped rim) and keeps the ``trim`` fraction with the
    smallest residuals, then solves for the rigid update: linearised
    point-to-plane least squares, or the closed-form point-to-point fit
    (:func:`facecap.markers.rigid_fit`).

    Parameters
    ----------
    source_points : (k, 3) float64 array, mm
        Points to move (markers, or a mesh's vertices); NaN rows are ignored.
    target_V : (n, 3) float64 array, mm
        Target surface vertices (a scan), in the same length unit.
    target_F : (m, 3) int64 array
        Target triangles. Their orientation matters only for ``offset_mm``.
    init : (4, 4) float array or None, optional
        Starting motion (source frame to target frame). None (default):
        24 starts that map the source's principal axes onto the target's
        (every signed permutation that is a rotation), each refined by 6
        coarse point-to-point iterations (nearest of at most 2000 target
        vertices); the best 4 by trimmed RMS get 20 more, and the best of
        those goes on.
    max_iterations : int, default 50
    trim : float, default 0.9
        Fraction of the usable pairs kept each iteration, in (0, 1].
    method : {'point_to_plane', 'point_to_point'}, default 'point_to_plane'
    offset_mm : float, default 0.0
        Signed height above the surface at which the points should come to
        rest (marker centres sit about half a marker above the skin), along
        the target's normals: vertex normals interpolated at the closest
        point, so the winding of the target's triangles decides the sign.
    reject_boundary : bool, default True
        Drop pairs whose closest point is on a boundary edge of the target.
    tolerance_mm : float, default 1e-4
        Convergence: the last update moved no inlier further than this, mm.
    size_tolerance : float or None, default 1.0
        Raise if the RMS radius of the target surface and of the source
        points differ by more than this fraction (units mix-up); None skips
        the check.

    Returns
    -------
    IcpResult
        ``rotation`` (3, 3), ``translation`` (3,) mm, ``rms`` mm,
        ``iterations``, ``converged``, ``distances`` (k,) mm, ``inliers`` (k,).

    Raises
    ------
    InputError
        If an array has the wrong shape, fewer than 3 source points are
        finite, or an option is out of range.
    MeshError
        If the target faces are out of range, or the target appears to be in
        other units than the points (see ``size_tolerance``).
    SolverError
        If fewer than 3 pairs are usable during the iterations.

    Notes
    -----
    Point-to-plane [2]_ minimises ``sum_i (n_i . (R x_i + t - c_i) - offset)^2``
    over the inliers, linearised about the current pose with the rotation
    ``exp([w]_x)`` about the inliers' centroid; point-to-point [1]_
    minimises ``sum_i |R x_i + t - (c_i + offset n_i)|^2`` exactly (it
    converges linearly: use it for coarse work). ``n_i`` interpolates the
    vertex normals at ``c_i``, so the energy is smooth across edges. An
    update that raises the trimmed mean squared residual is halved instead
    (backtracking), which ends the two-cycles a point between two surface
    sheets can cause. Pairs are trimmed as in [3]_ and boundary pairs
    rejected as in [4]_. Closest points come from libigl's AABB tree, built
    once. This is the rigid registration of Huang et al. [5]_, eq. (5).

    References
    ----------
    .. [1] P. J. Besl, N. D. McKay, "A method for registration of 3-D
       shapes", IEEE TPAMI 14(2), 1992.
    .. [2] Y. Chen, G. Medioni, "Object modelling by registration of multiple
       range images", Image Vision Comput. 10(3), 1992.
    .. [3] D. Chetverikov et al., "The trimmed iterative closest point
       algorithm", ICPR 2002.
    .. [4] G. Turk, M. Levoy, "Zippered polygon meshes from range images",
       SIGGRAPH 1994.
    .. [5] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture
       and 3D scanning for high-fidelity facial performance acquisition",
       ACM Trans. Graph. 30(4), 2011.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> u, v = np.meshgrid(np.linspace(-40, 40, 30), np.linspace(-40, 40, 30))
    >>> V = np.stack([u.ravel(), v.ravel(), 0.01 * u.ravel() ** 2 + 0.02 * v.ravel() ** 2], 1)
    >>> a = (np.arange(29)[:, None] * 30 + np.arange(29)).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 31], 1), np.stack([a, a + 31, a + 30], 1)])
    >>> R = Rotation.from_rotvec([0.05, -0.03, 0.02]).as_matrix()
    >>> P = V[::7] @ R.T + [1.0, 2.0, -1.0]  # vertices moved away; rigid_icp brings them back
    >>> start = np.eye(4)
    >>> start[:3, 3] = V[::7].mean(axis=0) - P.mean(axis=0)  # only the centroids matched
    >>> fit = rigid_icp(P, V, F, init=start)
    >>> bool(np.allclose(fit.apply(P), V[::7], atol=1e-3)), fit.converged
    (True, True)
    """
    X = as_points(source_points, name="source_points", allow_nan=True)
    V = as_vertices(target_V, name="target_V")
    F = as_faces(target_F, V.shape[0], name="target_F")
    finite = np.all(np.isfinite(X), axis=1)
    if finite.sum() < 3:
        raise InputError(f"source_points: expected at least 3 finite points, got {int(finite.sum())}")
    if method not in _METHODS:
        raise InputError(f"method: expected one of {_METHODS}, got {method!r}")
    if not 0.0 < float(trim) <= 1.0:
        raise InputError(f"trim: expected a fraction in (0, 1], got {trim!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise InputError(f"max_iterations: expected a positive integer, got {max_iterations!r}")
    tolerance_mm = as_positive(tolerance_mm, name="tolerance_mm")
    offset_mm = float(offset_mm)
    if not np.isfinite(offset_mm):
        raise InputError(f"offset_mm: expected a finite number, got {offset_mm!r}")
    T0 = None if init is None else as_rigid_transform(init, name="init", project=True)
    if size_tolerance is not None:
        check_surface_units(X[finite], V, F, as_positive(size_tolerance, name="size_tolerance"))
    surface = ClosestPointSurface(V, F, reject_boundary=bool(reject_boundary))
    return rigid_icp_to_surface(X, surface, T0, method=method, max_iterations=int(max_iterations),
                                offset_mm=offset_mm, trim=float(trim), tolerance_mm=tolerance_mm)


def rigid_icp_to_surface(
    X: FloatArray,
    surface: ClosestPointSurface,
    init: FloatArray | None,
    *,
    method: str = "point_to_plane",
    max_iterations: int = 50,
    offset_mm: float = 0.0,
    trim: float = 0.9,
    tolerance_mm: float = 1e-4,
) -> IcpResult:
    """:func:`rigid_icp` on a surface built once (several starts, or several point sets, on one scan).

    Parameters
    ----------
    X : (k, 3) float64 array, mm
        Points to move; NaN rows are ignored (at least 3 finite rows).
    surface : ClosestPointSurface
        The target, built once.
    init : (4, 4) float64 array or None
        Starting motion (a proper rotation, as :func:`~facecap.validate.as_rigid_transform`
        gives it); None searches from the principal axes (see :func:`rigid_icp`).
    method, max_iterations, offset_mm, trim, tolerance_mm
        As for :func:`rigid_icp`; they are not validated here.

    Returns
    -------
    IcpResult

    Raises
    ------
    SolverError
        If fewer than 3 pairs are usable during the iterations.
    """
    finite = np.all(np.isfinite(X), axis=1)
    Xf = X[finite]
    options = dict(offset_mm=offset_mm, trim=trim, tolerance_mm=tolerance_mm)
    if init is None:
        R, t = _global_start(Xf, surface, options)
    else:
        R, t = init[:3, :3], init[:3, 3]
    R, t, iterations, converged = _iterate(Xf, surface, R, t, method=method, max_iterations=max_iterations, **options)
    Y = Xf @ R.T + t
    sq, n, C, on_rim = surface.closest(Y)
    if method == "point_to_plane":
        residual = np.einsum("kd,kd->k", Y - C, n) - offset_mm
    else:
        residual = np.linalg.norm(Y - (C + offset_mm * n), axis=1)
    inl = trimmed_inliers(residual, ~on_rim, trim)
    distances = np.full(X.shape[0], np.nan)
    distances[finite] = np.sqrt(sq)
    inliers = np.zeros(X.shape[0], dtype=bool)
    inliers[finite] = inl
    return IcpResult(
        rotation=R,
        translation=t,
        rms=float(np.sqrt(np.mean(residual[inl] ** 2))),
        iterations=iterations,
        converged=converged,
        distances=distances,
        inliers=inliers,
    )


def _score(
    X: FloatArray, surface: ClosestPointSurface, R: FloatArray, t: FloatArray, *, offset_mm: float, trim: float, **_: float
) -> float:
    """Trimmed RMS point-to-surface residual of a pose (boundary pairs count as misses)."""
    Y = X @ R.T + t
    sq, n, C, on_rim = surface.closest(Y)
    residual = np.abs(np.einsum("kd,kd->k", Y - C, n) - offset_mm)
    miss = on_rim | ~np.isfinite(residual)
    residual[miss] = np.sqrt(sq[miss]) + abs(offset_mm)
    keep = max(3, int(np.ceil(trim * residual.size)))
    return float(np.sqrt(np.mean(np.sort(residual)[:keep] ** 2)))

