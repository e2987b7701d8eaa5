"""The scan-based capture workflow of Huang et al. 2011, file to file, as the CLI runs it.

``plan_scans`` (which frames to scan) -> the actor is scanned ->
``register_planned_scans`` (every scan in one topology, fitted to its frame)
-> ``blend_take`` (every frame of the take rebuilt from the bases).
The conditioning of the take (rest frame, stable markers, filtering) is
recorded in ``plan.json`` and repeated identically by the later steps, so
all three see the same markers.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..errors import FacecapWarning, InputError
from ..io.atomic_write import check_file_destination, check_folder_destination, recorded_path
from ..io.conditioned_take import file_sha256, read_conditioned_take, write_conditioned_take
from ..io.read_markers import read_markers
from ..io.read_mesh import read_mesh
from ..io.registered_scans import (BASES_MARKER_FILE, CONDITIONED_TAKE_FILE, read_registered_scans,
                                   write_registered_scans)
from ..io.scan_plan import read_scan_plan, write_scan_plan
from ..markers.condition_take import DEFAULT_HEAD_MOTION_SIGMA_S, ConditionedTake, condition_take
from ..structures import MarkerSequence, Mesh
from ..units import check_scan_units
from ..io.write_performance import check_result_destination
from .reconstruct_performance import blend_weights_with_head_pose, write_blended_performance
from .select_scan_frames import ScanPlan, select_scan_frames

__all__ = ["plan_scans", "register_planned_scans", "blend_take", "conditioned_take_path"]

SCAN_SKIN_HEAD_POSE = "consensus"
"""How ``plan-scans`` poses a head without a head band it can recognise (it has no map to tell one): the consensus
of the markers, as ``animate`` does without a band (:func:`facecap.markers.auto_stabilize`); recorded in
``plan.json``. Plans written before 2026-12-04 have no record and replay the most rigid set they used."""


def conditioned_take_path(plan_path: str | Path) -> Path:
    """Where ``plan-scans`` keeps the conditioned take of ``plan_path``: ``plan.json`` -> ``plan.conditioned.npz``."""
    p = Path(plan_path)
    return p.with_name(f"{p.stem}.conditioned.npz")


def _condition(take: MarkerSequence, conditioning: dict[str, Any]) -> ConditionedTake:
    """Condition ``take`` as ``conditioning`` (a plan's record) says."""
    stabilize = conditioning.get("stabilize")
    if stabilize is None:  # plans written before the consensus stabiliser: replay the fixed set
        stabilize = conditioning.get("stable_markers") or False
    elif stabilize == "auto":
        stabilize = True
    elif stabilize == "off":
        stabilize = False
    return condition_take(
        take, rest_frame=int(conditioning.get("rest_frame", 0)), stabilize=stabilize,
        smooth=bool(conditioning.get("smooth", True)),
        head_motion_sigma_s=float(conditioning.get("head_motion_sigma_s", DEFAULT_HEAD_MOTION_SIGMA_S)),
        # plans from before the cross-validated sigma were filtered at 0.02 s
        temporal_sigma_s=conditioning.get("temporal_sigma_s", 0.02),
        skin_head_pose=conditioning.get("skin_head_pose", "rigid_set"),  # unrecorded: a plan from before the consensus
    )


def _conditioned_take(take: MarkerSequence, markers_path: str | Path, conditioning: dict[str, Any],
                      saved: Path) -> ConditionedTake:
    """The take as the plan conditioned it: read from ``saved`` when it is the same take, else redone.

    Conditioning once keeps every step on the same markers and head motion. A
    different take (another take of the actor, or an edited file) is
    conditioned afresh with the plan's recorded settings.
    """
    if saved.is_file() and conditioning.get("source_sha256") == file_sha256(markers_path):
        conditioned, meta = read_conditioned_take(saved)
        if meta["labels"] == tuple(take.labels) and conditioned.positions.shape[0] == take.n_frames:
            return conditioned
    return _condition(take, conditioning)


def plan_scans(
    markers_path: str | Path,
    plan_path: str | Path,
    *,
    tolerance: float = 0.003,
    max_frames: int | None = None,
    rest_frame: int = 0,
    stabilize: bool | str | Sequence[str] = True,
    smooth: bool = True,
    plot_path: str | Path | None = None,
    marker_unit: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> ScanPlan:
    """Choose the fewest frames to scan (Algorithm 1) and write ``plan.json`` (+ the Fig. 8 plot).

    Parameters
    ----------
    markers_path : str or Path
        The take.
    plan_path : str or Path
        Where to write ``plan.json``.
    tolerance : float, default 0.003
        Reconstruction tolerance as a fraction of the marker bounding-box diagonal.
    max_frames : int, optional
        Stop after this many frames even if the tolerance is not met.
    rest_frame : int, default 0
    stabilize : bool or sequence of str, default True
        Head motion must be removed before choosing expressions (otherwise
        head poses get chosen); ``True`` finds the stable markers.
    smooth : bool, default True
    plot_path : str or Path, optional
        PNG of the error against the number of scans (Huang 2011, Fig. 8) and of the chosen
        frames over the take (:func:`~facecap.report.plot_scan_selection`).
    marker_unit : str, optional
        Override the unit the take declares.
    progress : bool, default True
    overwrite : bool, default False
        Replace an existing ``plan.json`` (and its ``.conditioned.npz`` and
        plot); without it they are refused before any work: the scans of a
        session were shot from a plan, so it is never replaced unasked.

    Returns
    -------
    ScanPlan
    """
    for path in (plan_path, conditioned_take_path(plan_path), *(() if plot_path is None else (plot_path,))):
        check_file_destination(path, overwrite=overwrite)
    take = read_markers(markers_path, unit=marker_unit)
    if stabilize is True:
        stabilize_setting: str | list[str] = "auto"
    elif stabilize is False:
        stabilize_setting = "off"
    elif isinstance(stabilize, str):
        stabilize_setting = stabilize
    else:
        stabilize_setting = list(stabilize)
    conditioning: dict[str, Any] = {
        "rest_frame": rest_frame, "stabilize": stabilize_setting, "smooth": smooth,
        "head_motion_sigma_s": DEFAULT_HEAD_MOTION_SIGMA_S, "temporal_sigma_s": "auto",
        "skin_head_pose": SCAN_SKIN_HEAD_POSE,
    }
    conditioned = _condition(take, conditioning)
    conditioning["temporal_sigma_chosen_s"] = conditioned.temporal_sigma_s
    plan = select_scan_frames(
        conditioned.positions, tolerance=tolerance, max_frames=max_frames, rate=take.rate,
        first_frame=take.first_frame, progress=progress,
    )
    saved = conditioned_take_path(plan_path)
    conditioning.update(stable_markers=list(conditioned.stable_labels), conditioned_take=saved.name,
                        source_sha256=file_sha256(markers_path))
    write_conditioned_take(saved, conditioned, labels=take.labels, rate=take.rate, settings=conditioning,
                           source_sha256=conditioning["source_sha256"])
    write_scan_plan(plan_path, plan.to_dict(), conditioning=conditioning, source=str(markers_path))
    if plot_path is not None:
        from ..report.plot_scan_selection import plot_scan_selection

        plot_scan_selection(plan, plot_path)
    return plan


def register_planned_scans(
    plan_path: str | Path,
    markers_path: str | Path,
    scan_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    template_path: str | Path | None = None,
    scan_unit: str = "mm",
    template_unit: str = "mm",
    marker_offset_mm: float = 1.5,
    refine: bool = False,
    template_texture_path: str | Path | None = None,
    align_colors: bool = False,
    marker_unit: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Register one scan per planned frame and write the bases folder.

    With ``align_colors`` the registrations are slid along the scans until
    the skin's colours match the template's (the scans and the template, or
    ``template_texture_path``, a coloured scan of the template's expression
    in the template's unit, need vertex colours), see
    :func:`facecap.registration.register_scans`.

    ``scan_unit`` and ``template_unit`` are length units, or ``'auto'``: each
    file's size is compared with its frame's markers
    (:func:`facecap.units.check_scan_units`); a given unit they contradict
    stops with an error naming the likely one, ``'auto'`` converts to it.

    An earlier bases folder in ``out_dir`` is replaced only with
    ``overwrite`` (checked before the registration and again at the end).
    Returns the registration report (also in ``bases.json``, with every
    scan's path as recorded there: final and absolute, or relative to the folder).
    """
    from ..registration.register_scans import register_scans

    check_folder_destination(out_dir, marker_file=BASES_MARKER_FILE, overwrite=overwrite)
    take = read_markers(markers_path, unit=marker_unit)
    plan = read_scan_plan(plan_path, n_frames=take.n_frames)
    frames = plan["frames"]
    if len(scan_paths) != len(frames):
        raise InputError(f"--scans: the plan lists {len(frames)} frames, {len(scan_paths)} scans were given "
                         "(one scan per planned frame, in the plan's order)")
    conditioning = plan["conditioning"]
    conditioned = _conditioned_take(take, markers_path, conditioning, conditioned_take_path(plan_path))
    auto, auto_template = scan_unit == "auto", template_unit == "auto"  # else a contradicted unit stops
    scans = [check_scan_units(read_mesh(p, unit=None if auto else scan_unit), conditioned.positions[f], convert=auto)
             for p, f in zip(scan_paths, frames)]
    template: Mesh | None = check_scan_units(
        read_mesh(template_path, unit=None if auto_template else template_unit),
        conditioned.positions[int(conditioning.get("rest_frame", 0))], convert=auto_template, option="--template-units",
    ) if template_path else None
    texture = None
    if template_texture_path is not None:
        if template is None:
            raise InputError("--template-texture needs --template (without one the first scan is the template)")
        texture = read_mesh(template_texture_path, unit=template.source_unit)
    t = time.perf_counter()
    registered = register_scans(
        scans, conditioned.positions[frames], template=template,
        template_markers=conditioned.positions[int(conditioning.get("rest_frame", 0))] if template else None,
        marker_offset_mm=marker_offset_mm, refine=refine, template_texture=texture, align_colors=align_colors,
        progress=progress,
    )
    report = {**registered.report, "total_s": time.perf_counter() - t,
              "registration_mm": registered.registration_mm.tolist()}
    for entry, path in zip(report.get("scans", []), scan_paths):
        entry["scan"] = recorded_path(path, folder=out_dir)
    # the plan as the bases saw it; its conditioned take is the one kept in the bases folder
    plan = {**plan, "markers": recorded_path(markers_path, folder=out_dir),
            "conditioning": {**conditioning, "conditioned_take": CONDITIONED_TAKE_FILE}}
    write_registered_scans(
        out_dir, template=registered.template, bases=registered.bases, basis_markers=registered.basis_markers,
        marker_labels=list(take.labels), output_from_mocap=registered.output_from_mocap,
        plan=plan, report=report, conditioned=conditioned, rate=take.rate, overwrite=overwrite,
    )
    return report


def blend_take(
    bases_dir: str | Path,
    markers_path: str | Path,
    out_dir: str | Path,
    *,
    exports: Sequence[str] = (),
    marker_unit: str | None = None,
    write_vertices: bool = True,
    rig_precision: str = "float32",
    export_options: dict[str, Any] | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Rebuild every frame of a take from the bases (eq. 12) and write it like ``facecap animate``.

    Besides the usual output folder (with the rig, and ``vertices.npy`` unless
    ``write_vertices`` is off), writes ``weights.npy`` (T, K), ``weights.csv``,
    ``bases.npy``, ``markers.npy`` (the conditioned markers in the output frame),
    ``blend_report.json`` (per-frame marker residuals), ``head_motion.npy`` and
    ``correspondence.npz`` (:mod:`facecap.io.mocap_correspondence`: the face back
    into the capture's frame, for the wrinkle layer's cameras). An earlier result in
    ``out_dir`` is replaced only with ``overwrite`` (checked first).
    """
    check_result_destination(out_dir, overwrite=overwrite)
    folder = read_registered_scans(bases_dir)
    take = read_markers(markers_path, unit=marker_unit)
    labels = folder["marker_labels"]
    missing = [s for s in labels if s not in take.label_index()]
    if missing:
        raise InputError(f"the take lacks markers the bases were made with: {missing}", path=str(markers_path))
    take = take.select(labels)
    conditioning = folder["plan"]["conditioning"]
    conditioned = _conditioned_take(take, markers_path, conditioning, Path(bases_dir) / CONDITIONED_TAKE_FILE)
    t = time.perf_counter()
    blend = blend_weights_with_head_pose(folder["basis_markers"], conditioned.positions)
    weights, residual = blend.weights, blend.residual_mm
    rest_frame = int(conditioning.get("rest_frame", 0))
    capture_motion = _capture_from_stabilized(conditioned, blend.rotations, blend.translations)
    head_motion = _head_motion(capture_motion, folder["output_from_mocap"], rest_frame)
    frames = folder["plan"]["frames"]
    header = "frame,time_s," + ",".join(f"basis_{i}_frame_{f}" for i, f in enumerate(frames))
    rows = [f"{t_},{t_ / take.rate:.6f}," + ",".join(f"{w:.6g}" for w in weights[t_]) for t_ in range(len(weights))]
    correction_deg = np.degrees(np.arccos(np.clip((np.trace(blend.rotations, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    report = {
        "n_frames": int(take.n_frames),
        "n_bases": int(weights.shape[1]),
        "marker_residual_mm": {"per_frame": residual.tolist(), "mean": float(residual.mean()),
                               "max": float(residual.max())},
        "head_pose_correction": {
            "about": "rigid correction of each frame's stabilisation found jointly with the weights",
            "rotation_deg": {"median": float(np.median(correction_deg)), "max": float(correction_deg.max())},
            "translation_mm": {"median": float(np.median(np.linalg.norm(blend.translations, axis=1))),
                               "max": float(np.linalg.norm(blend.translations, axis=1).max())},
        },
        "weights_s": time.perf_counter() - t,
    }
    A = np.asarray(folder["output_from_mocap"], dtype=np.float64)
    markers_out = folder["template"].to_source_unit(conditioned.positions @ A[:3, :3].T + A[:3, 3]).astype(np.float32)
    # the face back into the capture's frame (where cameras are calibrated), as animate writes it: the bases
    # live in the stabilised mocap frame, so the map is the rigid A^-1 (the warp of correspondence.npz
    # reproduces it exactly from the rest markers and their images), then the frame's capture motion
    rest = conditioned.positions[rest_frame]
    seen = np.isfinite(rest).all(axis=1)
    correspondence = None
    if seen.sum() >= 4 and np.isfinite(capture_motion).all():
        correspondence = {"mocap_points": rest[seen], "face_points": rest[seen] @ A[:3, :3].T + A[:3, 3],
                          "labels": [label for label, s in zip(labels, seen) if s],
                          "mocap_from_stabilized": capture_motion}
    else:
        warnings.warn(f"blend: no correspondence.npz ({int(seen.sum())} markers seen at the rest frame, or a "
                      "frame's pose not finite): facecap wrinkles cannot use this result", FacecapWarning, stacklevel=2)
    write_blended_performance(
        out_dir, folder["template"], folder["bases"], weights, rate=take.rate,
        output_from_bases=folder["output_from_mocap"], head_motion=head_motion, correspondence=correspondence,
        exports=exports, progress=progress,
        write_vertices=write_vertices, rig_precision=rig_precision, export_options=export_options, overwrite=overwrite,
        metadata={"source_files": {"bases": str(bases_dir), "markers": str(markers_path)},
                  "rest_frame": rest_frame, "planned_frames": frames,
                  "markers": list(labels)},
        extra_files={"weights.npy": weights, "weights.csv": header + "\n" + "\n".join(rows) + "\n",
                     "bases.npy": folder["bases"], "blend_report.json": json.dumps(report, indent=1),
                     "markers.npy": markers_out},
    )
    return report


def _capture_from_stabilized(conditioned: ConditionedTake, rotations: np.ndarray, translations: np.ndarray
                             ) -> np.ndarray:
    """Per frame, the rigid motion carrying the blend's stabilised face back to where the capture saw it, mm.

    ``(J_t S_t)^-1``: ``S_t`` is the take's stabilisation (mocap -> its rest pose, the identity when the take
    was not stabilised), ``J_t`` the blend's rigid correction of it, both in the mocap frame.
    """
    T = rotations.shape[0]
    S = np.tile(np.eye(4), (T, 1, 1))
    if conditioned.head_rotations is not None:
        S[:, :3, :3], S[:, :3, 3] = conditioned.head_rotations, conditioned.head_translations
    J = np.tile(np.eye(4), (T, 1, 1))
    J[:, :3, :3], J[:, :3, 3] = rotations, translations
    return np.linalg.inv(J @ S)


def _head_motion(capture_from_stabilized: np.ndarray, output_from_mocap: np.ndarray, rest_frame: int
                 ) -> np.ndarray | None:
    """Head motion per frame in the output (template) frame, mm: ``A (J_t S_t)^-1 A^-1``, anchored at the rest frame.

    ``(J_t S_t)^-1`` is :func:`_capture_from_stabilized` and ``A`` the mocap -> template transform.
    """
    A = np.asarray(output_from_mocap, dtype=np.float64)
    pose = A[None] @ capture_from_stabilized @ np.linalg.inv(A)[None]
    # Anchored at the rest frame, whose blend is the template's own expression in its own pose (the
    # template was registered to that frame's markers): the pose solve's correction there is the
    # bases' disagreement, not head motion. Measured against leaving it in (the capture's own
    # pose at rest, as animate writes it): world error 0.149 vs 0.165 and 0.252 vs 0.289 mm on two
    # generated head-band takes.
    pose = np.linalg.inv(pose[rest_frame])[None] @ pose
    return pose if np.all(np.isfinite(pose)) else None
