"""Large-scale registration of a template mesh to a face scan (Huang et al. 2011, section 6.1)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import igl
import numpy as np
import scipy.sparse as sp

from ..mesh.factor_spd import Backend, SpdFactor
from ..errors import InputError
from ..mesh.laplacian import laplace_operators
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from .rigid_icp import interpolated_normals

__all__ = ["register_template_to_scan", "register_template_to_scans", "TemplateRegistration",
           "DEFAULT_CLOSEST_POINT_WEIGHTS"]

DEFAULT_CLOSEST_POINT_WEIGHTS = (0.1, 0.5, 2.0)
"""The w3 schedule of the paper: the closest-point term grows over three iterations."""

MAX_NORMAL_ANGLE_DEG = 20.0
"""Largest angle between a template normal and the scan's at its closest point for the pair to count."""


@dataclass(frozen=True, eq=False)
class TemplateRegistration:
    """The template deformed onto a scan, in the template's topology.

    Attributes
    ----------
    vertices : (n, 3) float64 array, mm
        Deformed template vertices (the registered scan).
    distance_mm : (n,) float64 array
        Distance from each deformed vertex to the scan surface; NaN where the
        vertex had no valid closest point in the last iteration (scan holes,
        cropped border).
    matched : (n,) bool array
        Vertices attracted to the scan in the last iteration.
    marker_residual_mm : (K,) float64 array
        Distance between the template's markers after deformation and the
        scan's markers.
    mean_distance_mm : float
        Mean of ``distance_mm`` over matched vertices: the registration residual.
    flipped_scan_normals : bool
        True when the scan's triangles were wound the other way (inward normals);
        they are handled, and reported.
    """

    vertices: FloatArray
    distance_mm: FloatArray
    matched: np.ndarray
    marker_residual_mm: FloatArray
    mean_distance_mm: float
    flipped_scan_normals: bool


def register_template_to_scan(
    template: Mesh,
    template_marker_vertices: IntArray,
    template_marker_weights: FloatArray,
    scan: Mesh,
    scan_markers: FloatArray,
    *,
    marker_weight: float = 10000.0,
    laplacian_weight: float = 1.0,
    closest_point_weights: Sequence[float] = DEFAULT_CLOSEST_POINT_WEIGHTS,
    max_distance_mm: float = 5.0,
    max_normal_angle_deg: float = MAX_NORMAL_ANGLE_DEG,
    rest_weight: float = 0.0,
    backend: Backend = "auto",
) -> TemplateRegistration:
    """Deform a template onto a scan: markers, Laplacian detail, closest points (eq. 7).

    Minimises ``w1 |C d - b_c|^2 + w2 |L d - L s|^2 + w3 |d - cp(d)|^2``
    (``+ w0 |d - s|^2`` with ``rest_weight``) over
    the deformed template vertices ``d``: ``C`` puts the template's markers
    (barycentric) on ``d``, ``b_c`` are the markers registered on the scan,
    ``L`` is the template's cotangent Laplacian (detail preservation about the
    template ``s``) and ``cp`` the closest points on the scan. The first
    solve drops the closest-point term (a Laplacian deformation onto the
    markers); then each weight of ``closest_point_weights`` runs one
    closest-point iteration. Both meshes must already share a frame (the scan's
    global rigid pose factored out).

    Parameters
    ----------
    template : Mesh
        The template (mm).
    template_marker_vertices : (K, 3) int64 array
        Vertices of the triangle each template marker sits on (or (i, i, i)).
    template_marker_weights : (K, 3) float64 array
        Barycentric weights of the template markers.
    scan : Mesh
        The target scan (mm), any topology, holes allowed.
    scan_markers : (K, 3) float64 array, mm
        The same markers on the scan (section 5); NaN rows are skipped.
    marker_weight, laplacian_weight : float, default 10000, 1
        ``w1`` and ``w2`` of the paper.
    closest_point_weights : sequence of float, default (0.1, 0.5, 2.0)
        ``w3`` per iteration.
    max_distance_mm : float, default 5.0
        Closest points farther than this are ignored (holes, cropped borders).
    max_normal_angle_deg : float, default 20 (:data:`MAX_NORMAL_ANGLE_DEG`)
        Closest points whose surface normal (the scan's vertex normals,
        interpolated) disagrees more than this with the template's are
        ignored (the other side of a lip, an eyelid). Not in the paper. At 60
        degrees the inner lips, which face into the mouth and no scan sees,
        were pulled onto the lips' visible side: on four generated takes the
        blend's mouth error fell from 0.41-0.59 mm to 0.25-0.46 mm at 20
        degrees. Scans with three times the noise lose under 2 % of their
        matched vertices at 20 degrees.
    rest_weight : float, default 0
        ``w0``, not in the paper: a weak pull of every vertex towards the
        template's own position. Where neither a marker nor the scan says
        anything (the neck, ears and mouth inside a full-head template) the
        ``L d - L s`` term alone extrapolates the face's displacement
        linearly, so those parts drift by tenths of a mm; ``w0`` makes the
        displacement fade out instead, over about ``(w2 / w0) ** 0.25``
        edges (7 edges at 3e-4). Needs the scan in the template's head pose
        (to within stabilisation noise);
        :func:`~facecap.registration.register_scans.register_scans` uses
        :data:`~facecap.registration.register_scans.DEFAULT_REST_WEIGHT`.
    backend : {'auto', 'pardiso', 'scipy'}

    Returns
    -------
    TemplateRegistration

    Notes
    -----
    The cotangent Laplacian is dimensionless and positions are in mm, so the
    three terms are all in mm^2 and the paper's weights carry over. Every
    iteration is one sparse SPD solve for the three coordinates.
    """
    (result,) = register_template_to_scans(
        template, template_marker_vertices, template_marker_weights, [scan], [scan_markers],
        marker_weight=marker_weight, laplacian_weight=laplacian_weight, closest_point_weights=closest_point_weights,
        max_distance_mm=max_distance_mm, max_normal_angle_deg=max_normal_angle_deg, rest_weight=rest_weight,
        backend=backend)
    return result


