"""Export a finished result folder to the formats artists' tools read (``facecap export``, ``--export``).

Every export reads the frames through :func:`facecap.io.read_result`, so it
works the same on a folder with ``vertices.npy``, with only the rig, or both.
File names, in the result folder (or ``out_dir``):

==========  =================================  ======================================================
format      file                               what
==========  =================================  ======================================================
``usd``     ``performance_rig.usdc``           the rig as UsdSkel blend shapes, weights animated (with a rig)
            ``performance.usdc``               time-sampled points (without a rig, or streamed by the run)
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
head motion stays in ``head_motion.npy``).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import FacecapWarning, InputError
from .read_result import Result, read_result
from .write_performance import EXPORT_FORMATS, STREAMED_FORMATS, file_sizes

__all__ = ["export_result", "parse_export_formats", "DEFAULT_GLTF_TARGETS", "DEFAULT_REVIEW_VERTICES"]

DEFAULT_GLTF_TARGETS = 64
"""Morph targets of a glTF review file at most (principal components beyond an exact small rig)."""

DEFAULT_REVIEW_VERTICES = 100_000
"""Vertices of the glTF review mesh at most (decimated by vertex subset beyond)."""


def parse_export_formats(text: str | Iterable[str]) -> list[str]:
    """``'usd,gltf'`` (or a list) to a checked, de-duplicated list of formats.

    Raises
    ------
    InputError
        Naming the unknown formats and the known ones, or the package an
        optional format needs (Alembic: ``facecap[alembic]``).
    """
    items = [s.strip().lower() for s in (text.split(",") if isinstance(text, str) else text)]
    formats = list(dict.fromkeys(s for s in items if s))
    unknown = [f for f in formats if f not in EXPORT_FORMATS]
    if unknown:
        raise InputError(f"--export: unknown format(s) {unknown}; choose from {', '.join(EXPORT_FORMATS)}")
    if "abc" in formats:  # the optional writer's package, checked before any long work
        from .write_alembic import _import_alembic

        _import_alembic()
    return formats


def export_result(
    result_dir: str | os.PathLike[str] | Result,
    formats: str | Iterable[str],
    *,
    out_dir: str | os.PathLike[str] | None = None,
    gltf_targets: int = DEFAULT_GLTF_TARGETS,
    review_vertices: int = DEFAULT_REVIEW_VERTICES,
    gltf_compress: bool = False,
    usd_shapes: str | int = "auto",
    batch_frames: int = 64,
    skip_streamed: bool = False,
    progress: bool = False,
) -> dict[str, Any]:
    """Write ``formats`` of a finished result.

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
    batch_frames : int, default 64
        Frames per block read.
    skip_streamed : bool, default False
        Leave out what a run streams itself (time-sampled USD points, OBJ, PLY).
    progress : bool, default False

    Returns
    -------
    dict
        Per format: the files written and what the writer reports (e.g. the
        glTF's principal-component error). Also recorded in the result's
        ``performance.json`` under ``exports_report`` when ``out_dir`` is the result.

    Raises
    ------
    InputError
        If the folder is not a finished result, a format is unknown, or a writer refuses its input.
    """
    result = result_dir if isinstance(result_dir, Result) else read_result(result_dir)
    wanted = parse_export_formats(formats)
    target = Path(out_dir) if out_dir is not None else result.path
    target.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {}
    rest_obj = _rest_obj(result, target) if {"mdd", "pc2"} & set(wanted) else None  # one for both caches
    for fmt in wanted:
        if skip_streamed and fmt in STREAMED_FORMATS and not (fmt == "usd" and result.rig is not None):
            continue
        writer = _WRITERS[fmt]
        report[fmt] = writer(result, target, batch_frames=batch_frames, progress=progress,
                             gltf_targets=gltf_targets, review_vertices=review_vertices, gltf_compress=gltf_compress,
                             usd_shapes=usd_shapes, rest_obj=rest_obj)
    if target == result.path:
        _record(result.path, report)
    return report


def _record(folder: Path, report: dict[str, Any]) -> None:
    """Add the export reports and file sizes to ``performance.json`` (rewritten atomically)."""
    from ._atomic import atomic_write_text

    path = folder / "performance.json"
    info = json.loads(path.read_text())
    info.setdefault("exports_report", {}).update(report)
    info["exports"] = list(dict.fromkeys(list(info.get("exports", [])) + list(report)))
    info["files"] = file_sizes(folder)
    atomic_write_text(path, json.dumps(info, indent=2))


def _sizes(*paths: Path) -> dict[str, int]:
    return {p.name: p.stat().st_size for p in paths if p.is_file()}


def _export_usd(result: Result, target: Path, *, batch_frames: int, progress: bool, usd_shapes: str | int,
                **_: Any) -> dict[str, Any]:
    if result.rig is not None:
        from .write_usd_blendshapes import DEFAULT_USD_COMPONENTS, USD_EXACT_MAX_BYTES, write_usd_blendshapes

        rig = result.rig
        if usd_shapes == "exact":
            max_shapes = None
        elif usd_shapes == "auto":
            too_big = 12 * rig.n_shapes * rig.n_vertices > USD_EXACT_MAX_BYTES
            max_shapes = DEFAULT_USD_COMPONENTS if too_big else None
            if too_big:
                warnings.warn(
                    f"USD: the exact rig needs {rig.n_shapes} blend shapes of {rig.n_vertices} vertices "
                    f"({12 * rig.n_shapes * rig.n_vertices / 1e9:.1f} GB); writing its first {max_shapes} principal "
                    "components instead (error in performance.json; the exact form is rig/, or --usd-shapes exact)",
                    FacecapWarning, stacklevel=3)
        else:
            max_shapes = int(usd_shapes)
            if max_shapes < 1:
                raise InputError(f"--usd-shapes: expected 'auto', 'exact' or a positive count, got {usd_shapes!r}")
        path = target / "performance_rig.usdc"
        stats = write_usd_blendshapes(path, result.mesh, rig, rate=result.rate, head_motion=result.head_motion,
                                      max_shapes=max_shapes, progress=progress)
        return {"files": _sizes(path), **stats}
    from .write_usd import UsdPerformanceWriter

    path = target / "performance.usdc"
    to_mm = np.float32(result.mm_per_unit)
    pose = None
    if result.head_motion is not None:
        pose = result.head_motion.copy()
        pose[:, :3, 3] *= result.mm_per_unit
    with UsdPerformanceWriter(path, result.mesh, result.rate, result.n_frames) as usd:
        for start, block in _progress(result, batch_frames, progress, "USD"):
            usd.write_frames(start, block * to_mm, head_pose=None if pose is None else pose[start:start + len(block)])
    return {"files": _sizes(path)}


def _export_frames(fmt: str):
    def export(result: Result, target: Path, *, batch_frames: int, progress: bool, **_: Any) -> dict[str, Any]:
        from ._atomic import atomic_folder
        from .write_mesh import write_mesh

        to_mm = result.mm_per_unit
        with atomic_folder(target / fmt, marker_file=f"frame_000000.{fmt}") as staging:
            for start, block in _progress(result, batch_frames, progress, fmt.upper()):
                for k in range(block.shape[0]):
                    write_mesh(result.mesh, staging / f"frame_{start + k:06d}.{fmt}", vertices=block[k] * to_mm)
        return {"files": {f"{fmt}/": result.n_frames}}
    return export


def _rest_obj(result: Result, target: Path) -> Path:
    """The rest mesh a point cache is applied to, in the result's unit, vertex order kept."""
    from .write_mesh import write_mesh

    path = target / "performance_rest.obj"
    write_mesh(result.mesh, path)
    return path


def _export_mdd(result: Result, target: Path, *, batch_frames: int, progress: bool, rest_obj: Path,
                **_: Any) -> dict[str, Any]:
    from .write_point_cache import write_mdd

    path = write_mdd(target / "performance.mdd", _progress(result, batch_frames, progress, "MDD"),
                     n_frames=result.n_frames, n_vertices=result.n_vertices, rate=result.rate)
    return {"files": _sizes(Path(path), rest_obj)}


def _export_pc2(result: Result, target: Path, *, batch_frames: int, progress: bool, rest_obj: Path,
                **_: Any) -> dict[str, Any]:
    from .write_point_cache import write_pc2

    path = write_pc2(target / "performance.pc2", _progress(result, batch_frames, progress, "PC2"),
                     n_frames=result.n_frames, n_vertices=result.n_vertices, rate=result.rate)
    return {"files": _sizes(Path(path), rest_obj)}


def _export_abc(result: Result, target: Path, *, batch_frames: int, progress: bool, **_: Any) -> dict[str, Any]:
    from .write_alembic import write_alembic

    path = write_alembic(target / "performance.abc", result.mesh, _progress(result, batch_frames, progress, "Alembic"),
                         n_frames=result.n_frames, rate=result.rate, head_motion=result.head_motion)
    return {"files": _sizes(Path(path))}


def _export_gltf(result: Result, target: Path, *, batch_frames: int, progress: bool, gltf_targets: int,
                 review_vertices: int, gltf_compress: bool, **_: Any) -> dict[str, Any]:
    from .gltf_review import write_gltf_review

    path = target / "performance.glb"
    stats = write_gltf_review(path, result, max_targets=gltf_targets, max_vertices=review_vertices,
                              compress=gltf_compress, batch_frames=batch_frames, progress=progress)
    return {"files": _sizes(path), **stats}


def _progress(result: Result, batch_frames: int, progress: bool, desc: str):
    from tqdm.auto import tqdm

    bar = tqdm(total=result.n_frames, unit="frame", desc=desc, disable=not progress, leave=False)
    try:
        for start, block in result.blocks(batch_frames):
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
