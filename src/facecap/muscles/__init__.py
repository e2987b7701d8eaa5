"""The controls of the muscle-driven face: activations and bone frames from markers (Sifakis et al. 2005, sec. 5-8).

In the order the solver uses them:

- :class:`MuscleControls` (``muscle_controls.py``): activations ``(k,)`` and the cranium
  and mandible as affine frames ``(3, 4)``, packed as one control vector.
- :class:`JawConstraints` (``jaw_constraints.py``): the temporomandibular joint, psi1-psi6
  (condyles sliding on two parallel tracks, the opening angle bounded), its rigid
  transforms and poses.
- :func:`control_penalty`, :class:`ControlPenalty` (``control_penalty.py``): the feasibility
  penalty ``phi_p`` (activations in [0, 1], rigidity ``|M^T M - I|_F^2``, the jaw terms) with
  its gradient and positive semi-definite Hessian.
- :class:`MuscleModel` (``muscle_model.py``): the flesh model of an anatomy driven by the
  controls, its equilibrium and the Jacobians of eq. 5 and 6.
- :func:`marker_embedding`, :class:`MarkerEmbedding` (``marker_embedding.py``): each marker as
  a barycentric point of the tetrahedral mesh with its rest offset.
- :func:`forward_markers`, :class:`ForwardMarkers` (``forward_markers.py``): markers from
  known controls (the forward model the solver inverts).
- :class:`MuscleSolver`, :class:`MuscleFrame` (``muscle_solver.py``): Gauss-Newton on the
  linearised marker objective with the penalty continuation and a golden-section line
  search; set-up once, ``solve_frame(markers, previous)`` per frame.
- :func:`solve_muscles`, :class:`MuscleTake` (``solve_muscles.py``): every frame of a take,
  each warm-started from the one before.
- :class:`MuscleFrameStage` (``muscle_frame_stage.py``): the solve as a frame-runner stage
  (chunks of frames on Dask, resumable; the model and solver built once per process), its
  per-frame :data:`FRAME_FLAGS` bit mask (:func:`flag_names`; :data:`FRAME_FLAG_MEANINGS` says what each
  flag means) and :func:`model_folder_sha256`.
- :class:`MuscleEditor`, :func:`interpolate_controls`, :func:`interpolate_rigid_motions`
  (``muscle_editor.py``): editing in muscle space (sec. 9), what ``facecap edit-muscles``
  (:func:`facecap.pipelines.edit_muscles`) solves: two frames interpolated in activation and bone
  space, an expression exaggerated by scaling the force-length curves, a kinematic sphere pressing
  on the face; each frame a quasistatic solve.

Units: mm, radians; see ``docs/muscles.md``.
"""

from __future__ import annotations

from .control_penalty import ControlPenalty, control_penalty
from .forward_markers import ForwardMarkers, forward_markers
from .jaw_constraints import JawConstraints
from .marker_embedding import DEFAULT_MAX_OFFSET_MM, MarkerEmbedding, marker_embedding
from .muscle_controls import MuscleControls
from .muscle_model import FOLLOWER_WEIGHT_LIMIT, MuscleModel
from .muscle_solver import MuscleFrame, MuscleSolver
from .solve_muscles import MuscleTake, solve_muscles
from .muscle_frame_stage import FRAME_FLAG_MEANINGS, FRAME_FLAGS, MuscleFrameStage, flag_names, model_folder_sha256
from .muscle_editor import (DEFAULT_INTERPOLATION_FRAMES, DEFAULT_PENETRATION_TOLERANCE_MM, EditedFrame, MuscleEditor,
                            SphereReport, interpolate_controls, interpolate_rigid_motions)

__all__ = [
    "DEFAULT_INTERPOLATION_FRAMES",
    "DEFAULT_PENETRATION_TOLERANCE_MM",
    "EditedFrame",
    "MuscleEditor",
    "SphereReport",
    "interpolate_controls",
    "interpolate_rigid_motions",
    "FRAME_FLAGS",
    "FRAME_FLAG_MEANINGS",
    "MuscleFrameStage",
    "flag_names",
    "model_folder_sha256",
    "ControlPenalty",
    "DEFAULT_MAX_OFFSET_MM",
    "FOLLOWER_WEIGHT_LIMIT",
    "ForwardMarkers",
    "JawConstraints",
    "MarkerEmbedding",
    "MuscleControls",
    "MuscleFrame",
    "MuscleModel",
    "MuscleSolver",
    "MuscleTake",
    "control_penalty",
    "forward_markers",
    "marker_embedding",
    "solve_muscles",
]
