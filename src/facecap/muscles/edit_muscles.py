"""Editing a solved take in muscle space (Sifakis et al. 2005, sec. 9): ``facecap edit-muscles``.

Once a take's controls are solved (``facecap solve-muscles``), the same face model re-solved
under edited controls gives physically valid faces:

- **interpolation** between two solved frames, activations linearly and the bones as rigid
  motions (the cranium by slerp, the jaw through its joint's pose), each in-between frame a
  quasistatic solve (the paper's figure 10);
- **exaggeration** beyond the attainable by scaling the force-length curve of every muscle,
  the activations unchanged (figure 8: "it would be inadvisable to do so by extending the
  activation values beyond 1");
- **a kinematic sphere** pressing on the face under each frame's controls, by a penalty
  contact energy in the quasistatic solve (figure 9).

:class:`MuscleEditor` is the per-frame solve (set-up once); :func:`interpolate_controls` the
in-between controls; :func:`edit_muscles` reads a result folder and writes another.
"""

from __future__ import annotations

import csv
import os
import sys
import time
from pathlib import Path
from typing import Any, Iterable, Literal, Mapping, NamedTuple, Sequence

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation, Slerp

from ..anatomy.build_anatomy import boundary_nodes
from ..errors import FileFormatError, InputError
from ..typing import FloatArray, IntArray
from .jaw_constraints import JawConstraints
from .muscle_controls import MuscleControls
from .muscle_model import MuscleModel, apply_affine

__all__ = ["MuscleEditor", "EditedFrame", "SphereReport", "interpolate_controls", "edit_muscles",
           "MuscleEditResult", "DEFAULT_PENETRATION_TOLERANCE_MM", "EDIT_METHOD"]

DEFAULT_PENETRATION_TOLERANCE_MM = 0.05
"""Largest penetration of a contact point (skin node or scan vertex) into the sphere, mm; the penalty
stiffness is raised tenfold until it holds."""
DEFAULT_STIFFNESS_FACTOR = 1000.0
"""The first penalty stiffness, in units of the flesh's ``mu h`` (shear modulus times mean edge)."""
DEFAULT_INTERPOLATION_FRAMES = 30
_MAX_STIFFNESS_RAISES = 5
EDIT_METHOD = "sifakis2005-muscle-edit"
"""``performance.json``'s ``method`` of an edited result."""
_MODEL_OPTIONS = ("rim", "backend", "tolerance", "muscle_strength")  # of the solver options, the model's


class SphereReport(NamedTuple):
    """The sphere's contact in one edited frame.

    Attributes
    ----------
    centre : (3,) float64 array, mm
        World (the result's coordinates).
    radius_mm : float
    stiffness : float, mN / mm
        The penalty stiffness the frame ended with.
    stiffness_raises : int
        Tenfold raises needed in this frame to meet the tolerance.
    skin_node_penetration_mm : float
        Deepest flesh node of the skin surface inside the sphere (0: none inside).
    scan_penetration_mm : float
        Deepest scan vertex (the output skin, every vertex) inside the sphere.
    contact_points : int
        Contact points (skin nodes and scan vertices) inside the sphere.
    force_mn : (3,) float64 array, mN
        The sphere's total force on the face, world.
    """

    centre: FloatArray
    radius_mm: float
    stiffness: float
    stiffness_raises: int
    skin_node_penetration_mm: float
    scan_penetration_mm: float
    contact_points: int
    force_mn: FloatArray


class EditedFrame(NamedTuple):
    """One frame solved by :meth:`MuscleEditor.solve`.

    Attributes
    ----------
    skin : (n_scan, 3) float64 array, mm
        The scan's vertices, world (the cranium applied), in the scan's order.
    nodes : (N, 3) float64 array, mm
        The equilibrium flesh nodes in the cranium's frame (the next frame's warm start).
    converged : bool
    iterations : int
        Newton iterations (summed over the stiffness raises).
    residual_mn : float
        Largest free nodal residual force, mN.
    inverted_tets : int
    sphere : SphereReport or None
    """

    skin: FloatArray
    nodes: FloatArray
    converged: bool
    iterations: int
    residual_mn: float
    inverted_tets: int
    sphere: SphereReport | None = None


def _polar_rotation(M: FloatArray) -> FloatArray:
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:  # not a solved frame (those are rigid to 1e-5); keep it proper
        U[:, -1] *= -1
        R = U @ Vt
    return R


