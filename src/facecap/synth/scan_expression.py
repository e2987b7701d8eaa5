"""Scan a known expression mesh the way a range scanner would, keeping the truth."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import igl
import numpy as np
import scipy.sparse as sp
from scipy.ndimage import distance_transform_edt
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..errors import InputError, MeshError
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from ..units import normalize_unit
from ..validate import as_faces, as_positive, as_rigid_transform, as_vertices
from .capture_colors import capture_colors
from .skin_albedo import SkinRegions, skin_albedo
from .skin_texture import SkinTexture

__all__ = ["ScannedExpression", "scan_expression", "DEFAULT_SCAN_TEXEL_MM"]

DEFAULT_SCAN_TEXEL_MM = 0.25
"""Texel spacing of a generated scan's colour texture (scanners deliver 0.1-0.5 mm)."""


@dataclass(frozen=True, eq=False)
class ScannedExpression:
    """A synthetic face scan and the truth it was made from.

    Attributes
    ----------
    mesh : Mesh
        The scan, in the scanner's frame (mm): its own vertex count and
        connectivity (a range-image triangulation), with noise, holes and a
        cropped rim. ``mesh.source_unit`` is the ``unit`` asked for.
    scanner_from_face : (4, 4) float64 array
        Rigid transform from the frame of the scanned mesh to the scanner's
        frame: ``mesh.vertices = R @ (surface_points + noise) + t``.
    surface_points : (s, 3) float64 array, mm
        Noise-free position of each scan vertex, on the scanned surface, in
        the frame of the scanned mesh.
    source_faces : (s,) int64 array
        Triangle of the scanned mesh that holds each ``surface_points`` row.
    barycentric : (s, 3) float64 array
        Barycentric coordinates of ``surface_points`` in ``source_faces``
        (rows sum to 1): evaluate them on another pose of the same mesh to
        follow the scan vertices through an expression change.
    noise_offsets : (s,) float64 array, mm
        Signed noise added along the unit normal of the source face: the scan
        vertex is ``surface_points + noise_offsets * normal`` (face frame).
    view_direction : (3,) float64 array
        Unit direction the scanner looked along, in the face frame.
    hole_centers : (h, 3) float64 array, mm
        Centres of the punched holes, on the surface, in the face frame.
    hole_radii : (h,) float64 array, mm
        Radius of each hole.
    pitch_mm : float
        Spacing of the range-image grid (mm, in the image plane).
    """

    mesh: Mesh
    scanner_from_face: FloatArray
    surface_points: FloatArray
    source_faces: IntArray
    barycentric: FloatArray
    noise_offsets: FloatArray
    view_direction: FloatArray
    hole_centers: FloatArray
    hole_radii: FloatArray
    pitch_mm: float


def _boundary_edges(F: IntArray) -> IntArray:
    """(b, 2) edges used by exactly one triangle, in the triangles' winding (libigl)."""
    return np.ascontiguousarray(igl.boundary_facets(F)[0], dtype=np.int64)


def _outer_boundary(V: FloatArray, F: IntArray) -> IntArray:
    """The boundary edges of the longest boundary loop (the rim of a face mesh)."""
    E = _boundary_edges(F)
    if E.shape[0] == 0:
        return E
    n = V.shape[0]
    G = sp.coo_matrix((np.ones(E.shape[0]), (E[:, 0], E[:, 1])), shape=(n, n))
    _, labels = connected_components(G, directed=False)
    lengths = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    per_loop = np.bincount(labels[E[:, 0]], weights=lengths)
    return E[labels[E[:, 0]] == int(np.argmax(per_loop))]


def _drop_specks(F: IntArray, n: int, *, min_fraction: float = 0.01) -> IntArray:
    """Faces of the connected pieces holding at least ``min_fraction`` of all faces."""
    rows = np.concatenate([F[:, 0], F[:, 1]])
    cols = np.concatenate([F[:, 1], F[:, 2]])
    G = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    _, labels = connected_components(G, directed=False)
    face_label = labels[F[:, 0]]
    sizes = np.bincount(face_label)
    return F[sizes[face_label] >= min_fraction * F.shape[0]]


