"""``facecap solve-muscles``'s job: a take solved for muscle activations on the frame runner, written as a result folder.

The one call the command makes (issue 11, items 5 and 6):

1. the anatomy model folder (``facecap build-anatomy``) is opened and its scan is the output mesh;
2. the take is read and conditioned as ``facecap animate`` conditions it
   (:func:`~facecap.markers.prepare_markers`: matched to the map, gap-filled, filtered);
3. the rest frame's markers are moved rigidly onto the scan (the solver's rest markers; the
   cranium then carries the take's own coordinates), and every frame is solved on the frame
   runner (:class:`~facecap.muscles.MuscleFrameStage`: Dask, resumable chunks, each chunk's
   first frame cold);
4. the result is written by :func:`~facecap.pipelines.write_muscle_result` like ``animate``'s
   (``vertices.npy``, ``performance.json``, ``report.json``, exports) plus ``activations.csv``,
   ``bone_transforms.npz``, ``markers.npy`` and ``activations.png``, all in one atomic folder.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Iterable, Mapping, NamedTuple

import numpy as np

from ..anatomy.face_anatomy import FaceAnatomy, load_anatomy
from ..deform.marker_offsets import marker_ring
from ..deform.triharmonic_warp import TriharmonicWarp, check_warp_sources
from ..errors import CorrespondenceError, FacecapWarning, InputError
from ..io.atomic_write import final_path
from ..io.read_correspondence import read_correspondence
from ..io.read_markers import read_markers
from ..io.result_layout import parse_export_formats
from ..io.write_performance import check_result_destination
from ..markers.consensus_stabilize import estimate_marker_noise
from ..markers.prepare_take import (DEFAULT_REST_AVERAGE_S, PreparedMarkers, head_pose_in_scan, prepare_markers,
                                    rest_average)
from ..markers.rigid_fit import rigid_fit
from ..muscles.marker_embedding import marker_embedding
from ..muscles.muscle_frame_stage import MuscleFrameStage, flag_names, model_folder_sha256
from ..runner.run_frames import FrameRun, run_frames
from ..structures import Correspondence, MarkerSequence
from ..validate import as_positive
from .finish_result import import_writers
from .write_muscle_result import write_muscle_result

__all__ = ["solve_muscle_take", "MuscleTakeResult", "RIGID_FIT_LIMIT_MM"]

DEFAULT_CHUNK_FRAMES = 32
RIGID_FIT_LIMIT_MM = 5.0
"""``retarget='auto'`` warps the take onto the scan when a rigid fit of its rest frame leaves a marker
farther than this from its lifted map point (markers normally sit 1-3 mm above the skin)."""
_MIN_MARKERS = 6  # MuscleSolver's min_markers: fewer cannot hold head, jaw and muscles


class MuscleTakeResult(NamedTuple):
    """What :func:`solve_muscle_take` wrote.

    Attributes
    ----------
    out_dir : Path
        The finished result folder.
    n_frames : int
        Frames solved (and written).
    report : dict
        The content of ``report.json``.
    computed, reused : tuple of int
        Runner chunks computed by this call, and found finished in the work folder.
    """

    out_dir: Path
    n_frames: int
    report: dict[str, Any]
    computed: tuple[int, ...]
    reused: tuple[int, ...]


def _frame_range(frames: str | tuple[int, int] | None, n_frames: int, source: str | None) -> tuple[int, int]:
    if frames is None:
        return 0, n_frames
    if isinstance(frames, str):
        try:
            a, b = frames.split(":")
            first = int(a) if a.strip() else 0
            stop = int(b) if b.strip() else n_frames
        except ValueError:
            raise InputError(f"frames: expected A:B (a frame range), got {frames!r}") from None
    else:
        first, stop = (int(v) for v in frames)
    if not (0 <= first < stop <= n_frames):
        raise InputError(f"frames {first}:{stop} are outside the take (0:{n_frames})", path=source)
    return first, stop


def solve_muscle_take(
    model_dir: str | os.PathLike[str],
    markers: str | os.PathLike[str] | MarkerSequence,
    correspondence: str | os.PathLike[str] | Correspondence,
    out_dir: str | os.PathLike[str],
    *,
    rest_frame: int = 0,
    marker_offset_mm: float = 1.5,
    retarget: str = "auto",
    rest_average_s: float | None = None,
    stabilize: bool | str | Iterable[str] | None = None,
    smooth: bool = True,
    temporal_sigma_s: float | str = "auto",
    frames: str | tuple[int, int] | None = None,
    scheduler: str | None = None,
    n_workers: int = 2,
    work_dir: str | os.PathLike[str] | None = None,
    chunk_frames: int = DEFAULT_CHUNK_FRAMES,
    exports: Iterable[str] = (),
    solver_options: Mapping[str, Any] | None = None,
    progress: bool = False,
    extra_metadata: Mapping[str, Any] | None = None,
    export_options: Mapping[str, Any] | None = None,
    overwrite: bool = False,
) -> MuscleTakeResult:
    """Solve a take for muscle activations, cranium and jaw, and write the result folder.

    Parameters
    ----------
    model_dir : str or path-like
        An anatomy model folder (``facecap build-anatomy``).
    markers : str, path-like or MarkerSequence
        The take (``.c3d``, ``.trc``, ``.csv``), or one already read.
    correspondence : str, path-like or Correspondence
        The marker map (JSON: label -> scan vertex or point) on the model's scan. A point is
        carried by the vertex of its largest barycentric weight (the solver embeds vertices).
    out_dir : str or path-like
        The result folder (:class:`~facecap.io.PerformanceWriter`: written atomically).
    rest_frame : int, default 0
        The take's frame whose expression is the scan's (the rest markers).
    marker_offset_mm : float, default 1.5
        Height of the marker centres above the skin, mm, as for ``animate``: the rest frame is
        moved rigidly onto the map's points lifted by it along the scan's normals (a take in any
        coordinates). Each marker's own offset is then measured from the model (the solver's rest
        offsets); this height only places the take on the scan.
    retarget : {'auto', 'rigid', 'warp'}, default 'auto'
        How the take's markers reach the scan. ``'rigid'``: the rest frame moved rigidly onto the
        lifted map points, every frame by the same motion (the take is of the scanned actor; the
        cranium then solves the head's motion). ``'warp'``: as ``animate`` does, the triharmonic
        warp from the rest markers (averaged round the rest frame) onto the lifted points, every
        frame through it (a take of another face than the scan's, or a loose map: the bundled
        AnimFace take on the ICT face). ``'auto'``: rigid when every marker of the rigidly moved
        rest frame lies within :data:`RIGID_FIT_LIMIT_MM` of its lifted point, else the warp.
    rest_average_s : float, optional
        Half-width (Gaussian sigma, s) of the average round the rest frame that gives the rest
        markers, as for ``animate`` (its noise would otherwise enter every marker's rest offset);
        0 takes the rest frame alone. Default ``animate``'s (0.1 s).
    stabilize : bool, str, sequence of str or None, default None
        Head motion removed before the warp, as for ``animate`` (``True`` picks the stable
        markers, labels name them). Default: with the warp, stabilised (a warp is a map of the
        rest pose: a turned head through it would bend); rigid, not (the cranium solves it).
    smooth, temporal_sigma_s
        The bilateral filter, as for ``animate`` (:func:`~facecap.markers.prepare_markers`).
    frames : 'A:B' or (A, B), optional
        Solve and write only take frames ``A <= frame < B`` (conditioned over the whole take).
    scheduler : str or None, default None
        The frame runner's (:func:`~facecap.runner.run_frames`): None a local cluster of
        ``n_workers`` processes, ``'synchronous'`` this process, or a scheduler address.
    n_workers : int, default 2
    work_dir : path-like, optional
        The runner's resumable work folder (kept: a second call resumes). Default: a temporary
        folder, removed at the end.
    chunk_frames : int, default 32
        Frames per runner chunk; each chunk's first frame is solved cold (3-5 Gauss-Newton
        steps instead of 1-2).
    exports : iterable of str
        As for ``animate`` (:data:`facecap.io.EXPORT_FORMATS`).
    solver_options : mapping, optional
        :class:`~facecap.muscles.MuscleSolver` options (JSON values).
    progress : bool, default False
        A progress line per stage on standard error, and the runner's bar.
    extra_metadata : mapping, optional
        Added to ``performance.json``.
    export_options : mapping, optional
        Passed to :func:`facecap.pipelines.export_result` (e.g. ``export_frame``).
    overwrite : bool, default False
        Replace an earlier result in ``out_dir``; without it one is refused before any work
        (:func:`facecap.io.write_performance.check_result_destination`) and again at the end.

    Returns
    -------
    MuscleTakeResult

    Raises
    ------
    FileFormatError
        A model folder, take or map that cannot be read (the message names the file).
    CorrespondenceError
        A map naming markers the take lacks, or markers whose vertices land off the model.
    InputError
        A frame range outside the take, rest markers far from the skin, bad options.

    Notes
    -----
    Rigid, ``vertices.npy`` holds the skin in the **take's coordinates** (the cranium's motion
    included), like an unstabilised ``animate`` result; ``bone_transforms.npz`` holds the
    cranium (scan rest coordinates to the take's) and the mandible (relative to the cranium,
    :class:`~facecap.muscles.MuscleControls`). Warped, the skin is in the scan's coordinates (the
    cranium there carries what stabilisation left of the head's motion), and a stabilised take's
    head motion is in ``head_motion.npy``, as for a stabilised ``animate`` result.
    """
    t_all = time.perf_counter()
    timings: dict[str, float] = {}

    def stage(message: str) -> None:
        if progress:
            print(f"facecap: {message}", file=sys.stderr, flush=True)

    exports = parse_export_formats(exports)
    check_result_destination(out_dir, overwrite=overwrite)
    if retarget not in ("auto", "rigid", "warp"):
        raise InputError(f"retarget: expected 'auto', 'rigid' or 'warp', got {retarget!r}")
    rest_average_s = as_positive(DEFAULT_REST_AVERAGE_S if rest_average_s is None else rest_average_s,
                                 name="rest_average_s", allow_zero=True)
    if int(chunk_frames) < 1 or int(n_workers) < 1:
        raise InputError("chunk_frames and n_workers: expected positive integers")
    t = time.perf_counter()
    model_dir = Path(model_dir)
    stage(f"reading the model {model_dir}")
    anatomy = load_anatomy(model_dir)
    scan = anatomy.scan_mesh()  # with the scan's polygons and UVs, for the exports
    take = markers if isinstance(markers, MarkerSequence) else read_markers(markers)
    corr = correspondence if isinstance(correspondence, Correspondence) else read_correspondence(correspondence, scan)
    map_name = corr.source_path
    timings["read_s"] = time.perf_counter() - t

    t = time.perf_counter()
    caught: list[str] = []

    def condition(stabilized: bool | str | Iterable[str]) -> tuple[PreparedMarkers, list[str]]:
        with warnings.catch_warnings(record=True) as records:
            warnings.simplefilter("always", FacecapWarning)
            stage(f"conditioning {take.n_frames} frames x {take.n_markers} markers"
                  f"{', stabilised' if stabilized else ''}")
            out = prepare_markers(take, scan, corr, rest_frame=rest_frame, stabilize=stabilized, smooth=smooth,
                                  temporal_sigma_s=temporal_sigma_s)
        return out, [str(w.message) for w in records if issubclass(w.category, FacecapWarning)]

    def stabilized_for(mode: str) -> bool | str | Iterable[str]:
        return stabilize if stabilize is not None else mode == "warp"

    prepared, said = condition(stabilized_for(retarget))  # 'auto' conditions as 'rigid' first
    labels = prepared.labels
    first, stop = _frame_range(frames, take.n_frames, take.source_path)
    n = stop - first

    vertices = prepared.constrained_vertices
    keep = np.ones(len(labels), dtype=bool)
    weights = np.asarray(anatomy.skin_weights)[vertices]
    off_model = ~np.asarray(anatomy.skin_meshed)[vertices] | (np.abs(weights).max(axis=1) > 3.0)
    left_out: list[str] = []
    if off_model.any():
        # the solver's own test (marker_embedding), said with the markers' names. A real map often has
        # markers the face model cannot carry (eyelids, ears): they are left out of the solve, as animate
        # leaves out markers outside its map, and out of the rigid fit below
        left_out = [labels[i] for i in np.flatnonzero(off_model)]
        keep = ~off_model
        if keep.sum() < _MIN_MARKERS:
            raise CorrespondenceError(f"only {int(keep.sum())} markers land on the model {model_dir} (at least "
                                      f"{_MIN_MARKERS} needed); the others are outside the meshed face (ears, scalp, "
                                      "neck, eyes, inner lips)", path=map_name)
        said.append(f"markers {', '.join(left_out)} land off the model {final_path(model_dir)} (outside the meshed face: ears, "
                    "scalp, neck, eyes, inner lips): left out of the solve")
        labels = tuple(labels[i] for i in np.flatnonzero(keep))
        vertices = vertices[keep]

    # the map's points lifted along the scan's normals, as animate lifts them (its warp's targets)
    normals = marker_ring(scan.vertices, scan.faces, prepared.constrained_vertices).rest_normals
    lifted = prepared.scan_points + float(marker_offset_mm) * normals
    rigid_gap = _rigid_gap(prepared.positions[rest_frame, keep], lifted[keep])
    chosen = retarget if retarget != "auto" else ("rigid" if rigid_gap <= RIGID_FIT_LIMIT_MM else "warp")
    if retarget == "auto" and chosen == "warp":
        said.append(f"the take's rest frame does not fit the scan rigidly (a marker {rigid_gap:.1f} mm from its map "
                    f"point, more than {RIGID_FIT_LIMIT_MM:g}): mapped onto it by the triharmonic warp, as animate "
                    "does (--retarget)")
        if stabilized_for("warp") != stabilized_for("rigid"):
            prepared, again = condition(stabilized_for("warp"))
            said += [m for m in again if m not in said]
    stabilized = prepared.head_rotations is not None
    positions = prepared.positions[:, keep]
    caught += said
    for message in caught:
        warnings.warn(message, FacecapWarning, stacklevel=2)
    timings["condition_markers_s"] = time.perf_counter() - t

    # the rest markers in the scan's frame (the solver measures each marker's own offset from its skin
    # point there). Rigid: the rest frame moved onto the map's points lifted by the marker height, every
    # frame by the same motion (the cranium then carries the scan into the take's coordinates). Warped:
    # animate's correspondence warp c (Bickel et al. 4.1), built from every usable marker as animate builds
    # it, so both methods see the same markers on the face
    head_pose = None
    noise_mm = estimate_marker_noise(prepared.raw_positions)  # the rest average weighs samples by it, as animate's
    rest_markers = rest_average(prepared.positions, rest_frame, rest_average_s * take.rate,
                                noise_mm=float(noise_mm) if np.isfinite(noise_mm) else None)
    if chosen == "rigid":
        rest_take = rest_markers[keep]
        fit = rigid_fit(rest_take, lifted[keep])
        rest_scan = rest_take @ fit.rotation.T + fit.translation
        to_scan = np.hstack([fit.rotation, fit.translation[:, None]])
    else:
        sources = check_warp_sources(rest_markers)
        warp = TriharmonicWarp(sources, lifted)
        positions = warp(positions)
        rest_scan = lifted[keep]
        to_scan = None
        if stabilized:
            head_pose = head_pose_in_scan(prepared, sources, lifted, rest_frame)
    try:
        marker_embedding(anatomy, vertices, rest_scan)
    except InputError as exc:
        raise InputError(f"the rest frame {rest_frame} does not fit the model's scan ({exc}); "
                         "is the map on this model's scan?", path=take.source_path) from None

    options = dict(solver_options or {})
    stage_obj = MuscleFrameStage(model_dir, vertices, rest_scan, positions[first:stop], options=options,
                                 model_sha256=model_folder_sha256(model_dir))
    own_work = work_dir is None
    work = Path(tempfile.mkdtemp(prefix="facecap-muscles-")) if own_work else Path(work_dir)
    try:
        t = time.perf_counter()
        where = ("this process" if scheduler == "synchronous" else
                 f"a local cluster of {n_workers} processes" if scheduler is None else scheduler)
        stage(f"solving {n} frames (take frames {first}:{stop}) x {len(labels)} markers, "
              f"{anatomy.n_tets} tetrahedra, in chunks of {chunk_frames} on {where}")
        run = run_frames(stage_obj, n, work, chunk_frames=int(chunk_frames), scheduler=scheduler,
                         n_workers=int(n_workers), progress=progress)
        timings["solve_s"] = time.perf_counter() - t
        import_writers(exports)
        t = time.perf_counter()
        stage(f"writing {out_dir}")
        result = {name: run.load(name, mmap=name == "vertices") for name in run.array_specs}
        report = _report(result, labels, anatomy, first, rest_frame, run, prepared, caught)
        report["markers_left_out"] = left_out
        metadata = {
            "source_files": {"model": str(model_dir), "markers": take.source_path, "map": map_name},
            "source_units": {"scan": "mm", "markers": take.source_unit},
            "method": "sifakis2005-muscle-activations",
            "frame": ("take (the skin in the take's coordinates; the cranium in bone_transforms.npz)" if chosen == "rigid"
                      else "scan (the take warped onto the scan, as animate's; head motion in head_motion.npy)"
                      if stabilized else "scan (the take warped onto the scan, as animate's)"),
            "rest_frame": int(rest_frame),
            "retarget": chosen,
            "stabilized": stabilized,
            "take_to_scan_at_rest": None if to_scan is None else to_scan.tolist(),
            "frames": [first, stop],
            "first_frame": int(take.first_frame) + first,
            "parameters": {"marker_offset_mm": float(marker_offset_mm), "retarget": retarget,
                           "rest_average_s": rest_average_s, "smooth": bool(smooth),
                           "temporal_sigma_s": prepared.temporal_sigma_s, "chunk_frames": int(chunk_frames),
                           "solver": options,
                           "model_sha256": stage_obj.model_sha256},
            "muscles": list(anatomy.muscle_names),
            "markers": list(labels),
            **dict(extra_metadata or {}),
        }
        extra = {"markers.npy": positions[first:stop].astype(np.float32)}
        if head_pose is not None:
            extra["head_motion.npy"] = head_pose[first:stop]
        final = write_muscle_result(out_dir, scan, take.rate, np.arange(first, stop), anatomy.muscle_names, result,
                                    report=report, metadata=metadata, extra_arrays=extra, exports=exports,
                                    progress=progress, timings=timings, started=t_all, write_started=t,
                                    export_options=export_options, overwrite=overwrite)
    finally:
        if own_work:
            shutil.rmtree(work, ignore_errors=True)
    return MuscleTakeResult(Path(final), n, report, tuple(run.computed), tuple(run.reused))


def _rigid_gap(rest: np.ndarray, targets: np.ndarray) -> float:
    """The largest distance, mm, of a marker of the rest frame moved rigidly onto its target."""
    fit = rigid_fit(rest, targets)
    return float(np.linalg.norm(rest @ fit.rotation.T + fit.translation - targets, axis=1).max())


def _report(result: Mapping[str, np.ndarray], labels: tuple[str, ...], anatomy: FaceAnatomy, first: int,
            rest_frame: int, run: FrameRun, prepared: PreparedMarkers, caught: list[str]) -> dict[str, Any]:
    """``report.json``: per-frame marker residuals, flags, iterations, constraint and runner figures."""
    res = np.asarray(result["marker_residual"], dtype=np.float64)
    finite = np.where(np.isfinite(res), res, -np.inf)
    flags = [list(flag_names(b)) for b in result["flags"]]
    flagged = {str(first + j): f for j, f in enumerate(flags) if f}

    def listed(a: np.ndarray, digits: int = 5) -> list[Any]:
        return [None if not np.isfinite(v) else round(float(v), digits) for v in np.asarray(a, dtype=np.float64)]

    return {
        "n_frames": int(res.shape[0]),
        "first_frame": int(first),
        "n_vertices": int(anatomy.scan_vertices.shape[0]),
        "n_markers": len(labels),
        "n_tets": int(anatomy.n_tets),
        "n_muscles": int(anatomy.n_muscles),
        "rest_frame": int(rest_frame),
        "marker_residual_mm": {
            "labels": list(labels),
            "per_frame": [listed(row, 4) for row in res],
            "per_frame_max": listed(finite.max(axis=1)),
            "per_frame_rms": listed(result["rms_mm"]),
            "max": float(finite.max()) if np.isfinite(finite.max()) else None,
            "rms": float(np.sqrt(np.nanmean(res ** 2))) if np.isfinite(res).any() else None,
        },
        "flags": flagged,
        "frames_flagged": len(flagged),
        "steps": np.asarray(result["steps"]).tolist(),
        "quasistatic_solves": np.asarray(result["quasistatic_solves"]).tolist(),
        "newton_iterations": np.asarray(result["newton_iterations"]).tolist(),
        "cold_frames": [first + int(j) for j in np.flatnonzero(result["cold"])],
        "inverted_tets": np.asarray(result["inverted_tets"]).tolist(),
        "constraint_violation_max": float(np.max(result["constraint_violation"])),
        "runner": {"chunks": len(run.chunks), "computed": list(run.computed), "reused": list(run.reused)},
        "filled_samples": int(prepared.filled.sum()),
        "temporal_sigma_s": prepared.temporal_sigma_s,
        "notes": list(prepared.notes),
        "warnings": caught,
    }