def _rigid_path(start: FloatArray, end: FloatArray, s: FloatArray) -> FloatArray:
    """Rigid frames ``(len(s), 3, 4)`` from ``start`` to ``end`` (3, 4): rotation by slerp, translation linearly."""
    rotations = Rotation.from_matrix(np.stack([_polar_rotation(start[:, :3]), _polar_rotation(end[:, :3])]))
    R = Slerp([0.0, 1.0], rotations)(s).as_matrix()
    t = (1.0 - s)[:, None] * start[:, 3] + s[:, None] * end[:, 3]
    return np.concatenate([R, t[:, :, None]], axis=2)


def interpolate_controls(start: MuscleControls, end: MuscleControls, jaw: JawConstraints,
                         n_frames: int = DEFAULT_INTERPOLATION_FRAMES) -> list[MuscleControls]:
    """Controls from ``start`` to ``end`` in activation and kinematic space (the paper's figure 10).

    Parameters
    ----------
    start, end : MuscleControls
        Solved controls (two frames of a result).
    jaw : JawConstraints
        The model's joint (``MuscleModel.jaw``).
    n_frames : int, default 30
        Frames of the path, both ends included (at least 2): ``s = j / (n_frames - 1)``.

    Returns
    -------
    list of MuscleControls
        Activations ``(1 - s) a_A + s a_B`` clipped to [0, 1]; the cranium's rotation (the
        polar rotation of ``M_c``) by slerp and its translation linearly; the mandible
        :meth:`JawConstraints.transform` of the linearly interpolated :meth:`JawConstraints.pose`
        (opening, two slides), each end's pose first clipped to the joint's limits (opening in
        ``[0, max_opening_rad]``, slides in ``[0, track_length_mm]``), so every frame meets
        psi1-psi6 exactly (the allowed poses are a box).

    Notes
    -----
    The ends are the rigid frames on the joint nearest the solved ones: a solved frame is rigid,
    and on its joint, to the solver's tolerance (1e-5), so the ends reproduce the solved faces to
    about 1e-5 of the face's size (measured: within 0.003 mm).

    Examples
    --------
    >>> jaw = JawConstraints(np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.array([0.0, 40, -60]), 100.0)
    >>> a = MuscleControls(np.zeros(2), np.eye(3, 4), jaw.transform(0.0))
    >>> b = MuscleControls(np.ones(2), np.eye(3, 4), jaw.transform(0.2, 2.0, 1.0))
    >>> mid = interpolate_controls(a, b, jaw, 3)[1]
    >>> mid.activations.tolist(), np.round(jaw.pose(mid.mandible), 6).tolist()
    ([0.5, 0.5], [0.1, 1.0, 0.5])
    """
    for name, c in (("start", start), ("end", end)):
        if not isinstance(c, MuscleControls):
            raise InputError(f"{name}: expected MuscleControls, got {type(c).__name__}")
    if start.n_muscles != end.n_muscles:
        raise InputError(f"start and end: {start.n_muscles} and {end.n_muscles} activations")
    if int(n_frames) < 2:
        raise InputError(f"n_frames: expected at least 2 (both ends), got {n_frames}")
    s = np.linspace(0.0, 1.0, int(n_frames))
    activations = np.clip((1.0 - s)[:, None] * start.activations + s[:, None] * end.activations, 0.0, 1.0)
    cranium = _rigid_path(start.cranium, end.cranium, s)
    # the ends' poses on the joint's limits (a solved jaw meets them to the solver's 1e-5): every frame then
    # meets psi1-psi6 exactly, the allowed poses being a box
    lower = np.zeros(3)
    upper = np.array([jaw.max_opening_rad, jaw.track_length_mm, jaw.track_length_mm])
    pose_a = np.clip(jaw.pose(start.mandible), lower, upper)
    pose_b = np.clip(jaw.pose(end.mandible), lower, upper)
    poses = (1.0 - s)[:, None] * pose_a + s[:, None] * pose_b
    return [MuscleControls(a, c, jaw.transform(*p)) for a, c, p in zip(activations, cranium, poses)]


