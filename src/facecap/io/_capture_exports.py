"""Parse the text exports of two capture systems (private to :mod:`facecap.io`).

Qualisys QTM ``.tsv`` and OptiTrack Motive ``.csv``; the layouts are described in
the :mod:`facecap.io.read_markers` module docstring. Each parser returns the
arrays in the file's unit; ``read_markers`` converts and validates.
"""

from __future__ import annotations

import csv
import io
import math
from typing import NamedTuple

import numpy as np

from ..errors import FileFormatError
from ..typing import FloatArray

__all__ = ["ParsedExport", "parse_qualisys_tsv", "parse_motive_csv", "is_motive_csv"]


class ParsedExport(NamedTuple):
    """Positions (T, M, 3) in ``unit`` with NaN gaps, and what goes with them."""

    positions: FloatArray
    labels: list[str]
    rate: float
    unit: str | None
    first_frame: int
    capture_start: str | None = None  # as the file writes it


def _floats(rows: list[list[str]], line_numbers: list[int], path: str) -> FloatArray:
    out = np.full((len(rows), max((len(r) for r in rows), default=0)), np.nan)
    for i, (row, line) in enumerate(zip(rows, line_numbers)):
        for j, cell in enumerate(row):
            cell = cell.strip()
            if not cell:
                continue
            try:
                out[i, j] = float(cell)
            except ValueError:
                raise FileFormatError(f"line {line}, column {j + 1}: expected a number, got {cell!r}", path=path) from None
    return out


_TSV_KEYS = (
    "NO_OF_FRAMES", "NO_OF_CAMERAS", "NO_OF_MARKERS", "FREQUENCY", "NO_OF_ANALOG",
    "ANALOG_FREQUENCY", "DESCRIPTION", "TIME_STAMP", "DATA_INCLUDED", "MARKER_NAMES",
    "TRAJECTORY_TYPES", "EVENT", "COMMENT",
)


def parse_qualisys_tsv(text: str, path: str) -> ParsedExport:
    """Parse a QTM 3D ``.tsv`` export (unit mm; a gap is empty or x = y = z = 0)."""
    lines = text.splitlines()
    header: dict[str, tuple[list[str], int]] = {}
    k = 0
    while k < len(lines):
        cells = lines[k].rstrip("\r\n").split("\t")
        key = cells[0].strip().upper()
        if key in _TSV_KEYS:
            header.setdefault(key, (cells[1:], k + 1))
            k += 1
            continue
        if not lines[k].strip():
            k += 1
            continue
        break
    for required in ("NO_OF_FRAMES", "NO_OF_MARKERS", "FREQUENCY", "MARKER_NAMES"):
        if required not in header:
            raise FileFormatError(f"not a QTM .tsv export: no {required} line in its header", path=path)

    def number(key: str, integer: bool) -> float:
        cells, line = header[key]
        try:
            value = float(cells[0])
        except (IndexError, ValueError):
            raise FileFormatError(f"line {line}: {key} is not a number", path=path) from None
        if integer and (value != round(value) or value < 0):
            raise FileFormatError(f"line {line}: {key} must be a non-negative integer", path=path)
        return value

    n_frames = int(number("NO_OF_FRAMES", True))
    n_markers = int(number("NO_OF_MARKERS", True))
    rate = number("FREQUENCY", False)
    names_cells, names_line = header["MARKER_NAMES"]
    labels = [c.strip() for c in names_cells]
    while labels and not labels[-1]:
        labels.pop()
    if len(labels) != n_markers:
        raise FileFormatError(
            f"line {names_line}: MARKER_NAMES lists {len(labels)} markers but NO_OF_MARKERS says {n_markers}",
            path=path,
        )
    if n_markers == 0:
        raise FileFormatError("the file holds no markers (NO_OF_MARKERS 0)", path=path)
    width = 3 * n_markers
    lead = 0
    first_frame = 0
    if k < len(lines) and lines[k].split("\t")[0].strip().lower() == "frame":
        columns = [c.strip() for c in lines[k].split("\t")]
        lead = 2 if len(columns) > 1 and columns[1].lower() == "time" else 1
        k += 1
    rows, line_numbers = [], []
    for i in range(k, len(lines)):
        if not lines[i].strip():
            continue
        cells = lines[i].rstrip("\r\n").split("\t")
        if len(cells) < lead + width:
            cells += [""] * (lead + width - len(cells))
        if any(c.strip() for c in cells[lead + width :]):
            raise FileFormatError(
                f"line {i + 1}: {len(cells)} values, more than the {lead + width} the header implies", path=path
            )
        rows.append(cells[: lead + width])
        line_numbers.append(i + 1)
    if len(rows) != n_frames:
        raise FileFormatError(f"NO_OF_FRAMES says {n_frames} but the file holds {len(rows)} data rows", path=path)
    if n_frames == 0:
        raise FileFormatError("the file holds no frames", path=path)
    data = _floats(rows, line_numbers, path)
    if lead:
        frames = data[:, 0]
        if not np.isfinite(frames).all() or (np.diff(frames) != 1).any():
            raise FileFormatError("the Frame column must hold consecutive integers", path=path)
        first_frame = int(frames[0]) - 1  # QTM counts frames from 1
    P = data[:, lead:].reshape(n_frames, n_markers, 3)
    P[(P == 0.0).all(axis=2)] = np.nan
    stamp = header.get("TIME_STAMP", ([""], 0))[0]  # date and time, then seconds since the PC started
    return ParsedExport(P, labels, rate, "mm", first_frame, (stamp[0].strip() if stamp else "") or None)


