"""``facecap blend``'s job: every frame of a take rebuilt from the bases (Huang et al. 2011, eq. 12), written like ``animate``.

The bases folder and the take read, the take conditioned as the plan did
(:func:`~facecap.pipelines.replay_conditioning`), each frame's weights and head pose solved together
(:func:`~facecap.blendshapes.blend_weights_with_head_pose`), and the result folder written
(:func:`~facecap.pipelines.write_blended_performance`) with the weights, the head motion and the map
back into the capture's frame.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..blendshapes.reconstruct_performance import BlendWithPose, blend_weights_with_head_pose
from ..errors import FacecapWarning, InputError
from ..io.atomic_write import recorded_path, resolve_recorded_path
from ..io.read_markers import read_markers
from ..io.registered_scans import CONDITIONED_TAKE_FILE, read_registered_scans
from ..io.write_performance import check_result_destination
from ..structures import ConditionedTake
from .replay_conditioning import replay_conditioning
from .write_blended_performance import write_blended_performance

__all__ = ["blend_take"]


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
    conditioned = replay_conditioning(take, conditioning, markers_path=markers_path,
                                      saved=Path(bases_dir) / CONDITIONED_TAKE_FILE)
    t = time.perf_counter()
    blend = blend_weights_with_head_pose(folder["basis_markers"], conditioned.positions)
    weights = blend.weights
    rest_frame = int(conditioning.get("rest_frame", 0))
    capture_motion = _capture_from_stabilized(conditioned, blend.rotations, blend.translations)
    head_motion = _head_motion(capture_motion, folder["output_from_mocap"], rest_frame)
    frames = folder["plan"]["frames"]
    weights_csv = _weights_csv(weights, frames, take.rate)
    report = {**_blend_report(blend, int(take.n_frames), time.perf_counter() - t),
              "scan_bases": _bases_quality(folder["report"], frames, bases_dir, out_dir)}
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
        extra_files={"weights.npy": weights, "weights.csv": weights_csv,
                     "bases.npy": folder["bases"], "blend_report.json": json.dumps(report, indent=1),
                     "markers.npy": markers_out},
    )
    return report


def _weights_csv(weights: np.ndarray, frames: Sequence[int], rate: float) -> str:
    """``weights.csv``: a row per frame (frame, time in s, each basis's weight), a column per planned frame."""
    header = "frame,time_s," + ",".join(f"basis_{i}_frame_{f}" for i, f in enumerate(frames))
    rows = [f"{t_},{t_ / rate:.6f}," + ",".join(f"{w:.6g}" for w in weights[t_]) for t_ in range(len(weights))]
    return header + "\n" + "\n".join(rows) + "\n"


def _bases_quality(registration: dict[str, Any], frames: Sequence[int], bases_dir: str | Path,
                   out_dir: str | Path) -> list[dict[str, Any]]:
    """Each basis's figures from its registration (``bases.json``) that need no truth, for the result's report:
    its scan (recorded for ``out_dir``), its frame, the distance to its scan, the markers' disagreement before
    section 7, how far the template slid along and across itself, and the colour alignment's texture mismatch
    and slide."""
    out = []
    for i, (entry, frame) in enumerate(zip(registration.get("scans", []), frames)):
        quality = entry.get("quality", {})
        scan = entry.get("scan")
        out.append({
            "basis": i, "frame": int(frame),
            "scan": None if scan is None else recorded_path(resolve_recorded_path(scan, folder=bases_dir),
                                                            folder=out_dir),
            "registration_mm": entry.get("large_scale_mm"),
            "marker_residual_mm": quality.get("marker_residual_mm"),
            "tangential_motion_mm": quality.get("tangential_motion_mm"),
            "normal_motion_mm": quality.get("normal_motion_mm"),
            "colour_mismatch_by_round": entry.get("colour_mismatch_by_round"),
            "colour_alignment_moved_mm": entry.get("colour_alignment_moved_mm"),
        })
    return out


def _blend_report(blend: BlendWithPose, n_frames: int, weights_s: float) -> dict[str, Any]:
    """``blend_report.json``: the marker residuals per frame and the head-pose corrections the blend made."""
    residual = blend.residual_mm
    correction_deg = np.degrees(np.arccos(np.clip((np.trace(blend.rotations, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    return {
        "n_frames": n_frames,
        "n_bases": int(blend.weights.shape[1]),
        "marker_residual_mm": {"per_frame": residual.tolist(), "mean": float(residual.mean()),
                               "max": float(residual.max())},
        "head_pose_correction": {
            "about": "rigid correction of each frame's stabilisation found jointly with the weights",
            "rotation_deg": {"median": float(np.median(correction_deg)), "max": float(correction_deg.max())},
            "translation_mm": {"median": float(np.median(np.linalg.norm(blend.translations, axis=1))),
                               "max": float(np.linalg.norm(blend.translations, axis=1).max())},
        },
        "weights_s": weights_s,
    }


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
