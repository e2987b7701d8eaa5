"""The closed soft-tissue volume of a face scan: skin outside, bone inside, walls along the cut.

The bone surface is the skin, with the cartilaginous nose replaced by a
membrane across its base, offset inwards along smoothed normals by the
soft-tissue thickness field (:mod:`.tissue_thickness`), then smoothed so that
the lips and eyelids (soft tissue) are not copied onto the bone, and corrected
so that the thickness at each tabulated landmark is the table's. The skin that
curls back into the head (inner eyelids and lips) is left out of the meshed
skin, so the bone cannot cross it.
The face region of a scan is an open surface (eye and mouth openings, an outer
rim), so the volume is closed by ruled side walls joining each skin boundary
loop to the matching bone loop.
"""

from __future__ import annotations

from typing import NamedTuple

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import trimesh

from ..errors import InputError, MeshError
from ..mesh import laplace_operators
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from .anatomy_landmarks import AnatomyLandmarks
from .tissue_thickness import MIN_TISSUE_MM, landmark_depth, tissue_thickness

__all__ = ["SoftTissueShell", "soft_tissue_shell", "PART_SKIN", "PART_BONE", "PART_WALL", "PART_RIM"]

PART_SKIN, PART_BONE, PART_WALL, PART_RIM = 0, 1, 2, 3
"""Labels of the closed surface's faces: skin, bone, walls of the eye and mouth openings, wall of the outer rim."""

NORMAL_SMOOTHING_MM = 10.0
"""Diffusion length of the vertex normals the offset follows (implicit smoothing, ``lambda = length^2``)."""
BONE_SMOOTHING_MM = 6.0
"""Diffusion length that removes skin detail (nose, lips, eyelids) from the offset bone surface."""
THICKNESS_CORRECTIONS = 6
"""Fixed-point passes that restore the table thickness at the landmarks after smoothing."""
_OFFSET_FLOOR_MM = 1.0
"""Least offset before smoothing (the result keeps :data:`MIN_TISSUE_MM`)."""

# The meshed skin: the face in front of the ears, from the forehead to just under the chin
# (face-frame mm relative to the landmarks, see docs/anatomy.md).
CROP_BELOW_MENTON_MM = 12.0
CROP_ABOVE_MID_FOREHEAD_MM = 15.0
CROP_BEHIND_SUPRAGLENOID_MM = 8.0


class SoftTissueShell(NamedTuple):
    """The closed surface bounding the soft tissue, and how it was made.

    Attributes
    ----------
    skin_vertices : (s,) int64 array
        Scan vertices of the meshed skin, in order: vertex ``i`` of the skin
        part is scan vertex ``skin_vertices[i]``.
    skin_faces : (f, 3) int64 array
        Meshed skin triangles, indexing the skin part (0 .. s-1).
    bone : (s, 3) float64 array, mm
        Bone surface vertex under each skin vertex (same triangles).
    normals : (s, 3) float64 array
        Smoothed unit skin normals the offset follows.
    thickness : (s,) float64 array, mm
        Interpolated tissue thickness field (before smoothing the bone).
    V : (2 s, 3) float64 array, mm
        Closed surface vertices: the skin part, then the bone.
    F : (k, 3) int64 array
        Closed surface triangles, outward (away from the tissue).
    part : (k,) int64 array
        ``PART_SKIN``, ``PART_BONE``, ``PART_WALL`` (eye and mouth openings)
        or ``PART_RIM`` (outer edge) per triangle of ``F``.
    landmark_rows : (j,) int64 array
        Skin-part rows of the tabulated landmarks used.
    landmark_names : tuple of str
        Their names.
    landmark_depths : (j,) float64 array, mm
        Their table depths.
    """

    skin_vertices: IntArray
    skin_faces: IntArray
    bone: FloatArray
    normals: FloatArray
    thickness: FloatArray
    V: FloatArray
    F: IntArray
    part: IntArray
    landmark_rows: IntArray
    landmark_names: tuple[str, ...]
    landmark_depths: FloatArray


def _crop(scan: Mesh, lm: AnatomyLandmarks) -> IntArray:
    """Scan faces of the face in front of the ears, between forehead and chin (one piece)."""
    P = lm.local(scan.vertices)
    y_low = lm.local(lm.point("menton"))[1] - CROP_BELOW_MENTON_MM
    y_high = lm.local(lm.point("mid_forehead"))[1] + CROP_ABOVE_MID_FOREHEAD_MM
    z_back = min(lm.local(lm.point(f"supraglenoid_{s}"))[2] for s in "LR") - CROP_BEHIND_SUPRAGLENOID_MM
    keep_v = (P[:, 1] > y_low) & (P[:, 1] < y_high) & (P[:, 2] > z_back)
    F = scan.faces
    keep_f = np.flatnonzero(keep_v[F].all(axis=1) & ~_folds_inwards(scan.vertices, F, lm))
    if keep_f.size == 0:
        raise MeshError("the scan has no faces in front of the ears between forehead and chin", path=scan.source_path)
    keep_f = _largest_piece(F, keep_f)
    return _clean_boundary(F, keep_f)


