"""Every scan of a plan in one template topology: markers, large scale, fine scale, fitted bases."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Sequence

import igl
import numpy as np

from .fit_bases_to_markers import fit_bases_to_markers
from .smooth_marker_changes import smooth_marker_changes
from .marker_places_from_bases import marker_places_from_bases
from .._processes import process_map
from .._threads import available_cores
from ..deform.marker_offsets import DEFAULT_MARKER_OFFSET_MM
from ..errors import FacecapWarning, InputError
from ..markers.rigid_fit import rigid_fit
from ..mesh.factor_spd import SpdFactor
from ..mesh.surface_colors import has_colors
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..structures import Mesh
from .register_markers_to_scan import MarkerRegistration, register_markers_to_scan
from .register_template_to_scan import register_template_to_scans
from .rigid_icp import rigid_icp

__all__ = ["RegisteredScans", "register_scans", "default_workers", "DEFAULT_REST_WEIGHT",
           "TEMPLATE_DEFORMATION_WEIGHT"]

DEFAULT_REST_WEIGHT = 3e-4
"""``w0`` of the template registration (swept in docs/scan_workflow.md)."""

TEMPLATE_DEFORMATION_WEIGHT = 0.01
"""Marker displacement weight when the markers are placed on the template (see ``register_scans``)."""

_CONSENSUS_BASES = 3  # colour-aligned bases needed to place the markers on the template by their consensus
_PROCESSES_FROM_VERTICES = 200_000  # scans holding fewer vertices in all register in seconds: no worker processes


@dataclass(frozen=True, eq=False)
class RegisteredScans:
    """The scans of a plan registered to one template and fitted to their frames' markers.

    Attributes
    ----------
    template : Mesh
        The template, in its own coordinates and unit (the output topology).
    bases : (K, n, 3) float64 array, mm
        Blendshape bases in the (stabilised) mocap frame.
    basis_markers : (K, M, 3) float64 array, mm
        The planned frames' markers, each frame moved rigidly onto its basis:
        the bases reproduce them.
    output_from_mocap : (4, 4) float64 array
        Rigid transform from the mocap frame to the template's coordinates.
    marker_vertices, marker_weights : (M, 3) int64 / float64 arrays
        Where each marker sits on the template (barycentric); rows of
        markers that never landed on the template are -1 / 0.
    registration_mm : (K,) float64 array
        Mean distance of each registered scan to its scan's surface.
    flagged : list of int
        Scans whose registration stayed above the threshold, or failed checks.
    report : dict
        Per-scan details (rigid transforms, marker residuals, flips, timings).
    """

    template: Mesh
    bases: np.ndarray
    basis_markers: np.ndarray
    output_from_mocap: np.ndarray
    marker_vertices: np.ndarray
    marker_weights: np.ndarray
    registration_mm: np.ndarray
    flagged: list[int]
    report: dict[str, Any] = field(default_factory=dict)


def _to_mocap(mesh: Mesh, reg: MarkerRegistration) -> Mesh:
    """The scan moved into the mocap frame (the inverse of the registration's rigid motion)."""
    V = (mesh.vertices - reg.translation) @ reg.rotation
    return mesh.with_vertices(V)


def _surface_motion(template: Mesh, registered: np.ndarray, matched: np.ndarray) -> tuple[list[float], list[float]]:
    """Mean tangential and normal motion (mm) of each registered scan from the template, over matched vertices.

    Both are in the (stabilised) frame the template and the bases share, so a
    pose error of a basis shows as motion too.
    """
    normals = igl.per_vertex_normals(template.vertices, template.faces)
    slide, lift = [], []
    for i in range(registered.shape[0]):
        d = registered[i] - template.vertices
        along = np.einsum("nc,nc->n", d, normals)
        tangential = np.linalg.norm(d - along[:, None] * normals, axis=1)
        keep = matched[i] & np.isfinite(tangential)
        slide.append(float(tangential[keep].mean()) if keep.any() else float("nan"))
        lift.append(float(np.abs(along[keep]).mean()) if keep.any() else float("nan"))
    return slide, lift


def _template_texture(texture: Mesh | None, tmpl_mocap: Mesh, template_markers: np.ndarray | None,
                      subspace: np.ndarray, marker_offset_mm: float, deformation_weight: float) -> Mesh | None:
    """The coloured surface of the template's expression in the mocap frame, or None without colours."""
    if texture is None:
        return tmpl_mocap if has_colors(tmpl_mocap) else None
    if not has_colors(texture):
        raise InputError("template_texture has no colour (no texture and no vertex colours)", path=texture.source_path)
    if template_markers is None:
        raise InputError("template_texture needs the template's markers (template_markers) to be placed")
    reg = register_markers_to_scan(template_markers, texture, subspace=subspace, marker_offset_mm=marker_offset_mm,
                                   deformation_weight=deformation_weight)
    placed = _to_mocap(texture, reg)
    # The markers place it to within their noise (tenths of a mm, a tenth of a degree); every basis
    # is slid onto its colours, so any offset of the texture against the template would be copied into
    # all of them. Both show the same expression: the surfaces themselves align it exactly.
    icp = rigid_icp(placed.vertices, tmpl_mocap.vertices, tmpl_mocap.faces, init=np.eye(4), trim=0.8)
    return placed.with_vertices(placed.vertices @ icp.rotation.T + icp.translation)


def register_scans(
    scans: Sequence[Mesh],
    frame_markers: np.ndarray,
    *,
    template: Mesh | None = None,
    template_markers: np.ndarray | None = None,
    marker_offset_mm: float = DEFAULT_MARKER_OFFSET_MM,
    refine: bool = False,
    template_texture: Mesh | None = None,
    align_colors: bool = False,
    flag_threshold_mm: float = 0.2,
    rest_weight: float = DEFAULT_REST_WEIGHT,
    template_deformation_weight: float = TEMPLATE_DEFORMATION_WEIGHT,
    smooth_marker_fit: bool | None = None,
    workers: int = 1,
    progress: bool = True,
) -> RegisteredScans:
    """Register a plan's scans (Huang et al. 2011, sections 5, 6.1, 6.2 and 7).

    Each scan: its markers registered onto it (section 5), which puts it in
    the stabilised mocap frame; the template deformed onto it (eq. 7, with a
    weak pull towards the template's own position, ``rest_weight``, for
    what neither scan nor markers constrain); the optional fine-scale
    refinement (6.2); and every basis fitted to its frame's markers (7)
    after those markers are moved rigidly onto the basis, so the fit changes
    the basis's shape, not its pose.

    Parameters
    ----------
    scans : sequence of Mesh, length K
        One scan per planned frame, in the plan's order, each in its own
        scanner frame and topology (mm).
    frame_markers : (K, M, 3) float array, mm
        The planned frames' conditioned (gap-filled, stabilised) markers.
    template : Mesh, optional
        The mesh whose topology the bases take. Default: the first scan.
    template_markers : (M, 3) float array, optional
        Markers of a frame whose expression matches ``template`` (for example
        the take's rest frame for a neutral template); registered onto the
        template to place the markers on it. Required with ``template``.
    marker_offset_mm : float, default 1.5
        Marker centre height above the skin.
    template_texture : Mesh, optional
        A coloured scan of the template's expression (``vertex_colors`` set),
        in its own scanner frame: typically the neutral's own scan when the
        template is a retopologised neutral. It is placed like any scan (the
        template's markers registered onto it). Default: the template itself
        when it has colours.
    align_colors : bool, default False
        Slide every registered scan along its scan until the skin's colours
        match the template's (:func:`~facecap.registration.align_albedo.align_albedo`):
        the tangential correspondence geometry cannot give. Needs colours on
        the scans and on the template or ``template_texture``. Off by
        default: how much it helps depends on how much texture the scans
        resolve. With a dense 3-10 mm texture (exact markers, two strong
        brow/eye bases of a real-motion take) each basis's error fell from
        0.38 to 0.28 mm and from 0.23 to 0.17 mm (forehead 0.36 -> 0.12); with
        the generator's skin model at 20k-vertex scans (mottling, blotches,
        sparse freckles, brows) it did not (0.38 -> 0.34, 0.23 -> 0.25), and
        through the whole workflow on a default take the blend got worse
        (0.15 -> 0.22 mm). See docs/scan_workflow.md.
    refine : bool, default False
        Run the fine-scale registration (section 6.2). Off by default: on the
        generated ICT scans (smooth, few curvature features) it has not yet
        been shown to improve correspondence (see docs/scan_workflow.md).
    flag_threshold_mm : float, default 0.2
        Scans whose mean distance to their surface stays above this are flagged.
    rest_weight : float, default 3e-4 (:data:`DEFAULT_REST_WEIGHT`)
        ``w0`` of
        :func:`~facecap.registration.register_template_to_scan.register_template_to_scan`.
    template_deformation_weight : float, default 0.01 (:data:`TEMPLATE_DEFORMATION_WEIGHT`)
        ``deformation_weight`` of
        :func:`~facecap.registration.register_markers_to_scan.register_markers_to_scan`
        when ``template_markers`` are placed on ``template``. The template shows
        their frame's own expression, so any deformation of those markers only
        fits their noise; left free (as for the scans, which are re-performed
        expressions), the subspace slid one marker 0.7 mm along an eyelid on a
        generated take, and every basis inherited that offset through the
        section-7 fit (the eyes' error went from 0.17 to 0.35 mm).
    smooth_marker_fit : bool or None, default None
        True: section 7 moves each basis by only the part of its markers' disagreement that is
        smooth over the face beyond the markers' own noise
        (:func:`~facecap.registration.smooth_marker_changes.smooth_marker_changes`, hyperparameters
        by likelihood, recorded in the report's ``marker_fit``); False: the paper's exact fit to the
        noisy markers. None (default): True with ``align_colors``, else False. With colour the skin's
        texture fixes the bases along the skin and the markers' noise only pulls them off it (8
        bases of a tuned take whose scans are the frames performed again: 0.258 -> 0.248 mm, the
        exact fit 0.258, no fit 0.280); without colour the markers are the only cue along the skin
        and their full pull was worth a little more (0.335 exact, 0.340 smoothed).
    workers : int, default 1
        Processes that register scans side by side (each scan's markers,
        template registration and colour alignment are independent of the
        others'); capped at the cores this process may use. 1: all in this
        process. The results do not depend on it. Worker processes are
        spawned: a script that asks for them needs Python's
        ``if __name__ == "__main__":`` guard.
        :func:`~facecap.pipelines.register_planned_scans` (the command) picks
        :func:`default_workers`.
    progress : bool, default True

    Returns
    -------
    RegisteredScans

    Raises
    ------
    InputError
        On mismatched counts, or a template without its markers.
    """
    X = np.asarray(frame_markers, dtype=np.float64)
    K = len(scans)
    if X.ndim != 3 or X.shape[0] != K or X.shape[2] != 3:
        raise InputError(f"--scans: the plan has {X.shape[0] if X.ndim == 3 else '?'} frames but {K} scans were given")
    if template is not None and template_markers is None:
        raise InputError("a template needs the markers of a frame matching its expression (template_markers)")
    if align_colors:  # refused before any work, naming the first mesh without colour
        source = template_texture if template_texture is not None else (template if template is not None else None)
        for i, mesh in enumerate(scans if source is None else [source, *scans]):
            if not has_colors(mesh):
                name = "template_texture" if mesh is template_texture else ("template" if mesh is template else
                                                                            f"scan {i - (source is not None)}")
                raise InputError(f"align_colors: {name} has no colour (a texture or vertex colours); the scans and "
                                 "the template (or template_texture) need one", path=mesh.source_path)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InputError(f"workers: expected a positive integer, got {workers!r}")
    with process_map(min(int(workers), K), progress=progress) as each_scan:
        return _register_scans(scans, X, each_scan, template, template_markers, marker_offset_mm, refine,
                               template_texture, align_colors, flag_threshold_mm, rest_weight,
                               template_deformation_weight, smooth_marker_fit)


def default_workers(scans: Sequence[Mesh]) -> int:
    """Worker processes worth starting for ``scans``: every core this process may use when they hold
    200,000 vertices or more in all, else 1. Below that the whole registration takes seconds, and a worker
    costs about one to start (it imports the package); above it each scan takes seconds (20 scans of 78k
    vertices with colour textures: see benchmarks/RESULTS.md)."""
    return available_cores() if sum(scan.n_vertices for scan in scans) >= _PROCESSES_FROM_VERTICES else 1


def _align_colours(run: Sequence[tuple[np.ndarray, Mesh]], *, faces: np.ndarray, rest: np.ndarray, texture: Mesh,
                   axis: np.ndarray) -> list[Any]:
    """:func:`~facecap.registration.align_albedo.align_albedo` of a run of registered scans (a worker's task),
    one factor of the update kept through the run (PARDISO's analysis once, not once a scan)."""
    from .align_albedo import SEAM_WELD_MM, align_albedo

    # the size align_albedo solves for: the template with its seams welded, as it welds them
    factor = SpdFactor.unfactored(weld_duplicate_vertices(run[0][0], faces, tolerance=SEAM_WELD_MM).V.shape[0])
    try:
        return [align_albedo(vertices, faces, rest, texture, scan, axis=axis, factor=factor) for vertices, scan in run]
    finally:
        factor.free()


def _register_scans(scans: Sequence[Mesh], X: np.ndarray, each_scan: Any, template: Mesh | None,
                    template_markers: np.ndarray | None, marker_offset_mm: float, refine: bool,
                    template_texture: Mesh | None, align_colors: bool, flag_threshold_mm: float, rest_weight: float,
                    template_deformation_weight: float, smooth_marker_fit: bool | None) -> RegisteredScans:
    """:func:`register_scans` after its checks, the per-scan stages through ``each_scan`` (a ProcessMap)."""
    K = len(scans)
    timings: dict[str, float] = {}
    report: dict[str, Any] = {"scans": [], "workers": each_scan.workers}
    flagged: set[int] = set()
    t = time.perf_counter()
    registrations = each_scan(partial(register_markers_to_scan, subspace=X, marker_offset_mm=marker_offset_mm),
                              [(X[i], scan) for i, scan in enumerate(scans)], desc="markers -> scans")
    for i, (scan, reg) in enumerate(zip(scans, registrations)):
        matched = int((~reg.unmatched).sum())
        entry = {
            "scan": scan.source_path or f"scan {i}",
            "vertices": scan.n_vertices,
            "markers_matched": matched,
            "marker_rms_mm": reg.rms,
            "normals_flipped": reg.normals_flipped,
        }
        if matched < 4:
            raise InputError(
                f"no usable marker lands on this scan ({matched} matched); is it the planned expression?",
                path=scan.source_path,
            )
        if reg.normals_flipped:
            warnings.warn(f"{entry['scan']}: triangles are wound inward (flipped normals); handled", FacecapWarning,
                          stacklevel=2)
        report["scans"].append(entry)
    timings["marker_registration_s"] = time.perf_counter() - t

    scans_mocap = [_to_mocap(s, r) for s, r in zip(scans, registrations)]
    if template is None:
        tmpl_mocap = scans_mocap[0]
        tmpl_reg = registrations[0]
        template = scans[0]
    else:
        tmpl_reg = register_markers_to_scan(np.asarray(template_markers, dtype=np.float64), template, subspace=X,
                                            marker_offset_mm=marker_offset_mm,
                                            deformation_weight=template_deformation_weight)
        tmpl_mocap = _to_mocap(template, tmpl_reg)
    output_from_mocap = np.eye(4)
    output_from_mocap[:3, :3], output_from_mocap[:3, 3] = tmpl_reg.rotation, tmpl_reg.translation
    on_template = ~tmpl_reg.unmatched
    tri = np.where(on_template, tmpl_reg.face_indices, 0)
    marker_vertices = np.where(on_template[:, None], template.faces[tri], -1)
    marker_weights = np.where(on_template[:, None], tmpl_reg.barycentric, 0.0)

    t = time.perf_counter()
    registered = np.empty((K, template.n_vertices, 3))
    matched = np.empty((K, template.n_vertices), dtype=bool)  # vertices with a trusted closest point
    distances = np.empty(K)
    # Markers the scan does not show (the sides of the face beyond a single-view scan) still say
    # where their skin is: the frame's marker less its height along the template's normal there.
    # Left out, eq. 7 extrapolated those parts from the scan's edge and section 7 then had to pull
    # them by up to 17 mm (bases 0.75-0.87 mm off where the others were 0.3).
    tmpl_normals = igl.per_vertex_normals(tmpl_mocap.vertices, template.faces)
    marker_normals_rest = np.einsum("mj,mjc->mc", marker_weights, tmpl_normals[np.maximum(marker_vertices, 0)])
    marker_normals_rest /= np.maximum(np.linalg.norm(marker_normals_rest, axis=1, keepdims=True), 1e-12)
    skins = np.empty((K, X.shape[1], 3))
    targets = []
    for i, reg in enumerate(registrations):
        skins[i] = (reg.surface_points - reg.translation) @ reg.rotation  # skin under each marker, mocap frame
        usable = on_template & ~reg.unmatched
        off_scan = X[i] - marker_offset_mm * marker_normals_rest
        targets.append(np.where(usable[:, None], skins[i], off_scan)[on_template])
    # scans in runs, each run building the template's system once (register_template_to_scans); two runs a
    # worker keep every worker busy to the end
    size = -(-K // (2 * each_scan.workers))
    runs = [(scans_mocap[i:i + size], targets[i:i + size]) for i in range(0, K, size)]
    results = [r for run in each_scan(partial(register_template_to_scans, tmpl_mocap, marker_vertices[on_template],
                                              marker_weights[on_template], rest_weight=rest_weight),
                                      runs, desc="template -> scans") for r in run]
    for i, result in enumerate(results):
        registered[i] = result.vertices
        matched[i] = result.matched
        distances[i] = result.mean_distance_mm
        report["scans"][i]["large_scale_mm"] = result.mean_distance_mm
        report["scans"][i]["matched_fraction"] = float(result.matched.mean())
    timings["large_scale_registration_s"] = time.perf_counter() - t

    if align_colors:
        texture = _template_texture(template_texture, tmpl_mocap,
                                    None if template_markers is None else np.asarray(template_markers, dtype=np.float64),
                                    X, marker_offset_mm, template_deformation_weight)
        assert texture is not None  # register_scans refused a colour source without colour before any work

        t = time.perf_counter()
        up = output_from_mocap[:3, :3].T @ np.array([0.0, 1.0, 0.0])
        pairs = list(zip(registered, scans_mocap))
        alignments = [a for run in each_scan(partial(_align_colours, faces=template.faces, rest=tmpl_mocap.vertices,
                                                     texture=texture, axis=up),
                                             [(pairs[i:i + size],) for i in range(0, K, size)], desc="colour alignment")
                      for a in run]
        for i, aligned in enumerate(alignments):
            registered[i] = aligned.vertices
            report["scans"][i]["colour_alignment_moved_mm"] = {
                "mean": float(aligned.moved_mm.mean()), "max": float(aligned.moved_mm.max())}
            report["scans"][i]["colour_mismatch_by_round"] = aligned.mismatch_by_round
        timings["colour_alignment_s"] = time.perf_counter() - t
        # The template's marker places came from the rest frame, which may hold a resting expression
        # (lowered brows, a smile) that puts them off their skin points; the colour-aligned bases know
        # each marker's skin point on every scan in the template's own material: their consensus
        # replaces the rest frame's guess before section 7 pins the bases to the markers.
        if K >= _CONSENSUS_BASES:
            landed_on = np.stack([~r.unmatched for r in registrations]) & on_template[None]
            places = marker_places_from_bases(registered, template.faces, tmpl_mocap.vertices, skins, landed_on)
            moved = places.moved_mm(tmpl_mocap.vertices, marker_vertices, marker_weights)
            marker_vertices = np.where(places.found[:, None], places.vertices, marker_vertices)
            marker_weights = np.where(places.found[:, None], places.weights, marker_weights)
            report["marker_places_from_bases_mm"] = {"mean": float(np.nanmean(moved)) if places.found.any() else 0.0,
                                                     "max": float(np.nanmax(moved)) if places.found.any() else 0.0,
                                                     "markers": int(places.found.sum())}

    if refine and K > 1:
        from .refine_registration import refine_registration

        t = time.perf_counter()
        # The cylinder's axis is the face's up direction: the template's +Y (the convention of
        # DCC tools and of the ICT model) carried into the stabilised mocap frame the bases live in.
        up = output_from_mocap[:3, :3].T @ np.array([0.0, 1.0, 0.0])
        refined = refine_registration(registered, template.faces, scans_mocap, axis=up)
        registered = refined.vertices
        timings["fine_scale_registration_s"] = time.perf_counter() - t
        for i in range(K):  # the same vertices as the large-scale figure, so the two compare
            d = refined.distance_to_scan_mm[i][matched[i]]
            distances[i] = float(np.mean(d)) if d.size else float("nan")
            report["scans"][i]["fine_scale_mm"] = distances[i]
        flagged.update(int(i) for i in np.flatnonzero(refined.flagged))
        report["fine_scale_misalignment"] = {"before": refined.misalignment_before.tolist(),
                                             "after": refined.misalignment_after.tolist()}

    # section 7: bases fitted to their frames' markers (skin under each marker), after the
    # markers are moved rigidly onto their basis, so the fit changes the shape, not the pose
    t = time.perf_counter()
    fit_rows = on_template
    normals = np.stack([igl.per_vertex_normals(registered[i], template.faces) for i in range(K)])
    mv, mw = marker_vertices[fit_rows], marker_weights[fit_rows]
    marker_normals = np.einsum("mj,kmjc->kmc", mw, normals[:, mv])
    marker_normals /= np.linalg.norm(marker_normals, axis=2, keepdims=True)
    virtual = np.einsum("mj,kmjc->kmc", mw, registered[:, mv]) + marker_offset_mm * marker_normals
    landed = np.stack([~r.unmatched[fit_rows] for r in registrations]).astype(np.float64)
    to_basis = rigid_fit(X[:, fit_rows], virtual, weights=landed)  # off-scan markers' virtual spots are guesses
    X = to_basis.apply(X)
    skin_targets = X[:, fit_rows] - marker_offset_mm * marker_normals
    on_basis = np.einsum("mj,kmjc->kmc", mw, registered[:, mv])
    change = np.linalg.norm(skin_targets - on_basis, axis=2)  # what the markers say, before any fit
    if align_colors if smooth_marker_fit is None else smooth_marker_fit:
        # only what the markers agree on beyond their own noise moves the bases (see smooth_marker_changes)
        rest_points = np.einsum("mj,mjc->mc", mw, tmpl_mocap.vertices[mv])
        smoothed = smooth_marker_changes(skin_targets - on_basis, rest_points, weights=landed)
        skin_targets = on_basis + smoothed.changes
        report["marker_fit"] = {"length_mm": smoothed.length_mm, "smooth_mm": smoothed.amplitude_mm,
                                "noise_mm": smoothed.noise_mm}
    bases, applied = fit_bases_to_markers(registered, template.faces, mv, mw, skin_targets)
    timings["fit_bases_s"] = time.perf_counter() - t
    slide, lift = _surface_motion(tmpl_mocap, registered, matched)
    for i in range(K):
        report["scans"][i]["basis_fit_change_mm"] = float(np.mean(applied[i]))
        # Readable without truth: how well the registered surface already agreed with its frame's
        # markers before section 7 forced them (a pose or correspondence error shows here first),
        # and how far the template slid along itself to reach the scan (expressions slide skin a
        # few mm at most; much more, or one basis far above the others, is a sliding registration).
        seen = np.isfinite(change[i])
        report["scans"][i]["quality"] = {
            "marker_residual_mm": {"mean": float(np.mean(change[i][seen])) if seen.any() else float("nan"),
                                   "max": float(np.max(change[i][seen])) if seen.any() else float("nan")},
            "tangential_motion_mm": slide[i],
            "normal_motion_mm": lift[i],
        }
        if not np.isfinite(distances[i]) or distances[i] > flag_threshold_mm:
            flagged.add(i)
    report["timings"] = timings
    report["flagged"] = sorted(flagged)
    return RegisteredScans(
        template=template,
        bases=bases,
        basis_markers=X,
        output_from_mocap=output_from_mocap,
        marker_vertices=marker_vertices,
        marker_weights=marker_weights,
        registration_mm=distances,
        flagged=sorted(flagged),
        report=report,
    )
