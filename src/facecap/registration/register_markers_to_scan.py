"""Register one mocap frame's markers onto a face scan: rigid ICP, then a deformation in a blendshape subspace."""

from __future__ import annotations

from typing import Any, NamedTuple

import igl
import numpy as np
from scipy.linalg import lstsq
from scipy.spatial.transform import Rotation

from ..errors import InputError, MarkerError
from ..markers.rigid_fit import rigid_fit
from ..mesh.facing_outward import facing_outward
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_points, as_positive, as_rigid_transform
from .rigid_icp import ClosestPointSurface, IcpResult, check_surface_units, rigid_icp_to_surface, trimmed_inliers

__all__ = ["MarkerRegistration", "register_markers_to_scan", "scan_winding", "MIN_FACING_OUTWARD"]

MIN_FACING_OUTWARD = 0.02
""":func:`~facecap.mesh.facing_outward` of a scan, as a fraction of its bounding-box diagonal, that decides
its winding (a face scan: about 0.15; a flat patch: 0)."""


class MarkerRegistration(NamedTuple):
    """Markers of one frame registered onto a scan, by :func:`register_markers_to_scan`.

    Attributes
    ----------
    markers : (M, 3) float64 array, mm
        Marker centres in scan coordinates after the rigid motion and the
        subspace deformation; NaN for markers missing from the frame.
    surface_points : (M, 3) float64 array, mm
        The skin under each marker: the scan point whose smooth (interpolated
        vertex) normal, ``marker_offset_mm`` long, reaches the marker centre;
        the closest point when the offset is 0.
    face_indices : (M,) int64 array
        Scan triangle holding each surface point; -1 for missing markers.
    barycentric : (M, 3) float64 array
        Barycentric coordinates of the surface point in that triangle.
    distances : (M,) float64 array, mm
        Distance from each marker centre to its surface point.
    unmatched : (M,) bool array
        Markers that cannot be matched: missing from the frame, over a hole
        or past the scan's rim (closest point on a boundary), or off the
        surface by more than ``max_residual_mm`` beyond the marker offset.
    rotation : (3, 3) float64 array
        Rigid rotation from the mocap frame to the scan's (eq. 5).
    translation : (3,) float64 array, mm
        Rigid translation from the mocap frame to the scan's.
    weights : (K,) float64 array
        Subspace coefficients ``c`` of the deformation (eq. 6, see Notes);
        empty without a subspace.
    normals_flipped : bool
        True if the markers were found on the back side of the scan's
        triangles (its normals point into the head). Always False when
        ``marker_offset_mm`` is 0 (the side cannot be told).
    rigid : IcpResult
        The rigid ICP result (in the flipped-normal case, the fit with the
        offset on the triangles' back side).
    rms : float
        RMS residual (distance less the offset) of the inlier markers after
        the deformation, mm.
    """

    markers: FloatArray
    surface_points: FloatArray
    face_indices: IntArray
    barycentric: FloatArray
    distances: FloatArray
    unmatched: BoolArray
    rotation: FloatArray
    translation: FloatArray
    weights: FloatArray
    normals_flipped: bool
    rigid: IcpResult
    rms: float


def _off_skin(
    X: FloatArray, rigid: IcpResult, surface: ClosestPointSurface, offset: float, max_residual_mm: float
) -> BoolArray:
    """Markers that land, under ``rigid``, more than ``max_residual_mm`` (or 3 median residuals) off the skin.

    The height is measured on either side of the triangles (``|n . (y - c)| - offset``), so the test
    does not depend on the scan's winding. Nothing is flagged when fewer than 4 markers would be left
    on the scan (off its rim) to fit a pose.
    """
    finite = np.all(np.isfinite(X), axis=1)
    Y = X[finite] @ rigid.rotation.T + rigid.translation
    sq, n, C, on_rim = surface.closest(Y)
    residual = np.abs(np.abs(np.einsum("kd,kd->k", Y - C, n)) - offset)
    inside = ~on_rim & np.isfinite(residual)
    none = np.zeros(X.shape[0], dtype=bool)
    if inside.sum() < 4:
        return none
    limit = max(max_residual_mm, 3.0 * float(np.median(residual[inside])))
    far = inside & (residual > limit)
    if (inside & ~far).sum() < 4:
        return none
    off = none.copy()
    off[finite] = far
    return off


