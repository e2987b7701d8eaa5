"""Fine-scale registration of registered scans by optical flow on curvature images (Huang et al. 2011, 6.2)."""

from __future__ import annotations

from functools import partial
from typing import Any, Literal, NamedTuple, Sequence

import cv2
import igl
import numpy as np
from scipy.spatial import cKDTree

from ..mesh.factor_spd import Backend
from ..errors import InputError
from ..mesh.mean_curvature import DEFAULT_FEATURE_THRESHOLD, mean_curvature
from ..mesh.median_edge_length import median_edge_length
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_count, as_faces, as_positive
from .cylindrical_map import CylindricalMap, TriangleRaster, cylindrical_map
from .optical_flow import Flow, optical_flow
from .regularised_update import regularised_update
from .visible_in_raster import visible_in_raster

__all__ = ["refine_registration", "Refinement"]

UserCorrespondence = tuple[int, int, int, Any]
"""``(scan_a, vertex_a, scan_b, point_b)``: see :func:`refine_registration`."""

_CURVATURE_NEIGHBOURS = 32  # k-NN candidates of each curvature fit
_STRONG_FEATURE = 0.25  # local RMS feature (in units of its 99th percentile) that earns full confidence
_STRENGTH_SIGMA_PX = 4.0  # Gaussian radius of that local RMS, pixels


class Refinement(NamedTuple):
    """Result of :func:`refine_registration`.

    Attributes
    ----------
    vertices : (K, n, 3) float64 array, mm
        Refined registered meshes, same topology (and vertex count) as the input.
    misalignment_before, misalignment_after : (K,) float64 arrays, 1/mm
        Feature misalignment of each mesh with its per-region neighbours before
        and after refinement: the root mean square of
        ``G(d_i)[j] - G(d_{i_m,r})[j]`` over regions ``r``, neighbours ``m`` and
        the vertices ``j`` of ``r`` (the square root of eq. 9 per term).
    flagged : (K,) bool array
        ``misalignment_after > error_threshold`` (default: twice the median):
        scans to check by eye and perhaps give ``user_correspondences`` (the
        paper's monitoring step).
    neighbours : (K, R, M) int64 array
        The ``M`` closest meshes of each mesh in each region.
    region_labels : (n,) int64 array
        Region of every vertex (given or derived).
    distance_to_scan_mm : (K, n) float64 array
        Distance of each refined vertex to its scan.
    """

    vertices: FloatArray
    misalignment_before: FloatArray
    misalignment_after: FloatArray
    flagged: BoolArray
    neighbours: IntArray
    region_labels: IntArray
    distance_to_scan_mm: FloatArray