def register_template_to_scans(
    template: Mesh,
    template_marker_vertices: IntArray,
    template_marker_weights: FloatArray,
    scans: Sequence[Mesh],
    scan_markers: Sequence[FloatArray],
    *,
    marker_weight: float = 10000.0,
    laplacian_weight: float = 1.0,
    closest_point_weights: Sequence[float] = DEFAULT_CLOSEST_POINT_WEIGHTS,
    max_distance_mm: float = 5.0,
    max_normal_angle_deg: float = MAX_NORMAL_ANGLE_DEG,
    rest_weight: float = 0.0,
    backend: Backend = "auto",
) -> list[TemplateRegistration]:
    """:func:`register_template_to_scan` of one template onto several scans, what they share built once.

    The template's welded surface, its Laplacian, the marker term's matrix and
    the factor of the first (markers-only) solve do not depend on the scan
    when its markers are the same; the closest-point rounds' matrices differ
    by a diagonal, so one analysis serves every round of every scan
    (:meth:`~facecap.mesh.factor_spd.SpdFactor.refactor`). At 78k vertices that
    is about 0.6 s of the 2.5 s a scan takes on one core. The results are
    those of :func:`register_template_to_scan` for each scan alone.

    Parameters
    ----------
    template, template_marker_vertices, template_marker_weights
        As :func:`register_template_to_scan`.
    scans : sequence of Mesh
        The scans (mm), each already in the template's frame.
    scan_markers : sequence of (K, 3) float64 arrays, mm
        Each scan's markers (NaN rows skipped), in the order of ``scans``.
    marker_weight, laplacian_weight, closest_point_weights, max_distance_mm, max_normal_angle_deg, rest_weight, backend
        As :func:`register_template_to_scan`.

    Returns
    -------
    list of TemplateRegistration
        One per scan, in order.
    """
    K = np.asarray(template_marker_vertices, dtype=np.int64)
    Wm = np.asarray(template_marker_weights, dtype=np.float64)
    if K.ndim != 2 or K.shape[1] != 3 or Wm.shape != K.shape:
        raise InputError(f"template markers: expected (K, 3) vertices and weights, got {K.shape}, {Wm.shape}")
    if K.size and (K.min() < 0 or K.max() >= template.n_vertices):
        raise InputError("template_marker_vertices: index out of range")
    if len(scans) != len(scan_markers):
        raise InputError(f"scan_markers: expected one array per scan ({len(scans)}), got {len(scan_markers)}")
    all_targets = []
    for targets in scan_markers:
        targets = np.asarray(targets, dtype=np.float64)
        if targets.shape != K.shape:
            raise InputError(f"template markers: expected (K, 3) vertices, weights and scan markers, got {K.shape}, "
                             f"{Wm.shape}, {targets.shape}")
        seen = np.all(np.isfinite(targets), axis=1)
        if seen.sum() < 3:
            raise InputError(f"only {int(seen.sum())} markers are visible on the scan; at least 3 are needed")
        all_targets.append(targets)
    for w in (marker_weight, laplacian_weight, rest_weight, *closest_point_weights):
        if not np.isfinite(w) or w < 0:
            raise InputError(f"registration weights must be non-negative, got {w}")

    # weld seams so the Laplacian sees one surface; map back at the end
    welded = weld_duplicate_vertices(template.vertices, template.faces, tolerance=1e-6)
    S, Fs, back = welded.V, welded.F, welded.welded_index
    n = S.shape[0]
    L = laplace_operators(S, Fs).L
    LtL = (L.T @ L).tocsr()
    detail_rhs = laplacian_weight * (LtL @ S) + rest_weight * S
    systems: dict[bytes, tuple[sp.csr_matrix, sp.csr_matrix, float, SpdFactor]] = {}  # by the markers seen
    # every round's matrix has the same non-zeros (a diagonal changes): one analysis for all of them
    rounds = SpdFactor.unfactored(n, backend=backend)
    results = []
    try:
        for scan, targets in zip(scans, all_targets):
            seen = np.all(np.isfinite(targets), axis=1)
            if seen.tobytes() not in systems:
                rows = np.repeat(np.arange(int(seen.sum())), 3)
                C = sp.csr_matrix((Wm[seen].ravel(), (rows, back[K[seen]].ravel())), shape=(int(seen.sum()), n))
                base = (marker_weight * (C.T @ C) + laplacian_weight * LtL
                        + rest_weight * sp.eye(n, format="csr")).tocsr()
                # a tiny identity term keeps the system definite where L and C leave translations free
                eps = 1e-9 * max(float(base.diagonal().mean()), 1e-12)
                systems[seen.tobytes()] = (C, base, eps, SpdFactor((base + eps * sp.eye(n)).tocsr(), backend=backend))
            C, base, eps, first = systems[seen.tobytes()]
            results.append(_register_one(scan, S, Fs, back, C, base, eps, first, rounds,
                                         marker_weight * (C.T @ targets[seen]) + detail_rhs, targets, seen,
                                         closest_point_weights, max_distance_mm, max_normal_angle_deg))
    finally:
        rounds.free()
        for *_, first in systems.values():
            first.free()
    return results