FOLD_NORMAL_Z = 0.2
"""Faces near the eyes and mouth whose normal's forward component is below this curl into the head."""


def _folds_inwards(V: FloatArray, F: IntArray, lm: AnatomyLandmarks) -> np.ndarray:
    """Faces where the skin curls back into the head: inner eyelids and inner lips.

    Scans (the ICT topology among them) continue the eyelid and lip margins
    some millimetres into the eye sockets and the mouth. Offset inwards, the
    bone would cross those folds, so they are left out of the meshed skin
    (their vertices are still carried by the nearest tetrahedron): faces
    within 22 mm of an eye centre or within the mouth's half-width plus 6 mm
    of the stomion whose unit normal points less than 0.2 forwards.
    """
    P = lm.local(V)
    tri = P[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n_z = n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-300)
    centre = tri.mean(axis=1)
    near = np.zeros(F.shape[0], dtype=bool)
    for side in "LR":
        eye = 0.5 * (lm.local(lm.point(f"exocanthion_{side}")) + lm.local(lm.point(f"endocanthion_{side}")))
        near |= np.linalg.norm(centre - eye, axis=1) < 22.0
    mouth_half = 0.5 * abs(lm.local(lm.point("cheilion_L"))[0] - lm.local(lm.point("cheilion_R"))[0])
    near |= np.linalg.norm(centre - lm.local(lm.point("stomion")), axis=1) < mouth_half + 6.0
    return near & (n_z < FOLD_NORMAL_Z)


def _largest_piece(F: IntArray, faces: IntArray) -> IntArray:
    sub = F[faces]
    adj = trimesh.graph.face_adjacency(sub)
    g = sp.coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(len(sub),) * 2)
    n, lab = sp.csgraph.connected_components(g, directed=False)
    big = np.argmax(np.bincount(lab))
    return faces[lab == big]


