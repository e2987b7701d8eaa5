"""What a marker file, a mesh or a facecap result holds (``facecap info``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ..io.read_markers import MARKER_SUFFIXES

__all__ = ["describe_file"]

MESH_SUFFIXES = (".obj", ".ply", ".glb", ".gltf")


def describe_file(path: str | Path, *, unit: str | None = None) -> dict[str, Any]:
    """Summarise a take, a mesh or an output folder as a JSON-ready dict.

    Parameters
    ----------
    path : str or Path
        A ``.c3d``/``.trc``/``.csv``/``.tsv`` take, an ``.obj``/``.ply``/``.glb`` mesh,
        or a folder written by ``facecap animate``.
    unit : str, optional
        Length unit of a mesh file (mesh files do not say); default mm. For a
        take, overrides the unit the file declares.

    Returns
    -------
    dict

    Raises
    ------
    FileFormatError
        If the file is of no kind facecap reads.
    """
    p = Path(path)
    if p.is_dir():
        return _describe_result(p)
    suffix = p.suffix.lower()
    if suffix in MARKER_SUFFIXES:
        return _describe_markers(p, unit)
    if suffix in MESH_SUFFIXES:
        return _describe_mesh(p, unit or "mm")
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    raise FileFormatError(
        f"unknown file type {suffix!r}; expected a take {MARKER_SUFFIXES}, a mesh {MESH_SUFFIXES} or an output folder",
        path=str(p),
    )


def _describe_markers(path: Path, unit: str | None) -> dict[str, Any]:
    from ..io.read_markers import read_markers

    take = read_markers(path, unit=unit)
    gaps = take.gap_mask
    P = take.positions
    lo = np.nanmin(P.reshape(-1, 3), axis=0) if np.isfinite(P).any() else np.full(3, np.nan)
    hi = np.nanmax(P.reshape(-1, 3), axis=0) if np.isfinite(P).any() else np.full(3, np.nan)
    per_marker = {label: int(gaps[:, i].sum()) for i, label in enumerate(take.labels) if gaps[:, i].any()}
    return {
        "kind": "marker take",
        "file": str(path),
        "markers": take.n_markers,
        "labels": list(take.labels),
        "rate_hz": take.rate,
        "frames": take.n_frames,
        "duration_s": round(take.n_frames / take.rate, 3),
        "first_frame": take.first_frame,
        "source_unit": take.source_unit,
        "gaps": {
            "missing_samples": int(gaps.sum()),
            "missing_percent": round(100.0 * float(gaps.mean()), 3),
            "markers_with_gaps": len(per_marker),
            "missing_samples_per_marker": per_marker,
        },
        "bounding_box_mm": {"min": np.round(lo, 3).tolist(), "max": np.round(hi, 3).tolist()},
    }


def _describe_mesh(path: Path, unit: str) -> dict[str, Any]:
    from ..io.read_mesh import read_mesh
    from ..mesh.check_mesh import check_mesh

    mesh = read_mesh(path, unit=unit)
    check = check_mesh(mesh.vertices, mesh.faces)
    sizes = mesh.polygon_sizes
    return {
        "kind": "mesh",
        "file": str(path),
        "source_unit": mesh.source_unit,
        "vertices": mesh.n_vertices,
        "triangles": mesh.n_faces,
        "polygons": int(sizes.size) if sizes is not None else mesh.n_faces,
        "quads": int((sizes == 4).sum()) if sizes is not None else 0,
        "uvs": int(mesh.uvs.shape[0]) if mesh.uvs is not None else 0,
        "check": check.summary(),
        "problems": check.problems or ["none found"],
    }


def _describe_result(folder: Path) -> dict[str, Any]:
    from ..io.read_result import read_result

    result = read_result(folder)
    info = result.info
    described = {
        "kind": "facecap result",
        "folder": str(folder),
        "frames": result.n_frames,
        "vertices": result.n_vertices,
        "rate_hz": result.rate,
        "units": result.units,
        "method": info.get("method"),
        "stabilized": info.get("stabilized"),
        "frames_in": ("vertices.npy" if result.has_vertices else "")
        + (" and " if result.has_vertices and result.rig is not None else "")
        + (f"rig/ ({result.rig.kind}, {result.rig.n_basis} x {result.rig.n_vertices}, {result.rig.precision}"
           + (f", error bound {result.rig.error_bound:.3g} {result.units})" if result.rig.precision == "int16" else ")")
           if result.rig is not None else ""),
        "exports": info.get("exports"),
        "size_mb": round(sum(result.files().values()) / 1e6, 2),
        "source_files": info.get("source_files"),
    }
    return described