def scan_winding(V: FloatArray, F: IntArray) -> int:
    """Which way a scan's triangles face: +1 out of the head, -1 into it, 0 when its shape cannot tell.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Scan vertices.
    F : (m, 3) int64 array
        Scan triangles.

    Returns
    -------
    int
        The sign of :func:`~facecap.mesh.facing_outward`, or 0 when it is under
        :data:`MIN_FACING_OUTWARD` of the bounding-box diagonal (a nearly flat patch).
    """
    facing = facing_outward(V, F)
    diagonal = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    if abs(facing) < MIN_FACING_OUTWARD * diagonal:
        return 0
    return 1 if facing > 0 else -1


def _as_subspace(subspace: Any, n_markers: int) -> FloatArray:
    try:
        S = np.ascontiguousarray(subspace, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MarkerError(f"subspace: expected a numeric (K, {n_markers}, 3) array ({exc})") from None
    if S.ndim != 3 or S.shape[1:] != (n_markers, 3) or S.shape[0] < 1:
        raise MarkerError(f"subspace: expected shape (K, {n_markers}, 3) with K >= 1, got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise MarkerError("subspace: contains NaN or infinite values (fill the gaps of the selected frames first)")
    return S


def register_markers_to_scan(
    markers_frame: FloatArray,
    scan: Mesh,
    *,
    template_markers: FloatArray | None = None,
    subspace: FloatArray | None = None,
    init: FloatArray | None = None,
    marker_offset_mm: float = 0.0,
    trim: float = 0.9,
    max_iterations: int = 50,
    nonrigid_iterations: int = 30,
    regularization: float = 1e-3,
    deformation_weight: float = 0.0,
    max_residual_mm: float = 2.0,
    tolerance_mm: float = 1e-4,
    refine_rigid: bool = True,
    size_tolerance: float | None = 1.0,
    surface: ClosestPointSurface | None = None,
) -> MarkerRegistration:
    """Register the markers of one mocap frame onto a face scan of the same expression (Huang et al. 2011, sec. 5).

    First a rigid motion ``T`` from the mocap frame to the scan's (eq. 5:
    trimmed point-to-plane ICP, :func:`rigid_icp`); then, with ``T`` fixed,
    the markers deform inside the subspace spanned by the selected frames
    (eq. 6) so that they land on the scan, alternating closest points and
    linear least squares, as the paper's "extended ICP". Finally (unless
    ``refine_rigid=False``) ``T`` and the deformation are refined together,
    minimising the joint energy of eq. (4) from that start.

    Parameters
    ----------
    markers_frame : (M, 3) float64 array, mm
        The frame's marker positions in the mocap frame; NaN rows are
        markers not seen (reported unmatched).
    scan : Mesh
        The face scan (mm), its triangles consistently oriented.
    template_markers : (M, 3) float64 array or None, optional
        Rough positions of the same markers on this scan, in scan
        coordinates (picked by hand, or carried over from a previous
        registration); NaN rows are ignored. Gives the starting motion by a
        least-squares rigid fit (:func:`facecap.markers.rigid_fit`).
    subspace : (K, M, 3) float64 array or None, optional
        The selected frames ``x_t1 .. x_tK`` (Algorithm 1), head-stabilised
        and in the same frame as ``markers_frame``, without gaps. None:
        rigid registration only.
    init : (4, 4) float array or None, optional
        Starting motion from the mocap frame to the scan's; overrides
        ``template_markers``. With neither, :func:`rigid_icp` searches from
        the principal axes.
    marker_offset_mm : float, default 0.0
        Height of the marker centres above the skin (half the marker
        diameter plus the base), mm. The paper treats the markers as on the
        skin (0); with a positive offset the scan's shape tells which side
        of its triangles is outside (see Notes).
    trim : float, default 0.9
        Fraction of the usable markers kept as inliers each iteration.
    max_iterations : int, default 50
        Rigid ICP iterations.
    nonrigid_iterations : int, default 30
        Closest-point / least-squares iterations of the deformation.
    regularization : float, default 1e-3
        Tikhonov weight on the subspace coefficients, relative to the mean
        squared column norm of the least-squares matrix.
    deformation_weight : float, default 0.0
        Weight of the markers' displacement ``|x(c) - x_i|^2`` against the
        squared point-to-plane residuals. The residuals do not see a marker
        slide along the skin, so a free subspace can slide some markers to
        fit the noise of others. 0 (the paper) leaves the deformation free, as
        a scan of a re-performed expression needs; when the scan shows the
        frame's own expression (a template and the markers of its frame), a
        positive weight keeps the markers where the mocap saw them (0.01: a
        1 mm displacement costs as much as a 0.1 mm residual).
    max_residual_mm : float, default 2.0
        A marker whose distance to the scan differs from the offset by more
        than this, after registration, is unmatched. The rigid fit is also
        run a second time without the markers that the first one leaves
        further off the skin than this (or three median residuals): a head
        band's markers, which a plan's frames carry along.
    tolerance_mm : float, default 1e-4
        Convergence: no marker moved further than this in an iteration, mm.
    refine_rigid : bool, default True
        After the paper's two sequential steps, refine the rigid motion and
        the subspace coefficients together (eq. 4). The sequential solution
        keeps the rigid error that the expression difference caused in
        eq. (5); on the synthetic tests the joint step cuts the rotation
        error about fivefold. Only used with a ``subspace``.
    size_tolerance : float or None, default 1.0
        Raise if the scan's size differs from the markers' by more than this
        fraction (a scan in other units); None skips the check.
    surface : ClosestPointSurface, optional
        ``scan``'s closest-point trees, built by the caller for other fits on
        the same scan (with ``reject_boundary=True``); default None builds them.

    Returns
    -------
    MarkerRegistration
        ``markers``, ``surface_points`` (M, 3) mm in scan coordinates,
        ``face_indices``, ``barycentric``, ``distances``, ``unmatched``,
        ``rotation``, ``translation``, ``weights`` (K,), ``normals_flipped``,
        ``rigid`` and ``rms``.

    Raises
    ------
    MarkerError
        If fewer than 3 markers are seen, or the arrays have wrong shapes.
    MeshError
        If the scan appears to be in other units (see ``size_tolerance``).
    InputError
        If an option is out of range.
    SolverError
        If the ICP runs out of usable markers.

    Notes
    -----
    Eq. (6) of [1]_ writes the deformed markers as ``[x_t1 ... x_tK] w``.
    Taken literally, ``sum(w) != 1`` would scale the markers about the mocap
    system's origin; here the combination is affine and starts at the
    frame itself (the paper initialises ``x_{i,w}`` with ``x_i``):

    ``x(c) = x_i + sum_k c_k (x_tk - x_i)``,

    identical to the paper's ``[x_i, x_t1 .. x_tK] w`` with ``sum(w) = 1``.
    With ``T = (R, t)`` fixed each iteration finds the closest scan point
    ``p_m`` and normal ``n_m`` of every inlier marker and solves the linear
    least-squares problem

    ``min_c sum_m (n_m . (R x_m(c) + t - p_m) - offset)^2 + lambda |c|^2 + mu sum_m |x_m(c) - x_m|^2``

    (``mu``: ``deformation_weight``; ``scipy.linalg.lstsq`` on the stacked system), halving a step that
    raises the energy. The joint refinement adds a small rotation about the
    inliers' centroid and a translation to the same linearised system.
    Pairs whose closest point is on the scan's boundary, or whose residual
    exceeds ``max_residual_mm``, are left out, and the ``trim`` fraction of
    the rest is kept.

    The scan's normals are only needed for the marker offset: with
    ``marker_offset_mm > 0`` the markers go in front of the triangles as
    :func:`~facecap.mesh.facing_outward` says they face, so a scan whose
    triangles are wound the other way (normals into the head) still
    registers, and ``normals_flipped`` reports it. Where the scan is too flat
    to tell (:data:`MIN_FACING_OUTWARD` of its bounding-box diagonal), the
    rigid fit is run with the markers on both sides and the smaller RMS wins.
    That comparison alone went wrong on 6 of 30 scans of a generated take
    with 45 markers, 4 of them on a head band off the skin: the trimmed RMS
    followed those 4, and each such basis came out 1.4-1.9 mm off.

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture
       and 3D scanning for high-fidelity facial performance acquisition",
       ACM Trans. Graph. 30(4), 2011, section 5, eqs. (4)-(6).

    Examples
    --------
    >>> import numpy as np
    >>> from facecap.synth.generate_performance import generate_performance
    >>> from facecap.synth.scan_expression import scan_expression
    >>> case = generate_performance(n_frames=2, noise_mm=0.05, head_rotation_deg=0.0, head_translation_mm=0.0)
    >>> scan = scan_expression(case.truth_vertices[0], case.scan.faces, target_vertices=10000, seed=3)
    >>> frame = case.markers.positions[0, : case.marker_vertices.size]
    >>> reg = register_markers_to_scan(frame, scan.mesh, marker_offset_mm=1.5)
    >>> true = scan.scanner_from_face @ np.linalg.inv(case.mocap_from_scan)
    >>> bool(np.allclose(reg.rotation, true[:3, :3], atol=3e-3))
    True
    """
    X0 = as_points(markers_frame, name="markers_frame", allow_nan=True)
    if not isinstance(scan, Mesh):
        raise InputError(f"scan: expected a facecap.structures.Mesh, got {type(scan).__name__}")
    M = X0.shape[0]
    seen = np.all(np.isfinite(X0), axis=1)
    if seen.sum() < 3:
        raise MarkerError(f"markers_frame: expected at least 3 markers seen, got {int(seen.sum())}")
    offset = as_positive(marker_offset_mm, name="marker_offset_mm", allow_zero=True)
    max_residual_mm = as_positive(max_residual_mm, name="max_residual_mm")
    regularization = as_positive(regularization, name="regularization", allow_zero=True)
    deformation_weight = as_positive(deformation_weight, name="deformation_weight", allow_zero=True)
    if int(nonrigid_iterations) != nonrigid_iterations or nonrigid_iterations < 0:
        raise InputError(f"nonrigid_iterations: expected a non-negative integer, got {nonrigid_iterations!r}")
    S = None if subspace is None else _as_subspace(subspace, M)

    if init is not None:
        init = as_rigid_transform(init, name="init", project=True)
    elif template_markers is not None:
        P = as_points(template_markers, name="template_markers", allow_nan=True)
        if P.shape[0] != M:
            raise MarkerError(f"template_markers: expected {M} rows to match markers_frame, got {P.shape[0]}")
        fit = rigid_fit(X0, P)
        if not np.all(np.isfinite(fit.rotation)):
            raise MarkerError("template_markers: fewer than 3 markers are both seen and placed on the scan")
        init = np.eye(4)
        init[:3, :3], init[:3, 3] = fit.rotation, fit.translation

    V, F = scan.vertices, scan.faces
    if size_tolerance is not None:
        check_surface_units(X0[seen], V, F, as_positive(size_tolerance, name="size_tolerance"),
                     points="markers_frame", surface="scan")
    if not 0.0 < float(trim) <= 1.0:
        raise InputError(f"trim: expected a fraction in (0, 1], got {trim!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise InputError(f"max_iterations: expected a positive integer, got {max_iterations!r}")
    tolerance_mm = as_positive(tolerance_mm, name="tolerance_mm")
    if surface is None:
        surface = ClosestPointSurface(V, F, reject_boundary=True)
    elif not isinstance(surface, ClosestPointSurface) or surface.V.shape != V.shape or surface.F.shape != F.shape:
        raise InputError("surface: expected the ClosestPointSurface of this scan")
    options = dict(method="point_to_plane", max_iterations=int(max_iterations), trim=float(trim),
                   tolerance_mm=tolerance_mm)
    winding = scan_winding(V, F) if offset > 0 else 1
    sign = -1.0 if winding < 0 else 1.0
    rigid = rigid_icp_to_surface(X0, surface, init, offset_mm=sign * offset, **options)
    off_skin = _off_skin(X0, rigid, surface, offset, max_residual_mm)
    X_fit = np.where(off_skin[:, None], np.nan, X0)
    if off_skin.any():
        # Markers off the skin (a head band, a marker on the hair) that the trimming keeps pull the
        # pose: with 4 band markers among 49, the rigid RMS was 0.7-2.4 mm against 0.1-0.2 without them
        rigid = rigid_icp_to_surface(X_fit, surface, rigid.matrix, offset_mm=sign * offset, **options)
    if winding == 0:  # a shape too flat to tell: the side the markers fit better
        back = rigid_icp_to_surface(X_fit, surface, rigid.matrix, offset_mm=-offset, **options)
        if back.rms < rigid.rms:
            rigid, sign = back, -1.0
    R, t = rigid.rotation, rigid.translation

    Xs = X0[seen]
    c = np.zeros(0 if S is None else S.shape[0])
    D = np.zeros((Xs.shape[0], 3, 0)) if S is None else np.moveaxis(S[:, seen] - Xs[None], 0, -1)
    fit_options = dict(
        surface=surface, target_offset=sign * offset, trim=float(trim), max_residual_mm=max_residual_mm,
        regularization=regularization, deformation_weight=deformation_weight, iterations=int(nonrigid_iterations),
        tolerance_mm=tolerance_mm,
    )
    if S is not None and nonrigid_iterations > 0:
        R, t, c = _subspace_icp(Xs, D, R, t, c, joint=False, **fit_options)  # eq. (6), T fixed
        if refine_rigid:
            R, t, c = _subspace_icp(Xs, D, R, t, c, joint=True, **fit_options)  # eq. (4), jointly

    markers = np.full((M, 3), np.nan)
    markers[seen] = (Xs + D @ c) @ R.T + t
    C, n, I, on_rim = _skin_under(markers[seen], surface, sign * offset)
    residual = np.einsum("md,md->m", markers[seen] - C, n) - sign * offset
    surface_points = np.full((M, 3), np.nan)
    surface_points[seen] = C
    face_indices = np.full(M, -1, dtype=np.int64)
    face_indices[seen] = I
    barycentric = np.full((M, 3), np.nan)
    corners = F[I]
    barycentric[seen] = igl.barycentric_coordinates(C, V[corners[:, 0]], V[corners[:, 1]], V[corners[:, 2]])
    distances = np.full(M, np.nan)
    distances[seen] = np.linalg.norm(markers[seen] - C, axis=1)
    unmatched = np.ones(M, dtype=bool)
    unmatched[seen] = on_rim | (np.abs(residual) > max_residual_mm)
    good = ~unmatched[seen]
    rms = float(np.sqrt(np.mean(residual[good] ** 2))) if good.any() else float("nan")
    return MarkerRegistration(
        markers=markers,
        surface_points=surface_points,
        face_indices=face_indices,
        barycentric=barycentric,
        distances=distances,
        unmatched=unmatched,
        rotation=R,
        translation=t,
        weights=c,
        normals_flipped=sign < 0,
        rigid=rigid,
        rms=rms,
    )


def _skin_under(
    Y: FloatArray, surface: ClosestPointSurface, offset: float, *, iterations: int = 4
) -> tuple[FloatArray, FloatArray, IntArray, BoolArray]:
    """The skin point under each marker centre: where the surface's smooth normal, ``offset`` long, reaches it.

    A marker sits ``offset`` above the skin along the skin's normal, and a real skin's normal is
    smooth; the closest point of a faceted scan is not that point wherever the triangles turn (an
    eyelid crease, the nostrils): there it lands up to half a millimetre aside. Starting from the
    closest point, each step projects ``Y - offset n`` onto the surface, with ``n`` the mean of the
    last two interpolated normals (the plain fixed-point step can swing between two faces of a crease).

    Returns the points (k, 3), their interpolated unit normals, triangle indices and rim flags.
    """
    query = Y
    _, n, C, on_rim = surface.closest(query)
    direction = n
    for _ in range(iterations if offset != 0.0 else 0):
        query = np.where(np.isfinite(direction), Y - offset * direction, query)
        _, n, C, on_rim = surface.closest(query)
        mean = np.where(np.isfinite(n), np.where(np.isfinite(direction), direction + n, n), direction)
        direction = mean / np.linalg.norm(mean, axis=1, keepdims=True)
    _, I, _ = surface.tree.squared_distance(surface.V, surface.F, query)
    return C, n, I, on_rim


def _subspace_icp(
    Xs: FloatArray,
    D: FloatArray,
    R: FloatArray,
    t: FloatArray,
    c: FloatArray,
    *,
    joint: bool,
    surface: ClosestPointSurface,
    target_offset: float,
    trim: float,
    max_residual_mm: float,
    regularization: float,
    deformation_weight: float,
    iterations: int,
    tolerance_mm: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Closest points and linear least squares for the subspace coefficients (and, if ``joint``, the pose).

    The markers are ``R (Xs + D c) + t``. Each iteration linearises the point-to-plane residuals
    in ``c`` (exact) and, when ``joint``, in a small rotation about the inliers' centroid and a
    translation; an update that raises the trimmed energy is halved instead of taken.
    """
    K = c.size
    best = np.inf
    base = (R, t, c)
    step = (np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(K))  # rotation vector, centre, translation, dc
    for _ in range(iterations):
        Y = (Xs + D @ c) @ R.T + t
        _, n, C, on_rim = surface.closest(Y)
        residual = np.einsum("md,md->m", Y - C, n) - target_offset
        inl = trimmed_inliers(residual, ~on_rim & (np.abs(residual) <= max_residual_mm), trim)
        if inl.sum() < 3 + (6 if joint else 0):
            break
        energy = float(np.sum(residual[inl] ** 2) + deformation_weight * np.sum((D @ c) ** 2)) / inl.sum()
        if energy > best:
            w, y0, tau, dc = step
            step = (0.5 * w, y0, 0.5 * tau, 0.5 * dc)
        else:
            best, base = energy, (R, t, c)
            Jc = np.einsum("md,mdk->mk", n[inl], np.einsum("ij,mjk->mik", R, D[inl]))
            lam = regularization * float(np.mean(np.sum(Jc**2, axis=0))) if K else 0.0
            y0 = Y[inl].mean(axis=0)
            if joint:
                J = np.concatenate([np.cross(Y[inl] - y0, n[inl]), n[inl], Jc], axis=1)
            else:
                J = Jc
            ridge = np.zeros((K, J.shape[1]))
            ridge[:, J.shape[1] - K :] = np.sqrt(lam) * np.eye(K)
            # the markers' own displacement, 3 rows each: the normal residuals leave a slide along
            # the surface free, and the subspace uses that freedom to fit noise elsewhere
            RD = np.einsum("ij,mjk->mik", R, D).reshape(-1, K) if deformation_weight > 0 else np.zeros((0, K))
            stiff = np.zeros((RD.shape[0], J.shape[1]))
            stiff[:, J.shape[1] - K :] = np.sqrt(deformation_weight) * RD
            A = np.concatenate([J, ridge, stiff])
            b = np.concatenate([-residual[inl], -np.sqrt(lam) * c, -np.sqrt(deformation_weight) * (RD @ c)])
            x = lstsq(A, b)[0]
            if joint:
                step = (x[:3], y0, x[3:6], x[6:])
            else:
                step = (np.zeros(3), y0, np.zeros(3), x)
        w, y0, tau, dc = step
        dR = Rotation.from_rotvec(w).as_matrix()
        R0, t0, c0 = base
        R, t, c = dR @ R0, dR @ t0 + y0 - dR @ y0 + tau, c0 + dc
        before = (Xs + D @ c0) @ R0.T + t0
        after = (Xs + D @ c) @ R.T + t
        if float(np.max(np.linalg.norm(after - before, axis=1))) < tolerance_mm:
            break
    return R, t, c
