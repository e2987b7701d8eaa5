"""Export a finished result folder to the formats artists' tools read (``facecap export``, ``--export``).

Every export reads the frames through :func:`facecap.io.read_result`, so it
works the same on a folder with ``vertices.npy``, with only the rig, or both.
File names, in the result folder (or ``out_dir``):

==========  =================================  ======================================================
format      file                               what
==========  =================================  ======================================================
``usd``     ``performance_rig.usdc``           the rig as UsdSkel blend shapes, weights animated (with a rig)
            ``performance.usdc``               time-sampled points (with ``vertices.npy``, or without a rig)
``gltf``    ``performance.glb``                review mesh, morph targets, weights animation (metres)
``mdd``     ``performance.mdd``                LightWave/Blender point cache, with ``performance_rest.obj``
``pc2``     ``performance.pc2``                Maya/3ds Max/Blender point cache, with ``performance_rest.obj``
``abc``     ``performance.abc``                Alembic mesh with per-frame positions (``facecap[alembic]``)
``obj``     ``obj/frame_000000.obj ...``       one file per frame, polygons and UVs kept
``ply``     ``ply/frame_000000.ply ...``       one file per frame
==========  =================================  ======================================================

Point caches, Alembic and USD carry the result's unit (the scan's); glTF is in
metres, its unit. The head motion of a stabilised result is the root's
animated transform in USD, glTF and Alembic (``/Head``); point caches and
OBJ/PLY frames hold the stabilised face (a point cache has no transform: the
head motion stays in ``head_motion.npy``). ``export_frame='world'`` bakes the
head motion (``x_world = R_t x + t_t``) into the points of the point caches and
the Alembic instead, written as ``performance_world.mdd``, ``.pc2``, ``.abc``
(the file name says which frame it holds; ``/Head`` is then the identity).

An export adds to a folder and never removes what is there: a file it would
write that exists already is refused (one error naming them all, before
anything is written) unless ``overwrite`` is given. ``performance_rest.obj``,
shared by both point caches, is no conflict when it is the same file this
result writes (an MDD exported after a PC2).
"""

from __future__ import annotations

import filecmp
import json
import os
import tempfile
import warnings
from concurrent.futures import Future
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import FacecapWarning, InputError
from ..io.atomic_write import atomic_folder, atomic_write_text, ensure_folder
from ..io.read_result import Result, read_result
from ..io.result_rig import ResultRig
from ..io.result_layout import (EXPORT_FRAMES, PERFORMANCE_FILE, REST_OBJ_FILE, WORLD_FRAME_FORMATS, export_files,
                                file_sizes, parse_export_formats)

__all__ = ["export_result", "usd_shape_count", "usd_principal_components", "DEFAULT_GLTF_TARGETS",
           "DEFAULT_REVIEW_VERTICES", "MAX_ERROR_PASS_FLOPS"]

DEFAULT_GLTF_TARGETS = 64
"""Morph targets of a glTF review file at most (principal components beyond an exact small rig)."""

DEFAULT_REVIEW_VERTICES = 100_000
"""Vertices of the glTF review mesh at most (decimated by vertex subset beyond)."""

MAX_ERROR_PASS_FLOPS = 2e11
"""Largest pass (frames x vertices x rig elements) a principal-component USD rig's exact maximum error is computed
with (one pass over the take, ``T n m`` multiply-adds, a few seconds; beyond, ``max_mm`` is None)."""

