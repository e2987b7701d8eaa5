"""``facecap scans-pipeline``'s job: the scan workflow of Huang et al. 2011 in one go, once the scans exist.

Three jobs, one after the other, into one folder: the plan (:func:`~facecap.pipelines.plan_scans`,
``plan.json`` and ``plan.png``; skipped when a plan is given), the scans registered into bases
(:func:`~facecap.pipelines.register_planned_scans`, ``bases/``), and every frame of the take rebuilt from
them (:func:`~facecap.pipelines.blend_take`, ``animation/``). Whatever the three would replace is
refused before the first starts (replaced only with ``overwrite``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from ..io.atomic_write import check_file_destination, check_folder_destination, ensure_folder
from ..io.registered_scans import BASES_MARKER_FILE
from ..io.write_performance import check_result_destination
from .blend_take import blend_take
from .plan_scans import conditioned_take_path, plan_scans
from .register_planned_scans import register_planned_scans

__all__ = ["run_scan_workflow"]


def run_scan_workflow(
    markers_path: str | Path,
    scan_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    plan_path: str | Path | None = None,
    tolerance: float = 0.003,
    scan_unit: str = "mm",
    template_path: str | Path | None = None,
    template_unit: str = "mm",
    marker_offset_mm: float = 1.5,
    template_texture_path: str | Path | None = None,
    align_colors: bool | None = None,
    refine: bool = False,
    workers: int | None = None,
    exports: Sequence[str] = (),
    write_vertices: bool = True,
    rig_precision: str = "float32",
    export_options: dict[str, Any] | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Plan the scans (unless a plan is given), register them, and blend the take: ``out_dir`` holds all three.

    Parameters
    ----------
    markers_path : str or Path
        The take.
    scan_paths : sequence of str or Path
        One scan per planned frame, in the plan's order.
    out_dir : str or Path
        The folder written: ``plan.json`` and ``plan.png`` (without ``plan_path``), ``bases/``,
        ``animation/`` (a result folder like ``facecap animate``'s).
    plan_path : str or Path, optional
        An existing plan; default: plan now, as ``out_dir/plan.json``, and expect scans to match it.
    tolerance : float, default 0.003
        The plan's reconstruction tolerance, a fraction of the marker bounding-box diagonal.
    scan_unit, template_path, template_unit, marker_offset_mm, template_texture_path, align_colors, refine, workers
        As :func:`~facecap.pipelines.register_planned_scans` takes them.
    exports, write_vertices, rig_precision, export_options
        As :func:`~facecap.pipelines.blend_take` takes them.
    progress : bool, default True
        Progress bars.
    overwrite : bool, default False
        Replace an earlier plan, bases folder and result in ``out_dir`` (else refused before any work).

    Returns
    -------
    dict
        The blend's report (:func:`~facecap.pipelines.blend_take`).
    """
    out = Path(out_dir)
    plan = Path(plan_path) if plan_path else out / "plan.json"
    # everything the three steps would replace, refused before the first one starts
    if not plan_path and out.is_dir():
        for path in (plan, conditioned_take_path(plan), out / "plan.png"):
            check_file_destination(path, overwrite=overwrite)
    check_folder_destination(out / "bases", marker_file=BASES_MARKER_FILE, overwrite=overwrite)
    check_result_destination(out / "animation", overwrite=overwrite)
    ensure_folder(out)
    if not plan_path:
        plan_scans(markers_path, plan, tolerance=tolerance, plot_path=out / "plan.png", progress=progress,
                   overwrite=overwrite)
    register_planned_scans(plan, markers_path, scan_paths, out / "bases", template_path=template_path,
                           scan_unit=scan_unit, template_unit=template_unit, marker_offset_mm=marker_offset_mm,
                           refine=refine, template_texture_path=template_texture_path, align_colors=align_colors,
                           workers=workers, progress=progress, overwrite=overwrite)
    return blend_take(out / "bases", markers_path, out / "animation", exports=exports, write_vertices=write_vertices,
                      rig_precision=rig_precision, export_options=export_options, progress=progress,
                      overwrite=overwrite)