def _first_hits(V: FloatArray, F: IntArray, tree: Any, origins: FloatArray, d: FloatArray
                ) -> tuple[np.ndarray, IntArray, FloatArray]:
    """Parallel rays along ``d``: which hit, the triangle each hit first (0 for a miss), its barycentrics."""
    hit_face, _, uv = tree.intersect_ray_first(V, F, origins, np.broadcast_to(d, origins.shape).copy())
    hit = hit_face >= 0
    fid = np.where(hit, hit_face, 0).astype(np.int64)
    uv = np.clip(np.nan_to_num(uv), 0.0, 1.0)
    bary = np.clip(np.stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], axis=1), 0.0, None)
    return hit, fid, bary / bary.sum(axis=1, keepdims=True)


def _range_image(
    pitch: float,
    *,
    V: FloatArray,
    F: IntArray,
    tree: Any,
    d: FloatArray,
    e1: FloatArray,
    e2: FloatArray,
    offset: FloatArray,
    facing: FloatArray,
    cos_max: float,
    rim: IntArray,
    crop_mm: float,
) -> tuple[np.ndarray, IntArray, FloatArray, FloatArray, tuple[int, int]]:
    """Cast a grid of parallel rays; return kept mask, faces, barycentrics, points and the grid shape."""
    u, v, depth = V @ e1, V @ e2, V @ d
    us = u.min() + pitch * (offset[0] + np.arange(int(np.ceil((u.max() - u.min()) / pitch)) + 1))
    vs = v.min() + pitch * (offset[1] + np.arange(int(np.ceil((v.max() - v.min()) / pitch)) + 1))
    UU, VV = np.meshgrid(us, vs)  # rows follow e2, columns follow e1
    origins = UU.reshape(-1, 1) * e1 + VV.reshape(-1, 1) * e2 + (depth.min() - 10.0) * d
    hit, fid, bary = _first_hits(V, F, tree, origins, d)
    hit[hit] = facing[fid[hit]] >= cos_max  # grazing or back-facing first hits give no sample
    points = np.einsum("kc,kcd->kd", bary, V[F[fid]])
    if crop_mm > 0 and rim.shape[0] and hit.any():
        sq, _, _ = igl.point_mesh_squared_distance(points[hit], V, rim)
        hit[np.flatnonzero(hit)[sq < crop_mm**2]] = False
    return hit, fid, bary, points, UU.shape


