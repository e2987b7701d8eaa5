"""Editing in muscle space (Sifakis et al. 2005, sec. 9): a solved take's controls re-solved, edited.

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
in-between controls, :func:`interpolate_rigid_motions` the same path for a rigid 4 x 4 motion (a
result's head motion). The job of ``facecap edit-muscles``, a result folder read and another
written, is :func:`facecap.pipelines.edit_muscles`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation, Slerp

from ..anatomy.build_anatomy import boundary_nodes
from ..errors import InputError
from ..rotations import nearest_rotation
from ..typing import FloatArray, IntArray
from .jaw_constraints import JawConstraints
from .muscle_controls import MuscleControls
from .muscle_model import MuscleModel, apply_affine

__all__ = ["MuscleEditor", "EditedFrame", "SphereReport", "interpolate_controls", "interpolate_rigid_motions",
           "DEFAULT_PENETRATION_TOLERANCE_MM", "DEFAULT_INTERPOLATION_FRAMES"]

DEFAULT_PENETRATION_TOLERANCE_MM = 0.05
"""Largest penetration of a contact point (skin node or scan vertex) into the sphere, mm; the penalty
stiffness is raised tenfold until it holds."""
DEFAULT_STIFFNESS_FACTOR = 1000.0
"""The first penalty stiffness, in units of the flesh's ``mu h`` (shear modulus times mean edge)."""
DEFAULT_INTERPOLATION_FRAMES = 30
"""Frames of an interpolation, both ends included (:func:`interpolate_controls`)."""
_MAX_STIFFNESS_RAISES = 5


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


def _rigid_path(start: FloatArray, end: FloatArray, s: FloatArray) -> FloatArray:
    """Rigid frames ``(len(s), 3, 4)`` from ``start`` to ``end`` (3, 4): rotation by slerp, translation linearly."""
    rotations = Rotation.from_matrix(np.stack([nearest_rotation(start[:, :3]), nearest_rotation(end[:, :3])]))
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


def interpolate_rigid_motions(start: FloatArray, end: FloatArray, n_frames: int) -> FloatArray:
    """Rigid 4 x 4 motions from ``start`` to ``end``, as :func:`interpolate_controls` moves the cranium.

    Parameters
    ----------
    start, end : (4, 4) float array
        Rigid motions (a result's ``head_motion.npy`` rows); the bottom row is not read.
    n_frames : int
        Frames of the path, both ends included: ``s = j / (n_frames - 1)``.

    Returns
    -------
    (n_frames, 4, 4) array, ``start``'s dtype
        The rotation (the polar rotation of each end's 3 x 3 part) by slerp, the translation
        linearly, the bottom row ``(0, 0, 0, 1)``.
    """
    path = _rigid_path(np.asarray(start, dtype=np.float64)[:3], np.asarray(end, dtype=np.float64)[:3],
                       np.linspace(0.0, 1.0, n_frames))
    out = np.zeros((n_frames, 4, 4))
    out[:, :3] = path
    out[:, 3, 3] = 1.0
    return out.astype(np.asarray(start).dtype)


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
