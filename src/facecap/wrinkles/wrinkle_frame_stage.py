"""One video frame of the wrinkle layer (Bickel et al. 2007, section 5), and the checks before a take's run.

:class:`WrinkleFrameStage` is what ``facecap wrinkles`` (:func:`facecap.pipelines.capture_wrinkles`)
runs on every video frame; the steps of the whole take:

From a large-scale result (``facecap animate``), calibrated footage of the
painted wrinkles and one paint mask per camera:

1. each camera's footage is tracked (:func:`~facecap.wrinkles.track_wrinkles`,
   5.1), in order: a wrinkle keeps its identity from frame to frame;
2. every video frame is then independent, and runs as a chunk task on the
   frame runner (:func:`~facecap.runner.run_frames`: Dask, resumable): the
   large-scale frame is carried into the mocap frame by the inverse
   correspondence map, the cross-sections of 5.2 are fitted along each
   camera's splines, the splines are cast onto the mesh and merged across
   cameras (:mod:`~facecap.wrinkles.surface_wrinkles`), and the wrinkles are
   synthesised (:func:`~facecap.wrinkles.synthesize_wrinkles`, 5.3);
3. the wrinkle displacement is interpolated linearly from the video frames to
   the mocap rate and added to every large-scale frame, and the result is
   written as ``animate`` writes it, plus ``wrinkles.json``.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FacecapWarning, InputError
from ..mesh.resample_polyline import resample_polyline
from ..rotations import nearest_rotation
from ..typing import FloatArray

__all__ = ["WrinkleFrameStage", "large_scale_in_mocap", "result_frame_at", "first_frame_anchors",
           "check_cameras_see_the_face", "check_paint_on_face"]

CURVE_SAMPLES = 48
"""Points per merged valley line in the stage's fixed-size output (and in ``wrinkles.json``)."""

MIN_FACE_IN_VIEW = 0.05
"""A camera that sees less than this share of the face's vertices at the first video frame is refused: a
stage camera films the face from the front and sees a third to a half of them; a few percent means a
calibration that is not this stage's, or a pose in another unit or frame."""

MIN_PAINT_ON_FACE = 0.5
"""Below this share of a camera's tracked valley points landing on the face at the first video frame, the
calibration and the footage disagree (the paint is on the skin): a warning names the camera."""


def large_scale_in_mocap(face_vertices: Any, correspondence: Mapping[str, np.ndarray], frame: float) -> FloatArray:
    """A frame of the face carried into the mocap frame: ``M_t c^-1(x)`` (5.3's inverse correspondence map).

    Parameters
    ----------
    face_vertices : (n, 3) float array, mm
        The frame of the large-scale result (the face's frame).
    correspondence : mapping
        ``correspondence.npz`` of the result (``mocap_points``, ``face_points``, optional
        ``mocap_from_stabilized``).
    frame : float
        The mocap time in frames (selects the head motion of a stabilised take; between two frames
        the two motions are blended, the rotation projected back onto the rotations).

    Returns
    -------
    (n, 3) float64 array, mm
        ``c^-1`` is the triharmonic warp from the face points back to the rest markers: it interpolates the
        markers exactly and reproduces any affine motion, as the forward map does.
    """
    from ..deform.triharmonic_warp import TriharmonicWarp

    X = np.asarray(face_vertices, dtype=np.float64)
    back = TriharmonicWarp(np.asarray(correspondence["face_points"], np.float64),
                           np.asarray(correspondence["mocap_points"], np.float64))
    Y = back(X)
    if "mocap_from_stabilized" in correspondence:
        motion = np.asarray(correspondence["mocap_from_stabilized"], np.float64)
        position = float(np.clip(frame, 0, len(motion) - 1))
        lo = int(np.floor(position))
        hi, weight = min(lo + 1, len(motion) - 1), position - lo
        M = (1.0 - weight) * motion[lo] + weight * motion[hi]
        R = nearest_rotation(M[:3, :3])  # the blend of two frames' rotations is none
        Y = Y @ R.T + M[:3, 3]
    return Y


def result_frame_at(result: Any, position: float) -> FloatArray:
    """A result's face (mm, float64) at a fractional mocap frame: linear between the two frames around it.

    ``position`` is clipped to the take; the layers on top of a result (wrinkles, fine detail) read
    their large scale at each video frame's mocap time this way.
    """
    position = float(np.clip(position, 0, result.n_frames - 1))
    lo = int(np.floor(position))
    hi = min(lo + 1, result.n_frames - 1)
    block = result.frames(lo, hi + 1).astype(np.float64) * _mm_per(result.units)
    weight = position - lo
    return block[0] if hi == lo or weight == 0 else (1 - weight) * block[0] + weight * block[-1]