def refine_registration(
    registered: Any,
    F: Any,
    scans: Sequence[Mesh],
    *,
    region_labels: Any = None,
    neighbours: int = 3,
    iterations: int = 3,
    alpha: float = 1.0,
    flow: Flow = "dis",
    average: Literal["flows", "images"] = "flows",
    error_threshold: float | None = None,
    user_correspondences: Sequence[UserCorrespondence] | None = None,
    constraint_weight: float = 100.0,
    axis: Any = (0.0, 1.0, 0.0),
    forward: Any = None,
    pixel_mm: float | None = None,
    overlap_mm: float | None = None,
    curvature_radius_mm: float | None = None,
    feature_threshold: float = DEFAULT_FEATURE_THRESHOLD,
    confidence_floor: float | None = 0.01,
    snap_distance_mm: float = 0.5,
    backend: Backend = "auto",
) -> Refinement:
    """Slide registered meshes along their scans until their curvature details line up (eq. 8-11).

    Every mesh ``d_i`` is a copy of one template lying on scan ``i``; vertex
    ``j`` of every mesh should be the same point of the face. Large-scale
    registration leaves medium- and fine-scale details (wrinkles, folds)
    misaligned. For ``iterations`` rounds, each mesh in turn (Gauss-Seidel)
    is moved along its own scan so that its mean-curvature features match
    those of its ``neighbours`` closest meshes, region by region:

    1. features ``G`` = thresholded mean curvature (:func:`~facecap.mesh.mean_curvature.mean_curvature`)
       of every registered mesh;
    2. mesh ``i`` is unwrapped into a cylindrical image; for each region, the
       source image holds ``G(d_i)`` and each target channel the features of
       one neighbour carried onto mesh ``i`` through the current
       correspondence (vertex ``j`` to vertex ``j``: the paper's pre-warp);
    3. a dense optical flow (OpenCV) from each target channel to the source
       image, averaged over channels, gives per region where each vertex's
       feature lies on mesh ``i``; regions are blended with eq. 10's cosine
       weights;
    4. each vertex's displaced pixel is mapped back to a point on the surface
       of ``d_i`` (``d_i' in Surf(d_i)``), giving ``dv``;
    5. the update is regularised by eq. 11 (plus any user constraints) and
       the result is put back on the scan (closest point), so registration
       residuals stay at zero.

    Parameters
    ----------
    registered : (K, n, 3) float64 array, mm
        The large-scale registrations: the template deformed onto each scan
        (:func:`~facecap.registration.register_template_to_scan.register_template_to_scan`).
    F : (m, 3) int64 array
        The template's triangles, shared by all registrations. Vertices
        duplicated along UV seams are welded internally.
    scans : sequence of K Mesh
        The scans the registrations lie on (any topology), mm.
    region_labels : (n,) int array, optional
        Region of every template vertex (the paper uses 8: Fig. 6a). Default:
        8 regions from a 2 x 4 grid over the cylindrical image of the mean
        registered mesh (left/right halves, four bands from forehead to chin),
        cut at the quantiles of the vertices' image positions so each region
        holds about the same number of vertices.
    neighbours : int, default 3
        ``M``, the number of closest meshes each mesh is aligned with in each
        region (closest by mean vertex distance over the region); fewer if
        there are fewer other meshes.
    iterations : int, default 3
        Outer Gauss-Seidel rounds over all meshes (the paper stops after 3).
    alpha : float, default 1.0
        Laplacian weight of eq. 11 (the paper's value).
    flow : {'dis', 'farneback'}, default 'dis'
        OpenCV dense optical flow standing in for the paper's Papenberg et
        al. 2006: DIS (Dense Inverse Search with variational refinement, on
        8-bit images, full resolution) or Farneback's polynomial expansion (on
        float images). On a synthetic face (ICT, 37k vertices, 1.5 mm slides)
        DIS halved the correspondence error where Farneback gained ~10 %;
        on bumpy sheets both do about as well.
    average : {'flows', 'images'}, default 'flows'
        How the ``M`` neighbour channels of a target image enter the flow:
        ``'flows'`` runs one flow per channel and averages the flows;
        ``'images'`` runs one flow against the channels' mean (3 times fewer
        flows; 10-20 % less accurate in our synthetic tests).
    error_threshold : float or None, default None
        Misalignment (1/mm, RMS feature difference, see :class:`Refinement`)
        above which a scan is flagged after refinement. None flags the
        outliers: scans above twice the median misalignment of all scans (its
        absolute level depends on the scans' detail and resolution).
    user_correspondences : sequence of (int, int, int, (3,) float array), optional
        Manual fixes ``(scan_a, vertex_a, scan_b, point_b)``: the point of scan
        ``scan_a`` under vertex ``vertex_a`` of its input registration is the
        same point of the face as ``point_b`` (mm, on scan ``scan_b``).
        Enforced as soft constraints in every eq. 11 update: vertex
        ``vertex_a`` of mesh ``scan_a`` is held where it was, and vertex
        ``vertex_a`` of mesh ``scan_b`` is pulled to ``point_b``.
    constraint_weight : float, default 100
        Weight of each user constraint relative to the unit data term of eq. 11.
    axis : (3,) float array, default (0, 1, 0)
        The face's up direction, the cylinder's axis.
    forward : (3,) float array, optional
        The direction the face looks; default the mean vertex normal of the
        mean registered mesh.
    pixel_mm : float, optional
        Image pixel size, mm; default half the median edge length of the
        template (images between 64 and 1024 pixels wide).
    overlap_mm : float, optional
        How far each region reaches into its neighbours; the overlaps are twice
        this wide. Default 4 % of the face's larger extent in the image.
    curvature_radius_mm : float, optional
        Neighbourhood radius of the curvature fits; default 2.5 median edge
        lengths. The 32 nearest candidates within 1.5 times it are searched
        once, on the mean registered mesh, and cut to the radius on each mesh.
    feature_threshold : float, default 0.05
        Mean curvatures below this magnitude (1/mm) are zeroed (the paper's
        0.05), softly: ``sign(H) max(|H| - t, 0)``, so the feature images have
        no jumps at the threshold (a hard cut made correctly registered
        meshes drift by up to 2 pixels in our tests).
    confidence_floor : float or None, default 0.01
        Weight of the data term of eq. 11 per vertex: the local strength of
        the features around the vertex (RMS of the source image over a few
        pixels, relative to a quarter of the 99th-percentile feature), clipped
        to ``[confidence_floor, 1]``. Where a face has no detail (a smooth
        cheek) an optical flow is guesswork; there the Laplacian term carries
        the motion of the detailed parts instead. None weights every vertex
        1, the paper's eq. 11 as printed.
    snap_distance_mm : float, default 0.5
        Vertices farther than this from their scan before refinement (over
        holes, beyond a cropped border) are not moved by the flow nor snapped.
    backend : {'auto', 'pardiso', 'scipy'}
        Sparse solver of eq. 11 (:class:`~facecap.mesh.factor_spd.SpdFactor`).

    Returns
    -------
    Refinement
        Refined vertices, misalignment before and after, flagged scans,
        neighbours, regions, distances to the scans.

    Raises
    ------
    InputError
        On shapes or counts that do not match, fewer than 2 meshes, region
        labels or user correspondences out of range, or invalid options.
    MeshError
        If ``F`` or a scan is malformed.

    Notes
    -----
    Eq. 8 of Huang et al. [1]_,
    ``argmin sum_i sum_r sum_m |G(d'_{i,r}) - G(d'_{i_m,r})|^2`` with
    ``d'_i in Surf(d_i)``, is solved one mesh at a time (eq. 9), in place
    (Gauss-Seidel: a mesh sees the others' latest correspondences).

    *Flow direction.* The flow runs from each target channel to the source
    image, so its value at a vertex's own pixel ``p_j`` says where on mesh
    ``i`` the feature of vertex ``j`` lies: ``p_j + flow(p_j)``. This is the
    inverse of the paper's source-to-target offset, evaluated where it is
    needed. OpenCV's flows take one channel, hence the averaging.

    *Regions.* Each region's support is its triangles in the image, dilated
    by ``overlap_mm``; flows are computed on the support's bounding box with
    everything outside it blank. Region flows are blended with
    ``w_r = 1 - cos(pi d / (2 l_d))`` (eq. 10), ``d`` the distance to the edge
    of region ``r``'s support inside the face and ``l_d`` the overlap width
    (twice ``overlap_mm``), ``w_r = 1`` beyond ``l_d``.

    *Update.* ``argmin sum_j c_j |v'_j - v_j - dv_j|^2 + alpha |L v' - L v|^2``
    (eq. 11, ``c_j`` the confidence, 1 in the paper) with the cotangent
    Laplacian ``L`` of the current mesh (edge weights clipped to +-10 so slivers
    cannot make it singular): one SPD factorisation per mesh update. Where the
    update would flip triangles, it is dropped around them (two rings) and
    solved again; triangles that still flip get their vertices put back.
    Vertices hidden in the image (inside a fold of the map) and
    displacements that jump across a fold keep ``dv = 0``. Neighbours are
    chosen once, from the input registrations.

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture and
       3D scanning for high-fidelity facial performance acquisition", ACM
       SIGGRAPH 2011, section 6.2.

    Examples
    --------
    Two scans of the same bumpy patch, registered consistently, stay as they are:

    >>> import numpy as np
    >>> from facecap.structures import Mesh
    >>> x, y = np.meshgrid(np.linspace(-20, 20, 21), np.linspace(-20, 20, 21))
    >>> z = 2 * np.exp(-(x**2 + y**2) / 20) - 1.5 * np.exp(-((x - 8) ** 2 + (y + 6) ** 2) / 12)
    >>> V = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    >>> a = (np.arange(20)[:, None] * 21 + np.arange(20)[None]).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 21], 1), np.stack([a + 1, a + 22, a + 21], 1)])
    >>> result = refine_registration(np.stack([V, V]), F, [Mesh(V, F), Mesh(V, F)], backend="scipy")
    >>> float(np.abs(result.vertices - V).max()) < 1e-3
    True
    """
    D0, Fw, back, keep = _validated_meshes(registered, F, scans)
    K, nw = D0.shape[0], D0.shape[1]
    n_full = back.size
    M = as_count(neighbours, name="neighbours")
    n_iter = as_count(iterations, name="iterations", minimum=0)
    alpha = as_positive(alpha, name="alpha", allow_zero=True)
    if flow not in ("farneback", "dis"):
        raise InputError(f"flow: expected 'farneback' or 'dis', got {flow!r}")
    if average not in ("flows", "images"):
        raise InputError(f"average: expected 'flows' or 'images', got {average!r}")
    if error_threshold is not None:
        error_threshold = as_positive(error_threshold, name="error_threshold", allow_zero=True)
    constraint_weight = as_positive(constraint_weight, name="constraint_weight")
    feature_threshold = as_positive(feature_threshold, name="feature_threshold", allow_zero=True)
    snap_distance = as_positive(snap_distance_mm, name="snap_distance_mm", allow_zero=True)
    if confidence_floor is not None:
        confidence_floor = as_positive(confidence_floor, name="confidence_floor")
        if confidence_floor > 1:
            raise InputError(f"confidence_floor: expected a number in (0, 1] or None, got {confidence_floor!r}")
    if curvature_radius_mm is not None:
        curvature_radius_mm = as_positive(curvature_radius_mm, name="curvature_radius_mm")
    constraints = _validated_constraints(user_correspondences, K, n_full, back, D0)

    mean_mesh = D0.mean(axis=0)
    edge = median_edge_length(mean_mesh, Fw)
    if forward is None:
        normals = igl.per_vertex_normals(mean_mesh, Fw)
        forward = np.nansum(normals, axis=0)
    # image scale: fit once with a nominal size, then rescale to the pixel size wanted
    probe = cylindrical_map(mean_mesh, axis=axis, forward=forward, size_px=64, margin_px=2)
    extent_mm = (probe.shape[1] - 1 - 4) / probe.px_per_mm, (probe.shape[0] - 1 - 4) / probe.px_per_mm
    pix = 0.5 * edge if pixel_mm is None else as_positive(pixel_mm, name="pixel_mm")
    size_px = int(np.clip(np.ceil(max(extent_mm) / pix), 64, 1024 if pixel_mm is None else 8192))
    cmap = cylindrical_map(mean_mesh, axis=axis, forward=forward, centre=probe.centre, size_px=size_px, margin_px=4)
    overlap_px = (0.04 * max(cmap.shape) if overlap_mm is None
                  else as_positive(overlap_mm, name="overlap_mm") * cmap.px_per_mm)
    overlap_px = max(int(round(overlap_px)), 1)

    labels_full = _region_labels(region_labels, n_full, cmap, back)
    labels = labels_full[keep]
    n_regions = int(labels.max()) + 1
    region_vertices = [np.flatnonzero(labels == r) for r in range(n_regions)]
    nbrs = _closest_meshes(D0, region_vertices, M)                          # (K, R, M)

    # curvature neighbourhoods: searched once on the mean mesh (wider), cut to the radius on each mesh
    radius = curvature_radius_mm if curvature_radius_mm is not None else 2.5 * edge
    _, candidates = cKDTree(mean_mesh).query(mean_mesh, k=min(_CURVATURE_NEIGHBOURS, nw),
                                             distance_upper_bound=1.5 * radius)
    candidates = candidates.reshape(nw, -1).astype(np.int32)

    def features(i: int, V: FloatArray) -> FloatArray:
        return mean_curvature(V, Fw, radius_mm=radius, threshold=feature_threshold, threshold_mode="soft",
                              max_neighbours=_CURVATURE_NEIGHBOURS, neighbours=candidates)

    G = np.stack([features(i, D0[i]) for i in range(K)])
    nonzero = np.abs(G[G != 0])
    scale = 1.0 / (float(np.percentile(nonzero, 99)) if nonzero.size else 1.0)
    before = _misalignment(G, nbrs, region_vertices)

    trees, scan_data = [], []
    for s in scans:
        tree = igl.AABB()
        tree.init(s.vertices, s.faces)
        trees.append(tree)
        scan_data.append((s.vertices, s.faces))
    on_scan = np.stack([
        np.sqrt(trees[i].squared_distance(*scan_data[i], D0[i])[0]) <= snap_distance for i in range(K)
    ])

    D = D0.copy()
    flow_fn = partial(optical_flow, method=flow)
    for _ in range(n_iter):
        for i in range(K):
            V = D[i]
            pixels = cmap.project(V)
            raster = cmap.rasterise(Fw, pixels=pixels)
            visible = visible_in_raster(raster)
            offset, strength = _region_flow(raster, labels, G, i, nbrs[i], n_regions, overlap_px, scale, flow_fn,
                                            average)
            delta = cmap.sample(offset, pixels, fill=0.0)
            if confidence_floor is None:
                confidence = np.ones(V.shape[0])
            else:
                confidence = np.clip(cmap.sample(strength, pixels, fill=0.0) / _STRONG_FEATURE, confidence_floor, 1.0)
            target, found = raster.surface_points(pixels + delta, V)
            dv = np.where(found[:, None], target - V, 0.0)
            # a displacement far longer than its flow jumped across a fold of the map
            limit = 3.0 * np.linalg.norm(delta, axis=1) / cmap.px_per_mm + 2.0 / cmap.px_per_mm
            movable = visible & found & on_scan[i] & (np.linalg.norm(dv, axis=1) <= limit)
            dv[~movable] = 0.0
            D[i] = regularised_update(V, Fw, dv, confidence, scans[i], on_scan[i], alpha=alpha,
                                      constraints=constraints.get(i, []), constraint_weight=constraint_weight,
                                      scan_tree=trees[i], backend=backend)
            G[i] = features(i, D[i])
    after = _misalignment(G, nbrs, region_vertices)

    distance = np.stack([np.sqrt(trees[i].squared_distance(*scan_data[i], D[i])[0]) for i in range(K)])
    return Refinement(
        vertices=np.ascontiguousarray(D[:, back]),
        misalignment_before=before,
        misalignment_after=after,
        flagged=after > (2.0 * float(np.median(after)) if error_threshold is None else error_threshold),
        neighbours=nbrs,
        region_labels=labels_full,
        distance_to_scan_mm=np.ascontiguousarray(distance[:, back]),
    )


