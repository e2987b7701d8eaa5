"""Tangential correspondence from skin colour: slide a registered template along its scan until its colours line up."""

from __future__ import annotations

from typing import Any, NamedTuple

import cv2
import igl
import numpy as np

from ..mesh.factor_spd import Backend, SpdFactor
from ..errors import InputError
from ..mesh.median_edge_length import median_edge_length
from ..mesh.surface_colors import has_colors, surface_colors, texel_size_mm
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from ..typing import FloatArray
from ..validate import as_positive
from .cylindrical_map import cylindrical_map
from .optical_flow import optical_flow
from .regularised_update import regularised_update
from .visible_in_raster import visible_in_raster

__all__ = ["AlbedoAlignment", "align_albedo", "DEFAULT_ALBEDO_ITERATIONS", "UNSEEN_ANCHOR", "SEAM_WELD_MM"]

SEAM_WELD_MM = 1e-6
"""Template vertices closer than this (mm; UV-seam copies) are one vertex of the alignment's images and update."""

DEFAULT_ALBEDO_ITERATIONS = 2
"""Flow-and-update rounds of :func:`align_albedo`."""

UNSEEN_ANCHOR = 1.0
"""Data weight holding a vertex the scan does not see where it was (the Laplacian weight is ``alpha``)."""

_SHADING_SIGMA_MM = 8.0  # colour variation wider than this is lighting and exposure, not skin: removed
_STRONG_TEXTURE = 0.5  # local RMS of the normalised texture that earns full confidence
_FINEST_PIXEL_MM = 0.15  # the flow's pixel on textured scans: no finer than this, whatever the texel


class AlbedoAlignment(NamedTuple):
    """Result of :func:`align_albedo`.

    Attributes
    ----------
    vertices : (n, 3) float64 array, mm
        The registered template after the slide, on the scan.
    moved_mm : (n,) float64 array
        How far each vertex moved.
    confidence : (n,) float64 array
        Texture strength under each vertex in the last round, in [0, 1]
        (0 where the vertex could not be moved: the scan does not see it).
    mismatch_by_round : list of float
        The mean absolute difference of the two normalised (band-passed) images over the pixels
        both see, at the start of each round: the first is the registration's before any slide,
        the later ones after each round's update. Measured on a textured face at 0.3 mm pixels:
        0.077 for the right correspondence, 0.103 with a slide of up to 1.5 mm over the forehead
        (0.078 after one round), 0.37 against an unrelated texture.
    """

    vertices: FloatArray
    moved_mm: FloatArray
    confidence: FloatArray
    mismatch_by_round: list[float]


