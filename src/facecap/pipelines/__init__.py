"""The jobs each command runs: thin sequences of solver calls, from the files a user gives to the folder written.

Directly under :mod:`facecap.cli` (docs/architecture.md): a job reads and checks its inputs,
calls the solver packages (arrays in, arrays out), and writes the result through
:mod:`facecap.io`; no solver package imports a job.

- :func:`animate_scan` (``animate_scan.py``): ``facecap animate``, a scan animated by a take
  (Bickel et al. 2007, section 4: the warp, the marker offsets, the thin shell), streamed to
  a result folder, as an :class:`AnimationResult`.
- :func:`capture_wrinkles` (``capture_wrinkles.py``): ``facecap wrinkles``, the wrinkle layer
  (section 5) over a whole take on the frame runner, as a :class:`WrinkleCapture`.
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

The other commands' jobs still live in their solver packages (issue 29): ``blend`` and the scan
workflow in :mod:`facecap.blendshapes`.

The functions share their modules' names, so ``facecap.pipelines.animate_scan`` is the
function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .animate_scan import OFFSET_WARNING_MM, AnimationResult, animate_scan
from .capture_wrinkles import WrinkleCapture, capture_wrinkles
from .edit_muscles import EDIT_METHOD, MuscleEditResult, edit_muscles
from .solve_muscle_take import RIGID_FIT_LIMIT_MM, MuscleTakeResult, solve_muscle_take
from .write_muscle_result import ACTIVATIONS_FILE, BONE_TRANSFORMS_FILE, plot_muscle_activations, write_muscle_result

__all__ = ["animate_scan", "AnimationResult", "OFFSET_WARNING_MM", "capture_wrinkles", "WrinkleCapture",
           "edit_muscles", "MuscleEditResult", "EDIT_METHOD", "solve_muscle_take", "MuscleTakeResult",
           "RIGID_FIT_LIMIT_MM", "write_muscle_result", "plot_muscle_activations", "ACTIVATIONS_FILE",
           "BONE_TRANSFORMS_FILE"]
