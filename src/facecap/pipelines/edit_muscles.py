"""``facecap edit-muscles``'s job: a ``solve-muscles`` result edited in muscle space, written as a new result folder.

Sifakis et al. 2005, sec. 9: the result's solved controls read back (``activations.csv``,
``bone_transforms.npz``), the model folder it was solved on opened, every frame of the edit
solved by a :class:`~facecap.muscles.MuscleEditor` (an interpolation between two frames by
:func:`~facecap.muscles.interpolate_controls`, the force-length curves scaled, or a kinematic
sphere pressing on the face), and the result written in ``solve-muscles``' layout
(:func:`~facecap.pipelines.write_muscle_result`) with ``report.json`` saying how each frame
solved.
"""

from __future__ import annotations

import csv
import os
import sys
import time
from pathlib import Path
from typing import Any, Iterable, Literal, Mapping, NamedTuple, Sequence

import numpy as np

from ..anatomy.face_anatomy import load_anatomy
from ..errors import FileFormatError, InputError
from ..io.atomic_write import resolve_recorded_path
from ..io.read_result import read_result
from ..io.result_layout import parse_export_formats, read_performance_info
from ..io.write_performance import check_result_destination
from ..muscles.jaw_constraints import JawConstraints
from ..muscles.muscle_controls import MuscleControls
from ..muscles.muscle_editor import (DEFAULT_INTERPOLATION_FRAMES, DEFAULT_PENETRATION_TOLERANCE_MM, EditedFrame,
                                     MuscleEditor, interpolate_controls, interpolate_rigid_motions)
from ..muscles.muscle_frame_stage import model_folder_sha256
from ..typing import FloatArray, IntArray
from .finish_result import import_writers
from .write_muscle_result import ACTIVATIONS_FILE, BONE_TRANSFORMS_FILE, write_muscle_result

__all__ = ["edit_muscles", "MuscleEditResult", "EDIT_METHOD"]

EDIT_METHOD = "sifakis2005-muscle-edit"
"""``performance.json``'s ``method`` of an edited result."""
_MODEL_OPTIONS = ("rim", "backend", "tolerance", "muscle_strength")  # of the solver options, the model's


class MuscleEditResult(NamedTuple):
    """What :func:`edit_muscles` wrote.

    Attributes
    ----------
    out_dir : Path
    n_frames : int
    report : dict
        The content of ``report.json``.
    """

    out_dir: Path
    n_frames: int
    report: dict[str, Any]


class _Source(NamedTuple):
    folder: Path
    info: dict[str, Any]
    frames: IntArray
    muscles: tuple[str, ...]
    activations: FloatArray
    cranium: FloatArray
    mandible: FloatArray