class WrinkleFrameStage:
    """The per-video-frame work of the wrinkle layer, as a frame-runner stage (picklable, deterministic).

    Parameters
    ----------
    result_dir : str
        The large-scale result.
    cameras : sequence of Camera
        In footage order.
    footage : sequence of str
        One footage path per camera.
    tracks : sequence (per camera) of sequences (per video frame) of lists of (identity, color, (m, 2) curve px)
        The tracker's valley curves.
    mocap_frames : (V,) float array
        The mocap frame of each video frame.
    n_slots : int
        Rows of the fixed-size per-frame wrinkle arrays (at least the tracked wrinkles of all cameras).
    options : mapping
        Passed to :func:`~facecap.wrinkles.synthesize_wrinkles` (``depth_scale``, the shell's constants, ...).
    anchors : mapping of str to (triangles, barycentric), optional
        Valley lines fixed to the skin by identity (``'<camera>:<id>'``, :func:`~facecap.wrinkles.anchor_curves`);
        a wrinkle without one is cast onto each frame anew.
    edits : WrinkleEdits, optional
        Depth edits by wrinkle and frame range, and wrinkles drawn by hand (:mod:`~facecap.wrinkles.wrinkle_edits`).
    """

    def __init__(self, result_dir: str, cameras: Sequence[Any], footage: Sequence[str], tracks: Sequence[Any],
                 mocap_frames: Any, n_slots: int, options: Mapping[str, Any] | None = None,
                 anchors: Mapping[str, Any] | None = None, edits: Any = None) -> None:
        self.result_dir = str(result_dir)
        self.cameras = list(cameras)
        self.footage = [str(p) for p in footage]
        self.tracks = tracks
        self.mocap_frames = np.asarray(mocap_frames, dtype=np.float64)
        self.n_slots = int(n_slots)
        self.options = dict(options or {})
        self.anchors = dict(anchors or {})
        self.edits = edits

    def __getstate__(self) -> dict[str, Any]:
        # the opened result and footage are a per-process cache, not part of the stage
        return {k: v for k, v in self.__dict__.items() if k not in ("_opened", "_clips")}

    def _result(self) -> tuple[Any, dict[str, np.ndarray]]:
        """The result folder and its correspondence map, opened once per process."""
        opened = getattr(self, "_opened", None)
        if opened is None:
            from ..io.mocap_correspondence import read_mocap_correspondence
            from ..io.read_result import read_result

            correspondence = read_mocap_correspondence(Path(self.result_dir) / "correspondence.npz")
            opened = self._opened = (read_result(self.result_dir), correspondence)
        return opened

    def _image(self, camera_index: int, video_frame: int) -> np.ndarray:
        """A footage frame; each footage is opened once per process (a video is not re-opened per frame)."""
        from ..cameras import open_footage

        clips = self.__dict__.setdefault("_clips", {})
        if camera_index not in clips:
            clips[camera_index] = open_footage(self.footage[camera_index])
        return clips[camera_index].frame(video_frame)

    def parameters(self) -> dict[str, Any]:
        """What the frames depend on (the runner refuses to resume a run with other values)."""
        return {"result_dir": self.result_dir, "cameras": [c.name for c in self.cameras], "footage": self.footage,
                "options": {k: (v if not isinstance(v, Mapping) else dict(v)) for k, v in self.options.items()},
                "n_slots": self.n_slots, "mocap_frames": self.mocap_frames.tolist(),
                "anchors": {k: [np.round(np.asarray(a, dtype=np.float64), 8).tolist() for a in v]
                            for k, v in sorted(self.anchors.items())},
                "edits": None if self.edits is None else self.edits.describe(),
                "tracks": [[[(i, c, np.round(np.asarray(p), 4).tolist()) for i, c, p in frame] for frame in cam]
                           for cam in self.tracks]}

    def large_scale(self, video_frame: int) -> FloatArray:
        """The large-scale face (mm) at a video frame's mocap time (linear between mocap frames)."""
        return result_frame_at(self._result()[0], float(self.mocap_frames[video_frame]))

    def geometry(self, video_frame: int) -> tuple[FloatArray, Any]:
        """The large scale at a video frame (face frame, mm) and its ray caster in the mocap frame."""
        from ..cameras import RayCaster

        result, correspondence = self._result()
        A = self.large_scale(video_frame)
        at = float(np.clip(self.mocap_frames[video_frame], 0, result.n_frames - 1))
        return A, RayCaster(large_scale_in_mocap(A, correspondence, at), result.mesh.faces)

    def camera_views(self, video_frame: int, A: FloatArray, caster: Any, anchors: Mapping[str, Any]
                     ) -> tuple[list[list[Any]], dict[str, float], float]:
        """Each camera's cross-sections at a frame and its lines on the face.

        Returns the per-camera :class:`~facecap.wrinkles.SurfaceWrinkle` lists, the mean fit residual per
        wrinkle identity, and the seconds spent fitting cross-sections.
        """
        from .fit_cross_sections import fit_cross_sections
        from .surface_wrinkles import wrinkles_on_surface

        faces = self._result()[0].mesh.faces
        views: list[list[Any]] = []
        residuals: dict[str, float] = {}
        seconds = 0.0
        for k, (camera, track) in enumerate(zip(self.cameras, self.tracks)):
            curves = track[video_frame]
            if not curves:
                views.append([])
                continue
            polylines = [np.asarray(p, dtype=np.float64) for _, _, p in curves]
            image = self._image(k, video_frame)
            clock = time.perf_counter()
            sections = fit_cross_sections(image, polylines, camera, caster)
            seconds += time.perf_counter() - clock
            names = [f"{camera.name}:{i}" for i, _, _ in curves]
            for j, name in enumerate(names):
                rms = sections.fit.rms[sections.samples.curve == j]
                residuals[name] = float(rms[np.isfinite(rms)].mean()) if np.isfinite(rms).any() else float("nan")
            views.append(wrinkles_on_surface(polylines, sections, camera, caster, A, faces, identities=names,
                                             colors=[c for _, c, _ in curves],
                                             anchors=[anchors.get(name) for name in names]))
        return views, residuals, seconds

    def frame(self, video_frame: int) -> tuple[dict[str, np.ndarray], list[Any]]:
        """One video frame: the wrinkle displacement and the merged valley lines."""
        from .surface_wrinkles import identity_parts, merge_camera_wrinkles
        from .synthesize_wrinkles import synthesize_wrinkles, wrinkle_depth_scale

        clock = time.perf_counter()
        faces = self._result()[0].mesh.faces
        A, caster = self.geometry(video_frame)
        seconds = {"large_scale_and_ray_caster_s": time.perf_counter() - clock}
        views, residuals, seconds["cross_sections_s"] = self.camera_views(video_frame, A, caster, self.anchors)
        clock = time.perf_counter()
        merged = merge_camera_wrinkles(views)
        options = dict(self.options)
        if self.edits is not None:
            at = float(self.mocap_frames[video_frame])
            merged += self.edits.surface_wrinkles(at, self.cameras, caster, A, faces)
            edited = self.edits.scales([w.wrinkle for w in merged], at)
            base = options.get("depth_scale", 1.0)
            options["depth_scale"] = {w.wrinkle: edited[w.wrinkle] * wrinkle_depth_scale(w, base) for w in merged}
        synthesis = synthesize_wrinkles(A, faces, merged, **options)
        seconds["synthesis_s"] = time.perf_counter() - clock
        self.last_seconds = seconds  # for benchmarks; never part of the chunk (its bytes must not vary)
        slots = np.full((self.n_slots, CURVE_SAMPLES, 5), np.nan, dtype=np.float32)
        sources = np.full((self.n_slots, len(self.cameras)), -1, dtype=np.int32)
        colors = np.full(self.n_slots, -1, dtype=np.int32)
        residual = np.full(self.n_slots, np.nan, dtype=np.float32)
        names = [c.name for c in self.cameras]
        for row, wrinkle in enumerate(merged[: self.n_slots]):
            P, (w, d), _ = resample_polyline(wrinkle.points, CURVE_SAMPLES, [wrinkle.width, wrinkle.depth])
            slots[row] = np.column_stack([P, w, d])
            colors[row] = wrinkle.color
            parts = identity_parts(wrinkle.wrinkle)
            for part in parts:
                cam, identity = part.rsplit(":", 1)
                if identity.isdigit():  # a drawn wrinkle has a name, no tracker id
                    sources[row, names.index(cam)] = int(identity)
            found = [residuals[p] for p in parts if np.isfinite(residuals.get(p, np.nan))]
            residual[row] = np.mean(found) if found else np.nan  # a drawn wrinkle has no fit
        arrays = {"displacement": (synthesis.vertices - A).astype(np.float32), "curves": slots,
                  "sources": sources, "colors": colors, "residual": residual,
                  "regions": np.int32(synthesis.n_regions)}
        return arrays, merged

    def __call__(self, start: int, stop: int, state: Any) -> tuple[dict[str, np.ndarray], None]:
        frames = [self.frame(j)[0] for j in range(start, stop)]
        return {k: np.stack([np.asarray(f[k]) for f in frames]) for k in frames[0]}, None