def is_motive_csv(text: str) -> bool:
    """True if the text starts like an OptiTrack Motive export (``Format Version,...``)."""
    first = text.lstrip("\ufeff").split("\n", 1)[0]
    return first.strip().strip('"').lower().startswith("format version")


_MOTIVE_UNITS = {"meters": "m", "meter": "m", "millimeters": "mm", "millimeter": "mm",
                 "centimeters": "cm", "centimeter": "cm", "inches": "in"}


def parse_motive_csv(text: str, path: str) -> ParsedExport:
    """Parse a Motive ``.csv`` export: the Position columns of its Marker entries."""
    rows = list(csv.reader(io.StringIO(text.lstrip("\ufeff"))))
    first = rows[0]
    meta = {first[i].strip().lower(): first[i + 1].strip() for i in range(0, len(first) - 1, 2)}
    frame_row = next((i for i, r in enumerate(rows) if r and r[0].strip().lower() == "frame"), None)
    if frame_row is None or frame_row < 2:
        raise FileFormatError("not a Motive export: no 'Frame,Time (Seconds),...' row", path=path)
    keyed: dict[str, list[str]] = {}
    for r in rows[1:frame_row]:  # ",Type,..." (Motive 2.x) or "Type,..." rows
        if not r:
            continue
        key = (r[0].strip() or (r[1].strip() if len(r) > 1 else "")).lower()
        if key in ("type", "name", "id", "parent"):
            keyed.setdefault(key, r)
    if "type" not in keyed or "name" not in keyed:
        raise FileFormatError("not a Motive export: no Type and Name rows above the Frame row", path=path)
    kinds = rows[frame_row - 1]
    axes = rows[frame_row]
    n_cols = len(axes)

    def cell(row: list[str], j: int) -> str:
        return row[j].strip() if j < len(row) else ""

    markers: dict[str, dict[str, int]] = {}
    for j in range(2, n_cols):
        if cell(keyed["type"], j).lower() != "marker" or cell(kinds, j).lower() != "position":
            continue
        axis = cell(axes, j).upper()
        if axis in ("X", "Y", "Z"):
            markers.setdefault(cell(keyed["name"], j), {})[axis] = j
    labels = [name for name, cols in markers.items() if set(cols) == {"X", "Y", "Z"}]
    if not labels:
        raise FileFormatError("the Motive export holds no Marker position columns", path=path)
    rate_text = meta.get("export frame rate") or meta.get("capture frame rate")
    try:
        rate = float(rate_text) if rate_text else math.nan
    except ValueError:
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise FileFormatError("line 1: no positive Export Frame Rate or Capture Frame Rate", path=path)
    stated = meta.get("length units")
    unit = _MOTIVE_UNITS.get(stated.lower(), stated) if stated else "m"  # Motive's own unit is the metre
    body = [(i + 1, r) for i, r in enumerate(rows[frame_row + 1 :], start=frame_row) if any(c.strip() for c in r)]
    if not body:
        raise FileFormatError("the file holds no frames", path=path)
    data = _floats([r for _, r in body], [line for line, _ in body], path)
    if data.shape[1] < n_cols:
        data = np.hstack([data, np.full((data.shape[0], n_cols - data.shape[1]), np.nan)])
    frames = data[:, 0]
    if not np.isfinite(frames).all() or (np.diff(frames) != 1).any():
        raise FileFormatError("the Frame column must hold consecutive integers", path=path)
    cols = [[markers[name][a] for a in "XYZ"] for name in labels]
    P = data[:, np.array(cols)]  # (T, M, 3)
    return ParsedExport(np.ascontiguousarray(P), labels, rate, unit, int(frames[0]),
                        meta.get("capture start time") or None)