# ----------------------------------------------------------------------------- validation


def _validated_meshes(registered: Any, F: Any,
                      scans: Sequence[Mesh]) -> tuple[FloatArray, IntArray, IntArray, IntArray]:
    """Registrations welded along seams: (K, nw, 3) vertices, faces, welded index, kept vertices."""
    try:
        D = np.ascontiguousarray(registered, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"registered: expected a numeric (K, n, 3) array ({exc})") from None
    if D.ndim != 3 or D.shape[2] != 3 or D.shape[1] < 3:
        raise InputError(f"registered: expected shape (K, n, 3) with n >= 3, got {D.shape}")
    if D.shape[0] < 2:
        raise InputError(f"registered: fine-scale registration aligns meshes with each other; got {D.shape[0]} mesh")
    if not np.all(np.isfinite(D)):
        raise InputError("registered: contains NaN or infinite values")
    Fa = as_faces(F, D.shape[1], name="F")
    if len(scans) != D.shape[0]:
        raise InputError(f"scans: expected {D.shape[0]} scans (one per registration), got {len(scans)}")
    for k, s in enumerate(scans):
        if not isinstance(s, Mesh):
            raise InputError(f"scans[{k}]: expected a facecap Mesh, got {type(s).__name__}")
    # weld seam duplicates: vertices that coincide in every registration (not just in one)
    rep = weld_duplicate_vertices(D[0], Fa, tolerance=1e-6).welded_index
    _, first = np.unique(rep, return_index=True)
    rep_vertex = first[rep]                                             # lowest vertex of each group
    same = np.all(np.linalg.norm(D - D[:, rep_vertex], axis=2) <= 1e-6, axis=0)
    rep_vertex = np.where(same, rep_vertex, np.arange(D.shape[1]))
    keep, back = np.unique(rep_vertex, return_inverse=True)
    return np.ascontiguousarray(D[:, keep]), back[Fa], back.astype(np.int64), keep


