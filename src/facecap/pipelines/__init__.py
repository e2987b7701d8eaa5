"""The jobs each command runs: thin sequences of solver calls, from the files a user gives to the folder written.

Directly under :mod:`facecap.cli` (docs/architecture.md): a job reads and checks its inputs,
calls the solver packages (arrays in, arrays out), and writes the result through
:mod:`facecap.io`; no solver package imports a job.

- :func:`animate_scan` (``animate_scan.py``): ``facecap animate``, a scan animated by a take
  (Bickel et al. 2007, section 4: the warp, the marker offsets, the thin shell), streamed to
  a result folder, as an :class:`AnimationResult`.
- :func:`capture_wrinkles` (``capture_wrinkles.py``): ``facecap wrinkles``, the wrinkle layer
  (section 5) over a whole take on the frame runner, as a :class:`WrinkleCapture`.
- The scan workflow of Huang et al. 2011, a command a step: :func:`plan_scans`
  (``plan_scans.py``): ``facecap plan-scans``, the frames to scan written as ``plan.json``
  (:func:`conditioned_take_path`: where the conditioned take is kept beside it);
  :func:`register_planned_scans` (``register_planned_scans.py``): ``facecap register-scans``,
  the scans registered into a bases folder; :func:`blend_take` (``blend_take.py``):
  ``facecap blend``, every frame of the take rebuilt from the bases. All three condition the
  take once, as the plan recorded it: :func:`replay_conditioning` (``replay_conditioning.py``).
- :func:`write_blended_performance` (``write_blended_performance.py``): the result folder of a
  performance from bases and weights, as ``blend`` writes it.
- :func:`map_markers` (``map_markers.py``): ``facecap map``, a take's markers placed on a scan and
  written as ``map.json`` with its report and picture (:func:`map_side_files` names those two).
- :func:`edit_muscles` (``edit_muscles.py``): ``facecap edit-muscles``, a ``solve-muscles`` result
  edited in muscle space (Sifakis et al. 2005, sec. 9) and written as a new result folder, as a
  :class:`MuscleEditResult` (its ``performance.json`` says :data:`EDIT_METHOD`).
- :func:`solve_muscle_take` (``solve_muscle_take.py``): ``facecap solve-muscles``, a take solved
  for muscle activations, cranium and jaw (Sifakis et al. 2005) on the frame runner, from an
  anatomy model folder, as a :class:`MuscleTakeResult`; :data:`RIGID_FIT_LIMIT_MM` decides the
  retarget.
- :func:`write_muscle_result` (``write_muscle_result.py``): the result folder of both muscle jobs,
  ``animate``'s plus :data:`ACTIVATIONS_FILE`, :data:`BONE_TRANSFORMS_FILE` and the activation
  picture (:func:`plot_muscle_activations`).

Not here yet (issue 29): ``export`` and ``view`` (in :mod:`facecap.io` and :mod:`facecap.report`) and the demo.

The functions share their modules' names, so ``facecap.pipelines.animate_scan`` is the
function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .animate_scan import OFFSET_WARNING_MM, AnimationResult, animate_scan
from .blend_take import blend_take
from .capture_wrinkles import WrinkleCapture, capture_wrinkles
from .edit_muscles import EDIT_METHOD, MuscleEditResult, edit_muscles
from .map_markers import map_markers, map_side_files
from .plan_scans import conditioned_take_path, plan_scans
from .register_planned_scans import register_planned_scans
from .replay_conditioning import replay_conditioning
from .solve_muscle_take import RIGID_FIT_LIMIT_MM, MuscleTakeResult, solve_muscle_take
from .write_blended_performance import write_blended_performance
from .write_muscle_result import ACTIVATIONS_FILE, BONE_TRANSFORMS_FILE, plot_muscle_activations, write_muscle_result

__all__ = [
    "animate_scan", "AnimationResult", "OFFSET_WARNING_MM",
    "capture_wrinkles", "WrinkleCapture",
    "plan_scans", "conditioned_take_path", "register_planned_scans", "blend_take", "replay_conditioning",
    "write_blended_performance",
    "map_markers", "map_side_files",
    "edit_muscles", "MuscleEditResult", "EDIT_METHOD",
    "solve_muscle_take", "MuscleTakeResult", "RIGID_FIT_LIMIT_MM",
    "write_muscle_result", "plot_muscle_activations", "ACTIVATIONS_FILE", "BONE_TRANSFORMS_FILE",
]
