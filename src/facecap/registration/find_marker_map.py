"""Find where each marker of a take sits on a face scan, with no hand work: the map that ``facecap map`` writes.

The rest frame's markers sample the face's shape. A global search finds the rigid pose that lays them
on the scan's surface (the scan may be a whole head with neck and ears, in any scanner frame, the take
in any mocap frame), trimmed point-to-plane ICP refines it, the markers follow the take's own motion
directions until they touch the skin (the actor's resting face need not be the scan's), and each
marker is snapped to the skin under it.
"""

from __future__ import annotations

from typing import NamedTuple

import igl
import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError, MarkerError, SolverError
from ..markers.rigid_fit import rigid_fit
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_marker_positions, as_points, as_positive, as_rigid_transform, as_vertices
from .register_markers_to_scan import register_markers_to_scan, scan_winding
from .rigid_icp import ClosestPointSurface, rigid_icp_to_surface

__all__ = ["MarkerMap", "find_marker_map", "marker_status", "MIN_MAP_MARKERS", "DEFAULT_OFF_SKIN_MM",
           "DEFAULT_AMBIGUITY_MM", "DEFAULT_UNCERTAIN_MM", "UNSURE_SCORE_RATIO", "ALONG_SKIN_FLOOR_MM",
           "ALONG_SKIN_PER_HEIGHT"]

MIN_MAP_MARKERS = 4
"""Fewest markers seen at the rest frame that :func:`find_marker_map` accepts."""

DEFAULT_OFF_SKIN_MM = 3.0
"""A marker whose centre is further than this from where the marker offset puts it (above its skin point)
is not placed: a head band, a marker on the hair or off the scan's surface."""

DEFAULT_AMBIGUITY_MM = 2.0
"""A placed marker is ambiguous when another sheet of skin (the other lip, the other eyelid) comes within
this distance of its own skin's distance to the marker centre."""

DEFAULT_UNCERTAIN_MM = 1.0
"""A placed marker that may be further than this from its true place along the skin (``may_be_off_mm``) is
flagged uncertain."""

ALONG_SKIN_FLOOR_MM = 0.45
"""How far a placed marker may be off its true place where the fit left it on the marker offset, mm: the
90th percentile of the errors of such markers on the tuned generated takes (the rest frame's noise, the
snap, and expressions the skin's shape does not show)."""

ALONG_SKIN_PER_HEIGHT = 3.0
"""How far along the skin a placed marker may be off per mm the fit left its centre off the marker offset.
A resting expression the take's motion cannot take out (a lip rolled in, a frown) moves the skin along
itself and off itself together; what is left off the skin after the fit shows how much of it is left,
and on the tuned generated takes the error along the skin was within 3 times that (with
:data:`ALONG_SKIN_FLOOR_MM` added in quadrature) for 9 markers in 10."""

_OFF_SKIN_SPREADS = 6.0
"""Where the markers fit the scan loosely (another person's face), a marker is off the skin only beyond this
many robust deviations (1.4826 median absolute) of all markers' heights off the offset, if that exceeds
``max_off_skin_mm``: on the bundled real take the markers sit up to 6.3 mm off the generic face's skin."""

_MAX_EXPRESSION_RMS_MM = 1.5
"""Largest RMS motion of the markers along the take's motion directions accepted as a resting expression
(a resting face moved the generated takes' markers 0.2-0.8 mm RMS); beyond it the scan is not this face at
rest (the bundled real take: 9.8 mm, another person's face), and the markers are placed rigidly."""

UNSURE_SCORE_RATIO = 2.0
"""The search is unsure when the second-best distinct pose's score is within this factor of the best's."""

_SEARCH_VERTICES = 40_000
"""Scan vertices (evenly strided) the coarse search looks at; a dense scan's others add time, not shape."""

_SEARCH_MARKERS = 40
"""Markers (farthest-point sample) the coarse search moves; more add time, not reliability."""

_DIRECTIONS = 200
"""Directions (a Fibonacci sphere) tried for where the markers' facing direction goes on the scan."""

_ROLLS = 24
"""Rotations about that direction tried for each."""

_COARSE_ITERATIONS = 20
"""ICP steps of the coarse search."""

_POINT_TO_POINT_ITERATIONS = 8
"""The first of them point-to-point (wide basin), the rest point-to-plane (fast convergence)."""

_KEEP_AFTER = {1: 0.2, 3: 0.25, 6: 0.25, 9: 0.5}
"""Successive halving: after these coarse iterations, the best fraction of the candidates goes on."""

_MIN_KEPT = 64
"""Fewest candidates the halving keeps."""