def export_result(
    result_dir: str | os.PathLike[str] | Result,
    formats: str | Iterable[str],
    *,
    out_dir: str | os.PathLike[str] | None = None,
    gltf_targets: int = DEFAULT_GLTF_TARGETS,
    review_vertices: int = DEFAULT_REVIEW_VERTICES,
    gltf_compress: bool = False,
    usd_shapes: str | int = "auto",
    export_frame: str = "stabilized",
    overwrite: bool = False,
    batch_frames: int = 64,
    skip_streamed: bool = False,
    progress: bool = False,
    usd_principal: dict[str, Any] | Future | None = None,
    pages: bool = True,
) -> dict[str, Any]:
    """Write ``formats`` of a finished result, adding to the folder and removing nothing.

    Parameters
    ----------
    result_dir : path or Result
        A finished result folder (or one already opened).
    formats : str or iterable of str
        Any of :data:`~facecap.io.EXPORT_FORMATS`, comma-separated or a list.
    out_dir : path, optional
        Where to write (created); default the result folder itself. Each file
        is written under a temporary name and renamed, so an interrupted export
        leaves no file that looks finished.
    gltf_targets : int, default 64
        Most morph targets of the glTF (principal components when the rig needs more).
    review_vertices : int, default 100,000
        Most vertices of the glTF review mesh.
    gltf_compress : bool, default False
        meshopt compression of the glTF buffers (``EXT_meshopt_compression``).
    usd_shapes : 'auto', 'exact' or int, default 'auto'
        Blend shapes of the USD rig: 'exact' (3 per marker for the thin shell),
        a count (principal components when the exact form needs more), or
        'auto': exact up to :data:`~facecap.io.write_usd_blendshapes.USD_EXACT_MAX_BYTES`
        of shapes, else :data:`~facecap.io.write_usd_blendshapes.DEFAULT_USD_COMPONENTS`
        principal components (with a notice; the error is in the report).
    export_frame : {'stabilized', 'world'}, default 'stabilized'
        What the point caches and Alembic hold (:data:`WORLD_FRAME_FORMATS`):
        the stabilised face (the head motion, if any, on ``/Head`` in Alembic
        and in ``head_motion.npy``), or the face in the world,
        ``x_world = R_t x + t_t`` with ``head_motion.npy``'s ``(T, 4, 4)``,
        written as ``performance_world.<ext>`` (a result without head motion
        is in the world already: its frames are written as they are).
    overwrite : bool, default False
        Replace files of these exports that exist already; without it they
        are refused before anything is written.
    batch_frames : int, default 64
        Frames per block read.
    skip_streamed : bool, default False
        Leave out what a run streams itself (time-sampled USD points, OBJ, PLY).
    progress : bool, default False
    usd_principal : dict or Future of one, optional
        The USD rig's principal components computed already (:func:`usd_principal_components` of this
        result's rig and ``usd_shapes``, whose warning the caller has given), or being computed on another
        thread (waited for when the USD rig is written); default None: computed here.
    pages : bool, default True
        Write ``review.html`` beside a glTF (the page that plays it, as a run
        with ``--export gltf`` does) and, exporting into the result folder,
        its ``report.html`` again (it lists the exports). False for a job that
        writes its pages itself after its exports.

    Returns
    -------
    dict
        Per export (``'mdd'``, or ``'mdd_world'`` for the world frame): the
        files written and what the writer reports (e.g. the glTF's
        principal-component error). Also recorded in the result's
        ``performance.json`` (``exports``, ``exports_report``, ``files``) when
        ``out_dir`` is the result.

    Raises
    ------
    InputError
        If the folder is not a finished result, a format or frame is unknown,
        files of these exports exist and ``overwrite`` is False (one line naming
        them), the destination cannot be written (the cause), or a writer
        refuses its input.
    """
    result = result_dir if isinstance(result_dir, Result) else read_result(result_dir)
    wanted = parse_export_formats(formats)
    if export_frame not in EXPORT_FRAMES:
        raise InputError(f"--export-frame: expected one of {', '.join(EXPORT_FRAMES)}, got {export_frame!r}")
    target = Path(out_dir) if out_dir is not None else result.path
    planned = {fmt: export_files(result, fmt, export_frame=export_frame, skip_streamed=skip_streamed)
               for fmt in wanted}
    planned = {fmt: names for fmt, names in planned.items() if names}
    existing = [name for name in dict.fromkeys(n for names in planned.values() for n in names)
                if os.path.lexists(target / name.rstrip("/"))]
    rest_kept = REST_OBJ_FILE in existing and _same_rest_obj(result, target / REST_OBJ_FILE)
    if rest_kept:
        existing.remove(REST_OBJ_FILE)
    if existing and not overwrite:
        raise InputError(f"{', '.join(existing)} {'exists' if len(existing) == 1 else 'exist'} already; pass "
                         "--overwrite to replace (an export never removes what is there)", path=str(target))
    ensure_folder(target)
    report: dict[str, Any] = {}
    rest_obj = None
    if {"mdd", "pc2"} & set(planned):  # one rest mesh for both caches
        rest_obj = target / REST_OBJ_FILE if rest_kept else _rest_obj(result, target)
    for fmt in planned:
        world = export_frame == "world" and fmt in WORLD_FRAME_FORMATS
        entry = _WRITERS[fmt](result, target, batch_frames=batch_frames, progress=progress,
                              gltf_targets=gltf_targets, review_vertices=review_vertices, gltf_compress=gltf_compress,
                              usd_shapes=usd_shapes, rest_obj=rest_obj, world=world, overwrite=overwrite,
                              skip_streamed=skip_streamed, usd_principal=usd_principal)
        if world:
            entry["frame"] = "world"
            entry["head_motion"] = ("baked into the points (x_world = R_t x + t_t)" if result.head_motion is not None
                                    else "none: the result is not stabilised, its frames are the world's")
        report[f"{fmt}_world" if world else fmt] = entry
    if pages and "gltf" in report:
        from ..report.review_page import write_review_page

        write_review_page(target / "review.html", target / "performance.glb", title=f"facecap: {result.path.name}",
                          rate=result.rate, n_frames=result.n_frames)
        report["gltf"]["files"].update(_sizes(target / "review.html"))
    if target == result.path:
        _record(result.path, report)
        if pages and (result.path / "report.html").is_file():  # the page lists the exports: written again
            from ..report.write_run_report import write_run_report

            write_run_report(result.path)
            _record(result.path, {})  # the page's new size
    return report