class MuscleEditor:
    """Quasistatic faces of edited controls: set-up once, one :meth:`solve` per frame.

    Parameters
    ----------
    anatomy : FaceAnatomy
    force_length_scale : float, default 1
        Every muscle's force-length curve (active and passive) scaled by this (positive):
        the paper's exaggeration (sec. 9, figure 8), see :class:`~facecap.fem.FleshModel`.
    penetration_tolerance_mm : float, default 0.05
        A sphere's contact: the penalty stiffness is raised tenfold (up to 5 times per frame)
        until no contact point is deeper than this inside the sphere.
    stiffness : float, mN / mm, optional
        The first penalty stiffness; default 1000 ``mu h`` (the flesh's shear modulus times
        its mean edge length: about 70 000 mN/mm on the test model).
    max_iterations : int, default 100
        Newton iterations of one quasistatic solve (a sphere pressed 6 mm into the coarse
        test face takes about 60 from the face without it).
    **model_options
        :class:`MuscleModel` options (``rim``, ``backend``, ``tolerance``, ``muscle_strength``,
        ...): those the take was solved with.

    Attributes
    ----------
    model : MuscleModel
    skin_nodes : (s,) int64 array
        Flesh nodes on the skin surface: the tetrahedral mesh's boundary nodes less the bone
        (cranium, mandible) and rim nodes.
    contact_points : (s + v, N) scipy.sparse.csr_matrix
        The sphere's contact points over the nodes: the skin nodes, then the scan vertices
        that follow the flesh (their embedding weights).
    """

    def __init__(self, anatomy: Any, *, force_length_scale: float = 1.0,
                 penetration_tolerance_mm: float = DEFAULT_PENETRATION_TOLERANCE_MM,
                 stiffness: float | None = None, max_iterations: int = 100, **model_options: Any) -> None:
        if not (np.isfinite(force_length_scale) and force_length_scale > 0):
            raise InputError(f"force_length_scale: expected a positive value, got {force_length_scale!r}")
        if not (np.isfinite(penetration_tolerance_mm) and penetration_tolerance_mm > 0):
            raise InputError(f"penetration_tolerance_mm: expected a positive value, got {penetration_tolerance_mm!r}")
        self.anatomy = anatomy
        self.model = MuscleModel(anatomy, force_length_scale=float(force_length_scale), **model_options)
        self.model.solver.max_iterations = int(max_iterations)
        self.force_length_scale = float(force_length_scale)
        self.penetration_tolerance_mm = float(penetration_tolerance_mm)
        flesh = self.model.flesh
        self.initial_stiffness = (DEFAULT_STIFFNESS_FACTOR * flesh.material.shear_modulus_kpa * flesh.mean_edge_mm
                                  if stiffness is None else float(stiffness))
        if not (np.isfinite(self.initial_stiffness) and self.initial_stiffness > 0):
            raise InputError(f"stiffness: expected a positive value, mN/mm, got {stiffness!r}")
        held = np.concatenate([self.model.cranium_set, self.model.mandible_set, np.asarray(anatomy.rim_nodes)])
        self.skin_nodes: IntArray = np.setdiff1d(boundary_nodes(np.asarray(anatomy.tets)), held).astype(np.int64)
        N = self.model.flesh.n_nodes
        nodes = sp.csr_matrix((np.ones(self.skin_nodes.size), (np.arange(self.skin_nodes.size), self.skin_nodes)),
                              shape=(self.skin_nodes.size, N))
        self.contact_points = sp.vstack([nodes, anatomy.skin_matrix()[np.flatnonzero(self.model.skin_follows)]]).tocsr()

    @property
    def n_muscles(self) -> int:
        """k."""
        return self.model.n_muscles

    def solve(self, controls: MuscleControls, x0: FloatArray | None = None, *,
              sphere: tuple[Any, float] | None = None, stiffness: float | None = None) -> EditedFrame:
        """The quasistatic face of ``controls`` (and a sphere, if given).

        Parameters
        ----------
        controls : MuscleControls
            Activations are clipped to [0, 1].
        x0 : (N, 3) float64 array, mm, optional
            Initial nodes in the cranium's frame (the previous frame's ``nodes``); default rest.
        sphere : (centre, radius_mm), optional
            A kinematic sphere, centre ``(3,)`` mm in world coordinates (the result's): its
            penalty contact :class:`~facecap.fem.SphereContact` on :attr:`contact_points` joins
            the solve, in the cranium's frame.
        stiffness : float, mN / mm, optional
            The contact's first penalty stiffness (default :attr:`initial_stiffness`; pass the
            previous frame's ``sphere.stiffness`` to start where it ended).

        Returns
        -------
        EditedFrame
        """
        from ..fem import SphereContact

        if not isinstance(controls, MuscleControls) or controls.n_muscles != self.n_muscles:
            raise InputError(f"controls: expected MuscleControls with {self.n_muscles} activations")
        a = np.clip(controls.activations, 0.0, 1.0)
        model = self.model
        bones = model.bone_positions(controls.mandible)
        x = model.rest_positions if x0 is None else np.asarray(x0, dtype=np.float64)
        if sphere is None:
            result = model.solver.solve(a, bones, x0=x)
            skin = apply_affine(controls.cranium, model.skin(result.positions))
            return EditedFrame(skin, result.positions, bool(result.converged), int(result.iterations),
                               float(result.residual), int(result.inverted_tets))
        centre, radius = sphere
        centre = np.asarray(centre, dtype=np.float64).reshape(-1)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise InputError("sphere: expected a finite centre (3,) mm")
        if not (np.isfinite(radius) and radius > 0):
            raise InputError(f"sphere: expected a positive radius, mm, got {radius!r}")
        # the flesh is solved in the cranium's frame: the sphere goes there (M_c is rigid)
        Mc, tc = controls.cranium[:, :3], controls.cranium[:, 3]
        local = np.linalg.solve(Mc, centre - tc)
        k = self.initial_stiffness if stiffness is None else float(stiffness)
        iterations = raises = 0
        while True:
            contact = SphereContact(self.contact_points, local, float(radius), stiffness=k)
            result = model.solver.solve(a, bones, x0=x, external=contact)
            iterations += int(result.iterations)
            x = result.positions
            if (contact.penetration(x).max() <= self.penetration_tolerance_mm or raises >= _MAX_STIFFNESS_RAISES
                    or not result.converged):
                break
            k *= 10.0
            raises += 1
        skin = apply_affine(controls.cranium, model.skin(x))
        nodes_world = apply_affine(controls.cranium, x[self.skin_nodes])
        depth_nodes = np.maximum(radius - np.linalg.norm(nodes_world - centre, axis=1), 0.0)
        depth_scan = np.maximum(radius - np.linalg.norm(skin - centre, axis=1), 0.0)
        report = SphereReport(centre, float(radius), k, raises, float(depth_nodes.max(initial=0.0)),
                              float(depth_scan.max(initial=0.0)), int(np.count_nonzero(contact.penetration(x))),
                              Mc @ contact.point_forces(x).sum(axis=0))
        return EditedFrame(skin, x, bool(result.converged), iterations, float(result.residual),
                           int(result.inverted_tets), report)


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
    from ..io.result_layout import read_performance_info
    from .solve_muscle_take import ACTIVATIONS_FILE, BONE_TRANSFORMS_FILE

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
        The edited result, the same layout (:func:`~facecap.muscles.solve_muscle_take`'s
        writer; written atomically).
    scale_force_length : float, optional
        Re-solve every frame with every muscle's force-length curve scaled by this (positive;
        the paper's exaggeration beyond the attainable), the activations unchanged.
    interpolate : (A, B), optional
        Two frames of the result (the numbers of ``activations.csv``'s ``frame`` column):
        ``n_frames`` frames from A to B (:func:`interpolate_controls`), numbered 0..n-1.
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
        See :class:`MuscleEditor`.
    exports, progress, export_options, overwrite
        As for :func:`~facecap.muscles.solve_muscle_take` (an earlier result in ``out_dir`` is
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
    from ..anatomy import load_anatomy
    from ..io.result_layout import parse_export_formats
    from ..io.atomic_write import resolve_recorded_path
    from ..io.write_performance import check_result_destination
    from ..pipelines.finish_result import import_writers
    from .muscle_frame_stage import model_folder_sha256
    from .solve_muscle_take import write_muscle_result

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
                extra[name] = _interpolated_motion(array[ia], array[ib], n)
    scan = anatomy.scan_mesh()
    stage(f"writing {out_dir}")
    final = write_muscle_result(out_dir, scan, float(info.get("rate", 60.0)), out_frames, anatomy.muscle_names,
                                arrays, report=report, metadata=metadata, extra_arrays=extra, exports=exports,
                                progress=progress, timings=timings, started=t_all, write_started=t,
                                desc="edit-muscles", export_options=export_options, overwrite=overwrite)
    return MuscleEditResult(Path(final), n, report)


def _interpolated_motion(start: FloatArray, end: FloatArray, n: int) -> FloatArray:
    """Rigid 4 x 4 motions from ``start`` to ``end`` (slerp, linear translation), (n, 4, 4)."""
    path = _rigid_path(np.asarray(start, dtype=np.float64)[:3], np.asarray(end, dtype=np.float64)[:3],
                       np.linspace(0.0, 1.0, n))
    out = np.zeros((n, 4, 4))
    out[:, :3] = path
    out[:, 3, 3] = 1.0
    return out.astype(np.asarray(start).dtype)


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
        from ..io import read_result

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
