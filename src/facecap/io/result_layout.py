"""The result folder's layout: its file names, the exports and the files each writes.

A finished result folder (``docs/output_format.md``) holds ``performance.json``
(:data:`PERFORMANCE_FILE`, written last), the frames (``vertices.npy`` and/or
``rig/``), the scan (``faces.npy``, ``mesh.npz``) and the exports
(:data:`EXPORT_FORMATS`): :data:`STREAMED_FORMATS` are written with the frames,
the others from the finished folder. :func:`export_files` names the files each
export writes, :func:`parse_export_formats` checks a list of them,
:func:`file_sizes` lists what ``performance.json`` records as ``files``, and
:func:`read_performance_info` reads ``performance.json`` back. The writers
(:class:`facecap.io.PerformanceWriter`, the export writers) and the job that
exports (:func:`facecap.pipelines.export_result`) all take the names from here.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from ..errors import InputError
from .usd_material import texture_file_beside

if TYPE_CHECKING:
    from .read_result import Result

__all__ = ["PERFORMANCE_FILE", "EXPORT_FORMATS", "STREAMED_FORMATS", "EXPORT_FRAMES", "WORLD_FRAME_FORMATS",
           "REST_OBJ_FILE", "parse_export_formats", "export_files", "file_sizes", "read_performance_info"]

EXPORT_FORMATS = ("usd", "gltf", "mdd", "pc2", "abc", "obj", "ply")
"""Exports ``--export`` accepts besides ``vertices.npy`` and the rig."""

STREAMED_FORMATS = ("usd", "obj", "ply")
"""Exports written while the frames are computed (the others are made from the finished folder)."""

PERFORMANCE_FILE = "performance.json"
"""The finished folder's metadata: written last, so a folder holding it is a finished result."""

EXPORT_FRAMES = ("stabilized", "world")
"""Frames the point caches and Alembic can hold: the stabilised face, or the face moved by ``head_motion.npy``."""

WORLD_FRAME_FORMATS = ("mdd", "pc2", "abc")
"""Exports ``export_frame='world'`` changes (USD and glTF always carry the head motion as the root's transform)."""

REST_OBJ_FILE = "performance_rest.obj"
"""The rest mesh both point caches are applied to (in the result's unit, vertex order kept)."""


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
        from .write_alembic import import_alembic

        import_alembic()
    return formats


def export_files(result: Result, fmt: str, *, export_frame: str = "stabilized", skip_streamed: bool = False) -> list[str]:
    """The files (``'obj/'`` for a folder) that exporting ``fmt`` of ``result`` writes, relative to the destination.

    Parameters
    ----------
    result : Result
    fmt : str
        One of :data:`~facecap.io.EXPORT_FORMATS`.
    export_frame : {'stabilized', 'world'}, default 'stabilized'
    skip_streamed : bool, default False
        As for :func:`facecap.pipelines.export_result`.

    Returns
    -------
    list of str
        Empty when nothing is written (a streamed format with ``skip_streamed``).
    """
    world = "_world" if export_frame == "world" and fmt in WORLD_FRAME_FORMATS else ""
    if fmt == "usd":
        names = ["performance_rig.usdc"] if result.rig is not None else []
        if not skip_streamed and (result.rig is None or result.has_vertices):  # as a run streams it
            names.append("performance.usdc")
        if result.mesh.texture is not None and result.mesh.uvs is not None:  # each file's colour texture beside it
            names += [texture_file_beside(name).name for name in names]
        return names
    if fmt in ("obj", "ply"):
        return [] if skip_streamed else [f"{fmt}/"]
    if fmt in ("mdd", "pc2"):
        return [f"performance{world}.{fmt}", REST_OBJ_FILE]
    if fmt == "gltf":
        return ["performance.glb", "review.html"]  # the page that plays it beside it
    return [f"performance{world}.abc"]


def file_sizes(folder: str | os.PathLike[str]) -> dict[str, int]:
    """Every file under a result folder (relative path) with its size in bytes, less ``performance.json``.

    What ``performance.json`` lists as ``files``.
    """
    root = Path(folder)
    return {str(p.relative_to(root)): p.stat().st_size
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != PERFORMANCE_FILE}


def read_performance_info(out_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """Read ``performance.json`` of a finished output folder, or raise InputError."""
    path = Path(out_dir) / PERFORMANCE_FILE
    if not path.is_file():
        raise InputError("is not a finished facecap result (no performance.json)", path=str(out_dir))
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"unreadable performance.json ({exc})", path=str(path)) from None
