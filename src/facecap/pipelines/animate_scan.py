"""``facecap animate``'s job: the large-scale pipeline of Bickel et al. 2007 (section 4), end to end, streamed.

The take made ready (:mod:`facecap.markers.prepare_take`), the warp and the thin shell
(:mod:`facecap.deform`), the result written (:mod:`facecap.io`).
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, NamedTuple, Sequence

import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ..deform.basis_product import Precision
from ..deform.marker_offsets import DEFAULT_MARKER_OFFSET_MM, MarkerOffsets, MarkerRing, marker_ring
from ..deform.rest_pose import RestPose, choose_rest_pose, neutral_from_frames, neutral_from_take
from ..deform.thin_shell import DEFAULT_KB_MM2, DEFAULT_KS, ThinShellSolver, UnmarkedPieces
from ..deform.triharmonic_warp import TriharmonicWarp, check_warp_sources
from .._mkl import mkl_blas
from ..errors import FacecapWarning, MarkerError
from ..io.result_layout import parse_export_formats
from ..io.result_rig import ResultRig
from ..io.write_performance import PerformanceWriter
from ..markers.condition_take import moving_stable_markers
from ..markers.consensus_stabilize import estimate_marker_noise
from ..markers.prepare_take import (DEFAULT_REST_AVERAGE_S, MIN_DRIVING_MARKERS, PreparedMarkers,
                                    check_take_against_map, head_pose_in_scan, prepare_markers, rest_average)
from ..mesh.check_mesh import check_mesh
from ..mesh.factor_spd import Backend, load_backend
from ..structures import Correspondence, MarkerSequence, Mesh
from ..markers.check_take_units import check_take_units
from ..units import mm_per_unit
from ..validate import as_positive
from .export_result import usd_principal_components, usd_shape_count
from .finish_result import finish_result, import_writers

__all__ = ["animate_scan", "AnimationResult", "OFFSET_WARNING_MM"]

OFFSET_WARNING_MM = 0.5
"""A marker offset the rest frame contradicts by more than this (mm) is named in a warning."""


@dataclass(frozen=True)
class AnimationResult:
    """What :func:`animate_scan` did.

    Attributes
    ----------
    out_dir : Path
        The finished output folder.
    report : dict
        The content of ``report.json`` (timings, residuals, warnings).
    """

    out_dir: Path
    report: dict[str, Any]


def animate_scan(
    scan: Mesh,
    markers: MarkerSequence,
    correspondence: Correspondence,
    out_dir: str | Path,
    *,
    rest_frame: int = 0,
    ks: float = DEFAULT_KS,
    kb: float = DEFAULT_KB_MM2,
    stabilize: bool | str | Sequence[str] = True,
    smooth: bool = True,
    temporal_sigma_s: float | str = "auto",
    marker_offset_mm: float = DEFAULT_MARKER_OFFSET_MM,
    rest_average_s: float = DEFAULT_REST_AVERAGE_S,
    rest_pose: str = "auto",
    neutral: tuple[int, int] | MarkerSequence | None = None,
    exports: Iterable[str] = (),
    write_vertices: bool = True,
    rig_precision: str = "float32",
    export_options: dict[str, Any] | None = None,
    unmarked_pieces: UnmarkedPieces = "carry",
    batch_frames: int = 32,
    backend: Backend = "auto",
    precision: Precision = "float32",
    progress: bool = True,
    extra_metadata: dict[str, Any] | None = None,
    overwrite: bool = False,
) -> AnimationResult:
    """Animate a scan from a mocap take (Bickel et al. 2007, section 4) and write the result.

    Markers are conditioned (:func:`prepare_markers`), mapped to face space
    by the triharmonic warp (section 4.1), and drive the linear thin shell
    (section 4.2). Frames are computed in batches and streamed to ``out_dir``,
    so memory does not grow with the take's length.

    Parameters
    ----------
    scan : Mesh
        The static scan (mm inside; the output is in its own unit).
    markers : MarkerSequence
        The take.
    correspondence : Correspondence
        Marker label -> scan point.
    out_dir : str or Path
        Output folder (see :class:`~facecap.io.write_performance.PerformanceWriter`).
    rest_frame : int, default 0
        The take's rest frame: stabilisation aligns every frame to it, and
        the warp maps its markers onto the scan (see ``rest_pose``).
    ks, kb : float
        Stretching (dimensionless) and bending (mm^2) stiffness, see
        :class:`~facecap.deform.thin_shell.ThinShellSolver`.
    stabilize : bool, 'consensus' or sequence of str, default True
        Remove rigid head motion before deforming (the head motion is kept in
        ``head_motion.npy`` and the USD export); see :func:`prepare_markers`.
        ``True`` (``--stabilize auto``) leaves a still head as captured.
    smooth : bool, default True
        Spatio-temporal bilateral filtering of the markers.
    temporal_sigma_s : float or 'auto', default 'auto'
        The filter's temporal sigma, s, or chosen for the take by
        cross-validation (:func:`~facecap.markers.choose_temporal_sigma`;
        the choice and every candidate's score go into ``report.json``).
    marker_offset_mm : float, default 1.5
        Height of the marker centres above the skin, mm (the same meaning as
        ``register_scans``' option). The warp maps the rest markers onto the
        scan points lifted by it along the scan's normals, and each frame's
        marker displacement becomes the skin's by carrying the offset with the
        deformed surface (:class:`~facecap.deform.marker_offsets.MarkerOffsets`).
        0: the markers are taken to lie on the skin (the paper).
    rest_average_s : float, default 0.1
        The warp's rest markers are a Gaussian average (this sigma, in
        seconds, cut at 2.5 sigma) of the conditioned markers round
        ``rest_frame``, so the rest frame's noise does not offset every
        frame; assumes the face holds its rest expression that long (as the
        bilateral filter's rest does). 0: the rest frame alone (the paper).
    rest_pose : {'auto', 'scan', 'expression'}, default 'auto'
        What the rest frame's mismatch with the scan is (after a robust rigid
        fit): 'scan' takes the rest frame to show the scan's expression, and
        the warp maps its markers exactly onto the scan (the paper: a resting
        expression is then taken out of every frame); 'expression' keeps the
        mismatch as an expression the face holds (the warp absorbs only
        markers that look misplaced in the map); 'auto' measures it
        (:func:`~facecap.markers.measure_resting_expression`) and keeps it
        when it is clearly above the noise and neighbouring markers share
        it, as an expression moves the skin (a map picked by hand is off
        marker by marker) (:func:`~facecap.deform.rest_pose.choose_rest_pose`),
        with a warning that says so. The measurement goes to ``report.json``.
    neutral : (int, int) or MarkerSequence or None, optional
        An explicit neutral reference instead of the rest frame: frames
        ``(A, B)`` of this take (``A <= t < B``) in which the actor holds the
        scan's expression, or a separate neutral take with the same labels.
        Its markers are mapped onto the scan; ``rest_pose`` is then ignored.
    exports : iterable of str
        Exports, see :data:`facecap.io.EXPORT_FORMATS`.
    write_vertices : bool, default True
        Write ``vertices.npy``. The exact compact form (``rig/``: the scan,
        the shell's basis and each frame's marker displacements, see
        :class:`~facecap.io.ResultRig`) is always written; without
        ``vertices.npy`` and per-frame exports no frame is computed at all.
    rig_precision : {'float32', 'int16'}, default 'float32'
        Storage of the rig's basis (int16: half the size, bound in ``rig/rig.json``).
    export_options : dict, optional
        Passed to :func:`facecap.pipelines.export_result` (glTF targets, review mesh size).
    unmarked_pieces : {'carry', 'rigid'}, default 'carry'
        What pieces of the scan without markers do.
    batch_frames : int, default 32
        Frames per dense product.
    backend : {'auto', 'pardiso', 'scipy'}
        Sparse factorisation backend.
    precision : {'float32', 'int16'}, default 'float32'
        Arithmetic of the per-frame product, see
        :class:`~facecap.deform.basis_product.BasisProduct`.
    progress : bool, default True
        Show a progress bar.
    extra_metadata : dict, optional
        Added to ``performance.json`` (e.g. source file names).
    overwrite : bool, default False
        Replace an earlier result in ``out_dir``; without it one is refused
        (:class:`~facecap.io.PerformanceWriter`; the CLI checks before any work).

    Returns
    -------
    AnimationResult

    Raises
    ------
    MeshError
        If the scan's size disagrees with the markers' by a length unit (a
        scan in metres read as mm), naming the likely unit; see
        :func:`facecap.markers.check_take_units`, which can also convert.
    """
    check_take_units(scan, markers, correspondence, rest_frame=rest_frame)
    exports = parse_export_formats(exports)  # names and optional packages, before the set-up
    timings: dict[str, float] = {}
    caught: list[str] = []
    marker_offset_mm = as_positive(marker_offset_mm, name="marker_offset_mm", allow_zero=True)
    rest_average_s = as_positive(rest_average_s, name="rest_average_s", allow_zero=True)

    def stage(message: str) -> None:
        if progress:
            print(f"facecap: {message}", file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    # Checked before the long set-up: the map against the take, and a neutral take against its labels
    # its notes (unmapped markers) are given once, by the conditioning beside the set-up
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        matched, _, _ = check_take_against_map(markers, correspondence, rest_frame)
    shared = len(set(neutral.labels) & set(matched.labels)) if isinstance(neutral, MarkerSequence) else MIN_DRIVING_MARKERS
    if shared < MIN_DRIVING_MARKERS:
        raise MarkerError(f"the neutral take holds {shared} of the map's markers; at least {MIN_DRIVING_MARKERS} are needed",
                          path=neutral.source_path)
    # the markers the shell is built for: every matched one (the conditioning drops one only when it cannot
    # recover it at the rest frame; then the shell is built again)
    planned = np.asarray(matched.vertex_indices[np.arange(len(matched.labels)), np.argmax(matched.weights, axis=1)],
                         dtype=np.int64)
    # MKL's libraries, which the set-up's first factorisation would load, loaded here, before the other thread starts;
    # and the BLAS bindings of the per-frame product (ctypes), which the set-up would load while the other thread
    # imports usd-core (seen: the demo hung there, each thread in its own library's load)
    load_backend(backend)
    mkl_blas()
    with warnings.catch_warnings(record=True) as records, ThreadPoolExecutor(1) as beside_setup:
        warnings.simplefilter("always", FacecapWarning)
        # Beside the set-up, on a second thread: its sparse solves keep one core busy, not two (measured
        # at 700k vertices). The markers' side (conditioning, the rest pose, the mesh round the markers,
        # the warp and every frame through it), then the mesh check (a report only: the shell handles
        # what it finds on its own), then the modules the writer at the end needs (usd-core, matplotlib:
        # 0.5 s). One OpenBLAS thread meanwhile (the set-up itself uses MKL): a second would only contend
        # for the core PARDISO's solves use. Libraries load on the second thread only: with MKL's loaded
        # above, the set-up loads none (a library loading on one thread while another loads one can
        # deadlock; seen: usd-core's initialisers against MKL's first load inside PARDISO).
        t = time.perf_counter()
        with threadpool_limits(limits={"openblas": 1}):
            stage(f"conditioning {markers.n_frames} frames x {markers.n_markers} markers, beside the set-up")
            marker_run = beside_setup.submit(
                _timed, _markers_side, scan, markers, correspondence, rest_frame=rest_frame, stabilize=stabilize,
                smooth=smooth, temporal_sigma_s=temporal_sigma_s, rest_average_s=rest_average_s, neutral=neutral,
                marker_offset_mm=marker_offset_mm, rest_pose=rest_pose)
            mesh_check_run = beside_setup.submit(_timed, check_mesh, scan.vertices, scan.faces)
            writers_import = beside_setup.submit(import_writers, exports)
            stage(f"factoring the thin shell: {scan.n_vertices} vertices, {planned.size} markers")
            solver = ThinShellSolver(
                scan.vertices, scan.faces, planned,
                ks=ks, kb=kb, unmarked_pieces=unmarked_pieces, backend=backend, precision=precision,
            )
            side, timings["condition_and_warp_s"] = marker_run.result()
        # the second thread's imports finished before this thread does anything that may load a library (the
        # per-frame product's numba loop loads cffi at its first call): on a small scan the set-up is done first
        mesh_check, timings["check_mesh_s"] = mesh_check_run.result()
        writers_import.result()
        prepared, ring, centres, face_markers, chosen, head_motion, loo = side
        if not np.array_equal(prepared.constrained_vertices, planned):
            solver = ThinShellSolver(
                scan.vertices, scan.faces, prepared.constrained_vertices,
                ks=ks, kb=kb, unmarked_pieces=unmarked_pieces, backend=backend, precision=precision,
            )
        if chosen.warn:
            warnings.warn(f"rest pose: {chosen.reason}", FacecapWarning, stacklevel=2)
        offset_error = chosen.measurement.offset_error_mm
        if abs(offset_error) > OFFSET_WARNING_MM and chosen.measurement.fits_scan:
            warnings.warn(f"the rest frame's markers sit {abs(offset_error):.1f} mm {'further from' if offset_error > 0 else 'closer to'} "
                          f"the skin than --marker-offset {marker_offset_mm:g} says: about {marker_offset_mm + offset_error:.1f} mm "
                          "fits them (the warp absorbs the difference at rest; give the right offset so the motion "
                          "is carried with it)", FacecapWarning, stacklevel=2)
        offsets = MarkerOffsets(scan.vertices, scan.faces, solver, marker_offset_mm=marker_offset_mm, ring=ring)
        timings["shell_setup_s"] = time.perf_counter() - t  # the shell and the offsets' part of it that needs it
        marker_displacements = face_markers - centres[None]

        t = time.perf_counter()
        displacements = offsets.skin_displacements(marker_displacements)
        timings["marker_offsets_s"] = time.perf_counter() - t
        for w in records:
            if issubclass(w.category, FacecapWarning):
                caught.append(str(w.message))
    for message in caught:
        warnings.warn(message, FacecapWarning, stacklevel=2)

    # Per-frame marker residual of the deformed scan: distance between each
    # marker's warped position and where the deformed surface puts it (its
    # scan point moved with the marker vertex, lifted by the offset along the
    # deformed normal). Zero for vertex maps without offset; the snapping error
    # for barycentric ones; the fixed point's convergence with an offset.
    lift = offsets.marker_offset_mm * (offsets.deformed_normals(displacements) if offsets.marker_offset_mm else 0.0)
    marker_residual = np.linalg.norm(prepared.scan_points[None] + displacements + lift - face_markers, axis=2)
    offset_correction = np.linalg.norm(displacements - marker_displacements, axis=2)
    head_pose = (head_pose_in_scan(prepared, chosen.sources, chosen.targets, rest_frame)
                 if prepared.head_rotations is not None else None)

    T, n = markers.n_frames, scan.n_vertices
    t = time.perf_counter()
    rest32 = scan.vertices.astype(np.float32)
    disp32 = displacements.astype(np.float32)
    metadata = {
        "source_files": {"scan": scan.source_path, "markers": markers.source_path},
        "source_units": {"scan": scan.source_unit, "markers": markers.source_unit},
        "method": "bickel2007-large-scale",
        "rest_frame": rest_frame,
        "stabilized": head_pose is not None,
        "parameters": {
            "ks": ks, "kb_mm2": kb, "smooth": smooth, "temporal_sigma_s": prepared.temporal_sigma_s,
            "unmarked_pieces": unmarked_pieces,
            "marker_offset_mm": offsets.marker_offset_mm, "offset_iterations": offsets.iterations,
            "rest_average_s": float(rest_average_s), "rest_pose": chosen.mode,
            "stabilize": head_motion["mode"],
            "stable_markers": list(prepared.stable_labels), "backend": solver.backend,
            "precision": solver.product.precision,
            "product_error_bound_mm": solver.product.error_bound_mm(float(np.abs(disp32).max(initial=0.0))),
        },
        "markers": list(prepared.labels),
        "first_frame": markers.first_frame,
        **(extra_metadata or {}),
    }
    to_unit = np.float32(1.0 / mm_per_unit(scan.source_unit))
    rig = ResultRig(rest32 * to_unit, solver.basis, disp32 * to_unit, units=scan.source_unit, names=prepared.labels)
    options = {"progress": progress, **(export_options or {})}
    # The USD rig's principal components (1 s at 700k vertices) need only the rig: computed on a second thread
    # while this one writes the rest of the result, and handed to the export at the end
    with ThreadPoolExecutor(1) as beside_writing, \
            PerformanceWriter(out_dir, mesh=scan, rate=markers.rate, n_frames=T, exports=exports,
                              vertices=write_vertices, overwrite=overwrite, export_options=options) as writer:
        usd_principal = (beside_writing.submit(usd_principal_components, rig,
                                               usd_shape_count(rig, options.get("usd_shapes", "auto")))
                         if "usd" in exports else None)
        writer.write_rig(rig, precision=rig_precision)
        if writer.needs_frames:
            writer.stream(lambda start, stop, out: solver.deform_into(disp32[start:stop], rest32, out),
                          batch_frames=batch_frames, head_pose=head_pose, progress=progress, desc="animate")
        np.save(writer.path("markers.npy"), (face_markers * to_unit).astype(np.float32))
        _save_correspondence(writer.path("correspondence.npz"), prepared, chosen.sources, chosen.targets)
        timings["deform_and_write_s"] = time.perf_counter() - t
        # frames computed and written per second; None when nothing per frame was asked for
        timings["frames_per_second"] = T / max(timings["deform_and_write_s"], 1e-9) if writer.needs_frames else None
        timings["total_s"] = time.perf_counter() - t0

        if head_pose is not None:
            np.save(writer.path("head_motion.npy"), _pose_to_unit(head_pose, scan))
        report = {
            "timings": timings,
            "n_frames": T,
            "n_vertices": n,
            "n_markers": len(prepared.labels),
            "mesh_check": mesh_check.summary(),
            "pieces": solver.pieces.to_dict(),
            "warp_leave_one_out_mm": dict(zip(prepared.labels, np.round(loo, 4).tolist())),
            "warp_outliers": _outliers(prepared.labels, loo),
            "marker_residual_mm": {
                "per_frame_max": marker_residual.max(axis=1).tolist(),
                "max": float(marker_residual.max()),
            },
            "marker_offset_correction_mm": {
                "per_frame_max": offset_correction.max(axis=1).tolist(),
                "mean": float(offset_correction.mean()),
                "max": float(offset_correction.max()),
            },
            "conditioning_mm": {
                "per_frame_rms_change": _rms_change(prepared.raw_positions, prepared.positions, prepared).tolist(),
            },
            "temporal_sigma": _sigma_report(prepared),
            "filled_samples": int(prepared.filled.sum()),
            "stabilization_residual_mm": None
            if prepared.stabilization_residual is None
            else prepared.stabilization_residual.tolist(),
            "head_motion": head_motion,
            "rest_pose": chosen.to_dict(prepared.labels),
            "notes": prepared.notes,
            "warnings": caught,
        }
        writer.path("report.json").write_text(json.dumps(report, indent=1))
        metadata["timings"] = timings
        if usd_principal is not None:  # the export waits for it; the metadata and the page's plots do not
            writer.export_options["usd_principal"] = usd_principal
        final = finish_result(writer, metadata)
    return AnimationResult(out_dir=final, report=report)


def _sigma_report(prepared: PreparedMarkers) -> dict[str, Any] | None:
    """The filter's temporal sigma for ``report.json``: the value, and how it was chosen where it was."""
    if prepared.temporal_sigma_s is None:
        return None
    choice = prepared.temporal_sigma_choice
    if choice is None:
        return {"sigma_s": prepared.temporal_sigma_s, "chosen_by": "given"}
    return {"sigma_s": choice.sigma_s, "chosen_by": "leave-self-out cross-validation",
            "candidates_s": list(choice.candidates_s), "scores_mm2": [round(x, 6) for x in choice.scores_mm2],
            "scored_frames": choice.scored_frames}


class _MarkersSide(NamedTuple):
    prepared: PreparedMarkers
    ring: MarkerRing
    centres: np.ndarray
    face_markers: np.ndarray
    chosen: RestPose
    head_motion: dict[str, Any]
    leave_one_out: np.ndarray  # the warp's, per marker (mm)


def _markers_side(scan: Mesh, markers: MarkerSequence, correspondence: Correspondence, *, rest_frame: int,
                  stabilize: Any, smooth: bool, temporal_sigma_s: float | str, rest_average_s: float,
                  neutral: Any, marker_offset_mm: float, rest_pose: str) -> _MarkersSide:
    """Everything of :func:`animate_scan` that needs the markers and not the shell, run beside its set-up.

    The take conditioned (:func:`prepare_markers`), its rest markers (averaged, or a neutral reference),
    the head motion's report (and a warning per marker of the rigid set that may move with the face), and
    the markers' side of the scan with the rest pose chosen (:func:`_marker_side`).
    """
    prepared = prepare_markers(markers, scan, correspondence, rest_frame=rest_frame, stabilize=stabilize,
                               smooth=smooth, temporal_sigma_s=temporal_sigma_s)
    noise_mm = estimate_marker_noise(prepared.raw_positions)
    noise_mm = float(noise_mm) if np.isfinite(noise_mm) else 0.0
    rest_markers = check_warp_sources(rest_average(prepared.positions, rest_frame, rest_average_s * markers.rate,
                                                   noise_mm=noise_mm))
    neutral_markers = None
    if isinstance(neutral, MarkerSequence):
        neutral_markers, neutral_notes = neutral_from_take(neutral, prepared.labels, rest_markers)
        prepared.notes.extend(neutral_notes)
    elif neutral is not None:
        neutral_markers = neutral_from_frames(prepared.positions, *neutral)
    head_motion = _head_motion_report(prepared, stabilize, markers.labels, rest_frame)
    for label, why in head_motion["moving_stable_markers"].items():
        warnings.warn(f"the head pose rests on {label}, which may move with the face ({why}); name skull or "
                      "head-band markers with --stabilize LABELS if the face looks like it nods", FacecapWarning,
                      stacklevel=2)
    samples = _effective_samples(rest_average_s * markers.rate, rest_frame, markers.n_frames)
    ring, centres, warp, face_markers, chosen = _marker_side(scan, prepared, rest_markers, marker_offset_mm,
                                                              rest_pose, neutral_markers, noise_mm, samples)
    return _MarkersSide(prepared, ring, centres, face_markers, chosen, head_motion,
                        warp.leave_one_out_residuals())


def _marker_side(scan: Mesh, prepared: PreparedMarkers, rest_markers: np.ndarray, marker_offset_mm: float,
                 rest_pose: str, neutral_markers: np.ndarray | None, noise_mm: float,
                 rest_samples: float) -> tuple[MarkerRing, np.ndarray, TriharmonicWarp, np.ndarray, RestPose]:
    """What the markers need of the scan, no shell: ``(ring, centres, warp, face_markers, rest_pose)``.

    The triangles round the marker vertices with the scan's normals there,
    the markers at rest in face space (the scan points lifted by the offset),
    where the warp puts the rest markers (:func:`~facecap.deform.rest_pose.choose_rest_pose`),
    the warp and every frame's markers through it (T, K, 3).
    """
    ring = marker_ring(scan.vertices, scan.faces, prepared.constrained_vertices)
    centres = prepared.scan_points + marker_offset_mm * ring.rest_normals
    chosen = choose_rest_pose(rest_markers, centres, noise_mm=noise_mm, rest_samples=rest_samples,
                              normals=ring.rest_normals, motion=prepared.positions, rest_pose=rest_pose,
                              neutral_markers=neutral_markers)
    warp = TriharmonicWarp(chosen.sources, chosen.targets)
    return ring, centres, warp, warp(prepared.positions), chosen


def _effective_samples(sigma_frames: float, rest_frame: int, n_frames: int) -> float:
    """How many frames' worth of samples :func:`rest_average`'s Gaussian averages there: ``(sum w)^2 / sum w^2``.

    Its window cut at the take's ends, as :func:`rest_average` cuts it (at frame 0 about half of the full
    window's count); the closeness weights and the filter's correlation are not counted.
    """
    if sigma_frames <= 0:
        return 1.0
    reach = int(2.5 * sigma_frames + 0.5)
    frames = np.arange(max(0, rest_frame - reach), min(n_frames, rest_frame + reach + 1))
    w = np.exp(-0.5 * ((frames - rest_frame) / sigma_frames) ** 2)
    return float(w.sum() ** 2 / np.sum(w**2))


def _head_motion_report(prepared: PreparedMarkers, stabilize: Any, labels: Sequence[str],
                        rest_frame: int) -> dict[str, Any]:
    """The ``head_motion`` section of ``report.json``: how the head pose was found, how far it moved, and doubts."""
    if stabilize is False or stabilize is None:
        mode = "off"
    elif stabilize is True:
        mode = "auto"
    elif isinstance(stabilize, str):
        mode = stabilize
    else:
        mode = "labels"
    out: dict[str, Any] = {"mode": mode, "stabilized": prepared.head_rotations is not None,
                           "pose_from": prepared.head_pose_from, "stable_markers": list(prepared.stable_labels),
                           "max_rotation_deg": None, "max_translation_mm": None, "moving_stable_markers": {}}
    if prepared.head_rotations is None:
        return out
    R, t = prepared.head_rotations, prepared.head_translations
    ok = np.isfinite(R).all(axis=(1, 2)) & np.isfinite(t).all(axis=1)
    if ok.any():
        reference = R[rest_frame] if ok[rest_frame] else R[ok][0]  # the rest frame's pose, as the translation's
        relative = Rotation.from_matrix(R[ok]) * Rotation.from_matrix(reference).inv()
        out["max_rotation_deg"] = round(float(np.degrees(relative.magnitude().max())), 3)
        # how far the head's markers travelled: the stabilising motion applied to the rest markers, undone
        rest = prepared.positions[rest_frame]
        centre = np.nanmean(rest, axis=0)
        moved = np.einsum("tji,tj->ti", R[ok], centre[None] - t[ok])  # R^T (c - t): where c came from
        out["max_translation_mm"] = round(float(np.linalg.norm(moved - centre, axis=1).max()), 3)
    out["moving_stable_markers"] = moving_stable_markers(prepared.labels, [s for s in prepared.stable_labels
                                                                          if s in prepared.labels],
                                                         prepared.positions, rest_frame=rest_frame)
    return out


def _timed(function: Any, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """``(function(*args, **kwargs), seconds it took)``, for work run on another thread."""
    start = time.perf_counter()
    return function(*args, **kwargs), time.perf_counter() - start


def _save_correspondence(path: Any, prepared: PreparedMarkers, rest_markers: np.ndarray, centres: np.ndarray) -> None:
    """The correspondence map and the head motion in the mocap frame (:mod:`facecap.io.mocap_correspondence`).

    ``mocap_points`` are the rest markers in the (stabilised) mocap frame, ``face_points`` where the warp puts
    them on the face (the map ``c`` of Bickel et al. 4.1 is the triharmonic warp from the first to the second,
    its inverse the warp back) and, for a stabilised take, ``mocap_from_stabilized`` the rigid motion carrying
    frame t's stabilised markers back to where the capture saw them.
    """
    from ..io.mocap_correspondence import write_mocap_correspondence

    motion = None
    if prepared.head_rotations is not None:
        stabilize = np.tile(np.eye(4), (prepared.head_rotations.shape[0], 1, 1))
        stabilize[:, :3, :3], stabilize[:, :3, 3] = prepared.head_rotations, prepared.head_translations
        motion = np.linalg.inv(stabilize)
    write_mocap_correspondence(path, rest_markers, centres, prepared.labels, mocap_from_stabilized=motion)


def _pose_to_unit(pose: np.ndarray, scan: Mesh) -> np.ndarray:
    out = pose.copy()
    out[:, :3, 3] = scan.to_source_unit(out[:, :3, 3])
    return out


def _outliers(labels: Sequence[str], loo: np.ndarray) -> list[str]:
    """Markers whose leave-one-out warp residual stands out (likely mis-picked vertices)."""
    finite = np.isfinite(loo)
    if finite.sum() < 5:
        return []
    med = float(np.median(loo[finite]))
    mad = float(np.median(np.abs(loo[finite] - med))) + 1e-9
    return [labels[i] for i in np.flatnonzero(finite & (loo > med + 6 * 1.4826 * mad) & (loo > 2.0))]


def _rms_change(raw: np.ndarray, conditioned: np.ndarray, prepared: PreparedMarkers) -> np.ndarray:
    """Per-frame RMS distance between raw and conditioned markers where both exist (mm).

    With stabilisation the raw markers are first moved by the same rigid
    transform, so only the filtering change is measured.
    """
    R = raw
    if prepared.head_rotations is not None:
        R = np.einsum("tij,tkj->tki", prepared.head_rotations, raw) + prepared.head_translations[:, None]
    d2 = np.sum((R - conditioned) ** 2, axis=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.sqrt(np.nanmean(d2, axis=1))