def _scan_texture(
    keep: IntArray,
    grid_shape: tuple[int, int],
    pitch: float,
    texel_mm: float,
    skin: SkinTexture,
    capture_seed: int,
    *,
    V: FloatArray,
    F: IntArray,
    tree: Any,
    d: FloatArray,
    e1: FloatArray,
    e2: FloatArray,
    offset: FloatArray,
    **_: Any,
) -> tuple[np.ndarray, FloatArray]:
    """The colour camera's texture over the range image's plane, and each kept vertex's UV in it."""
    rows, cols = grid_shape
    s = max(1, int(round(pitch / texel_mm)))
    t = pitch / s
    H, W = (rows - 1) * s + 1, (cols - 1) * s + 1
    u0 = (V @ e1).min() + pitch * offset[0]
    v0 = (V @ e2).min() + pitch * offset[1]
    # only the texels of range-image cells with a kept vertex at a corner: the rest of the plane is not face
    cell_near = np.zeros((rows + 1, cols + 1), dtype=bool)  # cell (i, j) at [i + 1, j + 1]
    r, c = np.divmod(keep, cols)
    for dr in (0, 1):
        for dc in (0, 1):
            cell_near[r - dr + 1, c - dc + 1] = True
    ti, tj = np.nonzero(cell_near[np.arange(H) // s + 1][:, np.arange(W) // s + 1])
    origins = (u0 + tj * t)[:, None] * e1 + (v0 + ti * t)[:, None] * e2 + ((V @ d).min() - 10.0) * d
    hit, fid, bary = _first_hits(V, F, tree, origins, d)
    points = np.einsum("kc,kcd->kd", bary[hit], V[F[fid[hit]]])
    colour = capture_colors(skin.albedo_at(fid[hit], bary[hit]), points, seed=capture_seed)
    image = np.zeros((H, W, 3), dtype=np.float32)
    seen = np.zeros((H, W), dtype=bool)
    image[ti[hit], tj[hit]] = colour
    seen[ti[hit], tj[hit]] = True
    # texels that see no skin take the nearest seen one's colour (a scanner's atlas is padded too)
    _, (ni, nj) = distance_transform_edt(~seen, return_indices=True)
    image = image[ni, nj]
    uvs = np.stack([(c * s + 0.5) / W, 1.0 - (r * s + 0.5) / H], axis=1)
    return np.round(image * 255.0).astype(np.uint8), uvs


def scan_expression(
    vertices: FloatArray,
    faces: IntArray,
    *,
    target_vertices: int | None = None,
    seed: int = 0,
    noise_mm: float = 0.05,
    hole_fraction: float = 0.02,
    hole_radius_mm: tuple[float, float] = (2.0, 5.0),
    crop_mm: float = 6.0,
    max_incidence_deg: float = 75.0,
    view_direction: FloatArray | None = None,
    scanner_from_face: FloatArray | None = None,
    unit: str = "mm",
    material_points: FloatArray | None = None,
    albedo_seed: int = 0,
    skin_regions: SkinRegions | None = None,
    skin_texture: SkinTexture | None = None,
    texel_mm: float = DEFAULT_SCAN_TEXEL_MM,
) -> ScannedExpression:
    """Scan a triangle mesh as a range scanner would: new sampling, noise, holes, rim crop, own frame.

    The scanner casts a regular grid of parallel rays along ``view_direction``
    (a range image, as a laser or structured-light scanner records it), keeps
    the first hit of each ray on the surface, triangulates neighbouring
    pixels, and drops what a scanner cannot see well: surfaces seen at more
    than ``max_incidence_deg`` from the ray, triangles that bridge a depth
    jump, and a band of ``crop_mm`` along the rim (the outer boundary) of the
    scanned mesh. It then punches round holes (specular spots, hair) until
    ``hole_fraction`` of the area is gone, drops specks (pieces with under 1 %
    of the triangles),
    moves each vertex along the surface normal by Gaussian noise, and expresses
    the result in the scanner's own frame.

    Parameters
    ----------
    vertices : (n, 3) float64 array, mm
        The expression to scan, e.g. ``case.truth_vertices[t]``.
    faces : (m, 3) int64 array
        Its triangles, consistently oriented; the scanner sees their front
        side (normals towards it).
    target_vertices : int or None, optional
        Approximate vertex count of the scan before the holes (which
        remove about ``hole_fraction`` more). None (default): three times
        ``n``. A coarse range image measures how much of the view survives
        the incidence limit and the crop; the grid pitch is then set so that
        about this many samples do.
    seed : int, default 0
        Seeds the grid offset and roll, the holes, the noise and the random
        scanner frame (independent streams: changing ``hole_fraction`` keeps
        the sampling, the noise of the kept vertices and the frame).
    noise_mm : float, default 0.05
        Standard deviation of the noise along the surface normal, mm.
    hole_fraction : float, default 0.02
        Fraction of the scanned area to remove in holes, in [0, 0.5).
    hole_radius_mm : (float, float), default (2.0, 5.0)
        Range of the hole radii, mm (uniform).
    crop_mm : float, default 6.0
        Width of the band along the rim that the scan leaves out, mm.
    max_incidence_deg : float, default 75.0
        Largest angle between the ray and the surface normal that still
        gives a sample, degrees.
    view_direction : (3,) float array or None, optional
        Direction the scanner looks along, in the face frame. None (default):
        against the area-weighted mean normal of the mesh (facing the face).
    scanner_from_face : (4, 4) float array or None, optional
        Rigid transform to the scanner's frame. None (default): a uniformly
        random rotation and a translation of up to 500 mm per axis.
    unit : {'mm', 'cm', 'm', 'in'}, default 'mm'
        The unit recorded as ``mesh.source_unit`` (the unit a file written
        from the scan would use); the vertices are in mm whatever it is.
    material_points : (n, 3) float64 array, mm, or None, optional
        Rest position of each vertex of ``vertices`` (the neutral face of the
        identity, e.g. ``case.scan.vertices``). When given, the scan carries
        colours: scan vertex ``i`` has material point ``barycentric[i] @
        material_points[faces[source_faces[i]]]`` and colour
        ``capture_colors(skin_albedo(material point, seed=albedo_seed,
        region=...), surface_points, seed=<from seed>)`` in
        ``mesh.vertex_colors`` (sRGB-encoded float32). None (default): no
        colours, and the scan is bit for bit what it was without this option.
    albedo_seed : int, default 0
        Seed of the skin (:func:`~facecap.synth.skin_albedo.skin_albedo`):
        the same for every scan of one identity.
    skin_regions : SkinRegions or None, optional
        Brows and lips for the albedo, with ``labels`` per vertex of
        ``vertices`` (a scan vertex takes the label of its source triangle's
        corner of largest barycentric weight) and ``lip_outline`` in the
        frame of ``material_points``. Only used with ``material_points``.
    skin_texture : SkinTexture or None, optional
        The identity's albedo baked on its rest surface
        (:func:`~facecap.synth.skin_texture.bake_skin_albedo`), whose triangles are ``faces``.
        When given, the scan carries a colour texture as a range scanner's colour camera records
        it, instead of vertex colours: a second, finer grid of rays (``texel_mm`` apart, an integer
        fraction of the range grid's pitch) over the same image plane, each hit coloured by the
        albedo at its material point with this capture's exposure, shading and sensor noise
        (:func:`~facecap.synth.capture_colors.capture_colors`), sRGB-encoded to 8 bits; texels that
        see no skin take the nearest one's colour. The scan's UVs are its range image's
        coordinates: an atlas of its own, unrelated to the rest surface's. Overrides
        ``material_points``.
    texel_mm : float, default 0.25
        Texel spacing of ``skin_texture``'s scan texture (real scanners: 0.1-0.5 mm).

    Returns
    -------
    ScannedExpression
        The scan ``mesh`` and the truth: ``scanner_from_face``, the
        noise-free ``surface_points`` with their ``source_faces`` and
        ``barycentric`` coordinates, ``noise_offsets``, ``view_direction``,
        ``hole_centers``, ``hole_radii`` and ``pitch_mm``.

    Raises
    ------
    MeshError
        If the mesh is not a valid triangle mesh, or the scanner sees too
        little of it to make a scan.
    InputError
        If an option is out of range or ``scanner_from_face`` is not rigid.

    Notes
    -----
    Rays are intersected with libigl's AABB tree; each hit is rebuilt from
    its barycentric coordinates, so ``surface_points`` lie on the source
    triangles to rounding. Every scan vertex is therefore within
    ``|noise_offsets|`` of the scanned surface. Cells of the grid whose
    four corners are hits become two triangles oriented towards the
    scanner. The Minolta VIVID 910 used by Huang et al. [1]_ records
    100k-200k vertices with about 0.1 mm depth accuracy.

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong, H.-T. Wu, "Leveraging motion capture
       and 3D scanning for high-fidelity facial performance acquisition",
       ACM Trans. Graph. 30(4), 2011, section 4.

    Examples
    --------
    >>> from ..io.ict_sample import load_ict_sample
    >>> face = load_ict_sample().mesh
    >>> scan = scan_expression(face.vertices, face.faces, target_vertices=20000, seed=1)
    >>> scan.mesh.n_vertices != face.n_vertices
    True
    """
    V = as_vertices(vertices, name="vertices")
    F = as_faces(faces, V.shape[0], name="faces")
    noise_mm = as_positive(noise_mm, name="noise_mm", allow_zero=True)
    crop_mm = as_positive(crop_mm, name="crop_mm", allow_zero=True)
    if not 0.0 <= float(hole_fraction) < 0.5:
        raise InputError(f"hole_fraction: expected a fraction in [0, 0.5), got {hole_fraction!r}")
    r_lo, r_hi = (as_positive(r, name="hole_radius_mm") for r in hole_radius_mm)
    if r_hi < r_lo:
        raise InputError(f"hole_radius_mm: expected (low, high) with low <= high, got {hole_radius_mm!r}")
    if not 0.0 < float(max_incidence_deg) < 90.0:
        raise InputError(f"max_incidence_deg: expected an angle in (0, 90), got {max_incidence_deg!r}")
    unit = normalize_unit(unit, name="unit")
    if target_vertices is None:
        target_vertices = 3 * V.shape[0]
    if int(target_vertices) != target_vertices or target_vertices < 100:
        raise InputError(f"target_vertices: expected an integer >= 100, got {target_vertices!r}")
    # a fifth stream for the capture: spawn(5)[:4] are the same streams as spawn(4)
    seeds = np.random.SeedSequence(seed).spawn(5)
    rng_grid, rng_holes, rng_noise, rng_frame = (np.random.default_rng(s) for s in seeds[:4])
    if material_points is not None:
        M = as_vertices(material_points, name="material_points")
        if M.shape != V.shape:
            raise InputError(f"material_points: expected shape {V.shape} (one per vertex), got {M.shape}")

    N = igl.per_face_normals(V, F, np.array([0.0, 0.0, 0.0]))
    area = 0.5 * igl.doublearea(V, F)
    if view_direction is None:
        mean_normal = (N * area[:, None]).sum(axis=0)
        if np.linalg.norm(mean_normal) < 1e-3 * area.sum():
            raise MeshError("vertices: the mesh has no dominant facing side; pass view_direction")
        d = -mean_normal / np.linalg.norm(mean_normal)
    else:
        d = np.asarray(view_direction, dtype=np.float64).reshape(-1)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
            raise InputError(f"view_direction: expected a finite non-zero 3-vector, got {view_direction!r}")
        d = d / np.linalg.norm(d)

    # image axes: e1 at a random roll about the ray, e2 so that e1 x e2 = -d (triangles face the scanner)
    helper = np.eye(3)[int(np.argmin(np.abs(d)))]
    a = np.cross(d, helper)
    a /= np.linalg.norm(a)
    b = np.cross(d, a)
    roll = rng_grid.uniform(0.0, 2.0 * np.pi)
    e1 = np.cos(roll) * a + np.sin(roll) * b
    e2 = np.cross(-d, e1)

    cos_max = float(np.cos(np.deg2rad(float(max_incidence_deg))))
    facing = -(N @ d)
    seen_area = float(np.sum(area[facing >= cos_max] * facing[facing >= cos_max]))
    if seen_area <= 0:
        raise MeshError("vertices: no triangle faces the scanner within max_incidence_deg")
    tree = igl.AABB()
    tree.init(V, F)
    rim = _outer_boundary(V, F) if crop_mm > 0 else np.zeros((0, 2), dtype=np.int64)
    offset = rng_grid.uniform(0.0, 1.0, 2)
    shoot = dict(V=V, F=F, tree=tree, d=d, e1=e1, e2=e2, offset=offset, facing=facing,
                 cos_max=cos_max, rim=rim, crop_mm=crop_mm)
    # a coarse range image measures how much of the projected area survives the crop, then the pitch is set
    coarse = 2.0 * np.sqrt(seen_area / target_vertices)
    n_coarse = int(_range_image(coarse, **shoot)[0].sum())
    if n_coarse < 10:
        raise MeshError("vertices: the scanner sees too little of the mesh to make a scan")
    pitch = coarse * float(np.sqrt(n_coarse / target_vertices))
    hit, fid, bary, points, grid_shape = _range_image(pitch, **shoot)

    # triangulate the range image: two triangles per cell of four hits, none across a depth jump
    rows, cols = grid_shape
    index = np.where(hit, np.arange(hit.size), -1).reshape(rows, cols)
    c00, c01 = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    c10, c11 = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    T = np.concatenate([np.stack([c00, c01, c11], 1), np.stack([c00, c11, c10], 1)])
    T = T[(T >= 0).all(axis=1)]
    P = points[T]
    tri_n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    tri_len = np.linalg.norm(tri_n, axis=1)
    longest = np.max(np.linalg.norm(P - np.roll(P, 1, axis=1), axis=2), axis=1)
    ok = (tri_len > 0) & (-(tri_n @ d) >= cos_max * tri_len) & (longest <= 1.5 * np.sqrt(2.0) * pitch / cos_max)
    T = T[ok]
    if T.shape[0] < 10:
        raise MeshError("vertices: the scanner sees too little of the mesh to make a scan")

    hole_centers = np.zeros((0, 3))
    hole_radii = np.zeros(0)
    if hole_fraction > 0:
        C = points[T].mean(axis=1)
        A = 0.5 * np.linalg.norm(np.cross(points[T[:, 1]] - points[T[:, 0]], points[T[:, 2]] - points[T[:, 0]]), axis=1)
        used = np.unique(T)
        rim_points = points[np.unique(_boundary_edges(T))]
        clearance, _ = cKDTree(rim_points).query(points[used])
        goal = float(hole_fraction) * A.sum()
        removed = np.zeros(T.shape[0], dtype=bool)
        centers, radii = [], []
        for _ in range(10_000):
            if A[removed].sum() >= goal:
                break
            r = rng_holes.uniform(r_lo, r_hi)
            inside = np.flatnonzero(clearance > r + 2.0 * pitch)
            if inside.size == 0:
                break
            c = points[used[inside[rng_holes.integers(inside.size)]]]
            removed |= np.einsum("kd,kd->k", C - c, C - c) < r * r
            centers.append(c)
            radii.append(r)
        T = T[~removed]
        hole_centers = np.array(centers).reshape(-1, 3)
        hole_radii = np.array(radii)

    noise = rng_noise.normal(0.0, noise_mm, hit.size) if noise_mm > 0 else np.zeros(hit.size)
    T = _drop_specks(T, hit.size)
    keep = np.unique(T)
    new_index = np.full(hit.size, -1, dtype=np.int64)
    new_index[keep] = np.arange(keep.size)
    faces_out = new_index[T]
    surface = points[keep]
    offsets = noise[keep]
    noisy = surface + offsets[:, None] * N[fid[keep]]

    if scanner_from_face is None:
        X = np.eye(4)
        X[:3, :3] = Rotation.random(rng=rng_frame).as_matrix()
        X[:3, 3] = rng_frame.uniform(-500.0, 500.0, 3)
    else:
        X = as_rigid_transform(scanner_from_face, name="scanner_from_face")
    colors = None
    texture = scan_uvs = None
    if skin_texture is not None:
        capture_seed = int(seeds[4].generate_state(1)[0])
        texture, scan_uvs = _scan_texture(
            keep, grid_shape, pitch, as_positive(texel_mm, name="texel_mm"), skin_texture, capture_seed, **shoot)
    elif material_points is not None:
        src, w = fid[keep], bary[keep]
        mat = np.einsum("kc,kcd->kd", w, M[F[src]])
        region = None
        if skin_regions is not None:
            labels = np.asarray(skin_regions.labels, dtype=np.int64).reshape(-1)
            if labels.shape[0] != V.shape[0]:
                raise InputError(
                    f"skin_regions.labels: expected one label per vertex ({V.shape[0]}), got {labels.shape[0]}"
                )
            corner = F[src, np.argmax(w, axis=1)]
            region = SkinRegions(labels[corner], tuple(skin_regions.names), skin_regions.lip_outline)
        capture_seed = int(seeds[4].generate_state(1)[0])
        colors = capture_colors(skin_albedo(mat, seed=albedo_seed, region=region), surface,
                                seed=capture_seed)
    mesh = Mesh(noisy @ X[:3, :3].T + X[:3, 3], faces_out, source_unit=unit, source_path="<scanned>",
                vertex_colors=colors, uvs=scan_uvs, uv_indices=None if scan_uvs is None else faces_out.ravel(),
                texture=texture)
    return ScannedExpression(
        mesh=mesh,
        scanner_from_face=X,
        surface_points=surface,
        source_faces=fid[keep].astype(np.int64),
        barycentric=bary[keep],
        noise_offsets=offsets,
        view_direction=d,
        hole_centers=hole_centers,
        hole_radii=hole_radii,
        pitch_mm=pitch,
    )