_DISTINCT_MM = 10.0
"""Two poses are the same when the markers they place differ by less than this (RMS, mm)."""

_REFINED = 8
"""Distinct poses refined with exact closest points and compared."""

_REGISTRATION_TRIM = 1.0
"""Inlier fraction of the final fit: every marker on the skin counts (trimming 20 % dropped the very markers
the resting expression moved most, and left 10 of 102 markers of a take 1.5-2 mm off instead of 2)."""

_TRUNCATE_MM = 6.0
"""Residual cap of the coarse score: a marker off the skin (head band) costs this much and no more."""

_SCORE_CAP_MM = 3.0
"""Residual cap of the exact score that ranks the refined poses."""

_SCORE_KEPT = 0.85
"""Fraction of the markers (those nearest the skin) that count in that score."""

_GRID_VOXELS = 2_000_000
"""Largest voxel count of the nearest-vertex grid of the coarse search."""


class MarkerMap(NamedTuple):
    """Where each marker sits on the scan, found by :func:`find_marker_map`.

    Attributes
    ----------
    surface_points : (M, 3) float64 array, mm
        The skin point under each marker, in scan coordinates; NaN for a
        marker not placed.
    face_indices : (M,) int64 array
        Scan triangle holding each surface point; -1 where not placed.
    barycentric : (M, 3) float64 array
        Barycentric coordinates of the surface point in that triangle (NaN where not placed).
    markers_on_scan : (M, 3) float64 array, mm
        The rest markers moved onto the scan: the rigid pose, then the take's
        motion directions (see Notes); NaN for markers not seen.
    heights : (M,) float64 array, mm
        Distance from each marker centre to its skin point (the marker offset
        where the marker fits); NaN for markers not seen.
    placed : (M,) bool array
        Markers given a place.
    off_skin : (M,) bool array
        Seen markers further than ``max_off_skin_mm`` from where the offset puts them (not placed).
    past_rim : (M,) bool array
        Seen markers whose skin point would lie on the scan's boundary: over a
        hole or past the scan's rim (not placed).
    unseen : (M,) bool array
        Markers missing at the rest frame (not placed).
    ambiguous : (M,) bool array
        Placed markers with a second sheet of skin close under them (the lips, the eyelids).
    second_sheet_mm : (M,) float64 array, mm
        Distance from each marker centre to the nearest other sheet of skin
        near it; inf where there is none within reach, NaN where not placed.
    may_be_off_mm : (M,) float64 array, mm
        How far each placed marker may be from its true place along the skin
        (nine in ten within it on the tuned generated takes): grows with how
        far the fit left the marker centre off the marker offset (see Notes);
        NaN where not placed.
    uncertain : (M,) bool array
        Placed markers whose ``may_be_off_mm`` exceeds ``uncertain_mm``: the
        resting face (or the face itself) differs from the scan there.
    rotation : (3, 3) float64 array
        Rigid rotation from the take's (mocap) frame to the scan's.
    translation : (3,) float64 array, mm
        Rigid translation from the take's frame to the scan's.
    rms_mm : float
        RMS of ``heights - marker_offset_mm`` over the placed markers, mm.
    score_mm : float
        Score of the chosen pose: RMS distance of the 85 % best-fitting markers
        from where the offset puts them, each capped at 3 mm, mm.
    second_score_mm : float
        The same for the best pose distinct from it (markers more than 10 mm
        RMS away); inf when the search found none, NaN when it did not run
        (a starting pose was given).
    sure : bool
        The search is sure: the second-best distinct pose scores more than
        :data:`UNSURE_SCORE_RATIO` times the best (always True with a given start).
    normals_flipped : bool
        The scan's triangles face into the head (the markers were fitted on their back side).
    off_skin_limit_mm : float
        The height off the marker offset beyond which a marker was taken as off
        the skin: ``max_off_skin_mm``, or more where the markers fit the scan
        loosely (see :data:`_OFF_SKIN_SPREADS`), mm.
    expression_rms_mm : float
        RMS distance the markers moved along the take's motion directions to
        touch the skin (the resting expression taken out), mm; NaN without ``motion``.
    expression_kept : bool
        That motion was kept; False without ``motion``, or when it exceeded
        1.5 mm RMS (no resting face moves markers that far: the scan is another
        face, and the markers were placed rigidly).
    """

    surface_points: FloatArray
    face_indices: IntArray
    barycentric: FloatArray
    markers_on_scan: FloatArray
    heights: FloatArray
    placed: BoolArray
    off_skin: BoolArray
    past_rim: BoolArray
    unseen: BoolArray
    ambiguous: BoolArray
    second_sheet_mm: FloatArray
    may_be_off_mm: FloatArray
    uncertain: BoolArray
    rotation: FloatArray
    translation: FloatArray
    rms_mm: float
    score_mm: float
    second_score_mm: float
    sure: bool
    normals_flipped: bool
    off_skin_limit_mm: float
    expression_rms_mm: float
    expression_kept: bool

    @property
    def matrix(self) -> FloatArray:
        """(4, 4) float64 homogeneous matrix of the rigid pose (take frame to scan frame, mm)."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.rotation, self.translation
        return T


def marker_status(found: MarkerMap) -> list[str]:
    """Each marker's status as a word: 'placed', 'ambiguous', 'uncertain', 'off the skin', 'past the rim' or 'not seen'.

    A marker both ambiguous and uncertain is 'ambiguous' (the two sheets are the likelier cause).
    """
    out = []
    for k in range(found.placed.size):
        if found.unseen[k]:
            out.append("not seen")
        elif found.off_skin[k]:
            out.append("off the skin")
        elif found.past_rim[k]:
            out.append("past the rim")
        elif found.ambiguous[k]:
            out.append("ambiguous")
        elif found.uncertain[k]:
            out.append("uncertain")
        else:
            out.append("placed")
    return out


def _fibonacci_sphere(n: int) -> FloatArray:
    """(n, 3) unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)