def first_frame_anchors(stage: WrinkleFrameStage, geometry: tuple[FloatArray, Any] | None = None) -> dict[str, Any]:
    """Each wrinkle of the first video frame cast onto the large scale there, by identity.

    ``geometry`` is ``stage.geometry(0)`` when the caller already has it. Returns
    ``{'<camera>:<id>': (triangles, barycentric, rest_depth)}``: the line on the skin, and the depth the
    first frame's cross-sections already find along it (subtracted from every frame's: the first frame is the
    scan's expression, so a crease it shows is in the scan).
    """
    from .surface_wrinkles import anchor_curves

    A, caster = stage.geometry(0) if geometry is None else geometry
    lines: dict[str, Any] = {}
    for camera, track in zip(stage.cameras, stage.tracks):
        curves = track[0]
        found = anchor_curves([np.asarray(p, dtype=np.float64) for _, _, p in curves], camera, caster)
        lines.update({f"{camera.name}:{identity}": hit for (identity, _, _), hit in zip(curves, found) if hit})
    # the rest frame's own creases, along each line: the scan already holds them
    views, _, _ = stage.camera_views(0, A, caster, lines)
    rest_depth = {w.wrinkle: w.depth for view in views for w in view}
    return {name: (tri, bary, rest_depth.get(name, np.zeros(len(tri)))) for name, (tri, bary) in lines.items()}


