"""``facecap plan-scans``'s job: which frames of a take to scan (Huang et al. 2011, Algorithm 1), as ``plan.json``.

The take read and conditioned as the later steps replay it (:func:`~facecap.pipelines.replay_conditioning`),
the frames chosen (:func:`~facecap.blendshapes.select_scan_frames`), and the plan,
the conditioned take beside it (:func:`conditioned_take_path`) and the Fig. 8 picture written. The
scan workflow goes on with :func:`~facecap.pipelines.register_planned_scans` and
:func:`~facecap.pipelines.blend_take`.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Sequence

from ..blendshapes.select_scan_frames import ScanPlan, select_scan_frames
from ..errors import FacecapWarning
from ..io.atomic_write import check_file_destination
from ..io.conditioned_take import file_sha256, write_conditioned_take
from ..io.read_markers import read_markers
from ..io.scan_plan import write_scan_plan
from ..markers.condition_take import DEFAULT_HEAD_MOTION_SIGMA_S
from .replay_conditioning import replay_conditioning

__all__ = ["plan_scans", "conditioned_take_path"]

SCAN_SKIN_HEAD_POSE = "consensus"
"""How ``plan-scans`` poses a head without a head band it can recognise (it has no map to tell one): the consensus
of the markers, as ``animate`` does without a band (:func:`facecap.markers.auto_stabilize`); recorded in
``plan.json``. Plans written before 2026-12-04 have no record and replay the most rigid set they used."""


def conditioned_take_path(plan_path: str | Path) -> Path:
    """Where ``plan-scans`` keeps the conditioned take of ``plan_path``: ``plan.json`` -> ``plan.conditioned.npz``."""
    p = Path(plan_path)
    return p.with_name(f"{p.stem}.conditioned.npz")



def plan_scans(
    markers_path: str | Path,
    plan_path: str | Path,
    *,
    tolerance: float = 0.003,
    max_frames: int | None = None,
    rest_frame: int = 0,
    stabilize: bool | str | Sequence[str] = True,
    smooth: bool = True,
    plot_path: str | Path | None = None,
    marker_unit: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> ScanPlan:
    """Choose the fewest frames to scan (Algorithm 1) and write ``plan.json`` (+ the Fig. 8 plot).

    Parameters
    ----------
    markers_path : str or Path
        The take.
    plan_path : str or Path
        Where to write ``plan.json``.
    tolerance : float, default 0.003
        Reconstruction tolerance as a fraction of the marker bounding-box diagonal.
    max_frames : int, optional
        Stop after this many frames even if the tolerance is not met. Then
        the plan says what the cap costs (``cap`` in ``plan.json``, and a
        warning): the selection run on, up to four times the cap, finds how
        many scans the tolerance needs and the error with them, beside the
        error at the cap.
    rest_frame : int, default 0
    stabilize : bool or sequence of str, default True
        Head motion must be removed before choosing expressions (otherwise
        head poses get chosen); ``True`` finds the stable markers.
    smooth : bool, default True
    plot_path : str or Path, optional
        PNG of the error against the number of scans (Huang 2011, Fig. 8) and of the chosen
        frames over the take (:func:`~facecap.report.plot_scan_selection`).
    marker_unit : str, optional
        Override the unit the take declares.
    progress : bool, default True
    overwrite : bool, default False
        Replace an existing ``plan.json`` (and its ``.conditioned.npz`` and
        plot); without it they are refused before any work: the scans of a
        session were shot from a plan, so it is never replaced unasked.

    Returns
    -------
    ScanPlan
    """
    for path in (plan_path, conditioned_take_path(plan_path), *(() if plot_path is None else (plot_path,))):
        check_file_destination(path, overwrite=overwrite)
    take = read_markers(markers_path, unit=marker_unit)
    if stabilize is True:
        stabilize_setting: str | list[str] = "auto"
    elif stabilize is False:
        stabilize_setting = "off"
    elif isinstance(stabilize, str):
        stabilize_setting = stabilize
    else:
        stabilize_setting = list(stabilize)
    conditioning: dict[str, Any] = {
        "rest_frame": rest_frame, "stabilize": stabilize_setting, "smooth": smooth,
        "head_motion_sigma_s": DEFAULT_HEAD_MOTION_SIGMA_S, "temporal_sigma_s": "auto",
        "skin_head_pose": SCAN_SKIN_HEAD_POSE,
    }
    conditioned = replay_conditioning(take, conditioning)
    conditioning["temporal_sigma_chosen_s"] = conditioned.temporal_sigma_s
    plan = select_scan_frames(
        conditioned.positions, tolerance=tolerance, max_frames=max_frames, rate=take.rate,
        first_frame=take.first_frame, progress=progress,
    )
    # a zero tolerance asks for exactly max_frames scans: nothing to say about the cap then
    cap = None if plan.converged or max_frames is None or tolerance <= 0 else _cost_of_the_cap(plan, conditioned.positions, tolerance,
                                                                              int(max_frames), progress)
    saved = conditioned_take_path(plan_path)
    conditioning.update(stable_markers=list(conditioned.stable_labels), conditioned_take=saved.name,
                        source_sha256=file_sha256(markers_path))
    write_conditioned_take(saved, conditioned, labels=take.labels, rate=take.rate, settings=conditioning,
                           source_sha256=conditioning["source_sha256"])
    write_scan_plan(plan_path, {**plan.to_dict(), **({} if cap is None else {"cap": cap})}, conditioning=conditioning,
                    source=str(markers_path))
    if plot_path is not None:
        from ..report.plot_scan_selection import plot_scan_selection

        plot_scan_selection(plan, plot_path)
    return plan


_CAP_LOOK_AHEAD = 4  # how far past a --max-scans cap the plan looks for the scans its tolerance needs


def _cost_of_the_cap(plan: ScanPlan, positions: Any, tolerance: float, max_frames: int,
                     progress: bool) -> dict[str, Any]:
    """What stopping at ``max_frames`` costs: the errors there, and the scans the tolerance needs (a warning says it).

    Algorithm 1 is greedy, so the frames it adds past the cap extend the capped plan: the uncapped run
    shows what the next scans would have bought.
    """
    ahead = select_scan_frames(positions, tolerance=tolerance, max_frames=_CAP_LOOK_AHEAD * max_frames,
                               progress=progress)
    needed = len(ahead.frames) if ahead.converged else None
    cap = {
        "max_scans": max_frames,
        "rms_error_at_cap_mm": float(plan.error_after_each[-1]),
        "worst_frame_error_at_cap_mm": float(plan.worst_frame_after_each[-1]),
        "tolerance_mm": float(plan.tolerance_mm),
        "scans_for_tolerance": needed,
        "looked_up_to_scans": len(ahead.frames),
        "rms_error_after_each_uncapped_mm": [float(e) for e in ahead.error_after_each],
        "worst_frame_error_after_each_uncapped_mm": [float(e) for e in ahead.worst_frame_after_each],
    }
    if needed is not None:
        beyond = (f"the tolerance needs {needed} scans (worst frame {ahead.worst_frame_after_each[-1]:.3f} mm "
                  f"with them)")
    else:
        beyond = (f"{len(ahead.frames)} scans still miss it (worst frame {ahead.worst_frame_after_each[-1]:.3f} mm; "
                  "a larger tolerance, or a take with fewer distinct expressions)")
    warnings.warn(f"--max-scans {max_frames} stops short of the tolerance: the worst frame is rebuilt to "
                  f"{plan.worst_frame_after_each[-1]:.3f} mm from the markers where {plan.tolerance_mm:.3f} mm is "
                  f"asked; {beyond}", FacecapWarning, stacklevel=3)
    return cap