def _read_source(result_dir: str | os.PathLike[str]) -> _Source:
    """The solved controls of a ``solve-muscles`` result folder (errors name the file)."""
    folder = Path(result_dir)
    if not folder.is_dir():
        raise FileFormatError("no such result folder (make one with facecap solve-muscles)", path=str(folder))
    info = read_performance_info(folder)
    method = info.get("method")
    if method != "sifakis2005-muscle-activations":
        what = "an edited result (edit the solve-muscles result it came from)" if method == EDIT_METHOD else \
            f"not a solve-muscles result (method {method!r})"
        raise InputError(what, path=str(folder / "performance.json"))
    table = folder / ACTIVATIONS_FILE
    if not table.is_file():
        raise FileFormatError("missing from the result folder", path=str(table))
    try:
        with open(table, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
        header = rows[0]
        values = np.array(rows[1:], dtype=np.float64)
    except (IndexError, ValueError) as exc:
        raise FileFormatError(f"not an activations table (frame,<muscles> then numbers): {exc}", path=str(table)) \
            from None
    if header[:1] != ["frame"] or values.ndim != 2 or values.shape[1] != len(header) or values.shape[0] < 1:
        raise FileFormatError("not an activations table (frame,<muscles> then one row per frame)", path=str(table))
    bones_path = folder / BONE_TRANSFORMS_FILE
    if not bones_path.is_file():
        raise FileFormatError("missing from the result folder", path=str(bones_path))
    try:
        with np.load(bones_path) as bones:
            cranium, mandible, frames = (np.asarray(bones[k]) for k in ("cranium", "mandible", "frames"))
    except (KeyError, ValueError, OSError) as exc:
        raise FileFormatError(f"unreadable bone transforms ({exc})", path=str(bones_path)) from None
    T = values.shape[0]
    if cranium.shape != (T, 3, 4) or mandible.shape != (T, 3, 4) or frames.shape != (T,) \
            or not np.array_equal(frames, values[:, 0]):
        raise FileFormatError(f"cranium, mandible (T, 3, 4) and frames (T,) must match the {T} rows of "
                              f"{ACTIVATIONS_FILE}", path=str(bones_path))
    return _Source(folder, info, frames.astype(np.int64), tuple(header[1:]), values[:, 1:], cranium.astype(np.float64),
                   mandible.astype(np.float64))


def _as_point(value: Any, name: str) -> FloatArray:
    try:
        p = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected 3 numbers (mm), got {value!r}") from None
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputError(f"{name}: expected 3 finite numbers (mm), got {value!r}")
    return p


def edit_muscles(
    result_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    scale_force_length: float | None = None,
    interpolate: tuple[int, int] | None = None,
    n_frames: int = DEFAULT_INTERPOLATION_FRAMES,
    sphere: Sequence[float] | None = None,
    sphere_to: Sequence[float] | None = None,
    model_dir: str | os.PathLike[str] | None = None,
    penetration_tolerance_mm: float = DEFAULT_PENETRATION_TOLERANCE_MM,
    exports: Iterable[str] = (),
    progress: bool = False,
    export_options: Mapping[str, Any] | None = None,
    overwrite: bool = False,
) -> MuscleEditResult:
    """Edit a ``solve-muscles`` result in muscle space and write the edited result folder.

    Exactly one edit: ``scale_force_length``, ``interpolate`` or ``sphere``.

    Parameters
    ----------
    result_dir : str or path-like
        A ``facecap solve-muscles`` result (``performance.json``, ``activations.csv``,
        ``bone_transforms.npz``).
    out_dir : str or path-like
        The edited result, the same layout (:func:`~facecap.pipelines.solve_muscle_take`'s
        writer; written atomically).
    scale_force_length : float, optional
        Re-solve every frame with every muscle's force-length curve scaled by this (positive;
        the paper's exaggeration beyond the attainable), the activations unchanged.
    interpolate : (A, B), optional
        Two frames of the result (the numbers of ``activations.csv``'s ``frame`` column):
        ``n_frames`` frames from A to B (:func:`~facecap.muscles.interpolate_controls`), numbered 0..n-1.
    n_frames : int, default 30
        Of the interpolation, both ends included.
    sphere : (cx, cy, cz, r), optional
        A kinematic sphere (centre in the result's coordinates, radius; mm) pressing on every
        frame of the result under its solved controls.
    sphere_to : (cx, cy, cz), optional
        The sphere's centre at the last frame: it moves linearly from ``sphere``'s centre.
    model_dir : str or path-like, optional
        The anatomy model folder; default the one ``performance.json`` names (``source_files``:
        absolute, or relative to the result folder). It must be the one the take was solved on
        (its SHA-256 is checked).
    penetration_tolerance_mm : float, default 0.05
        See :class:`~facecap.muscles.MuscleEditor`.
    exports, progress, export_options, overwrite
        As for :func:`~facecap.pipelines.solve_muscle_take` (an earlier result in ``out_dir`` is
        refused before any work unless ``overwrite``).

    Returns
    -------
    MuscleEditResult

    Raises
    ------
    FileFormatError
        A missing or unreadable result folder or model folder (the message names the file).
    InputError
        Not exactly one edit, frames outside the result, a scale or radius that is not
        positive, a model folder other than the one the take was solved on.
    """
    t_all = time.perf_counter()

    def stage(message: str) -> None:
        if progress:
            print(f"facecap: {message}", file=sys.stderr, flush=True)

    chosen = [name for name, value in (("scale_force_length", scale_force_length), ("interpolate", interpolate),
                                       ("sphere", sphere)) if value is not None]
    if len(chosen) != 1:
        raise InputError(f"expected exactly one edit (scale_force_length, interpolate or sphere), got {chosen or 'none'}")
    kind: Literal["scale_force_length", "interpolate", "sphere"] = chosen[0]  # type: ignore[assignment]
    if sphere_to is not None and kind != "sphere":
        raise InputError("sphere_to: only with sphere")
    if kind == "scale_force_length":
        try:
            scale = float(scale_force_length)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise InputError(f"scale_force_length: expected a positive number, got {scale_force_length!r}") from None
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"scale_force_length: expected a positive number, got {scale_force_length!r}")
    if kind == "sphere":
        values = np.asarray(sphere, dtype=np.float64).reshape(-1)
        if values.shape != (4,) or not np.all(np.isfinite(values)):
            raise InputError(f"sphere: expected 4 finite numbers (centre x y z, radius; mm), got {sphere!r}")
        if values[3] <= 0:
            raise InputError(f"sphere: expected a positive radius, mm, got {values[3]:g}")
        start_centre, radius = values[:3], float(values[3])
        end_centre = start_centre if sphere_to is None else _as_point(sphere_to, "sphere_to")
    if kind == "interpolate" and int(n_frames) < 2:
        raise InputError(f"n_frames: expected at least 2 (both ends), got {n_frames}")
    exports = parse_export_formats(exports)
    check_result_destination(out_dir, overwrite=overwrite)

    stage(f"reading the result {result_dir}")
    source = _read_source(result_dir)
    info = source.info
    model_path = (Path(model_dir) if model_dir is not None else
                  resolve_recorded_path(str(info.get("source_files", {}).get("model") or ""), folder=source.folder))
    if not (model_path / "anatomy.json").is_file():
        raise FileFormatError("no anatomy model folder here (give the one the take was solved on: --model)",
                              path=str(model_path))
    parameters = info.get("parameters", {})
    solved_on = parameters.get("model_sha256")
    if solved_on is not None and model_folder_sha256(model_path) != solved_on:
        raise InputError(f"not the model folder the result {source.folder} was solved on (its anatomy differs)",
                         path=str(model_path))
    stage(f"reading the model {model_path}")
    anatomy = load_anatomy(model_path)
    if tuple(anatomy.muscle_names) != source.muscles:
        raise InputError(f"the muscles of activations.csv are not the model {model_path}'s",
                         path=str(source.folder / "activations.csv"))
    options = {k: v for k, v in dict(parameters.get("solver", {})).items() if k in _MODEL_OPTIONS}
    editor = MuscleEditor(anatomy, force_length_scale=scale if kind == "scale_force_length" else 1.0,
                          penetration_tolerance_mm=penetration_tolerance_mm, **options)
    T = source.frames.size
    frame_list = [int(f) for f in source.frames]

    if kind == "interpolate":
        try:
            a_frame, b_frame = (int(v) for v in interpolate)  # type: ignore[union-attr]
        except (TypeError, ValueError):
            raise InputError(f"interpolate: expected two frame numbers, got {interpolate!r}") from None
        for f in (a_frame, b_frame):
            if f not in frame_list:
                raise InputError(f"frame {f} is not in the result (frames {frame_list[0]}..{frame_list[-1]})",
                                 path=str(source.folder / "activations.csv"))
        ia, ib = frame_list.index(a_frame), frame_list.index(b_frame)
        ends = [MuscleControls(source.activations[i], source.cranium[i], source.mandible[i]) for i in (ia, ib)]
        controls = interpolate_controls(ends[0], ends[1], editor.model.jaw, int(n_frames))
        out_frames = np.arange(len(controls), dtype=np.int64)
        what = f"interpolating frames {a_frame} to {b_frame} in {len(controls)} frames"
    else:
        controls = [MuscleControls(source.activations[j], source.cranium[j], source.mandible[j]) for j in range(T)]
        out_frames = source.frames
        what = (f"re-solving {T} frames with the force-length curves scaled by {scale:g}"
                if kind == "scale_force_length" else f"pressing a sphere of {radius:g} mm on {T} frames")
    n = len(controls)
    centres = None
    if kind == "sphere":
        s = np.linspace(0.0, 1.0, n) if n > 1 else np.zeros(1)
        centres = (1.0 - s)[:, None] * start_centre + s[:, None] * end_centre

    import_writers(exports)
    stage(f"{what} ({anatomy.n_tets} tetrahedra)")
    t = time.perf_counter()
    n_scan = int(anatomy.scan_vertices.shape[0])
    skin = np.empty((n, n_scan, 3), dtype=np.float32)
    x = None
    stiffness = None
    frames_out: list[EditedFrame] = []
    seconds = []
    for j, c in enumerate(controls):
        t_frame = time.perf_counter()
        frame = editor.solve(c, x, sphere=None if centres is None else (centres[j], radius), stiffness=stiffness)
        seconds.append(time.perf_counter() - t_frame)
        x = frame.nodes
        if frame.sphere is not None:
            stiffness = frame.sphere.stiffness
        skin[j] = frame.skin
        frames_out.append(frame)
        if progress and (j + 1 == n or (j + 1) % 10 == 0):
            stage(f"frame {j + 1}/{n} ({seconds[-1]:.2f} s, {frame.iterations} Newton iterations)")
    timings = {"solve_s": time.perf_counter() - t}
    t = time.perf_counter()
    jaw = editor.model.jaw
    arrays = {
        "vertices": skin,
        "activations": np.stack([np.clip(c.activations, 0.0, 1.0) for c in controls]),
        "cranium": np.stack([c.cranium for c in controls]),
        "mandible": np.stack([c.mandible for c in controls]),
        "jaw_pose": np.stack([jaw.pose(c.mandible) for c in controls]),
    }
    report = _edit_report(kind, frames_out, out_frames, source, skin, controls, jaw, seconds)
    edit: dict[str, Any] = {"kind": kind}
    if kind == "scale_force_length":
        edit["force_length_scale"] = scale
    elif kind == "interpolate":
        edit.update({"from_frame": a_frame, "to_frame": b_frame, "n_frames": n})
    else:
        edit.update({"centre_mm": start_centre.tolist(), "centre_to_mm": end_centre.tolist(), "radius_mm": radius,
                     "penetration_tolerance_mm": float(penetration_tolerance_mm)})
    report["edit"] = edit
    same_frames = kind != "interpolate"
    metadata = {
        "source_files": {"model": str(model_path), "result": str(source.folder)},
        "source_units": info.get("source_units", {}),
        "method": EDIT_METHOD,
        "edit": edit,
        "frame": info.get("frame"),
        "frames": info.get("frames") if same_frames else [0, n],
        "first_frame": info.get("first_frame") if same_frames else 0,
        "parameters": {"solver": options, "model_sha256": solved_on, "source_parameters": parameters},
        "muscles": list(anatomy.muscle_names),
        "markers": list(info.get("markers", [])) if same_frames else [],
    }
    extra = {}
    for name in ("markers.npy", "head_motion.npy"):
        path = source.folder / name
        if path.is_file():
            array = np.load(path)
            if same_frames:
                extra[name] = array
            elif name == "head_motion.npy":  # rigid: interpolated as the cranium is
                extra[name] = interpolate_rigid_motions(array[ia], array[ib], n)
    scan = anatomy.scan_mesh()
    stage(f"writing {out_dir}")
    final = write_muscle_result(out_dir, scan, float(info.get("rate", 60.0)), out_frames, anatomy.muscle_names,
                                arrays, report=report, metadata=metadata, extra_arrays=extra, exports=exports,
                                progress=progress, timings=timings, started=t_all, write_started=t,
                                desc="edit-muscles", export_options=export_options, overwrite=overwrite)
    return MuscleEditResult(Path(final), n, report)


