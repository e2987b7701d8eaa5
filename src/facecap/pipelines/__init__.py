"""The jobs each command runs: thin sequences of solver calls, from the files a user gives to the folder written.

Directly under :mod:`facecap.cli` (docs/architecture.md): a job reads and checks its inputs,
calls the solver packages (arrays in, arrays out), and writes the result through
:mod:`facecap.io`; no solver package imports a job.

- :func:`animate_scan` (``animate_scan.py``): ``facecap animate``, a scan animated by a take
  (Bickel et al. 2007, section 4: the warp, the marker offsets, the thin shell), streamed to
  a result folder, as an :class:`AnimationResult`.
- :func:`capture_wrinkles` (``capture_wrinkles.py``): ``facecap wrinkles``, the wrinkle layer
  (section 5) over a whole take on the frame runner, as a :class:`WrinkleCapture`.
- :func:`capture_detail` (``capture_detail.py``): ``facecap detail``, fine detail by space-time
  shape from shading (Lo et al.) on a result, on the frame runner, as a :class:`DetailCapture`.
- The scan workflow of Huang et al. 2011, a command a step: :func:`plan_scans`
  (``plan_scans.py``): ``facecap plan-scans``, the frames to scan written as ``plan.json``
  (:func:`conditioned_take_path`: where the conditioned take is kept beside it);
  :func:`register_planned_scans` (``register_planned_scans.py``): ``facecap register-scans``,
  the scans registered into a bases folder; :func:`blend_take` (``blend_take.py``):
  ``facecap blend``, every frame of the take rebuilt from the bases. All three condition the
  take once, as the plan recorded it: :func:`replay_conditioning` (``replay_conditioning.py``).
  :func:`run_scan_workflow` (``run_scan_workflow.py``): ``facecap scans-pipeline``, the three in one
  go into one folder, once the scans exist.
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
- :func:`finish_result` (``finish_result.py``): the end every job's result folder shares: the
  exports made from the finished frames, ``review.html`` and ``report.html``, then the writer's
  rename; :func:`import_writers` imports what they need ahead of time.
- :func:`export_result` (``export_result.py``): ``facecap export`` (and ``--export``), a finished
  result written to artists' formats; its glTF review file is :func:`write_gltf_review`
  (``write_gltf_review.py``: a decimated review mesh and the take's principal morph targets).
- :func:`view_result` (``view_result.py``): ``facecap view``, the review page of a result (its
  glTF made if missing, the error heat map against a truth) and its report.

- :func:`build_anatomy_model` (``build_anatomy_model.py``): ``facecap build-anatomy``, the anatomy
  model folder of a neutral scan (Sifakis et al. 2005, sec. 3) with its layout picture.
- :func:`remove_scan_wrinkles` (``remove_scan_wrinkles.py``): ``facecap remove-wrinkles``, a neutral
  scan's wrinkles smoothed out in a region (Bickel et al. 2007, sec. 5.4), written as a new scan.
- :func:`generate_capture_case` (``generate_capture_case.py``): ``facecap synth``, a capture case
  with its dense ground truth (and wrinkle footage from two cameras) written as a folder.
- :func:`calibrate_stage_light` (``calibrate_stage_light.py``): ``facecap calibrate-light``, a light
  calibrated from footage of a chrome sphere, written as ``lights.json`` with a check picture
  (:func:`light_check_path`).
- :func:`run_demo` (``run_demo.py``): ``facecap demo``, the jobs above on the bundled sample (a
  generated take with its ground truth, the real AnimFace take, generated wrinkle footage), with
  pictures and ``demo_summary.json``.

The functions share their modules' names, so ``facecap.pipelines.animate_scan`` is the
function; reach a module itself with ``importlib.import_module``.

Each job's module is imported when one of its names is first used, not with the package: the jobs
between them load every solver package, matplotlib and trimesh (1-2 s), and a command needs one job
(``facecap animate`` loads neither the anatomy nor the muscle solver). Importing a job's module
binds its name here to the job's function, as an eager ``from .animate_scan import animate_scan``
would.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

_PUBLIC = {
    "animate_scan": ("animate_scan", "AnimationResult", "OFFSET_WARNING_MM"),
    "capture_wrinkles": ("capture_wrinkles", "WrinkleCapture"),
    "capture_detail": ("capture_detail", "DetailCapture", "write_detail_frame_maps"),
    "plan_scans": ("plan_scans", "conditioned_take_path"),
    "register_planned_scans": ("register_planned_scans", "colour_alignment_choice"),
    "blend_take": ("blend_take",),
    "replay_conditioning": ("replay_conditioning",),
    "write_blended_performance": ("write_blended_performance",),
    "map_markers": ("map_markers", "map_side_files"),
    "edit_muscles": ("edit_muscles", "MuscleEditResult", "EDIT_METHOD"),
    "solve_muscle_take": ("solve_muscle_take", "MuscleTakeResult", "RIGID_FIT_LIMIT_MM"),
    "write_muscle_result": ("write_muscle_result", "plot_muscle_activations", "ACTIVATIONS_FILE",
                            "BONE_TRANSFORMS_FILE"),
    "finish_result": ("finish_result", "import_writers"),
    "export_result": ("export_result", "usd_shape_count", "usd_principal_components", "DEFAULT_GLTF_TARGETS",
                      "DEFAULT_REVIEW_VERTICES", "MAX_ERROR_PASS_FLOPS"),
    "write_gltf_review": ("write_gltf_review",),
    "view_result": ("view_result", "ERROR_ROWS"),
    "run_demo": ("run_demo",),
    "run_scan_workflow": ("run_scan_workflow",),
    "generate_capture_case": ("generate_capture_case",),
    "build_anatomy_model": ("build_anatomy_model",),
    "remove_scan_wrinkles": ("remove_scan_wrinkles",),
    "calibrate_stage_light": ("calibrate_stage_light", "light_check_path"),
}
"""Each job module's public names, by module."""

_HOME = {name: module for module, names in _PUBLIC.items() for name in names}

__all__ = [name for names in _PUBLIC.values() for name in names]


def __getattr__(name: str) -> Any:
    module = _HOME.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _JobPackage(types.ModuleType):
    """The package, whose attribute named after a job module is that job's function, never the module."""

    def __setattr__(self, name: str, value: Any) -> None:
        # the import system binds a submodule to its name here once it has run: keep the function instead
        if isinstance(value, types.ModuleType) and _HOME.get(name) == name:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _JobPackage
