"""``facecap info map.json --scan SCAN --markers TAKE``: a marker map checked against the take it is for.

A hand-made map (or one from ``facecap map``, edited since) is checked the way ``facecap map`` finds
one: the take's rest markers are fitted rigidly to where the map puts them (a robust fit, so a few
wrong entries do not move it), and from that pose each marker is snapped to the skin under it. A map
entry far from both where the fitted marker is and where the skin under it is, is flagged: a wrong
vertex, a label swapped with another, a point in another unit.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import igl
import numpy as np

from ..errors import CorrespondenceError, FacecapWarning
from ..io.read_correspondence import match_correspondence
from ..markers.resting_expression import robust_rigid_fit
from ..structures import Correspondence, MarkerSequence, Mesh
from ..markers.check_take_units import check_take_units
from ..validate import as_positive
from .find_marker_map import MIN_MAP_MARKERS, find_marker_map, marker_status
from .register_markers_to_scan import scan_winding
from .rest_markers_of import rest_markers_of

__all__ = ["check_marker_map", "MAP_CHECK_MM"]

MAP_CHECK_MM = 3.0
"""A map entry further than this from where the take puts its marker on the skin is flagged, mm. The
places ``facecap map`` finds are within 1.5 mm of the truth for 95 % of markers and a careful hand
pick within about 1 mm, so 3 mm is a wrong entry, not an imprecise one."""


def check_marker_map(
    scan: Mesh,
    take: MarkerSequence,
    correspondence: Correspondence,
    *,
    rest_frame: int = 0,
    marker_offset_mm: float = 1.5,
) -> dict[str, Any]:
    """Check a marker map against a take: how far each entry is from where the take puts its marker.

    Parameters
    ----------
    scan : Mesh
        The scan the map refers to.
    take : MarkerSequence
        The take, every marker.
    correspondence : Correspondence
        The map, read with :func:`~facecap.io.read_correspondence` against ``scan``.
    rest_frame : int, default 0
        The frame whose expression is nearest the scan's.
    marker_offset_mm : float, default 1.5
        Marker centre height above the skin, mm.

    Returns
    -------
    dict
        JSON-ready: ``markers`` (one row per map entry: ``label``,
        ``to_mapped_mm`` the fitted marker centre's distance from the map's
        place lifted by the offset, ``height_off_offset_mm`` its distance to
        the skin less the offset, ``found_vs_mapped_mm`` the distance from the
        map's place to where the marker snaps onto the skin, ``weight`` in the
        robust fit, ``status`` as :func:`marker_status`, ``flagged``),
        ``flagged`` (labels, worst first), ``not_in_map`` (take markers the map
        lacks), ``fit_rms_mm`` (the unflagged markers' RMS ``to_mapped_mm``)
        and ``summary`` (the lines ``facecap info`` prints).

    Raises
    ------
    CorrespondenceError
        If the map names markers the take lacks, or fewer than 4 of its
        markers are seen at the rest frame.
    MarkerError
        If the rest frame is outside the take.
    MeshError
        If the map's places and the take's markers differ in size by a length
        unit (the scan read in the wrong unit).
    """
    offset = as_positive(marker_offset_mm, name="--marker-offset", allow_zero=True)
    with warnings.catch_warnings():  # the markers the map lacks are listed in the report, not warned about
        warnings.simplefilter("ignore", FacecapWarning)
        match = match_correspondence(correspondence, take.labels)
    rest, motion = rest_markers_of(take, rest_frame)
    check_take_units(scan, take, correspondence, rest_frame=rest_frame)
    corr, columns = match.correspondence, match.take_columns
    V, F = scan.vertices, scan.faces
    mapped = corr.points(V)
    side = -1.0 if scan_winding(V, F) < 0 else 1.0
    vertex_normals = igl.per_vertex_normals(V, F) * side
    normals = np.einsum("kj,kjd->kd", corr.weights, vertex_normals[corr.vertex_indices])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    centres = mapped + offset * normals
    seen = np.isfinite(rest[columns]).all(axis=1)
    if seen.sum() < MIN_MAP_MARKERS:
        raise CorrespondenceError(f"only {int(seen.sum())} of the map's markers are seen at the rest frame "
                                  f"{rest_frame}; at least {MIN_MAP_MARKERS} are needed", path=corr.source_path)
    fit, weights = robust_rigid_fit(rest[columns], centres)
    start = np.eye(4)
    start[:3, :3], start[:3, 3] = fit.rotation, fit.translation
    found = find_marker_map(rest, V, F, marker_offset_mm=offset, motion=motion, start=start)

    to_mapped = np.linalg.norm(fit.apply(rest[columns]) - centres, axis=1)
    found_vs_mapped = np.linalg.norm(found.surface_points[columns] - mapped, axis=1)
    status = marker_status(found)
    rows, flagged = [], []
    for k, label in enumerate(corr.labels):
        j = int(columns[k])
        worst = np.nanmax([to_mapped[k], found_vs_mapped[k]]) if seen[k] else np.nan
        bad = bool(seen[k] and (worst > MAP_CHECK_MM or not found.placed[j]))
        if bad:
            flagged.append((float(np.nan_to_num(worst, nan=np.inf)), label))
        rows.append({
            "label": label,
            "to_mapped_mm": _rounded(to_mapped[k]),
            "height_off_offset_mm": _rounded(found.heights[j] - offset),
            "found_vs_mapped_mm": _rounded(found_vs_mapped[k]),
            "weight": _rounded(weights[k]),
            "status": status[j],
            "flagged": bad,
        })
    flagged.sort(reverse=True)
    good = np.array([not row["flagged"] for row in rows]) & seen
    report: dict[str, Any] = {
        "kind": "marker map check",
        "map": corr.source_path,
        "scan": scan.source_path,
        "take": take.source_path,
        "rest_frame": int(rest_frame),
        "marker_offset_mm": offset,
        "n_mapped": len(corr),
        "not_in_map": list(match.ignored_labels),
        "not_seen_at_rest": [corr.labels[k] for k in np.flatnonzero(~seen)],
        "fit_rms_mm": _rounded(np.sqrt(np.mean(to_mapped[good] ** 2))) if good.any() else None,
        "flagged": [label for _, label in flagged],
        "markers": rows,
    }
    report["summary"] = _summary_lines(report, {row["label"]: row for row in rows})
    return report


def _rounded(x: float) -> float | None:
    return None if not np.isfinite(x) else round(float(x), 3)


def _summary_lines(report: dict[str, Any], rows: dict[str, dict[str, Any]]) -> list[str]:
    """The lines ``facecap info`` prints for a map check."""
    name = Path(os.fspath(report["map"] or "map")).name
    take = Path(os.fspath(report["take"] or "take")).name
    lines = [f"{name}: marker map, {report['n_mapped']} markers, checked against {take} at frame "
             f"{report['rest_frame']}"]
    if report["fit_rms_mm"] is not None:
        lines.append(f"  fit           the take's rest markers lie {report['fit_rms_mm']:.2f} mm RMS from the mapped "
                     f"places (lifted by the {report['marker_offset_mm']:g} mm marker offset), flagged entries "
                     "left out")
    if report["not_in_map"]:
        lines.append(f"  not in map    {len(report['not_in_map'])}: {', '.join(report['not_in_map'])} (used only to "
                     "stabilise the head)")
    if report["not_seen_at_rest"]:
        lines.append(f"  not checked   missing at the rest frame: {', '.join(report['not_seen_at_rest'])}")
    if not report["flagged"]:
        lines.append(f"  flagged       none: every entry within {MAP_CHECK_MM:g} mm of where the take puts its marker")
        return lines
    lines.append(f"  flagged       {len(report['flagged'])} entr{'y' if len(report['flagged']) == 1 else 'ies'} more "
                 f"than {MAP_CHECK_MM:g} mm from where the take puts the marker (a wrong vertex or a swapped label):")
    for label in report["flagged"]:
        row = rows[label]
        found = row["found_vs_mapped_mm"]
        where = (f"the skin under the marker is {found:.1f} mm from the mapped place" if found is not None
                 else f"the marker is not on the skin ({row['status']})")
        lines.append(f"    {label}: the fitted marker is {row['to_mapped_mm']:.1f} mm from its mapped place; {where}")
    return lines
