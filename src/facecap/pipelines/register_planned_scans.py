"""``facecap register-scans``'s job: one scan per planned frame in one topology, written as a bases folder.

The plan and the take read, the take conditioned as the plan did
(:func:`~facecap.pipelines.replay_conditioning`), the scans read and their units checked against
their frames' markers, the registration run (:func:`~facecap.registration.register_scans`,
Huang et al. 2011, sections 5-7), and the bases folder written (:mod:`facecap.io.registered_scans`).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Any, Sequence

from ..errors import FacecapWarning, InputError
from ..io.atomic_write import check_folder_destination, recorded_path
from ..io.read_markers import read_markers
from ..io.read_mesh import read_mesh
from ..io.registered_scans import BASES_MARKER_FILE, CONDITIONED_TAKE_FILE, write_registered_scans
from ..io.scan_plan import read_scan_plan
from ..markers.check_scan_units import check_scan_units
from ..mesh.surface_colors import texel_size_mm
from ..structures import Mesh
from .plan_scans import conditioned_take_path
from .replay_conditioning import replay_conditioning

__all__ = ["register_planned_scans", "colour_alignment_choice"]


def _why_no_texture(mesh: Mesh) -> str | None:
    """None when ``mesh``'s colour texture can be aligned to, else why it cannot."""
    if mesh.texture is None:
        return "no colour texture"
    try:
        texel_size_mm(mesh)
    except InputError as exc:
        return exc.message
    return None


def colour_alignment_choice(asked: bool | None, scans: Sequence[Mesh], template: Mesh | None,
                            texture: Mesh | None) -> tuple[bool, str]:
    """Whether to align by colour, and why: ``asked`` if given, else when every scan and the colour
    source (``texture``, else ``template``, else the first scan, the template then) have a usable texture.

    When some have one and others not (a texture lost on the way, UVs that cover no texels), colour
    alignment is off and a :class:`~facecap.errors.FacecapWarning` names the first mesh without,
    so that the fallback to geometry alone is not silent.
    """
    if asked is not None:
        return asked, "asked for" if asked else "turned off"
    source = texture if texture is not None else (template if template is not None else scans[0])
    meshes = [source, *scans] if source is not scans[0] else list(scans)
    missing = [(mesh, why) for mesh in meshes if (why := _why_no_texture(mesh)) is not None]
    if not missing:
        return True, "every scan and the template have a colour texture"
    if len(missing) == len(meshes):
        return False, "the scans or the template have no colour texture"
    mesh, why = missing[0]
    name = mesh.source_path or ("the template" if mesh is source else f"scan {[m is mesh for m in scans].index(True)}")
    more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
    reason = f"{name}: {why}{more}, where the others have a colour texture"
    warnings.warn(f"colour alignment off: {reason}; every scan is registered by its geometry alone",
                  FacecapWarning, stacklevel=2)
    return False, reason


def register_planned_scans(
    plan_path: str | Path,
    markers_path: str | Path,
    scan_paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    template_path: str | Path | None = None,
    scan_unit: str = "mm",
    template_unit: str = "mm",
    marker_offset_mm: float = 1.5,
    refine: bool = False,
    template_texture_path: str | Path | None = None,
    align_colors: bool | None = None,
    marker_unit: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Register one scan per planned frame and write the bases folder.

    With ``align_colors`` the registrations are slid along the scans until
    the skin's colours match the template's (the scans and the template, or
    ``template_texture_path``, a coloured scan of the template's expression
    in the template's unit, need a colour texture or vertex colours), see
    :func:`facecap.registration.register_scans`. None (default): on when every
    scan and the template (or its texture) carry a colour texture, which
    resolves the skin finely enough to follow it; per-vertex colour alone did
    not help on generated scans, so it is used only when asked for.

    ``scan_unit`` and ``template_unit`` are length units, or ``'auto'``: each
    file's size is compared with its frame's markers
    (:func:`facecap.markers.check_scan_units`); a given unit they contradict
    stops with an error naming the likely one, ``'auto'`` converts to it.

    ``workers`` processes register the scans side by side; None (default):
    :func:`facecap.registration.default_workers` (every core for scans of
    200,000 vertices or more in all, else this process alone). A script that
    runs this with worker processes needs Python's ``if __name__ ==
    "__main__":`` guard (they are spawned).

    An earlier bases folder in ``out_dir`` is replaced only with
    ``overwrite`` (checked before the registration and again at the end).
    Returns the registration report (also in ``bases.json``, with every
    scan's path as recorded there: final and absolute, or relative to the folder).
    """
    from ..registration.register_scans import default_workers, register_scans

    check_folder_destination(out_dir, marker_file=BASES_MARKER_FILE, overwrite=overwrite)
    take = read_markers(markers_path, unit=marker_unit)
    plan = read_scan_plan(plan_path, n_frames=take.n_frames)
    frames = plan["frames"]
    if len(scan_paths) != len(frames):
        raise InputError(f"--scans: the plan lists {len(frames)} frames, {len(scan_paths)} scans were given "
                         "(one scan per planned frame, in the plan's order)")
    conditioning = plan["conditioning"]
    conditioned = replay_conditioning(take, conditioning, markers_path=markers_path,
                                      saved=conditioned_take_path(plan_path))
    auto, auto_template = scan_unit == "auto", template_unit == "auto"  # else a contradicted unit stops
    scans = [check_scan_units(read_mesh(p, unit=None if auto else scan_unit), conditioned.positions[f], convert=auto)
             for p, f in zip(scan_paths, frames)]
    template: Mesh | None = check_scan_units(
        read_mesh(template_path, unit=None if auto_template else template_unit),
        conditioned.positions[int(conditioning.get("rest_frame", 0))], convert=auto_template, option="--template-units",
    ) if template_path else None
    texture = None
    if template_texture_path is not None:
        if template is None:
            raise InputError("--template-texture needs --template (without one the first scan is the template)")
        texture = read_mesh(template_texture_path, unit=template.source_unit)
    align_colors, why = colour_alignment_choice(align_colors, scans, template, texture)
    t = time.perf_counter()
    registered = register_scans(
        scans, conditioned.positions[frames], template=template,
        template_markers=conditioned.positions[int(conditioning.get("rest_frame", 0))] if template else None,
        marker_offset_mm=marker_offset_mm, refine=refine, template_texture=texture, align_colors=align_colors,
        workers=default_workers(scans) if workers is None else workers, progress=progress,
    )
    report = {**registered.report, "colour_alignment": f"{'on' if align_colors else 'off'} ({why})",
              "total_s": time.perf_counter() - t,
              "registration_mm": registered.registration_mm.tolist()}
    for entry, path in zip(report.get("scans", []), scan_paths):
        entry["scan"] = recorded_path(path, folder=out_dir)
    # the plan as the bases saw it; its conditioned take is the one kept in the bases folder
    plan = {**plan, "markers": recorded_path(markers_path, folder=out_dir),
            "conditioning": {**conditioning, "conditioned_take": CONDITIONED_TAKE_FILE}}
    write_registered_scans(
        out_dir, template=registered.template, bases=registered.bases, basis_markers=registered.basis_markers,
        marker_labels=list(take.labels), output_from_mocap=registered.output_from_mocap,
        plan=plan, report=report, conditioned=conditioned, rate=take.rate, overwrite=overwrite,
    )
    return report
