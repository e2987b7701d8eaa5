"""``facecap map``'s job: a take's markers placed on a scan, written as ``map.json`` with a report and a picture.

The job reads nothing and parses nothing: it takes a scan and a take, prepares the take's rest frame
(:func:`~facecap.registration.rest_markers_of`), runs :func:`~facecap.registration.find_marker_map`, and writes

- ``map.json``: ``{"units": <the scan file's unit>, "markers": {label: [x, y, z], ...}}``, each marker's
  place on the skin as a point in the scan file's unit, in the take's marker order; the form
  :func:`~facecap.io.read_correspondence` reads. Points, not vertex indices: a vertex is up to half an
  edge from the place (1.2 mm on a 2.4 mm mesh, most of the 1.5 mm a map may be off), a point is exact
  and is snapped back to the same triangle on reading. The unit is written because mesh files state
  none: read against a scan in another unit, the points no longer lie on it, and ``animate``'s unit
  check says so.
- ``map_report.json`` beside it (``<name>_report.json`` for a map named ``<name>.json``): every
  marker's status, its height over the skin, how far its place may be off along the skin
  (``may_be_off_mm``), the pose and how sure the search was.
- ``map.png`` beside it (``<name>.png``): the scan seen from the front with each marker's place and label.

Markers not placed are left out of the map (the take keeps them: ``animate`` uses markers outside the
map, a head band, to stabilise the head).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CorrespondenceError, MarkerError
from ..io.atomic_write import atomic_write_text, check_file_destination, recorded_path
from ..markers.check_scan_units import check_scan_units
from ..markers.prepare_take import DEFAULT_REST_AVERAGE_S
from ..markers.rigid_fit import rigid_fit
from ..registration.find_marker_map import (DEFAULT_OFF_SKIN_MM, MIN_MAP_MARKERS, MarkerMap, find_marker_map,
                                            marker_status)
from ..registration.rest_markers_of import rest_markers_of
from ..structures import Correspondence, MarkerSequence, Mesh
from ..typing import FloatArray
from ..units import mm_per_unit
from ..validate import as_positive

__all__ = ["map_markers", "map_side_files"]


def map_side_files(out: str | os.PathLike[str]) -> tuple[Path, Path]:
    """The report and the picture written beside a map: ``map.json`` -> ``map_report.json``, ``map.png``."""
    path = Path(os.fspath(out))
    return path.with_name(f"{path.stem}_report.json"), path.with_name(f"{path.stem}.png")


def _landmark_start(rest: FloatArray, labels: tuple[str, ...], landmarks: Correspondence, V: FloatArray,
                    ) -> tuple[FloatArray, dict[str, int]]:
    """The rigid pose that puts the landmark markers on their landmark points (4, 4), and their take columns."""
    column = {label: i for i, label in enumerate(labels)}
    unknown = [s for s in landmarks.labels if s not in column]
    if unknown:
        raise CorrespondenceError(f"names markers the take does not have: {unknown}", path=landmarks.source_path)
    used = {s: column[s] for s in landmarks.labels if np.isfinite(rest[column[s]]).all()}
    if len(used) < 3:
        raise CorrespondenceError(
            f"expected at least 3 landmark markers seen at the rest frame, got {len(used)} "
            f"({', '.join(used) or 'none'})", path=landmarks.source_path)
    targets = landmarks.select(list(used)).points(V)
    fit = rigid_fit(rest[list(used.values())], targets)
    if not np.isfinite(fit.rotation).all():
        raise CorrespondenceError("the landmark markers are in a line: no pose follows from them",
                                  path=landmarks.source_path)
    start = np.eye(4)
    start[:3, :3], start[:3, 3] = fit.rotation, fit.translation
    return start, used


def _front_view(scan: Mesh, found: MarkerMap) -> tuple[FloatArray, FloatArray]:
    """The direction the face looks (scan coordinates) and an up for the picture.

    Forward: the mean direction from the placed markers' skin points to their centres (the skin's
    outward normals under the markers). Up: the scan's +y, or +z where +y is nearer forward (a Z-up
    scanner frame); mesh files do not say which way is up.
    """
    rows = found.placed
    if rows.sum() < 1:
        rows = np.isfinite(found.markers_on_scan).all(axis=1)
        out = found.markers_on_scan[rows] - scan.vertices.mean(axis=0)
    else:
        out = found.markers_on_scan[rows] - found.surface_points[rows]
    forward = np.sum(out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12), axis=0)
    forward /= max(float(np.linalg.norm(forward)), 1e-12)
    up = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) <= abs(forward[2]) else np.array([0.0, 0.0, 1.0])
    return forward, up


def _summary_lines(report: dict[str, Any], out: Path) -> list[str]:
    """What ``facecap map`` prints: what was written, the fit, and every marker not placed or to check."""
    counts = report["counts"]
    search = report["search"]
    report_file, picture = map_side_files(out)
    lines = [f"wrote {out}: {counts['placed'] + counts['ambiguous'] + counts['uncertain']} of "
             f"{report['n_markers']} markers placed on the scan (report {report_file.name}, picture {picture.name})"]
    fit = report["height_off_offset_mm"]
    if fit["median"] is not None:
        lines.append(f"distance to the skin less the {report['marker_offset_mm']:g} mm marker offset, placed markers: "
                     f"median {fit['median']:.2f} mm, 95th percentile {fit['p95']:.2f} mm, largest {fit['max']:.2f} mm")
    if search["from"] == "landmarks":
        lines.append(f"pose from the landmarks ({', '.join(search['landmark_markers'])}); each of them is placed "
                     f"{search['landmark_agreement_mm']['max']:.1f} mm or less from its landmark")
    else:
        second = search["second_score_mm"]
        versus = "no other pose" if second is None else f"the next distinct pose {second:.2f} mm"
        lines.append(f"pose found by the global search: score {search['score_mm']:.2f} mm against {versus} "
                     f"({'sure' if search['sure'] else 'UNSURE: check map.png, or pass --landmarks'})")
    fit = report["fit"]
    moved = fit["resting_expression_rms_mm"]
    if moved is not None and not fit["resting_expression_kept"]:
        lines.append(f"warning: the markers would have to move {moved:.1f} mm RMS to lie on this scan, more than a "
                     "resting face moves them: the scan may be another person's face; the markers were placed "
                     "rigidly (check map.png)")
    elif fit["off_skin_limit_mm"] > DEFAULT_OFF_SKIN_MM:
        lines.append(f"warning: the markers fit this scan loosely, so a marker counts as off the skin only beyond "
                     f"{fit['off_skin_limit_mm']:.1f} mm (else {DEFAULT_OFF_SKIN_MM:g} mm)")
    by_status: dict[str, list[str]] = {}
    rows = sorted(report["markers"], key=lambda row: -(row["may_be_off_mm"] or 0.0))  # the likeliest misses first
    for row in rows:
        label = row["label"]
        if row["status"] == "uncertain":
            label += f" ({row['may_be_off_mm']:.1f} mm)"
        by_status.setdefault(row["status"], []).append(label)
    words = {
        "not seen": "not placed, missing at the rest frame",
        "off the skin": "not placed, off the skin (head band, hair, or not on this scan)",
        "past the rim": "not placed, over a hole or past the scan's rim",
        "ambiguous": "placed ambiguously, another sheet of skin close under them (lips, eyelids): check",
        "uncertain": "placed, but uncertain: the resting face differs from the scan there (the fit left them off "
                     "the marker offset), so each may be off along the skin by up to the mm shown: check",
    }
    for status, text in words.items():
        if by_status.get(status):
            lines.append(f"{len(by_status[status])} {text}: {', '.join(by_status[status])}")
    return lines


def _map_json(unit: str, points: dict[str, list[float]]) -> str:
    """The wrapped map, one marker a line (a JSON file a person can read and edit)."""
    rows = ",\n".join(f"  {json.dumps(label)}: {json.dumps(point)}" for label, point in points.items())
    return f'{{\n "units": {json.dumps(unit)},\n "markers": {{\n{rows}\n }}\n}}\n'


def map_markers(
    scan: Mesh,
    take: MarkerSequence,
    out: str | os.PathLike[str],
    *,
    rest_frame: int = 0,
    marker_offset_mm: float = 1.5,
    landmarks: Correspondence | None = None,
    convert_scan_units: bool = False,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Find every marker's place on the scan and write the map, its report and its picture.

    Parameters
    ----------
    scan : Mesh
        The neutral scan, as read (mm, ``source_unit`` the file's unit).
    take : MarkerSequence
        The take, every marker (head-band markers are found off the skin and left out).
    out : str or path-like
        The map file to write (``map.json``); the report and the picture go
        beside it (:func:`map_side_files`: ``map_report.json``, ``map.png``).
    rest_frame : int, default 0
        The frame whose expression is nearest the scan's.
    marker_offset_mm : float, default 1.5
        Marker centre height above the skin, mm.
    landmarks : Correspondence, optional
        A few markers' places on the scan, read with
        :func:`~facecap.io.read_correspondence` (map.json's own format: label
        -> vertex index or point): at least 3 markers seen at the rest frame.
        They give the pose instead of the global search.
    convert_scan_units : bool, default False
        When the scan's size says it is in another unit than it was read in:
        False stops (``--scan-units``), True converts (``--scan-units auto``).
    overwrite : bool, default False
        Replace an existing map, report or picture.

    Returns
    -------
    dict
        The report as written to ``map_report.json``, plus ``summary``: the
        lines ``facecap map`` prints.

    Raises
    ------
    InputError
        If ``out`` or a sibling exists (without ``overwrite``) or cannot be written.
    MarkerError
        If the rest frame is outside the take or fewer than 4 markers are seen there.
    MeshError
        If the scan's size says it is in another unit (see ``convert_scan_units``).
    CorrespondenceError
        If the landmarks name markers the take lacks, or fewer than 3 of them are seen at rest.
    SolverError
        If no pose puts the markers on the scan.
    """
    started = time.perf_counter()
    out = Path(os.fspath(out))
    report_file, picture = map_side_files(out)
    for path in (out, report_file, picture):  # refuse before the work, not after it
        check_file_destination(path, overwrite=overwrite)
    offset = as_positive(marker_offset_mm, name="--marker-offset", allow_zero=True)
    if not (isinstance(rest_frame, (int, np.integer)) and 0 <= rest_frame < take.n_frames):
        raise MarkerError(f"--rest-frame {rest_frame} is outside the take (0..{take.n_frames - 1})",
                          path=take.source_path)
    at_rest = take.positions[rest_frame]
    n_seen = int(np.isfinite(at_rest).all(axis=1).sum())
    if n_seen < MIN_MAP_MARKERS:
        raise MarkerError(f"only {n_seen} marker(s) seen at the rest frame {rest_frame}; at least "
                          f"{MIN_MAP_MARKERS} are needed (choose another --rest-frame)", path=take.source_path)
    scan = check_scan_units(scan, at_rest, convert=convert_scan_units)  # before the work, not after it
    if landmarks is not None:
        _landmark_start(at_rest, take.labels, landmarks, scan.vertices)  # a bad landmarks file stops here
    rest, motion = rest_markers_of(take, rest_frame)
    V, F = scan.vertices, scan.faces
    start, landmark_columns = (None, {}) if landmarks is None else _landmark_start(rest, take.labels, landmarks, V)
    found = find_marker_map(rest, V, F, marker_offset_mm=offset, motion=motion, start=start)

    status = marker_status(found)
    unit = scan.source_unit
    per_unit = mm_per_unit(unit)
    placed_points = {label: [round(float(x) / per_unit, 6) for x in found.surface_points[k]]
                     for k, label in enumerate(take.labels) if found.placed[k]}
    residual = np.abs(found.heights - offset)[found.placed]
    rows = []
    for k, label in enumerate(take.labels):
        rows.append({
            "label": label,
            "status": status[k],
            "skin_point": placed_points.get(label),
            "height_mm": None if not np.isfinite(found.heights[k]) else round(float(found.heights[k]), 3),
            "height_off_offset_mm": (None if not np.isfinite(found.heights[k])
                                     else round(float(found.heights[k] - offset), 3)),
            "second_sheet_mm": (None if not np.isfinite(found.second_sheet_mm[k])
                                else round(float(found.second_sheet_mm[k]), 2)),
            "may_be_off_mm": (None if not np.isfinite(found.may_be_off_mm[k])
                              else round(float(found.may_be_off_mm[k]), 2)),
        })
    counts = {s: status.count(s) for s in ("placed", "ambiguous", "uncertain", "off the skin", "past the rim",
                                           "not seen")}
    search: dict[str, Any] = {
        "from": "landmarks" if landmarks is not None else "global search",
        "score_mm": round(found.score_mm, 3),
        "second_score_mm": None if not np.isfinite(found.second_score_mm) else round(found.second_score_mm, 3),
        "sure": found.sure,
    }
    if landmarks is not None:
        targets = landmarks.select(list(landmark_columns)).points(V)
        rows_lm = list(landmark_columns.values())
        where = np.where(found.placed[rows_lm, None], found.surface_points[rows_lm], found.markers_on_scan[rows_lm])
        apart = np.linalg.norm(where - targets, axis=1)  # the place found against the place given
        search["landmark_markers"] = list(landmark_columns)
        search["landmark_agreement_mm"] = {"max": round(float(apart.max()), 2),
                                           "per_marker": dict(zip(landmark_columns, np.round(apart, 2).tolist()))}
    report: dict[str, Any] = {
        "map": out.name,
        "picture": picture.name,
        "scan": recorded_path(scan.source_path, folder=out.parent) if scan.source_path else None,
        "scan_unit": unit,
        "take": recorded_path(take.source_path, folder=out.parent) if take.source_path else None,
        "rest_frame": int(rest_frame),
        "rest_average_s": DEFAULT_REST_AVERAGE_S,
        "motion_frames": int(motion.shape[0]),
        "marker_offset_mm": offset,
        "n_markers": len(take.labels),
        "counts": counts,
        "height_off_offset_mm": {
            "median": round(float(np.median(residual)), 3) if residual.size else None,
            "p95": round(float(np.percentile(residual, 95)), 3) if residual.size else None,
            "max": round(float(residual.max()), 3) if residual.size else None,
        },
        "search": search,
        "fit": {
            "off_skin_limit_mm": round(found.off_skin_limit_mm, 2),
            "resting_expression_rms_mm": (None if not np.isfinite(found.expression_rms_mm)
                                          else round(found.expression_rms_mm, 3)),
            "resting_expression_kept": found.expression_kept,
        },
        "pose_take_to_scan": {"rotation": np.round(found.rotation, 6).tolist(),
                              "translation_mm": np.round(found.translation, 4).tolist()},
        "normals_flipped": found.normals_flipped,
        "markers": rows,
        "seconds": None,
    }

    from ..report.plot_marker_map import plot_marker_map  # matplotlib only when a picture is drawn

    forward, up = _front_view(scan, found)
    kinds = ["placed" if s == "placed" else "check" if s in ("ambiguous", "uncertain") else "not placed"
             for s in status]
    drawn = np.where(found.placed[:, None], found.surface_points, found.markers_on_scan)
    faces = F[:, ::-1] if found.normals_flipped else F
    plot_marker_map(V, faces, drawn, take.labels, kinds, picture, forward=forward, up=up,
                    title=f"{out.name}: {len(placed_points)} of {len(take.labels)} markers placed")
    report["seconds"] = round(time.perf_counter() - started, 2)
    atomic_write_text(report_file, json.dumps(report, indent=1) + "\n")
    atomic_write_text(out, _map_json(unit, placed_points))
    report["summary"] = _summary_lines(report, out)
    return report