def _edit_report(kind: str, frames: list[EditedFrame], numbers: IntArray, source: _Source, skin: np.ndarray,
                 controls: list[MuscleControls], jaw: JawConstraints, seconds: list[float]) -> dict[str, Any]:
    """``report.json`` of an edit: per-frame convergence, the change of the skin, the sphere's contact."""
    def rounded(values: Iterable[float], digits: int = 5) -> list[float]:
        return [round(float(v), digits) for v in values]

    report: dict[str, Any] = {
        "n_frames": len(frames),
        "frames": [int(f) for f in numbers],
        "n_vertices": int(skin.shape[1]),
        "newton_iterations": [f.iterations for f in frames],
        "converged": [f.converged for f in frames],
        "not_converged_frames": [int(numbers[j]) for j, f in enumerate(frames) if not f.converged],
        "residual_mn": rounded((f.residual_mn for f in frames), 6),
        "inverted_tets": [f.inverted_tets for f in frames],
        "seconds_per_frame": rounded(seconds, 4),
        "activations_range": [float(min(c.activations.min() for c in controls)),
                              float(max(c.activations.max() for c in controls))],
        "jaw_violation_max": float(max(jaw.violations(c.mandible).max() for c in controls)),
    }
    if kind != "interpolate":
        before = read_result(source.folder)
        change = np.empty((len(frames), 2))
        for j in range(len(frames)):
            d = np.linalg.norm(skin[j].astype(np.float64) - before.frames(j, j + 1)[0].astype(np.float64) * before.mm_per_unit,
                               axis=1)
            change[j] = d.mean(), d.max()
        report["skin_change_mm"] = {"per_frame_mean": rounded(change[:, 0]), "per_frame_max": rounded(change[:, 1]),
                                    "max": float(change[:, 1].max())}
    if kind == "sphere":
        spheres = [f.sphere for f in frames]
        assert all(s is not None for s in spheres)
        report["sphere"] = {
            "radius_mm": spheres[0].radius_mm,  # type: ignore[union-attr]
            "centre_mm": [rounded(s.centre, 4) for s in spheres],  # type: ignore[union-attr]
            "stiffness_mn_per_mm": [s.stiffness for s in spheres],  # type: ignore[union-attr]
            "stiffness_raises": [s.stiffness_raises for s in spheres],  # type: ignore[union-attr]
            "skin_node_penetration_mm": rounded((s.skin_node_penetration_mm for s in spheres), 6),  # type: ignore[union-attr]
            "scan_penetration_mm": rounded((s.scan_penetration_mm for s in spheres), 6),  # type: ignore[union-attr]
            "max_skin_node_penetration_mm": max(s.skin_node_penetration_mm for s in spheres),  # type: ignore[union-attr]
            "max_scan_penetration_mm": max(s.scan_penetration_mm for s in spheres),  # type: ignore[union-attr]
            "contact_points": [s.contact_points for s in spheres],  # type: ignore[union-attr]
            "force_mn": [rounded(s.force_mn, 3) for s in spheres],  # type: ignore[union-attr]
        }
    return report