def _luminance(rgb: FloatArray) -> FloatArray:
    """Rec. 709 luma of sRGB-encoded colours: exposure and white balance mostly scale it, which
    the local normalisation below removes."""
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def _band(image: FloatArray, valid: np.ndarray, fine_px: float, coarse_px: float) -> FloatArray:
    """Normalised band-pass of ``image`` over its valid pixels: blurred at ``fine_px``, minus and divided by
    its local mean and spread at ``coarse_px``, so that lighting, exposure and sampling density drop out.
    In float32: a textured scan's image is up to 2048 pixels wide, and its blurs twice as fast so."""
    mask = valid.astype(np.float32)
    image = image.astype(np.float32)
    # The coarse blurs (8 mm: tens of pixels) run on an image shrunk to about a quarter of that sigma a
    # pixel and are scaled back up: the same smooth field, at a small fraction of a full-size blur's cost.
    shrink = max(1, int(coarse_px // 4))
    small_mask = cv2.resize(mask, None, fx=1.0 / shrink, fy=1.0 / shrink, interpolation=cv2.INTER_AREA)
    small_den = cv2.GaussianBlur(small_mask, (0, 0), coarse_px / shrink)

    def blur(x: FloatArray, sigma: float) -> FloatArray:
        num = cv2.GaussianBlur(x * mask, (0, 0), sigma)
        den = cv2.GaussianBlur(mask, (0, 0), sigma)
        return np.where(den > 1e-6, num / np.maximum(den, 1e-6), np.float32(0.0))

    def coarse(x: FloatArray) -> FloatArray:
        small = cv2.resize(x * mask, None, fx=1.0 / shrink, fy=1.0 / shrink, interpolation=cv2.INTER_AREA)
        mean = cv2.GaussianBlur(small, (0, 0), coarse_px / shrink) / np.maximum(small_den, 1e-6)
        return cv2.resize(mean, (x.shape[1], x.shape[0]), interpolation=cv2.INTER_LINEAR)

    fine = blur(image, max(fine_px, 0.5))
    local_mean = coarse(fine)
    detail = fine - local_mean
    spread = np.sqrt(np.maximum(coarse(detail * detail), 0.0))
    level = float(np.median(spread[valid])) if valid.any() else 1.0
    return np.where(valid, detail / (3.0 * np.maximum(spread, 0.25 * level) + 1e-12), 0.0)


def _luma_at(points: FloatArray, tree: Any, mesh: Mesh, reach_mm: float) -> tuple[FloatArray, np.ndarray]:
    """Luma of ``mesh``'s colour at its closest points to ``points`` (k, 3) (its texture, else its vertex
    colours), and whether each lies within ``reach_mm``."""
    sq, tri, closest = tree.squared_distance(mesh.vertices, mesh.faces, points)
    corners = mesh.faces[tri]
    bary = igl.barycentric_coordinates(
        np.ascontiguousarray(closest), *(np.ascontiguousarray(mesh.vertices[corners[:, k]]) for k in range(3)))
    return _luminance(surface_colors(mesh, tri, bary).astype(np.float64)), np.sqrt(sq) <= reach_mm


def align_albedo(
    vertices: Any,
    F: Any,
    template_rest: Any,
    texture: Mesh,
    scan: Mesh,
    *,
    iterations: int = DEFAULT_ALBEDO_ITERATIONS,
    alpha: float = 1.0,
    axis: Any = (0.0, 1.0, 0.0),
    pixel_mm: float | None = None,
    snap_distance_mm: float = 0.5,
    confidence_floor: float = 0.02,
    backend: Backend = "auto",
    factor: SpdFactor | None = None,
) -> AlbedoAlignment:
    """Slide a template registered onto a scan along the scan until the skin's colours match.

    Geometry fixes where a registered vertex lies *across* the surface, not
    *along* it: skin slides by millimetres in an expression (a brow raise
    pulls the forehead up, a smile the cheeks) while the surface changes
    little, so closest points and a few markers leave every basis slid. The
    skin's own colour does not change with the expression (freckles, pores,
    blotches and brows stay where they are on the skin), and a scanner
    records it with the geometry. This is the fine-scale step of Huang et
    al. 2011 (section 6.2: dense optical flow in a cylindrical image, eq. 11
    regularisation) run on colour against the template itself, as the
    paper's conclusion proposes, instead of on mean curvature between
    neighbouring scans.

    Parameters
    ----------
    vertices : (n, 3) float64 array, mm
        The template registered onto ``scan`` (same frame as the scan).
    F : (m, 3) int64 array
        The template's triangles.
    template_rest : (n, 3) float64 array, mm
        The template's own (rest) vertices: where each point of the face is
        on the template.
    texture : Mesh
        A coloured scan of the template's expression in the template's frame
        (``vertex_colors`` set; typically the neutral's own scan, rigidly
        aligned): the skin's colour at each point of the template. A scan is
        used rather than per-vertex colours of the template because a
        template is often sampled too coarsely to hold the skin's texture
        (the bundled ICT face has 2.4 mm edges).
    scan : Mesh
        The scan, with ``vertex_colors``.
    iterations : int, default 2
        Rounds of flow and regularised update (2: more rounds let flow noise accumulate; on generated
        bases 4 and 8 rounds were 0.01-0.02 mm worse).
    alpha : float, default 1.0
        Laplacian weight of the update (eq. 11).
    axis : (3,) float array, default (0, 1, 0)
        The face's up direction in the frame of ``vertices``: the cylinder's axis.
    pixel_mm : float, optional
        Image pixel size; default half the template's median edge length.
    snap_distance_mm : float, default 0.5
        Vertices farther than this from the scan (holes, beyond its rim) are
        neither moved by the flow nor snapped back onto the scan.
    confidence_floor : float, default 0.02
        Smallest data weight of a seen vertex; where the skin shows no
        texture the Laplacian carries its neighbours' motion instead.
    backend : {'auto', 'pardiso', 'scipy'}
    factor : SpdFactor, optional
        The update's factor to keep between calls on one template (one
        :meth:`~facecap.mesh.factor_spd.SpdFactor.unfactored` of the welded
        template's vertex count for a run of scans, freed by the caller):
        every scan's update matrix has the template's pattern, so PARDISO's
        analysis runs once for the run instead of once a scan (0.45 s of one
        core a scan at 78k vertices). One of another size is not used.
        Default None: one is made here and freed on return.

    Returns
    -------
    AlbedoAlignment

    Raises
    ------
    InputError
        If shapes disagree, the scan has no colours, or an option is out of range.

    Notes
    -----
    Per round: both images are drawn in the cylindrical map of the current
    mesh; the *target* holds the template's colours at their vertices (the
    current correspondence), the *source* the scan's colour at the point of
    the scan under each pixel's surface point. Both are reduced to luma and
    band-passed (blurred to the template's sampling, minus and divided by
    their local mean and spread over 8 mm, which removes exposure, shading
    and white balance). OpenCV's DIS flow from target to source says, at a
    vertex's pixel, where its colour lies on the scan; that point, back on the
    mesh surface, is the vertex's target, weighted by the local texture
    strength, and eq. 11 (confidence-weighted data term plus ``alpha |L v' -
    L v|^2``) with the snap back onto the scan gives the new mesh, without
    flipped triangles.
    """
    V0 = np.ascontiguousarray(vertices, dtype=np.float64)
    if V0.ndim != 2 or V0.shape[1] != 3:
        raise InputError(f"vertices: expected shape (n, 3), got {V0.shape}")
    rest = np.asarray(template_rest, dtype=np.float64)
    if rest.shape != V0.shape or not np.all(np.isfinite(rest)):
        raise InputError(f"template_rest: expected finite ({V0.shape[0]}, 3) vertices, got {rest.shape}")
    for name, mesh in (("texture", texture), ("scan", scan)):
        if not isinstance(mesh, Mesh) or not has_colors(mesh):
            raise InputError(f"{name}: expected a Mesh with a texture or vertex_colors (a coloured scan)")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise InputError(f"iterations: expected an integer >= 0, got {iterations!r}")
    alpha = as_positive(alpha, name="alpha", allow_zero=True)
    snap = as_positive(snap_distance_mm, name="snap_distance_mm", allow_zero=True)
    floor = as_positive(confidence_floor, name="confidence_floor")

    welded = weld_duplicate_vertices(V0, np.asarray(F, dtype=np.int64), tolerance=SEAM_WELD_MM)
    Vw, Fw, back = welded.V, welded.F, welded.welded_index
    first = np.full(Vw.shape[0], -1, dtype=np.int64)
    first[back[::-1]] = np.arange(back.size)[::-1]  # one original vertex per welded vertex
    rest_w = rest[first]
    edge = median_edge_length(Vw, Fw)
    # colour textures resolve the skin at their texel size; vertex colours at about the template's sampling
    textured = scan.texture is not None and texture.texture is not None
    if pixel_mm is not None:
        pix = as_positive(pixel_mm, name="pixel_mm")
    elif textured:
        pix = max(texel_size_mm(scan), texel_size_mm(texture), _FINEST_PIXEL_MM)
    else:
        pix = 0.5 * edge
    normals = igl.per_vertex_normals(Vw, Fw)
    forward = np.nansum(normals, axis=0)
    probe = cylindrical_map(Vw, axis=axis, forward=forward, size_px=64, margin_px=2)
    extent_mm = max((probe.shape[1] - 5) / probe.px_per_mm, (probe.shape[0] - 5) / probe.px_per_mm)
    cmap = cylindrical_map(Vw, axis=axis, forward=forward, centre=probe.centre,
                           size_px=int(np.clip(np.ceil(extent_mm / pix), 64, 2048)), margin_px=4)
    # per-vertex colour below half a millimetre is noise at scan resolution; a texture is sharp to a texel
    fine_px = 1.0 if textured else 0.5 * cmap.px_per_mm
    coarse_px = _SHADING_SIGMA_MM * cmap.px_per_mm

    tree = igl.AABB()
    tree.init(scan.vertices, scan.faces)
    on_scan = np.sqrt(tree.squared_distance(scan.vertices, scan.faces, Vw)[0]) <= snap

    reach = max(snap, 2.0 * edge)
    # The template's colour at a point of the template: straight from its texture when the texture
    # mesh is the template itself (the default: the template's own scan), else through the closest
    # point of the separate texture mesh (a retopologised template with the neutral's own scan).
    own_texture = (texture.n_vertices == rest.shape[0] and texture.faces.shape == np.shape(F)
                   and np.array_equal(texture.faces, np.asarray(F)) and np.allclose(texture.vertices, rest, atol=1e-6))
    texture_tree = None
    if not own_texture:
        texture_tree = igl.AABB()
        texture_tree.init(texture.vertices, texture.faces)

    V = Vw.copy()
    confidence = np.zeros(V.shape[0])
    mismatch: list[float] = []
    src = source_valid = None
    if factor is not None and not isinstance(factor, SpdFactor):
        raise InputError(f"factor: expected an SpdFactor or None, got {type(factor).__name__}")
    own_factor = factor is None or factor.n != V.shape[0]
    if own_factor:  # every round's update: one analysis
        factor = SpdFactor.unfactored(V.shape[0], backend=backend)
    try:
        for _ in range(iterations):
            pixels = cmap.project(V)
            raster = cmap.rasterise(Fw, pixels=pixels)
            rows, cols = np.nonzero(raster.covered)
            tri, bary = raster.face[rows, cols], raster.barycentric[rows, cols]
            if src is None:
                # The scan's colour under each pixel. The registration put the mesh on the scan and every
                # round slides it along the scan, so the scan's surface under a pixel, and its colour, stay
                # the same from round to round: looked up and band-passed once.
                points = np.einsum("kc,kcj->kj", bary, V[Fw[tri]])
                colour, near = _luma_at(points, tree, scan, reach)
                source = np.zeros(raster.face.shape)
                source_valid = np.zeros(raster.face.shape, dtype=bool)
                source[rows, cols] = np.where(near, colour, 0.0)
                source_valid[rows, cols] = near
            # the same pixels on the template: its rest surface under them, coloured by its texture
            if own_texture:
                reference = _luminance(surface_colors(texture, tri, bary).astype(np.float64))
                on_texture = np.ones(tri.size, dtype=bool)
            else:
                rest_points = np.einsum("kc,kcj->kj", bary, rest_w[Fw[tri]])
                reference, on_texture = _luma_at(rest_points, texture_tree, texture, reach)
            target = np.zeros(raster.face.shape)
            valid = np.zeros(raster.face.shape, dtype=bool)
            valid[rows, cols] = on_texture
            valid &= source_valid
            target[rows, cols] = reference
            target[~valid] = 0.0
            if src is None:
                src = _band(np.where(valid, source, 0.0), valid, fine_px, coarse_px)
            tgt = _band(target, valid, fine_px, coarse_px)
            mismatch.append(float(np.abs(src - tgt)[valid].mean()) if valid.any() else float("nan"))
            flow = optical_flow(tgt, src, method="dis")
            delta = cmap.sample(flow, pixels, fill=0.0)
            strength = np.sqrt(cv2.GaussianBlur(src * src, (0, 0), max(2.0 * fine_px, 1.0)))
            confidence = np.clip(cmap.sample(strength, pixels, fill=0.0) / _STRONG_TEXTURE, floor, 1.0)
            confidence = np.where(cmap.sample(valid.astype(np.float64), pixels, fill=0.0) > 0.99, confidence, floor)
            moved, ok = raster.surface_points(pixels + delta, V)
            dv = np.where(ok[:, None], moved - V, 0.0)
            limit = 3.0 * np.linalg.norm(delta, axis=1) / cmap.px_per_mm + 2.0 / cmap.px_per_mm
            movable = visible_in_raster(raster) & ok & on_scan & (np.linalg.norm(dv, axis=1) <= limit)
            dv[~movable] = 0.0
            # what the scan does not show stays where the large-scale registration put it (from the
            # markers), rather than being dragged along by the Laplacian of its moving neighbours
            confidence = np.where(movable, confidence, 0.0)
            V = regularised_update(V, Fw, dv, np.where(movable, confidence, UNSEEN_ANCHOR), scan, on_scan,
                                   alpha=alpha, scan_tree=tree, factor=factor)
    finally:
        if own_factor:
            factor.free()
    out = V[back]
    return AlbedoAlignment(vertices=out, moved_mm=np.linalg.norm(out - V0, axis=1), confidence=confidence[back],
                           mismatch_by_round=mismatch)