def _frames_with_third_axis(d: FloatArray) -> FloatArray:
    """(k, 3, 3) rotations whose third column is each unit vector of ``d`` (k, 3)."""
    helper = np.where(np.abs(d[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return np.stack([u, np.cross(d, u), d], axis=2)


def _farthest_points(X: FloatArray, k: int) -> IntArray:
    """Indices of ``k`` rows of ``X`` chosen by farthest-point sampling (from the first row)."""
    chosen = [0]
    d = np.linalg.norm(X - X[0], axis=1)
    for _ in range(min(k, X.shape[0]) - 1):
        j = int(np.argmax(d))
        chosen.append(j)
        d = np.minimum(d, np.linalg.norm(X - X[j], axis=1))
    return np.array(chosen, dtype=np.int64)


class _NearestVertexGrid:
    """The nearest scan vertex of every voxel of a grid round the scan (a Euclidean distance transform).

    The coarse search asks for the nearest vertex of millions of points; a KD-tree answers each in
    microseconds, a lookup in this grid in nanoseconds, to within half a voxel's diagonal.
    """

    def __init__(self, P: FloatArray, margin_mm: float) -> None:
        lo, hi = P.min(axis=0) - margin_mm, P.max(axis=0) + margin_mm
        self.voxel = max(1.0, float(np.prod(hi - lo) / _GRID_VOXELS) ** (1.0 / 3.0))
        self.origin = lo
        self.shape = np.ceil((hi - lo) / self.voxel).astype(np.int64) + 1
        cell = self._cells(P)
        empty = np.ones(tuple(self.shape), dtype=bool)
        empty[cell[:, 0], cell[:, 1], cell[:, 2]] = False
        owner = np.zeros(tuple(self.shape), dtype=np.int64)
        owner[cell[:, 0], cell[:, 1], cell[:, 2]] = np.arange(P.shape[0])
        index = ndimage.distance_transform_edt(empty, return_distances=False, return_indices=True)
        self.nearest = owner[index[0], index[1], index[2]].ravel()

    def _cells(self, Y: FloatArray) -> IntArray:
        c = np.floor((Y - self.origin) / self.voxel).astype(np.int64)
        return np.clip(c, 0, self.shape - 1)

    def query(self, Y: FloatArray) -> IntArray:
        """Index (into the grid's points) of the nearest point of each (..., 3) query, to within a voxel."""
        c = self._cells(Y.reshape(-1, 3))
        flat = (c[:, 0] * self.shape[1] + c[:, 1]) * self.shape[2] + c[:, 2]
        return self.nearest[flat].reshape(Y.shape[:-1])


def _point_to_plane_steps(
    Y: FloatArray, n: FloatArray, h: FloatArray, weights: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """One linearised point-to-plane step per candidate: (N, 3, 3) rotations and (N, 3) translations.

    Minimises ``sum_k w_k (h_k + n_k . (w x (y_k - y0) + tau))^2`` over a small rotation ``w`` about
    the weighted centroid ``y0`` and a translation ``tau`` (Chen and Medioni's linearisation, as
    :func:`~facecap.registration.rigid_icp` takes it), for every candidate at once.
    """
    from scipy.spatial.transform import Rotation

    w = weights / weights.sum(axis=1, keepdims=True)
    y0 = np.einsum("nk,nkd->nd", w, Y)
    A = np.concatenate([np.cross(Y - y0[:, None], n), n], axis=2)  # (N, k, 6)
    AtA = np.einsum("nk,nki,nkj->nij", w, A, A) + 1e-6 * np.eye(6)
    Atb = -np.einsum("nk,nki,nk->ni", w, A, h)
    x = np.linalg.solve(AtA, Atb[..., None])[..., 0]
    dR = Rotation.from_rotvec(x[:, :3]).as_matrix()
    dt = y0 - np.einsum("nij,nj->ni", dR, y0) + x[:, 3:]
    return dR, dt


def _search_poses(
    X: FloatArray, V: FloatArray, F: IntArray, normals: FloatArray, offset: float
) -> list[tuple[FloatArray, FloatArray, float]]:
    """Distinct rigid poses (R, t, coarse score) laying the markers ``X`` on the scan, best first.

    Candidates: the markers' facing direction (the least principal axis of the markers, either sign)
    sent to each of :data:`_DIRECTIONS` directions, rolled :data:`_ROLLS` ways about it, placed with
    the markers' front on the scan's front along that direction and their centroid over the centroid
    of the scan's cap there (as deep as the markers). Each is refined by point-to-plane ICP against
    the nearest vertex (a voxel lookup), the worse ones dropped as it goes (successive halving).
    """
    every = np.unique(F)
    used = every[:: max(1, every.size // _SEARCH_VERTICES)]  # a coarse search needs no more
    P, N = V[used], normals[used]
    spacing = float(np.median(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1))) * np.sqrt(every.size / used.size)
    centre = X.mean(axis=0)
    Xc = X - centre
    _, axes = np.linalg.eigh(np.cov(Xc.T))
    facing = axes[:, 0]
    along = Xc @ facing
    depth = float(along.max() - along.min())
    S = Xc[_farthest_points(Xc, _SEARCH_MARKERS)]
    grid = _NearestVertexGrid(P, margin_mm=depth)
    area = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI).diagonal()[used]

    directions = _fibonacci_sphere(_DIRECTIONS)
    height = P @ directions.T  # (n, D)
    top = height.max(axis=0)
    in_cap = height >= top - depth
    cap_centre = ((in_cap * area[:, None]).T @ P) / (in_cap.T @ area)[:, None]  # (D, 3)
    scan_frames = _frames_with_third_axis(directions)
    roll = np.linspace(0.0, 2.0 * np.pi, _ROLLS, endpoint=False)
    Rz = np.zeros((_ROLLS, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = (
        np.cos(roll), -np.sin(roll), np.sin(roll), np.cos(roll), 1.0)
    rotations, translations = [], []
    for sign in (1.0, -1.0):
        marker_frame = _frames_with_third_axis(sign * facing[None])[0]
        front = float(np.max(Xc @ (sign * facing)))
        R = np.einsum("dij,rjk,lk->dril", scan_frames, Rz, marker_frame)  # (D, r, 3, 3)
        lateral = cap_centre - np.einsum("dk,dk->d", cap_centre, directions)[:, None] * directions
        t = lateral + (top + offset - front)[:, None] * directions
        rotations.append(R.reshape(-1, 3, 3))
        translations.append(np.repeat(t, _ROLLS, axis=0))
    R = np.concatenate(rotations)
    t = np.concatenate(translations)

    def residuals(Y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        j = grid.query(Y)
        n = N[j]
        h = np.einsum("nkd,nkd->nk", Y - P[j], n) - offset
        d = np.linalg.norm(Y - P[j], axis=-1)
        # near the surface the signed height over the nearest vertex's tangent plane; off it, the distance
        r = np.where(d < 3.0 * spacing + abs(offset) + grid.voxel, np.abs(h), d)
        return r, h, n

    score = np.full(R.shape[0], np.inf)
    for it in range(_COARSE_ITERATIONS):
        Y = np.einsum("nij,kj->nki", R, S) + t[:, None]
        r, h, n = residuals(Y)
        score = np.sqrt(np.mean(np.minimum(r, _TRUNCATE_MM) ** 2, axis=1))
        if it in _KEEP_AFTER:
            keep = np.argsort(score)[: max(_MIN_KEPT, int(_KEEP_AFTER[it] * score.size))]
            R, t, Y, r, h, n, score = R[keep], t[keep], Y[keep], r[keep], h[keep], n[keep], score[keep]
        reach = _TRUNCATE_MM + 4.0 * max(0, 6 - it)  # pairs further than this pull nothing; it shrinks
        weights = (r < reach).astype(np.float64) + 1e-9
        if it < _POINT_TO_POINT_ITERATIONS:  # far from the surface: the wide basin of point-to-point
            fit = rigid_fit(Y, Y - h[..., None] * n, weights=weights)
            dR, dt = fit.rotation, fit.translation
        else:
            dR, dt = _point_to_plane_steps(Y, n, h, weights)
        R = np.einsum("nij,njk->nik", dR, R)
        t = np.einsum("nij,nj->ni", dR, t) + dt
    Y = np.einsum("nij,kj->nki", R, S) + t[:, None]
    score = np.sqrt(np.mean(np.minimum(residuals(Y)[0], _TRUNCATE_MM) ** 2, axis=1))
    distinct: list[tuple[FloatArray, FloatArray, float]] = []
    placed: list[FloatArray] = []
    for i in np.argsort(score):
        if any(np.sqrt(np.mean(np.sum((Y[i] - Z) ** 2, axis=1))) < _DISTINCT_MM for Z in placed):
            continue
        placed.append(Y[i])
        distinct.append((R[i], t[i] - R[i] @ centre, float(score[i])))
        if len(distinct) == _REFINED:
            break
    return distinct


def _motion_subspace(motion: FloatArray, rest: FloatArray, seen: BoolArray, n_modes: int) -> FloatArray | None:
    """(K, M, 3) frames ``rest + mode_k``: the take's principal motion directions, RMS-sized; None without motion.

    ``motion`` holds head-stabilised frames; the frames that see every marker seen at rest give the
    directions (principal components of their displacement from ``rest``).
    """
    D = motion[:, seen] - rest[None, seen]
    complete = np.isfinite(D).all(axis=(1, 2))
    if complete.sum() <= n_modes or n_modes == 0:
        return None
    rows = D[complete].reshape(int(complete.sum()), -1)
    _, singular, Vt = np.linalg.svd(rows, full_matrices=False)
    size = singular[:n_modes] / np.sqrt(rows.shape[0])
    modes = np.zeros((n_modes, rest.shape[0], 3))
    modes[:, seen] = (Vt[:n_modes] * size[:, None]).reshape(n_modes, -1, 3)
    return np.where(seen[None, :, None], rest[None] + modes, np.nan)


def _pose_score(distances: FloatArray, offset: float) -> float:
    """Trimmed RMS of the markers' distances to the surface less the offset, each capped (mm).

    The :data:`_SCORE_KEPT` fraction of markers nearest the offset count, each at most
    :data:`_SCORE_CAP_MM`: a few markers off the skin (a head band) neither decide nor blur the ranking.
    """
    r = np.minimum(np.abs(distances - offset), _SCORE_CAP_MM)
    r = np.sort(np.where(np.isfinite(r), r, _SCORE_CAP_MM))
    kept = r[: max(3, int(np.ceil(_SCORE_KEPT * r.size)))]
    return float(np.sqrt(np.mean(kept**2)))


def _second_sheets(
    centres: FloatArray, skin: FloatArray, V: FloatArray, F: IntArray, reach: FloatArray
) -> FloatArray:
    """Distance from each marker centre to the nearest skin not joined to its own within ``reach`` of it.

    The scan's triangles whose corners all lie within ``reach`` (k,) of a marker centre (k, 3) fall
    into connected pieces (welded across UV seams); the piece nearest the marker's skin point
    ``skin`` (k, 3) is its own skin, any other piece another sheet: the other lip, the other eyelid.
    Returns (k,) mm, inf where no other piece comes within reach.
    """
    welded = weld_duplicate_vertices(V, F, tolerance=1e-6)
    W, Fw = welded.V, welded.F
    tree = cKDTree(W)
    out = np.full(centres.shape[0], np.inf)
    m = Fw.shape[0]
    incident = coo_matrix((np.ones(3 * m), (Fw.ravel(), np.repeat(np.arange(m), 3))), shape=(W.shape[0], m)).tocsr()
    local = np.full(W.shape[0], -1, dtype=np.int64)  # vertex -> its row among the current marker's near ones
    near = np.zeros(0, dtype=np.int64)
    for k in range(centres.shape[0]):  # a few dozen vertices per marker: a loop over the markers is cheap
        local[near] = -1
        near = np.asarray(tree.query_ball_point(centres[k], float(reach[k])), dtype=np.int64)
        if near.size < 3:
            continue
        local[near] = np.arange(near.size)
        touching = np.unique(incident[near].indices)
        tri = Fw[touching[(local[Fw[touching]] >= 0).all(axis=1)]]
        if tri.shape[0] == 0:
            continue
        e = local[np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])]
        graph = coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(near.size, near.size))
        _, piece = connected_components(graph, directed=False)
        in_tri = np.zeros(near.size, dtype=bool)
        in_tri[np.unique(local[tri])] = True
        candidates = np.flatnonzero(in_tri)
        own = piece[candidates[np.argmin(np.linalg.norm(W[near[candidates]] - skin[k], axis=1))]]
        other = in_tri & (piece != own)
        if other.any():
            sq, _, _ = igl.point_mesh_squared_distance(
                centres[k][None], W, tri[other[local[tri[:, 0]]]])
            out[k] = float(np.sqrt(sq[0]))
    return out


def find_marker_map(
    rest_markers: FloatArray,
    V: FloatArray,
    F: IntArray,
    *,
    marker_offset_mm: float = 1.5,
    motion: FloatArray | None = None,
    start: FloatArray | None = None,
    max_off_skin_mm: float = DEFAULT_OFF_SKIN_MM,
    uncertain_mm: float = DEFAULT_UNCERTAIN_MM,
    ambiguity_mm: float = DEFAULT_AMBIGUITY_MM,
    motion_modes: int = 8,
    regularization: float = 1e-3,
) -> MarkerMap:
    """Find each marker's place on a face scan from the take's rest frame, with no hand-picked points.

    Parameters
    ----------
    rest_markers : (M, 3) float64 array, mm
        The markers at the take's rest frame, in the take's (mocap) frame;
        NaN rows for markers not seen there.
    V : (n, 3) float64 array, mm
        Scan vertices, in the scan's own frame: a face or a whole head.
    F : (m, 3) int64 array
        Scan triangles, consistently wound (either way).
    marker_offset_mm : float, default 1.5
        Height of a marker centre above the skin, mm (half a 3 mm marker).
    motion : (T, M, 3) float64 array, mm, optional
        Frames of the take, head-stabilised onto the rest frame (gap-filled;
        frames with NaN among the markers seen at rest are skipped). Their
        principal motion directions let the markers follow the actor's resting
        expression back to the scan's (see Notes). None: rigid only.
    start : (4, 4) float array, optional
        A starting pose from the take's frame to the scan's (from landmarks, or
        a hand-made map); None (default) searches globally.
    max_off_skin_mm : float, default :data:`DEFAULT_OFF_SKIN_MM`
        A marker further than this from the marker offset, after the fit, is
        not placed; where the markers fit the scan loosely (another person's
        face) the limit grows to 6 robust deviations of all markers' heights
        (``off_skin_limit_mm`` of the result).
    uncertain_mm : float, default :data:`DEFAULT_UNCERTAIN_MM`
        A placed marker that may be further than this from its true place
        along the skin (``may_be_off_mm``) is flagged ``uncertain``.
    ambiguity_mm : float, default :data:`DEFAULT_AMBIGUITY_MM`
        A placed marker with another sheet of skin within its height plus this is ``ambiguous``.
    motion_modes : int, default 8
        Principal motion directions of ``motion`` used.
    regularization : float, default 1e-3
        Tikhonov weight of the motion coefficients (relative, as in
        :func:`~facecap.registration.register_markers_to_scan`).

    Returns
    -------
    MarkerMap
        The places (``surface_points``, ``face_indices``, ``barycentric``),
        the status of every marker and the pose with its score.

    Raises
    ------
    MarkerError
        If fewer than :data:`MIN_MAP_MARKERS` markers are seen at the rest frame,
        or ``motion`` does not have M markers.
    MeshError
        If the scan's arrays are malformed.
    InputError
        If an option is out of range.
    SolverError
        If no pose puts enough markers on the scan.

    Notes
    -----
    *Global search.* The least principal axis of the markers is the way the
    face looks (they cover its front). Every pairing of that axis (either
    sign) with one of 200 directions on the scan and 24 rolls about it is a
    candidate, placed with the markers' front on the scan's front along that
    direction and their centroid over the scan's cap there; 8 point-to-point
    then point-to-plane ICP steps against the nearest scan vertex (a voxel
    lookup) run on all candidates at once, the worse ones dropped as they go.
    The best 8 distinct poses (markers 10 mm RMS apart) are refined by trimmed
    point-to-plane ICP [2]_ (:func:`~facecap.registration.rigid_icp`, the
    marker offset on the outer side) and ranked by ``score_mm``: the RMS of the
    85 % best-fitting markers' distances from the offset, each capped at 3 mm,
    so that markers off the skin (a head band) neither decide nor blur it.
    ``second_score_mm`` is the best refined pose still 10 mm from the chosen one.

    *The resting expression.* The rest frame's face need not be the scan's.
    With ``motion`` the markers may move along the take's first
    ``motion_modes`` principal motion directions until they touch the skin,
    jointly with the pose (:func:`~facecap.registration.register_markers_to_scan`,
    [1]_ eqs. 4-6, every marker an inlier): the skin's normal constrains each
    marker, and the motion directions carry that to the shift along the skin
    that the surface cannot see. A fit that moves the markers more than 1.5 mm
    RMS is no resting face (another person's face: the bundled real take,
    9.8 mm) and is dropped for the rigid placement (``expression_kept``).

    *Placing.* Each marker is snapped to the skin under it: the point whose
    smooth normal, ``marker_offset_mm`` long, reaches the marker centre. A
    marker whose closest skin lies on the scan's boundary is ``past_rim``; one
    further off than the limit, ``off_skin``. *Ambiguity:* the scan's
    triangles within the marker's height plus ``ambiguity_mm`` (plus 1 mm) of
    its centre fall into connected pieces (welded across UV seams); another
    piece than the marker's own skin within its height plus ``ambiguity_mm``
    is a second sheet: the other lip, the other eyelid.

    *How far a place may be off.* A resting expression that the take's
    motion cannot take out moves a marker along the skin, which no single
    frame shows (the marker still sits on the skin), and, in the same region,
    off it. The fit's height residual ``|h_i - o|`` (``h_i`` the marker's
    distance to its skin point, ``o`` the marker offset) is what is left of
    the latter, and ``may_be_off_mm = sqrt(f^2 + (k |h_i - o|)^2)`` with
    ``f`` = :data:`ALONG_SKIN_FLOOR_MM` and ``k`` = :data:`ALONG_SKIN_PER_HEIGHT`
    (the 90th percentile of the error, fitted on the tuned generated takes).
    Neither the neighbours' residuals nor how far the take's motion moved the
    markers told the misses apart any better (``benchmarks/RESULTS.md``).

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture
       and 3D scanning for high-fidelity facial performance acquisition",
       ACM Trans. Graph. 30(4), 2011, section 5.
    .. [2] Y. Chen, G. Medioni, "Object modelling by registration of multiple
       range images", Image Vision Comput. 10(3), 1992.

    Examples
    --------
    A face-like cap with a nose off its middle, and markers 1.5 mm above it in another frame:

    >>> import igl
    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> u = np.linspace(-60.0, 60.0, 41)
    >>> x, y = [a.ravel() for a in np.meshgrid(u, u)]
    >>> z = 40.0 * np.exp(-(x**2 / 2500 + y**2 / 4500)) + 12.0 * np.exp(-((x - 6) ** 2 + (y + 8) ** 2) / 150)
    >>> V = np.stack([x, y, z], axis=1)
    >>> a = (np.arange(40)[:, None] * 41 + np.arange(40)).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 42], 1), np.stack([a, a + 42, a + 41], 1)])
    >>> inner = np.flatnonzero((np.abs(x) < 50) & (np.abs(y) < 50))[::9]  # clear of the rim
    >>> skin = V[inner]
    >>> markers = skin + 1.5 * igl.per_vertex_normals(V, F)[inner]
    >>> turn = Rotation.from_rotvec([2.0, -0.5, 1.0])
    >>> found = find_marker_map(turn.apply(markers) + [300.0, -80.0, 1400.0], V, F)
    >>> bool(found.placed.all()), bool(np.abs(found.surface_points - skin).max() < 0.1)
    (True, True)
    """
    X = as_points(rest_markers, name="rest_markers", allow_nan=True)
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    M = X.shape[0]
    seen = np.isfinite(X).all(axis=1)
    if seen.sum() < MIN_MAP_MARKERS:
        raise MarkerError(f"rest_markers: expected at least {MIN_MAP_MARKERS} markers seen at the rest frame, "
                          f"got {int(seen.sum())}")
    offset = as_positive(marker_offset_mm, name="marker_offset_mm", allow_zero=True)
    max_off_skin_mm = as_positive(max_off_skin_mm, name="max_off_skin_mm")
    uncertain_mm = as_positive(uncertain_mm, name="uncertain_mm")
    ambiguity_mm = as_positive(ambiguity_mm, name="ambiguity_mm", allow_zero=True)
    regularization = as_positive(regularization, name="regularization", allow_zero=True)
    if int(motion_modes) != motion_modes or motion_modes < 0:
        raise InputError(f"motion_modes: expected a non-negative integer, got {motion_modes!r}")
    subspace = None
    if motion is not None:
        frames = as_marker_positions(motion, name="motion")
        if frames.shape[1] != M:
            raise MarkerError(f"motion: expected {M} markers to match rest_markers, got {frames.shape[1]}")
        subspace = _motion_subspace(frames, X, seen, int(motion_modes))

    winding = scan_winding(V, F) if offset > 0 else 1
    side = -1.0 if winding < 0 else 1.0
    Xs = X[seen]
    if start is None:
        normals = igl.per_vertex_normals(V, F) * side
        candidates = [(R, t) for R, t, _ in _search_poses(Xs, V, F, normals, offset)]
    else:
        T0 = as_rigid_transform(start, name="start", project=True)
        candidates = [(T0[:3, :3], T0[:3, 3])]
    surface = ClosestPointSurface(V, F, reject_boundary=True)
    refined = []
    for R, t in candidates:
        init = np.eye(4)
        init[:3, :3], init[:3, 3] = R, t
        try:
            fit = rigid_icp_to_surface(Xs, surface, init, trim=0.8, offset_mm=side * offset)
        except SolverError:
            continue
        refined.append((_pose_score(fit.distances, offset), fit))
    if not refined:
        raise SolverError("find_marker_map: no pose puts 3 or more markers over the scan's surface")
    refined.sort(key=lambda item: item[0])
    score, best = refined[0]
    second = np.nan if start is not None else np.inf
    for other_score, other in refined[1:]:  # the best pose still distinct from it after refinement
        apart = np.sqrt(np.mean(np.sum((best.apply(Xs) - other.apply(Xs)) ** 2, axis=1)))
        if apart >= _DISTINCT_MM:
            second = min(second, other_score)

    # "off the skin" is judged against how well the face fits at all: a scan of another person
    # (the bundled take's markers on the generic face) leaves markers several mm off that are on skin
    rigid_off = np.abs(best.distances - offset)
    off_limit = max(max_off_skin_mm, _OFF_SKIN_SPREADS * 1.4826 * float(np.median(rigid_off)))
    options = dict(init=best.matrix, marker_offset_mm=offset, trim=_REGISTRATION_TRIM, max_residual_mm=off_limit,
                   regularization=regularization, size_tolerance=None, surface=surface)
    registration = register_markers_to_scan(X, Mesh(V, F), subspace=subspace, **options)
    moved = np.linalg.norm(registration.markers[seen] - best.apply(Xs), axis=1)
    expression_rms = float(np.sqrt(np.mean(moved**2)))
    expression_kept = subspace is not None and expression_rms <= _MAX_EXPRESSION_RMS_MM
    if subspace is not None and not expression_kept:  # no resting face moves markers this far: not an expression
        registration = register_markers_to_scan(X, Mesh(V, F), **options)
    heights = registration.distances
    # a marker whose closest skin is on the scan's boundary is past the rim (or over a hole), however far off
    on_rim = np.zeros(M, dtype=bool)
    on_rim[seen] = surface.closest(registration.markers[seen])[3]
    off_skin = seen & registration.unmatched & ~on_rim & (np.abs(heights - offset) > off_limit)
    past_rim = seen & registration.unmatched & ~off_skin
    placed = seen & ~registration.unmatched
    may_be_off = np.where(placed, np.hypot(ALONG_SKIN_FLOOR_MM, ALONG_SKIN_PER_HEIGHT * (heights - offset)), np.nan)
    uncertain = placed & (may_be_off > uncertain_mm)

    second_sheet = np.full(M, np.nan)
    if placed.any():
        reach = heights[placed] + ambiguity_mm + 1.0
        second_sheet[placed] = _second_sheets(registration.markers[placed], registration.surface_points[placed],
                                              V, F, reach)
    ambiguous = placed & (second_sheet - heights < ambiguity_mm)
    surface_points = np.where(placed[:, None], registration.surface_points, np.nan)
    return MarkerMap(
        surface_points=surface_points,
        face_indices=np.where(placed, registration.face_indices, -1),
        barycentric=np.where(placed[:, None], registration.barycentric, np.nan),
        markers_on_scan=registration.markers,
        heights=heights,
        placed=placed,
        off_skin=off_skin,
        past_rim=past_rim,
        unseen=~seen,
        ambiguous=ambiguous,
        second_sheet_mm=second_sheet,
        may_be_off_mm=may_be_off,
        uncertain=uncertain,
        rotation=registration.rotation,
        translation=registration.translation,
        rms_mm=float(np.sqrt(np.mean((heights[placed] - offset) ** 2))) if placed.any() else float("nan"),
        score_mm=score,
        second_score_mm=float(second),
        sure=bool(start is not None or not second < UNSURE_SCORE_RATIO * score),
        normals_flipped=registration.normals_flipped,
        off_skin_limit_mm=off_limit,
        expression_rms_mm=expression_rms if subspace is not None else float("nan"),
        expression_kept=bool(expression_kept),
    )
