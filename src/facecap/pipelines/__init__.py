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
- :func:`finish_result` (``finish_result.py``): the end every job's result folder shares: the
  exports made from the finished frames, ``review.html`` and ``report.html``, then the writer's
  rename; :func:`import_writers` imports what they need ahead of time.
- :func:`export_result` (``export_result.py``): ``facecap export`` (and ``--export``), a finished
  result written to artists' formats; its glTF review file is :func:`write_gltf_review`
  (``write_gltf_review.py``: a decimated review mesh and the take's principal morph targets).
- :func:`view_result` (``view_result.py``): ``facecap view``, the review page of a result (its
  glTF made if missing, the error heat map against a truth) and its report.

The other commands' jobs still live in their solver packages (issue 29): ``solve-muscles`` and
``edit-muscles`` in :mod:`facecap.muscles`.

The functions share their modules' names, so ``facecap.pipelines.animate_scan`` is the
function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .animate_scan import OFFSET_WARNING_MM, AnimationResult, animate_scan
from .blend_take import blend_take
from .capture_wrinkles import WrinkleCapture, capture_wrinkles
from .export_result import DEFAULT_GLTF_TARGETS, DEFAULT_REVIEW_VERTICES, MAX_ERROR_PASS_FLOPS, export_result
from .finish_result import finish_result, import_writers
from .map_markers import map_markers, map_side_files
from .plan_scans import conditioned_take_path, plan_scans
from .register_planned_scans import register_planned_scans
from .replay_conditioning import replay_conditioning
from .view_result import ERROR_ROWS, view_result
from .write_blended_performance import write_blended_performance
from .write_gltf_review import write_gltf_review

__all__ = [
    "animate_scan",
    "AnimationResult",
    "OFFSET_WARNING_MM",
    "capture_wrinkles",
    "WrinkleCapture",
    "plan_scans",
    "conditioned_take_path",
    "register_planned_scans",
    "blend_take",
    "replay_conditioning",
    "write_blended_performance",
    "map_markers",
    "map_side_files",
    "finish_result",
    "import_writers",
    "export_result",
    "DEFAULT_GLTF_TARGETS",
    "DEFAULT_REVIEW_VERTICES",
    "MAX_ERROR_PASS_FLOPS",
    "write_gltf_review",
    "view_result",
    "ERROR_ROWS",
]