def check_cameras_see_the_face(caster: Any, cameras: Sequence[Any], *,
                               min_face_in_view: float = MIN_FACE_IN_VIEW) -> list[float]:
    """Refuse a camera that does not see the face at the first video frame.

    Parameters
    ----------
    caster : facecap.cameras.RayCaster
        The face at the first video frame in the mocap frame, where the cameras are calibrated
        (:meth:`WrinkleFrameStage.geometry`).
    cameras : sequence of facecap.cameras.Camera
    min_face_in_view : float, default :data:`MIN_FACE_IN_VIEW`
        A camera that sees a smaller share of the face's vertices is refused; 0 lets every camera through
        (a close-up camera filming a small part of a full-head scan).

    Returns
    -------
    list of float
        Per camera, in order, the share of the face's vertices it sees: in front of it, inside its image,
        unoccluded.

    Raises
    ------
    InputError
        Naming the camera, the share of the face it sees and what to check.
    """
    shares = []
    for camera in cameras:
        seen = float(caster.visible_vertices(camera).mean())
        if seen < min_face_in_view:
            in_front = float(camera.project(caster.V).in_front.mean())
            raise InputError(f"camera {camera.name!r} does not see the face at video frame 0 ({seen:.1%} of the "
                             f"face's vertices visible in its image, {in_front:.0%} in front of it): check its R "
                             "and T (the mocap frame, in the calibration's unit) against the take")
        shares.append(seen)
    return shares


def check_paint_on_face(caster: Any, cameras: Sequence[Any], first_curves: Sequence[Any], *,
                        stacklevel: int = 2) -> list[float]:
    """Warn about a camera whose tracked paint at the first video frame mostly misses the face.

    Parameters
    ----------
    caster : facecap.cameras.RayCaster
        As for :func:`check_cameras_see_the_face`.
    cameras : sequence of facecap.cameras.Camera
    first_curves : sequence (per camera) of sequences of (m, 2) arrays, px
        Each camera's tracked valley curves at the first video frame.
    stacklevel : int, default 2
        Of the warning, as :func:`warnings.warn`'s.

    Returns
    -------
    list of float
        Per camera, the share of its valley points whose pixel rays hit the face; NaN where it tracks none.

    Warns
    -----
    FacecapWarning
        A camera less than :data:`MIN_PAINT_ON_FACE` of whose valley points land on the face: its
        calibration and its footage disagree (the paint is on the skin), and the wrinkles that miss the
        face would be left out.
    """
    shares = []
    for camera, curves in zip(cameras, first_curves):
        curves = list(curves)
        if not curves:
            shares.append(float("nan"))
            continue
        points = np.concatenate([np.asarray(c, dtype=np.float64).reshape(-1, 2) for c in curves])
        on_face = float(caster.cast_pixels(camera, points).hit.mean())
        if on_face < MIN_PAINT_ON_FACE:
            warnings.warn(f"camera {camera.name!r}: only {on_face:.0%} of the painted wrinkles it tracks at "
                          "video frame 0 land on the face; its calibration may not match the footage "
                          "(wrinkles that miss the face are left out)", FacecapWarning, stacklevel=stacklevel)
        shares.append(on_face)
    return shares


def _mm_per(unit: str) -> float:
    from ..units import mm_per_unit

    return float(mm_per_unit(unit))