def _same_rest_obj(result: Result, path: Path) -> bool:
    """Whether ``path`` is byte for byte the rest mesh this result's point caches write (then it is kept)."""
    if not path.is_file():
        return False
    with tempfile.TemporaryDirectory(prefix="facecap-rest-") as scratch:
        return filecmp.cmp(_rest_obj(result, Path(scratch)), path, shallow=False)


def _record(folder: Path, report: dict[str, Any]) -> None:
    """Add the export reports and file sizes to ``performance.json`` (rewritten atomically)."""
    path = folder / PERFORMANCE_FILE
    info = json.loads(path.read_text())
    info.setdefault("exports_report", {}).update(report)
    info["exports"] = list(dict.fromkeys(list(info.get("exports", [])) + list(report)))
    info["files"] = file_sizes(folder)
    atomic_write_text(path, json.dumps(info, indent=2))


def _sizes(*paths: Path) -> dict[str, int]:
    return {p.name: p.stat().st_size for p in paths if p.is_file()}


def _export_usd(result: Result, target: Path, *, batch_frames: int, progress: bool, usd_shapes: str | int,
                skip_streamed: bool, usd_principal: dict[str, Any] | Future | None = None, **_: Any) -> dict[str, Any]:
    """``performance_rig.usdc`` from the rig; ``performance.usdc`` (time-sampled points) as a run streams it."""
    files: dict[str, int] = {}
    stats: dict[str, Any] = {}
    if result.rig is not None:
        stats = _export_usd_rig(result, target / "performance_rig.usdc", progress=progress, usd_shapes=usd_shapes,
                                usd_principal=usd_principal)
        files.update(_sizes(target / "performance_rig.usdc"))
    if not skip_streamed and (result.rig is None or result.has_vertices):
        from ..io.write_usd import UsdPerformanceWriter

        path = target / "performance.usdc"
        to_mm = np.float32(result.mm_per_unit)
        pose = None
        if result.head_motion is not None:
            pose = result.head_motion.copy()
            pose[:, :3, 3] *= result.mm_per_unit
        with UsdPerformanceWriter(path, result.mesh, result.rate, result.n_frames) as usd:
            for start, block in _progress(result, batch_frames, progress, "USD"):
                usd.write_frames(start, block * to_mm, head_pose=None if pose is None else pose[start:start + len(block)])
        files.update(_sizes(path))
    return {"files": files, **stats}


