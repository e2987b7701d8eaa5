"""What a marker take, a mesh or a facecap result holds (``facecap info``).

:func:`describe_file` gathers the facts as a JSON-ready dict (``facecap info
--json``); :func:`format_description` writes them for a capture TD: one line per
fact, a unit on every number, the first labels and the markers with the most
gaps rather than every label (``labels=True`` lists them all), the pieces of a
mesh once, and a ``warning`` line where a mesh or a take has a size no face has,
naming the length unit that would make it one
(:func:`facecap.units.check_face_size`).
"""

from __future__ import annotations

import json
import textwrap
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ..io.read_markers import MARKER_FORMATS, MARKER_SUFFIXES
from ..io.read_mesh import MESH_FORMATS, MESH_SUFFIXES
from ..units import FACE_MARKERS_SIZE_MM, FACE_SIZE_MM, FaceSize, check_face_size
from ..units import three_figures as _length  # as the size warnings write lengths

__all__ = ["describe_file", "format_description"]

_LABELS_SHOWN = 8  # labels printed before "and N more"
_GAPS_SHOWN = 5  # markers with the most gaps printed
_PIECES_SHOWN = 5  # largest pieces printed
_WIDTH = 100  # text columns; longer values wrap under their value column
_KEY_WIDTH = 14  # two spaces, the key, at least two spaces
_POLYGON_NAMES = {3: "triangles", 4: "quads"}


def describe_file(path: str | Path, *, unit: str | None = None) -> dict[str, Any]:
    """Summarise a take, a mesh or an output folder as a JSON-ready dict.

    Parameters
    ----------
    path : str or Path
        A take (``.c3d``, ``.trc``, ``.tsv``, ``.csv``), a mesh (``.obj``,
        ``.ply``, ``.glb``, ``.gltf``) or a folder written by ``facecap animate``
        (or another command writing a result).
    unit : {'mm', 'cm', 'm', 'in'}, optional
        Length unit of a mesh file (mesh files do not say; default mm). For a
        take, overrides the unit the file declares.

    Returns
    -------
    dict
        ``kind`` (``'marker take'``, ``'mesh'`` or ``'facecap result'``) and
        the facts of that kind, lengths in mm (keys ending ``_mm``). A take or
        mesh has ``face_size``: its size as read, whether a face has it, its
        size in each length unit and the units that make it a face's, and a
        one-line ``note`` when the size is no face's (None otherwise).

    Raises
    ------
    FileFormatError
        If the file is of no kind facecap reads.
    FileNotFoundError
        If there is nothing at ``path``.
    """
    p = Path(path)
    if p.is_dir():
        return _describe_result(p)
    suffix = p.suffix.lower()
    if suffix in MARKER_SUFFIXES:
        return _describe_markers(p, unit)
    if suffix in MESH_SUFFIXES:
        return _describe_mesh(p, unit or "mm", given=unit is not None)
    if not p.exists():
        raise FileNotFoundError(2, "No such file", str(p))
    raise FileFormatError(
        f"unknown file type {suffix!r}; expected a take ({', '.join(MARKER_SUFFIXES)}), a mesh "
        f"({', '.join(MESH_SUFFIXES)}) or a result folder",
        path=str(p),
    )


def _face_size(found: FaceSize, what: str) -> dict[str, Any]:
    finite = bool(np.isfinite(found.across_mm))
    return {
        "across_mm": round(found.across_mm, 3) if finite else None,
        "face_range_mm": list(found.expected_mm),
        "is_a_face_size": found.fits,
        "across_if_read_as_mm": {u: round(v, 3) for u, v in found.across_as_mm.items()} if finite else None,
        "likely_units": list(found.likely_units),
        "note": found.note(what),
    }


def _box(points: np.ndarray) -> dict[str, Any] | None:
    X = points.reshape(-1, 3)
    X = X[np.isfinite(X).all(axis=1)]
    if not len(X):
        return None
    return {"min": np.round(X.min(axis=0), 3).tolist(), "max": np.round(X.max(axis=0), 3).tolist()}