def _clean_boundary(F: IntArray, faces: IntArray) -> IntArray:
    """Drop faces that make the boundary non-manifold (bow-ties) or are ears of the cut (2-3 open edges)."""
    for _ in range(20):
        sub = F[faces]
        E = np.sort(sub[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        key = E[:, 0] * (F.max() + 1) + E[:, 1]
        uniq, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
        open_edge = (cnt[inv] == 1).reshape(-1, 3)
        ears = open_edge.sum(axis=1) >= 2
        bverts = E[(cnt[inv] == 1)]
        deg = np.bincount(bverts.ravel(), minlength=F.max() + 1)
        bowtie_v = deg > 2
        bowtie_f = bowtie_v[sub].any(axis=1) & open_edge.any(axis=1)
        drop = ears | bowtie_f
        if not drop.any():
            return faces
        faces = _largest_piece(F, faces[~drop])
    return faces


def _smooth(V: FloatArray, F: IntArray, X: FloatArray, length_mm: float, fixed: IntArray | None = None) -> FloatArray:
    """Implicit diffusion ``(M + l^2 L) Y = M X`` (rows ``fixed`` kept as they are)."""
    ops = laplace_operators(V, F)
    A = (sp.diags(ops.mass) + length_mm**2 * ops.L).tocsr()
    B = ops.mass[:, None] * X
    if fixed is None or fixed.size == 0:
        return np.asarray(spla.splu(A.tocsc()).solve(B))
    n = V.shape[0]
    free = np.setdiff1d(np.arange(n), fixed)
    Y = X.copy()
    rhs = B[free] - A[free][:, fixed] @ X[fixed]
    Y[free] = spla.splu(A[free][:, free].tocsc()).solve(rhs)
    return Y


def _depth_along(origins: FloatArray, directions: FloatArray, V: FloatArray, F: IntArray) -> FloatArray:
    """Distance from each origin to the surface (V, F) along its direction (NaN where missed)."""
    mesh = trimesh.Trimesh(V, F, process=False)
    loc, ray, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=False)
    out = np.full(origins.shape[0], np.nan)
    out[ray] = np.einsum("ij,ij->i", loc - origins[ray], directions[ray])
    return out


NOSE_MARGIN_MM = 5.0
"""The nose zone reaches this far beyond the alae sideways and below the subnasale."""


def _nose_footprint(S: FloatArray, landmarks: AnatomyLandmarks, *, behind_alae: bool) -> np.ndarray:
    """Vertices over the cartilaginous nose's footprint, in front of (or behind) the alae.

    In the face frame: ``y`` from the subnasale minus 5 mm up to the
    rhinion, ``|x|`` within a half-width growing linearly from 6 mm at the
    rhinion to the alae plus 5 mm at the subnasale; in front of the plane
    5 mm behind the alae (the outer nose), or behind it (the nostril
    passages that scans carry into the head).
    """
    lm = landmarks
    P = lm.local(S)
    y_top = lm.local(lm.point("rhinion"))[1]
    y_low = lm.local(lm.point("subnasale"))[1] - NOSE_MARGIN_MM
    alar = 0.5 * (abs(lm.local(lm.point("alare_L"))[0]) + abs(lm.local(lm.point("alare_R"))[0])) + NOSE_MARGIN_MM
    z_alae = 0.5 * (lm.local(lm.point("alare_L"))[2] + lm.local(lm.point("alare_R"))[2]) - NOSE_MARGIN_MM
    share = np.clip((y_top - P[:, 1]) / max(y_top - y_low, 1e-9), 0.0, 1.0)
    half = 6.0 + share * (alar - 6.0)
    over = (P[:, 1] <= y_top) & (P[:, 1] >= y_low) & (np.abs(P[:, 0]) <= half)
    return over & ((P[:, 2] < z_alae) if behind_alae else (P[:, 2] >= z_alae))


def _nose_zone(S: FloatArray, landmarks: AnatomyLandmarks) -> np.ndarray:
    """Skin vertices of the cartilaginous nose: below the rhinion, above the subnasale, between the alae."""
    return _nose_footprint(S, landmarks, behind_alae=False)


def _without_nose(S: FloatArray, F: IntArray, landmarks: AnatomyLandmarks) -> FloatArray:
    """The skin with the nose zone replaced by a harmonic membrane across its base.

    Uniform (graph) Laplacian weights: the nose's folded nostrils give the
    cotangent weights negative values, the graph Laplacian keeps the
    membrane inside the convex hull of the zone's rim.
    """
    zone = _nose_zone(S, landmarks)
    if not zone.any():
        return S
    n = S.shape[0]
    E = np.unique(np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    A = (A + A.T).tocsr()
    L = (sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A).tocsr()
    inside, outside = np.flatnonzero(zone), np.flatnonzero(~zone)
    out = S.copy()
    rhs = -(L[inside][:, outside] @ S[outside])
    out[inside] = spla.splu(L[inside][:, inside].tocsc()).solve(rhs)
    return out


def _keep_behind_skin(bone: FloatArray, S: FloatArray, F: IntArray, N: FloatArray, passes: int = 4) -> FloatArray:
    """Push bone vertices deeper (along ``-N``) where they come closer than the floor to any skin.

    Needed where the skin folds back over the bone's offset (inner lips,
    nostrils at the edge of the nose zone). Each pass moves a vertex at most
    the floor's depth, so nothing runs away.
    """
    bone = bone.copy()
    for _ in range(passes):
        d2, _, _ = igl.point_mesh_squared_distance(bone, S, F)
        d = np.sqrt(d2)
        close = d < MIN_TISSUE_MM
        if not close.any():
            break
        bone[close] -= (MIN_TISSUE_MM - d[close] + 0.1)[:, None] * N[close]
    return bone


def _walls(skin_faces: IntArray, n: int) -> tuple[IntArray, IntArray]:
    """Quads (two triangles) joining each skin boundary edge a->b to its bone copy a'->b', and their labels.

    The walls of the longest boundary loop (the outer rim) are ``PART_RIM``,
    the others (eye and mouth openings) ``PART_WALL``.
    """
    E = skin_faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key_sorted = np.sort(E, axis=1)
    _, inv, cnt = np.unique(key_sorted[:, 0] * n + key_sorted[:, 1], return_inverse=True, return_counts=True)
    directed = E[cnt[inv] == 1]  # as the skin triangles run them
    a, b = directed[:, 0], directed[:, 1]
    loops = igl.boundary_loop_all(skin_faces)
    rim = np.zeros(n, dtype=bool)
    rim[np.asarray(max(loops, key=len), dtype=np.int64)] = True
    label = np.where(rim[a] & rim[b], PART_RIM, PART_WALL)
    F = np.concatenate([np.stack([b, a, a + n], axis=1), np.stack([b, a + n, b + n], axis=1)])
    return F, np.concatenate([label, label])


def soft_tissue_shell(scan_mesh: Mesh, landmarks: AnatomyLandmarks) -> SoftTissueShell:
    """Build the closed skin-bone surface of the soft tissue of a face scan.

    Parameters
    ----------
    scan_mesh : Mesh
        The skin, mm, outward normals (counter-clockwise seen from outside).
    landmarks : AnatomyLandmarks
        Its named landmarks (:func:`~facecap.anatomy.anatomy_landmarks`).

    Returns
    -------
    SoftTissueShell

    Raises
    ------
    MeshError
        If the face region's triangles face into the head, or the closed
        surface is not watertight or encloses no volume.
    InputError
        If fewer than 4 tabulated landmarks lie on the meshed face region.

    Notes
    -----
    1. Crop: the scan faces in front of the ears (8 mm behind the
       supraglenoid points), from 12 mm under the menton to 15 mm above the
       mid-forehead point, less the inward folds at the eyes and mouth
       (:func:`_folds_inwards`); the largest piece, without bow-tie
       boundary vertices.
    2. Base: the skin with the nose zone (:func:`_nose_footprint`) replaced by
       a harmonic membrane.
    3. Normals ``n``: the base's vertex normals diffused over 10 mm and renormalised.
    4. Thickness ``t``: harmonic interpolation of the landmark depths, at least 1 mm.
    5. Bone ``B = smooth_6mm(base - t n)`` with the boundary rows held; then the
       landmark depths are corrected ``t_k += t_table - t_measured`` (measured
       along ``-n`` from the skin to ``B``) and steps 4-5 repeated 6 times.
       Where the bone ends up closer than 3 mm to any skin it is pushed
       deeper along ``-n``.
    6. Closed surface: skin, bone reversed, walls on every boundary loop.
    """
    V = scan_mesh.vertices
    faces = _crop(scan_mesh, landmarks)
    tri = V[scan_mesh.faces[faces]]
    area_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(axis=0)
    if area_normal @ landmarks.frame[2] <= 0:
        raise MeshError("the scan's triangles face into the head (its normals point away from the viewer "
                        "of the face); flip their orientation", path=scan_mesh.source_path)
    skin_vertices, inverse = np.unique(scan_mesh.faces[faces], return_inverse=True)
    Fs = inverse.reshape(-1, 3).astype(np.int64)
    S = V[skin_vertices]
    n = S.shape[0]
    rows, names, depths = [], [], []
    where = {int(v): i for i, v in enumerate(skin_vertices)}
    for name, vert in zip(landmarks.names, landmarks.vertices):
        d = landmark_depth(name)
        if d is not None and int(vert) in where and where[int(vert)] not in rows:
            rows.append(where[int(vert)])
            names.append(name)
            depths.append(d)
    if len(rows) < 4:
        raise InputError("landmarks: fewer than 4 tabulated landmarks lie on the meshed face region",
                         path=scan_mesh.source_path)
    rows_a, depth_table = np.array(rows, dtype=np.int64), np.array(depths)

    # the nose below the nasal bones is cartilage and soft tissue: the bone is offset from the face
    # with the nose taken away (a membrane across its base), not from the nose itself
    base = _without_nose(S, Fs, landmarks)
    N0 = igl.per_vertex_normals(base, Fs)
    N = _smooth(base, Fs, N0, NORMAL_SMOOTHING_MM)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    boundary = np.unique(np.concatenate(igl.boundary_loop_all(Fs))).astype(np.int64)

    target = depth_table.copy()
    for _ in range(THICKNESS_CORRECTIONS + 1):
        # the offset before smoothing may go thinner than the floor where smoothing pushes the bone
        # back out (convex skin: forehead, below the eyes); the floor is checked on the result below
        t = np.maximum(tissue_thickness(S, Fs, rows_a, np.maximum(target, _OFFSET_FLOOR_MM)), _OFFSET_FLOOR_MM)
        bone = _smooth(base, Fs, base - t[:, None] * N, BONE_SMOOTHING_MM, fixed=boundary)
        measured = _depth_along(S[rows_a], -N[rows_a], bone, Fs)
        ok = np.isfinite(measured)
        target[ok] += depth_table[ok] - measured[ok]
    bone = _keep_behind_skin(bone, S, Fs, N)

    closed_V = np.concatenate([S, bone])
    walls, wall_part = _walls(Fs, n)
    closed_F = np.concatenate([Fs, Fs[:, ::-1] + n, walls]).astype(np.int64)
    part = np.concatenate([np.full(len(Fs), PART_SKIN), np.full(len(Fs), PART_BONE), wall_part])
    check = trimesh.Trimesh(closed_V, closed_F, process=False)
    if not check.is_watertight or check.volume <= 0:
        raise MeshError("the skin-bone surface is not closed or encloses no volume (is the scan's face region "
                        "one piece with outward normals?)", path=scan_mesh.source_path)
    return SoftTissueShell(skin_vertices.astype(np.int64), Fs, bone, N, t, closed_V, closed_F,
                           part.astype(np.int64), rows_a, tuple(names), depth_table)