def usd_shape_count(rig: ResultRig, usd_shapes: str | int = "auto") -> int | None:
    """How many blend shapes the USD rig of ``rig`` gets: None for the exact ones, else a principal-component count.

    As :func:`export_result`'s ``usd_shapes`` says; 'auto' warns (one line) where it drops to principal components.

    Raises
    ------
    InputError
        If ``usd_shapes`` is not 'auto', 'exact' or a positive count.
    """
    from ..io.write_usd_blendshapes import DEFAULT_USD_COMPONENTS, USD_EXACT_MAX_BYTES

    if usd_shapes == "exact":
        return None
    if usd_shapes == "auto":
        too_big = 12 * rig.n_shapes * rig.n_vertices > USD_EXACT_MAX_BYTES
        if too_big:
            warnings.warn(
                f"USD: the exact rig needs {rig.n_shapes} blend shapes of {rig.n_vertices} vertices "
                f"({12 * rig.n_shapes * rig.n_vertices / 1e9:.1f} GB); writing its first {DEFAULT_USD_COMPONENTS} "
                "principal components instead (error in performance.json; the exact form is rig/, or --usd-shapes exact)",
                FacecapWarning, stacklevel=3)
        return DEFAULT_USD_COMPONENTS if too_big else None
    try:
        count = int(usd_shapes)
    except (TypeError, ValueError):
        count = 0
    if count < 1:
        raise InputError(f"--usd-shapes: expected 'auto', 'exact' or a positive count, got {usd_shapes!r}")
    return count


def usd_principal_components(rig: ResultRig, shape_count: int | None, *, progress: bool = False) -> dict[str, Any]:
    """The principal components the USD rig of ``rig`` holds, as :func:`~facecap.io.write_usd_blendshapes` takes them.

    ``{}`` where the rig is written exactly (``shape_count`` None, or no fewer than the rig's shapes); else
    ``principal_targets``, ``principal_weights`` and ``principal_error`` of the take's first ``shape_count``
    components (:func:`~facecap.deform.principal_targets_from_rig`, the exact maximum error where one pass over
    the take costs at most :data:`MAX_ERROR_PASS_FLOPS`). Arrays in and out, no warning: a job may compute it
    on another thread while it writes the rest of the result, and pass it to :func:`export_result`.
    """
    if shape_count is None or rig.n_shapes <= shape_count:
        return {}
    from ..deform.principal_targets import principal_targets_from_rig

    basis, coefficients = rig.in_mm()
    found = principal_targets_from_rig(
        basis, coefficients, max_targets=shape_count, progress=progress,
        exact_max=rig.n_frames * rig.n_vertices * rig.n_shapes <= MAX_ERROR_PASS_FLOPS)
    return {"principal_targets": found.targets, "principal_weights": found.weights, "principal_error": found.error}


def _export_usd_rig(result: Result, path: Path, *, progress: bool, usd_shapes: str | int,
                    usd_principal: dict[str, Any] | Future | None) -> dict[str, Any]:
    from ..io.write_usd_blendshapes import write_usd_blendshapes

    rig = result.rig
    if isinstance(usd_principal, Future):
        usd_principal = usd_principal.result()
    if usd_principal is None:
        usd_principal = usd_principal_components(rig, usd_shape_count(rig, usd_shapes), progress=progress)
    return write_usd_blendshapes(path, result.mesh, rig, rate=result.rate, head_motion=result.head_motion,
                                 progress=progress, **usd_principal)