def _describe_markers(path: Path, unit: str | None) -> dict[str, Any]:
    from ..io.read_markers import read_markers

    take = read_markers(path, unit=unit)
    gaps = take.gap_mask
    per_marker = {label: int(gaps[:, i].sum()) for i, label in enumerate(take.labels) if gaps[:, i].any()}
    found = check_face_size(take.positions, unit=take.source_unit, expected_mm=FACE_MARKERS_SIZE_MM)
    return {
        "kind": "marker take",
        "file": str(path),
        "format": MARKER_FORMATS[path.suffix.lower()],
        "markers": take.n_markers,
        "labels": list(take.labels),
        "subjects": sorted({s for s in take.subjects if s}) if take.subjects else [],
        "rate_hz": take.rate,
        "frames": take.n_frames,
        "duration_s": round(take.n_frames / take.rate, 3),
        "first_frame": take.first_frame,
        "timecode": take.timecode,
        "capture_start": take.capture_start,
        "source_unit": take.source_unit,
        "unit_from": "file" if unit is None else "--units",
        "gaps": {
            "missing_samples": int(gaps.sum()),
            "missing_percent": round(100.0 * float(gaps.mean()), 3),
            "markers_with_gaps": len(per_marker),
            "missing_samples_per_marker": per_marker,
        },
        "bounding_box_mm": _box(take.positions),
        "face_size": _face_size(found, "the markers"),
    }


def _describe_mesh(path: Path, unit: str, *, given: bool) -> dict[str, Any]:
    from ..io.read_mesh import read_mesh
    from ..mesh.check_mesh import check_mesh

    mesh = read_mesh(path, unit=unit)
    check = check_mesh(mesh.vertices, mesh.faces)
    summary = check.summary()
    pieces = sorted(summary.pop("piece_sizes"), reverse=True)
    # the pieces are listed once, under "pieces"; the other defects keep check_mesh's wording
    summary.pop("problems")
    problems = replace(check, n_pieces=min(check.n_pieces, 1)).problems
    sizes = mesh.polygon_sizes
    sides, counts = np.unique(sizes, return_counts=True) if sizes is not None else ([3], [mesh.n_faces])
    return {
        "kind": "mesh",
        "file": str(path),
        "format": MESH_FORMATS[path.suffix.lower()],
        "source_unit": mesh.source_unit,
        "unit_from": "--units" if given else "default",
        "vertices": mesh.n_vertices,
        "triangles": mesh.n_faces,
        "polygons": int(sizes.size) if sizes is not None else mesh.n_faces,
        "quads": int((sizes == 4).sum()) if sizes is not None else 0,
        "polygons_by_sides": {str(int(k)): int(n) for k, n in zip(sides, counts)},
        "uvs": int(mesh.uvs.shape[0]) if mesh.uvs is not None else 0,
        "face_size": _face_size(check_face_size(mesh.vertices, unit=mesh.source_unit, expected_mm=FACE_SIZE_MM),
                                "the mesh"),
        "pieces": {"count": check.n_pieces, "vertices_each": pieces},
        "problems": problems,
        "check": summary,
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
        "duration_s": round(result.n_frames / result.rate, 3),
        "first_frame": info.get("first_frame"),
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
        "source_units": info.get("source_units"),
        "map": info.get("map"),
    }
    report = folder / "report.json"
    if report.is_file():
        try:
            described.update(_run_report(json.loads(report.read_text(encoding="utf-8"))))
        except (OSError, ValueError):
            pass  # the report is a summary for people; the result reads without it
    return described


def _run_report(report: dict[str, Any]) -> dict[str, Any]:
    """The figures of ``report.json`` that say how a run went, where it has them."""
    out: dict[str, Any] = {}
    loo = report.get("warp_leave_one_out_mm")
    if isinstance(loo, dict) and loo:
        values = {k: float(v) for k, v in loo.items() if isinstance(v, (int, float)) and np.isfinite(v)}
        if values:
            worst = max(values, key=values.__getitem__)
            out["warp_leave_one_out_mm"] = {"median": round(float(np.median(list(values.values()))), 3),
                                            "max": round(values[worst], 3), "worst_marker": worst,
                                            "outliers": list(report.get("warp_outliers") or [])}
    for key in ("warnings", "notes"):
        if isinstance(report.get(key), list):
            out[key] = [str(s) for s in report[key]]
    return out


# --------------------------------------------------------------------------- text