def _validated_constraints(items: Sequence[UserCorrespondence] | None, K: int, n: int, back: IntArray,
                           D0: FloatArray) -> dict[int, list[tuple[int, FloatArray]]]:
    """Per mesh, the (welded vertex, target point) pairs of the user's correspondences."""
    out: dict[int, list[tuple[int, FloatArray]]] = {}
    for c, item in enumerate(items or ()):
        try:
            a, va, b, pb = item
        except (TypeError, ValueError):
            raise InputError(f"user_correspondences[{c}]: expected (scan_a, vertex_a, scan_b, point_b)") from None
        for value, limit, what in ((a, K, "scan_a"), (b, K, "scan_b"), (va, n, "vertex_a")):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < limit:
                raise InputError(f"user_correspondences[{c}]: {what} must be an integer in [0, {limit}), got {value!r}")
        p = np.asarray(pb, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InputError(f"user_correspondences[{c}]: point_b must be a finite (3,) point in mm, got {p.shape}")
        w = int(back[va])
        out.setdefault(int(a), []).append((w, D0[a, w].copy()))
        out.setdefault(int(b), []).append((w, p))
    return out


def _region_labels(labels: Any, n: int, cmap: CylindricalMap, back: IntArray) -> IntArray:
    """The given region labels, checked, or 8 regions from a 2 x 4 grid of the cylindrical image."""
    if labels is None:
        u, v = cmap.pixels[:, 0], cmap.pixels[:, 1]
        col = (u > np.median(u)).astype(np.int64)
        row = np.searchsorted(np.quantile(v, [0.25, 0.5, 0.75]), v, side="right")
        welded_labels = row * 2 + col
        return welded_labels[back]
    lab = np.asarray(labels)
    if lab.shape != (n,) or not np.issubdtype(lab.dtype, np.integer):
        raise InputError(f"region_labels: expected ({n},) integers, got {lab.shape} {lab.dtype}")
    lab = lab.astype(np.int64)
    if lab.min() < 0:
        raise InputError("region_labels: labels must be non-negative")
    _, dense = np.unique(lab, return_inverse=True)
    return dense.astype(np.int64)


# ----------------------------------------------------------------------------- steps


def _closest_meshes(D: FloatArray, region_vertices: list[IntArray], M: int) -> IntArray:
    """(K, R, M): per mesh and region, the M other meshes with the smallest mean vertex distance."""
    K = D.shape[0]
    M = min(M, K - 1)
    R = len(region_vertices)
    out = np.zeros((K, R, M), dtype=np.int64)
    for i in range(K):
        dist = np.linalg.norm(D - D[i][None], axis=2)                  # (K, n)
        per_region = np.stack([dist[:, vr].mean(axis=1) if vr.size else np.zeros(K) for vr in region_vertices], 1)
        per_region[i] = np.inf
        out[i] = np.argsort(per_region, axis=0, kind="stable")[:M].T
    return out


def _misalignment(G: FloatArray, nbrs: IntArray, region_vertices: list[IntArray]) -> FloatArray:
    """(K,) RMS of G_i - G_neighbour over regions, neighbours and region vertices (1/mm)."""
    K = G.shape[0]
    out = np.zeros(K)
    for i in range(K):
        total, count = 0.0, 0
        for r, vr in enumerate(region_vertices):
            diff = G[i, vr][None] - G[nbrs[i, r]][:, vr]
            total += float(np.sum(diff * diff))
            count += diff.size
        out[i] = np.sqrt(total / max(count, 1))
    return out


def _region_flow(raster: TriangleRaster, labels: IntArray, G: FloatArray, i: int, nbrs_i: IntArray,
                 n_regions: int, overlap_px: int, scale: float, flow_fn: Any,
                 average: str) -> tuple[FloatArray, FloatArray]:
    """(h, w, 2) flow image of mesh i: per-region flows from its neighbours' features, blended (eq. 10)."""
    h, w = raster.face.shape
    covered = raster.covered
    tri_label = _triangle_labels(labels, raster.F)
    pixel_label = np.where(covered, tri_label[np.where(covered, raster.face, 0)], -1)
    used = np.unique(nbrs_i)
    channel_of = {int(k): c for c, k in enumerate(used)}
    source = raster.interpolate(G[i]) * scale
    targets = raster.interpolate(G[used].T) * scale                    # (h, w, len(used))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * overlap_px + 1, 2 * overlap_px + 1))
    total = np.zeros((h, w, 2))
    weight_sum = np.zeros((h, w))
    for r in range(n_regions):
        core = (pixel_label == r).astype(np.uint8)
        if not core.any():
            continue
        support = (cv2.dilate(core, kernel) > 0) & covered
        rows, cols = np.nonzero(support)
        r0, r1 = max(rows.min() - 2, 0), min(rows.max() + 3, h)
        c0, c1 = max(cols.min() - 2, 0), min(cols.max() + 3, w)
        sup = support[r0:r1, c0:c1]
        src = np.where(sup, source[r0:r1, c0:c1], 0.0)
        if average == "images":
            tmean = np.mean([targets[r0:r1, c0:c1, channel_of[int(k)]] for k in nbrs_i[r]], axis=0)
            region_flow = flow_fn(np.where(sup, tmean, 0.0), src)
        else:
            flows = [flow_fn(np.where(sup, targets[r0:r1, c0:c1, channel_of[int(k)]], 0.0), src) for k in nbrs_i[r]]
            region_flow = np.mean(flows, axis=0)
        # eq. 10: weight rises as 1 - cos from the edge of the support (inside the face) to l_d = 2 overlap
        inside = (support | ~covered).astype(np.uint8)
        d = cv2.distanceTransform(inside, cv2.DIST_L2, 5)[r0:r1, c0:c1]
        wr = np.where(sup, 1.0 - np.cos(0.5 * np.pi * np.minimum(d / (2.0 * overlap_px), 1.0)), 0.0)
        total[r0:r1, c0:c1] += wr[:, :, None] * region_flow
        weight_sum[r0:r1, c0:c1] += wr
    offset = np.where(weight_sum[:, :, None] > 0, total / np.maximum(weight_sum, 1e-300)[:, :, None], 0.0)
    strength = np.sqrt(cv2.GaussianBlur(np.where(covered, source, 0.0) ** 2, (0, 0), _STRENGTH_SIGMA_PX))
    return offset, strength


def _triangle_labels(labels: IntArray, F: IntArray) -> IntArray:
    """Region of each triangle: the label two or three of its corners share, else the first corner's."""
    a, b, c = labels[F[:, 0]], labels[F[:, 1]], labels[F[:, 2]]
    return np.where(b == c, b, a)