def _export_frames(fmt: str):
    def export(result: Result, target: Path, *, batch_frames: int, progress: bool, overwrite: bool,
               **_: Any) -> dict[str, Any]:
        from ..io.write_mesh import write_mesh

        to_mm = result.mm_per_unit
        with atomic_folder(target / fmt, marker_file=f"frame_000000.{fmt}", overwrite=overwrite) as staging:
            for start, block in _progress(result, batch_frames, progress, fmt.upper()):
                for k in range(block.shape[0]):
                    write_mesh(result.mesh, staging / f"frame_{start + k:06d}.{fmt}", vertices=block[k] * to_mm)
        return {"files": {f"{fmt}/": result.n_frames}}
    return export


def _rest_obj(result: Result, target: Path) -> Path:
    """The rest mesh a point cache is applied to, in the result's unit, vertex order kept."""
    from ..io.write_mesh import write_mesh

    path = target / REST_OBJ_FILE
    write_mesh(result.mesh, path)
    return path


def _export_mdd(result: Result, target: Path, *, batch_frames: int, progress: bool, rest_obj: Path, world: bool,
                **_: Any) -> dict[str, Any]:
    from ..io.write_point_cache import write_mdd

    path = write_mdd(target / f"performance{'_world' if world else ''}.mdd",
                     _progress(result, batch_frames, progress, "MDD", world=world),
                     n_frames=result.n_frames, n_vertices=result.n_vertices, rate=result.rate)
    return {"files": _sizes(Path(path), rest_obj)}


def _export_pc2(result: Result, target: Path, *, batch_frames: int, progress: bool, rest_obj: Path, world: bool,
                **_: Any) -> dict[str, Any]:
    from ..io.write_point_cache import write_pc2

    path = write_pc2(target / f"performance{'_world' if world else ''}.pc2",
                     _progress(result, batch_frames, progress, "PC2", world=world),
                     n_frames=result.n_frames, n_vertices=result.n_vertices, rate=result.rate)
    return {"files": _sizes(Path(path), rest_obj)}


def _export_abc(result: Result, target: Path, *, batch_frames: int, progress: bool, world: bool,
                **_: Any) -> dict[str, Any]:
    from ..io.write_alembic import write_alembic

    path = write_alembic(target / f"performance{'_world' if world else ''}.abc", result.mesh,
                         _progress(result, batch_frames, progress, "Alembic", world=world),
                         n_frames=result.n_frames, rate=result.rate, head_motion=None if world else result.head_motion)
    return {"files": _sizes(Path(path))}


def _export_gltf(result: Result, target: Path, *, batch_frames: int, progress: bool, gltf_targets: int,
                 review_vertices: int, gltf_compress: bool, **_: Any) -> dict[str, Any]:
    from .write_gltf_review import write_gltf_review

    path = target / "performance.glb"
    stats = write_gltf_review(path, result, max_targets=gltf_targets, max_vertices=review_vertices,
                              compress=gltf_compress, batch_frames=batch_frames, progress=progress)
    return {"files": _sizes(path), **stats}


def _progress(result: Result, batch_frames: int, progress: bool, desc: str, *, world: bool = False):
    """The result's frames block by block, in its unit; ``world``: moved by its head motion, ``R_t x + t_t``."""
    from tqdm.auto import tqdm

    motion = result.head_motion if world else None
    bar = tqdm(total=result.n_frames, unit="frame", desc=desc, disable=not progress, leave=False)
    try:
        for start, block in result.blocks(batch_frames):
            if motion is not None:
                pose = motion[start:start + block.shape[0]]
                block = (np.einsum("tij,tnj->tni", pose[:, :3, :3], block) + pose[:, None, :3, 3]).astype(np.float32)
            yield start, block
            bar.update(block.shape[0])
    finally:
        bar.close()


_WRITERS = {
    "usd": _export_usd,
    "gltf": _export_gltf,
    "mdd": _export_mdd,
    "pc2": _export_pc2,
    "abc": _export_abc,
    "obj": _export_frames("obj"),
    "ply": _export_frames("ply"),
}