def format_description(info: dict[str, Any], *, labels: bool = False) -> str:
    """The text ``facecap info`` prints for a :func:`describe_file` dict.

    Parameters
    ----------
    info : dict
        What :func:`describe_file` returned.
    labels : bool, default False
        List every marker label of a take, one per line with its gaps,
        instead of the first few.

    Returns
    -------
    str
        Lines of ``key  value``, values wrapped at 100 columns; every length
        in mm, every rate in Hz, every duration in s.

    Examples
    --------
    >>> info = {"kind": "marker take", "file": "take.c3d", "format": "C3D", "markers": 2, "labels": ["Chin", "Nose"],
    ...         "subjects": [], "rate_hz": 120.0, "frames": 240, "duration_s": 2.0, "first_frame": 0,
    ...         "timecode": "10:22:31:12", "capture_start": None, "source_unit": "mm", "unit_from": "file",
    ...         "gaps": {"missing_samples": 0}, "bounding_box_mm": None,
    ...         "face_size": {"across_mm": None, "note": None}}
    >>> print(format_description(info))
    take.c3d: marker take (C3D)
      markers       2: Chin, Nose
      frames        240 at 120 Hz, 2.000 s
      timecode      10:22:31:12 at the first frame
      unit          mm, as the file states
      gaps          none
    """
    kind = info.get("kind")
    if kind == "marker take":
        rows = _take_rows(info, labels)
        head = f"{Path(info['file']).name}: marker take ({info['format']})"
    elif kind == "mesh":
        rows = _mesh_rows(info)
        head = f"{Path(info['file']).name}: mesh ({info['format']})"
    elif kind == "facecap result":
        rows = _result_rows(info)
        head = f"{info['folder']}: facecap result" + (f" ({info['method']})" if info.get("method") else "")
    else:
        raise ValueError(f"info: not a describe_file dict (kind {kind!r})")
    return "\n".join([head] + [line for key, value in rows for line in _row(key, value)])


def _row(key: str, value: str) -> list[str]:
    indent = " " * (2 + _KEY_WIDTH)
    return textwrap.wrap(value, _WIDTH, initial_indent=f"  {key:<{_KEY_WIDTH - 2}}  ", subsequent_indent=indent,
                         break_on_hyphens=False) or [f"  {key}"]


def _frames(info: dict[str, Any]) -> str:
    text = f"{info['frames']:,} at {info['rate_hz']:g} Hz, {info['duration_s']:.3f} s"
    first = info.get("first_frame")
    if first:
        text += f" (capture frames {first:,} to {first + info['frames'] - 1:,})"
    return text


def _xyz(values: Any) -> str:
    return ", ".join(_length(v) for v in values)


def _frames_count(n: int) -> str:
    return f"{n:,} frame" + ("" if n == 1 else "s")


def _take_rows(info: dict[str, Any], all_labels: bool) -> list[tuple[str, str]]:
    names = info["labels"]
    gaps = info["gaps"]
    per_marker = gaps.get("missing_samples_per_marker", {})
    rows = []
    if all_labels or len(names) <= _LABELS_SHOWN:
        rows.append(("markers", f"{info['markers']:,}" + ("" if all_labels else ": " + ", ".join(names))))
    else:
        rows.append(("markers", f"{info['markers']:,}: {', '.join(names[:_LABELS_SHOWN])} and "
                                f"{len(names) - _LABELS_SHOWN:,} more (--labels lists them all)"))
    if info.get("subjects"):
        rows.append(("subject", ", ".join(info["subjects"])))
    rows.append(("frames", _frames(info)))
    if info.get("timecode"):
        rows.append(("timecode", f"{info['timecode']} at the first frame"))
    if info.get("capture_start"):
        rows.append(("recorded", str(info["capture_start"])))
    unit = info["source_unit"]
    rows.append(("unit", f"{unit}, as the file states" if info.get("unit_from") == "file"
                 else f"{unit}, as --units gives it (the file's own unit set aside)"))
    if not gaps.get("missing_samples"):
        rows.append(("gaps", "none"))
    else:
        worst = sorted(per_marker.items(), key=lambda item: -item[1])[:_GAPS_SHOWN]
        total = info["frames"] * info["markers"]
        rows.append(("gaps", f"{gaps['missing_samples']:,} of {total:,} samples missing "
                             f"({gaps['missing_percent']:.1f}%) in {gaps['markers_with_gaps']:,} of "
                             f"{info['markers']:,} markers; most in "
                             + ", ".join(f"{label} ({_frames_count(n)})" for label, n in worst)))
    rows += _size_rows(info, "in a frame (the middle side of the markers' box, median over frames)")
    box = info.get("bounding_box_mm")
    if box:
        rows.append(("extent", f"({_xyz(box['min'])}) to ({_xyz(box['max'])}) mm over the take"))
    if all_labels:
        width = max(len(s) for s in names)
        rows += [("labels" if i == 0 else "", f"{label:<{width}}  " + (f"{_frames_count(per_marker[label])} missing"
                                                                      if label in per_marker else ""))
                 for i, label in enumerate(names)]
    return rows


def _size_rows(info: dict[str, Any], measure: str) -> list[tuple[str, str]]:
    size = info.get("face_size") or {}
    rows = []
    if size.get("across_mm") is not None:
        rows.append(("size", f"{_length(size['across_mm'])} mm across {measure}"))
    if size.get("note"):
        rows.append(("warning", size["note"]))
    return rows


