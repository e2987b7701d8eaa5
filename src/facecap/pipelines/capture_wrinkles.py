"""``facecap wrinkles``'s job: the wrinkle layer over a whole take (Bickel et al. 2007, section 5).

The take's footage tracked, every video frame run on the frame runner as a
:class:`~facecap.wrinkles.WrinkleFrameStage` (its module says what each does), and the
result written as ``animate`` writes it, plus ``wrinkles.json``.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import FacecapWarning, InputError
from ..units import mm_per_unit
from ..wrinkles.wrinkle_frame_stage import (CURVE_SAMPLES, MIN_FACE_IN_VIEW, WrinkleFrameStage,
                                            check_cameras_see_the_face, check_paint_on_face, first_frame_anchors)

__all__ = ["WrinkleCapture", "capture_wrinkles"]


class WrinkleCapture(NamedTuple):
    """What :func:`capture_wrinkles` wrote.

    Attributes
    ----------
    out_dir : Path
        The result folder (``vertices.npy`` with the wrinkles, ``wrinkles.json``, exports).
    n_video_frames : int
    timings : dict of str to float
        Seconds per step.
    """

    out_dir: Path
    n_video_frames: int
    timings: dict[str, float]


def capture_wrinkles(result_dir: str | os.PathLike[str], cameras: Sequence[Any], footage: Sequence[Any],
                     masks: Sequence[Any], out_dir: str | os.PathLike[str], *, video_rate_hz: float | None = None,
                     first_mocap_frame: float = 0.0, depth_scale: float | Mapping[str, float] = 1.0,
                     scheduler: str | None = "synchronous", n_workers: int = 2, work_dir: Any = None,
                     exports: Sequence[str] = (), chunk_frames: int = 4, anchor: bool = True, edits: Any = None,
                     min_face_in_view: float = MIN_FACE_IN_VIEW, progress: bool = False,
                     options: Mapping[str, Any] | None = None, export_options: Mapping[str, Any] | None = None,
                     overwrite: bool = False) -> WrinkleCapture:
    """Track, measure and synthesise the painted wrinkles of a take onto its large-scale result.

    Parameters
    ----------
    result_dir : str or path-like
        A ``facecap animate`` or ``facecap blend`` result (it must hold ``correspondence.npz``).
    cameras : sequence of facecap.cameras.Camera
        Calibrated in the mocap frame, one per footage.
    footage : sequence of str or path-like
        Image folders or video files, in ``cameras`` order.
    masks : sequence of (H, W) arrays or paths
        Each camera's paint mask of the first video frame (see :func:`~facecap.wrinkles.track_wrinkles`).
    out_dir : str or path-like
        The new result folder.
    video_rate_hz : float, optional
        The footage's rate (required).
    first_mocap_frame : float, default 0
        The mocap frame of video frame 0.
    depth_scale : float or mapping of str to float, default 1
        Scale every wrinkle's depth, or chosen ones by identity ('<camera>:<id>', as in ``wrinkles.json``;
        a merged wrinkle by any camera's part).
    scheduler : str or None, default 'synchronous'
        The frame runner's (:func:`~facecap.runner.run_frames`): ``'synchronous'`` in this process, None for a
        local cluster of ``n_workers`` processes, or a scheduler address.
    n_workers : int, default 2
    work_dir : path-like, optional
        The runner's resumable work folder (default: a temporary one, removed at the end).
    exports : sequence of str, default ()
        As for ``facecap animate``.
    chunk_frames : int, default 4
        Video frames per runner task.
    anchor : bool, default True
        Fix each valley line to the skin where its paint lies in the first video frame (cast onto the large
        scale there) and carry it with the mesh, the cross-sections of each frame placed along it; False
        casts every frame's spline onto that frame's mesh, as the paper does. See ``docs/wrinkles.md``
        (Synthesis) for why anchoring is the default.
    edits : WrinkleEdits or path-like, optional
        Depth edits per wrinkle and frame range, wrinkles drawn by hand (:func:`~facecap.wrinkles.read_wrinkle_edits`).
    min_face_in_view : float, default :data:`MIN_FACE_IN_VIEW`
        A camera seeing a smaller share of the face at the first video frame is refused before any tracking
        (:func:`check_cameras_see_the_face`); 0 turns the check off.
    progress : bool, default False
    options : mapping, optional
        More options of :func:`~facecap.wrinkles.synthesize_wrinkles`.
    export_options : mapping, optional
        Passed to :func:`facecap.pipelines.export_result` (e.g. ``export_frame``).
    overwrite : bool, default False
        Replace an earlier result in ``out_dir``; without it one is refused before any work and
        again at the end (:class:`~facecap.io.PerformanceWriter`).

    Returns
    -------
    WrinkleCapture

    Raises
    ------
    InputError
        A result without its correspondence map, a camera count that does not match the footage or masks,
        a camera name holding '+' or ':', footage of another size than its calibration, footage that does not
        cover the take, a mask without a paint, no camera seeing any wrinkle in any frame, a camera that does
        not see the face (:func:`check_cameras_see_the_face`).
    """
    from ..cameras import open_footage, read_image, synchronize
    from ..io.read_result import read_result
    from ..io.write_performance import PerformanceWriter, check_result_destination
    from .finish_result import finish_result
    from ..runner import run_frames
    from ..wrinkles.track_wrinkles import track_wrinkles

    timings: dict[str, float] = {}
    start_all = time.perf_counter()
    check_result_destination(out_dir, overwrite=overwrite)
    result_dir = Path(result_dir)
    result = read_result(result_dir)
    if not (result_dir / "correspondence.npz").is_file():
        raise InputError("the result has no correspondence.npz (the map into the mocap frame, where the cameras "
                         "are calibrated): make it with facecap animate or facecap blend", path=str(result_dir))
    cameras, footage, masks = list(cameras), [str(f) for f in footage], list(masks)
    if not cameras or len(cameras) != len(footage) or len(masks) != len(footage):
        raise InputError(f"expected one camera and one mask per footage: {len(cameras)} cameras, "
                         f"{len(footage)} footage, {len(masks)} masks")
    if video_rate_hz is None:
        raise InputError("video_rate_hz: the footage's rate is needed (the camera file's footage.rate_hz)")
    if isinstance(min_face_in_view, bool) or not isinstance(min_face_in_view, (int, float)) \
            or not 0.0 <= min_face_in_view < 1.0:
        raise InputError(f"min_face_in_view: expected a share in [0, 1), got {min_face_in_view!r}")
    for camera in cameras:
        if "+" in camera.name or ":" in camera.name:
            raise InputError(f"camera {camera.name!r}: a name with '+' or ':' cannot name wrinkles "
                             "('<camera>:<id>', joined by '+' when merged); rename it in the calibration")
    if edits is not None and not hasattr(edits, "surface_wrinkles"):
        from ..wrinkles.wrinkle_edits import read_wrinkle_edits

        edits = read_wrinkle_edits(edits)
    counts = []
    for camera, path in zip(cameras, footage):
        with open_footage(path) as clip:
            clip.check_camera(camera)
            counts.append(len(clip))
    n_video = min(counts)
    sync = synchronize(result.rate, result.n_frames, video_rate_hz, n_video, first_mocap_frame=first_mocap_frame,
                       footage_name=" and ".join(footage))
    # the face at video frame 0, before any tracking: a calibration that does not see it is refused at once
    # (a stage without tracks, for its geometry alone; the same geometry serves the paint check and the anchors)
    first = WrinkleFrameStage(str(result_dir.resolve()), cameras, footage, [[] for _ in cameras],
                              sync.mocap_frame(np.arange(1)), 1)
    first_geometry = first.geometry(0)
    check_cameras_see_the_face(first_geometry[1], cameras, min_face_in_view=min_face_in_view)
    t = time.perf_counter()
    tracks = []
    for camera, path, mask in zip(cameras, footage, masks):
        mask_image = read_image(mask) if isinstance(mask, (str, os.PathLike)) else np.asarray(mask)
        with open_footage(path) as clip:
            tracked = track_wrinkles(clip, mask_image, camera=camera.name, progress=progress)
        tracks.append([[(w.wrinkle, w.color, w.curve()) for w in frame] for frame in tracked])
    timings["tracking_s"] = time.perf_counter() - t
    check_paint_on_face(first_geometry[1], cameras, [[p for _, _, p in track[0]] for track in tracks], stacklevel=3)
    if not any(any(frame) for track in tracks for frame in track):
        raise InputError("no camera sees a painted wrinkle in any frame (check the masks and the footage)")
    n_slots = sum(max((len(frame) for frame in track), default=0) for track in tracks)
    opts = dict(options or {})
    opts["depth_scale"] = dict(depth_scale) if isinstance(depth_scale, Mapping) else float(depth_scale)
    if opts.get("backend", "auto") == "auto":
        from ..mesh.factor_spd import available_backends

        # one factorisation for every chunk, recorded with the run: a resume or a re-run task on another
        # worker then solves the same way
        opts["backend"] = available_backends()[0]
    if edits is not None:
        covered = sync.mocap_frame(np.arange(n_video))
        ranges = [e.frames for e in edits.depth if e.frames is not None] + \
                 [d.frames for d in edits.add if d.frames is not None]
        for first, last in ranges:
            if not ((covered >= first) & (covered <= last)).any():
                warnings.warn(f"edits: mocap frames {first:g}-{last:g} hold no video frame, so the edit does "
                              "nothing (edits apply at video frames and blend over the interval after)",
                              FacecapWarning, stacklevel=2)
    stage = WrinkleFrameStage(str(result_dir.resolve()), cameras, footage, [track[:n_video] for track in tracks],
                              sync.mocap_frame(np.arange(n_video)), max(n_slots, 1) + len(getattr(edits, "add", ())),
                              opts, edits=edits)
    if anchor:
        stage.anchors = first_frame_anchors(stage, first_geometry)
    t = time.perf_counter()
    own_work = work_dir is None
    work = Path(tempfile.mkdtemp(prefix="facecap-wrinkles-")) if own_work else Path(work_dir)
    try:
        run = run_frames(stage, n_video, work, chunk_frames=chunk_frames, scheduler=scheduler, n_workers=n_workers,
                         progress=progress)
        timings["cross_sections_and_synthesis_s"] = time.perf_counter() - t
        displacement = run.load("displacement")
        t = time.perf_counter()
        bracket = sync.bracket(np.arange(result.n_frames))
        mm = float(mm_per_unit(result.units))
        head_pose = result.head_motion.copy() if result.head_motion is not None else None
        if head_pose is not None:
            head_pose[:, :3, 3] *= mm
        with PerformanceWriter(out_dir, mesh=result.mesh, rate=result.rate, n_frames=result.n_frames,
                               exports=exports, export_options=export_options, overwrite=overwrite) as writer:
            def compute(lo: int, hi: int, out: np.ndarray) -> None:
                out[:] = result.frames(lo, hi) * np.float32(mm)
                b, a, w = bracket.before[lo:hi], bracket.after[lo:hi], bracket.weight[lo:hi].astype(np.float32)
                out += (1 - w)[:, None, None] * displacement[b] + w[:, None, None] * displacement[a]

            writer.stream(compute, batch_frames=16, head_pose=head_pose, progress=progress, desc="wrinkles")
            for name in ("head_motion.npy", "markers.npy", "correspondence.npz"):
                if (result_dir / name).is_file():
                    shutil.copyfile(result_dir / name, writer.path(name))
            writer.path("wrinkles.json").write_text(json.dumps(
                _wrinkles_document(run, stage, sync), indent=1))
            timings["write_s"] = time.perf_counter() - t
            timings["total_s"] = time.perf_counter() - start_all
            final = finish_result(writer, {"method": "bickel2007-medium-scale", "large_scale": writer.record_path(result_dir),
                                   "footage": [writer.record_path(f) for f in footage],
                                   "cameras": [c.name for c in cameras],
                                   "video_rate_hz": float(video_rate_hz), "first_mocap_frame": float(first_mocap_frame),
                                   "depth_scale": opts["depth_scale"], "anchored": bool(anchor),
                                   "markers": list(result.marker_labels) if result.markers is not None else [],
                                   "timings": timings})
    finally:
        if own_work:
            shutil.rmtree(work, ignore_errors=True)
    return WrinkleCapture(Path(final), n_video, timings)


def _wrinkles_document(run: Any, stage: WrinkleFrameStage, sync: Any) -> dict[str, Any]:
    """``wrinkles.json``: per video frame and wrinkle, the splines, the line on the face, depth and width."""
    curves, sources = run.load("curves"), run.load("sources")
    colors, residual = run.load("colors"), run.load("residual")
    names = [c.name for c in stage.cameras]
    frames = []
    for j in range(curves.shape[0]):
        splines = {name: {str(i): np.round(np.asarray(p), 2).tolist() for i, _, p in stage.tracks[k][j]}
                   for k, name in enumerate(names)}
        wrinkles = []
        # the drawn wrinkles follow the tracked ones, in the edit file's order (WrinkleFrameStage.frame)
        drawn = iter([] if stage.edits is None else
                     [f"{d.camera}:{d.name}" for d in stage.edits.drawn_at(float(stage.mocap_frames[j]))])
        for row in np.flatnonzero(np.isfinite(curves[j, :, 0, 0])):
            seen = {names[k]: int(s) for k, s in enumerate(sources[j, row]) if s >= 0}
            c = curves[j, row]
            wrinkles.append({
                "wrinkle": "+".join(sorted(f"{cam}:{i}" for cam, i in seen.items())) if seen else next(drawn),
                "drawn": not seen,
                "color": int(colors[j, row]) if colors[j, row] >= 0 else None,
                "cameras": seen, "splines_px": {cam: splines[cam][str(i)] for cam, i in seen.items()},
                "points_mm": np.round(c[:, :3], 4).tolist(), "width_mm": np.round(c[:, 3], 4).tolist(),
                "depth_mm": np.round(c[:, 4], 4).tolist(),
                "residual": None if not np.isfinite(residual[j, row]) else round(float(residual[j, row]), 5),
            })
        frames.append({"video_frame": j, "mocap_frame": float(sync.mocap_frame([j])[0]), "wrinkles": wrinkles})
    return {"units": "mm", "frame": "face (the result's vertices)", "curve_samples": CURVE_SAMPLES,
            "cameras": names, "frames": frames}