def _register_one(scan: Mesh, S: np.ndarray, Fs: np.ndarray, back: np.ndarray, C: sp.csr_matrix,
                  base: sp.csr_matrix, eps: float, first: SpdFactor, rounds: SpdFactor, base_rhs: np.ndarray,
                  targets: np.ndarray, seen: np.ndarray, closest_point_weights: Sequence[float],
                  max_distance_mm: float, max_normal_angle_deg: float) -> TemplateRegistration:
    """Eq. 7 on one scan: the markers-only solve (``first``), then the closest-point rounds (``rounds``)."""
    n = S.shape[0]
    scan_V, scan_F = scan.vertices, scan.faces
    scan_tree = igl.AABB()  # one tree for the scan's every closest-point query
    scan_tree.init(scan_V, scan_F)
    boundary_vertex = np.zeros(scan.n_vertices, dtype=bool)
    boundary_vertex[np.unique(igl.boundary_facets(scan_F)[0])] = True
    on_rim = boundary_vertex[scan_F].any(axis=1)
    cos_limit = np.cos(np.deg2rad(max_normal_angle_deg))

    D = first.solve(base_rhs + eps * S)
    sq, tri, cp = scan_tree.squared_distance(scan_V, scan_F, D)
    scan_face_normals = igl.per_face_normals(scan_V, scan_F, np.array([0.0, 0.0, 1.0]))
    flipped = _scan_normals_flipped(D, Fs, np.sqrt(sq), tri, scan_face_normals)
    # the scan's normal at a closest point interpolates its vertex normals: a face normal of a
    # dense noisy scan tilts by several degrees, which a tight agreement limit would punish
    scan_vertex_normals = igl.per_vertex_normals(scan_V, scan_F) * (-1.0 if flipped else 1.0)
    matched = np.zeros(n, dtype=bool)
    for w3 in closest_point_weights:
        smooth = interpolated_normals(cp, scan_F[tri], scan_V, scan_vertex_normals)
        normals = igl.per_vertex_normals(D, Fs)
        agree = np.einsum("ij,ij->i", normals, smooth) >= cos_limit  # NaN compares False: unusable
        matched = (np.sqrt(sq) <= max_distance_mm) & agree & ~on_rim[tri]
        weight = np.where(matched, w3, 0.0)
        rounds.refactor((base + sp.diags(weight + eps)).tocsr())
        D = rounds.solve(base_rhs + weight[:, None] * cp + eps * D)
        sq, tri, cp = scan_tree.squared_distance(scan_V, scan_F, D)
    distance = np.where(matched, np.sqrt(sq), np.nan)
    marker_residual = np.linalg.norm(C @ D - targets[seen], axis=1)
    full_residual = np.full(seen.size, np.nan)
    full_residual[seen] = marker_residual
    return TemplateRegistration(
        vertices=D[back],
        distance_mm=distance[back],
        matched=matched[back],
        marker_residual_mm=full_residual,
        mean_distance_mm=float(np.nanmean(distance)) if matched.any() else float("nan"),
        flipped_scan_normals=flipped,
    )


def _scan_normals_flipped(D: np.ndarray, F: np.ndarray, distance: np.ndarray, tri: np.ndarray,
                          scan_normals: np.ndarray) -> bool:
    """True when most close correspondences (``distance``, ``tri``: each vertex's closest scan point)
    see the scan's face normals opposite to the template's."""
    close = distance < np.percentile(distance, 50) + 1e-9
    normals = igl.per_vertex_normals(D, F)
    dots = np.einsum("ij,ij->i", normals[close], scan_normals[tri[close]])
    return bool(np.median(dots) < 0)