def _mesh_rows(info: dict[str, Any]) -> list[tuple[str, str]]:
    check = info["check"]
    rows = [("vertices", f"{info['vertices']:,}" + (f", {info['uvs']:,} UVs" if info.get("uvs") else ""))]
    by_sides = {int(k): n for k, n in info.get("polygons_by_sides", {}).items()}
    if set(by_sides) <= {3}:
        rows.append(("faces", f"{info['triangles']:,} triangles"))
    else:
        kinds = ", ".join(f"{n:,} {_POLYGON_NAMES.get(k, f'{k}-sided')}" for k, n in sorted(by_sides.items(),
                                                                                       key=lambda kn: -kn[1]))
        rows.append(("faces", f"{info['polygons']:,} polygons ({kinds}), {info['triangles']:,} triangles once split"))
    unit = info["source_unit"]
    if info.get("unit_from") == "--units":
        rows.append(("unit", f"{unit}, as --units gives it"))
    elif info["format"] == "glTF":  # read_mesh reads every mesh file as mm unless told
        rows.append(("unit", f"{unit}, the default; glTF files are in metres by the glTF spec (--units m)"))
    else:
        rows.append(("unit", f"{unit}: mesh files state none (--units gives another)"))
    box = check.get("bounding_box_mm")
    if box:
        lo, hi = np.asarray(box[0]), np.asarray(box[1])
        rows.append(("box", " x ".join(_length(v) for v in hi - lo) + f" mm (x, y, z), from ({_xyz(lo)}) to "
                            f"({_xyz(hi)}) mm"))
    rows += [row for row in _size_rows(info, "") if row[0] == "warning"]  # the box gives the size
    if check.get("mean_edge_length_mm") is not None:
        rows.append(("edges", f"{check['mean_edge_length_mm']:.3g} mm long on average"))
    pieces = info["pieces"]
    each = pieces["vertices_each"]
    if pieces["count"] <= 1:
        rows.append(("pieces", "1 (all connected)" if pieces["count"] == 1 else "none"))
    else:
        shown = each[:_PIECES_SHOWN]
        rest = each[_PIECES_SHOWN:]
        text = f"{pieces['count']:,}: " + ", ".join(f"{n:,}" for n in shown) + " vertices"
        if rest:
            text += (f", then {len(rest):,} of {rest[-1]:,}" + (f" to {rest[0]:,}" if rest[0] != rest[-1] else "")
                     + " vertices")
        rows.append(("pieces", text))
    if check.get("n_boundary_loops"):
        rows.append(("borders", f"{check['n_boundary_loops']:,} open borders or holes "
                                f"({check['n_boundary_edges']:,} boundary edges)"))
    problems = info.get("problems") or []
    rows += [("problems", p) for p in problems[:1]] + [("", p) for p in problems[1:]]
    if not problems:
        rows.append(("problems", "none found"))
    return rows



def _result_rows(info: dict[str, Any]) -> list[tuple[str, str]]:
    rows = [("frames", _frames(info)), ("vertices", f"{info['vertices']:,}, in {info['units']}")]
    if info.get("frames_in"):
        rows.append(("stored in", info["frames_in"]))
    if info.get("stabilized") is not None:
        rows.append(("head motion", "removed (stabilised), kept in head_motion.npy" if info["stabilized"]
                     else "not removed: the face moves with the head"))
    sources = dict(info.get("source_files") or {})
    if info.get("map") and "map" not in sources:
        sources["map"] = info["map"]
    units = info.get("source_units") or {}
    if sources:
        rows.append(("made from", ", ".join(f"{k} {v}" + (f" ({units[k]})" if k in units else "")
                                            for k, v in sources.items())))
    loo = info.get("warp_leave_one_out_mm")
    if loo:
        outliers = loo.get("outliers") or []
        rows.append(("warp check", f"a held-out marker lands {loo['median']:.3g} mm from its place (median), "
                                   f"{loo['max']:.3g} mm at worst ({loo['worst_marker']}); "
                                   + (f"check the map at {', '.join(outliers)}" if outliers else "no outlier")))
    exports = info.get("exports") or []
    rows.append(("exports", ", ".join(map(str, exports)) if exports else "none"))
    rows.append(("on disk", f"{info['size_mb']:,.1f} MB"))
    for key in ("warnings", "notes"):
        lines = info.get(key) or []
        rows += [(key if i == 0 else "", s) for i, s in enumerate(lines)]
    return rows
