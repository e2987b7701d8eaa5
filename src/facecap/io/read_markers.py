"""Read a labelled marker take from C3D, TRC, Qualisys TSV, OptiTrack Motive CSV or facecap CSV.

Formats
-------
``.c3d``
    The binary motion-capture standard (https://www.c3d.org), read with
    ezc3d. Labels come from ``POINT:LABELS`` (then ``LABELS2``, ...), the rate
    from ``POINT:RATE``, the unit from ``POINT:UNITS`` (a word cut to the
    parameter's width, such as ``'mete'``, is completed). A sample is occluded
    when its residual is negative or its x, y, z are all exactly zero (how
    C3D writers, ezc3d included, store a gap). Intel, DEC (VAX floats) and
    SGI/MIPS big-endian files are read; big-endian ones are converted to
    Intel byte order in a temporary copy that ezc3d reads. The counts are the
    parameters' (``POINT:USED``, ``POINT:FRAMES``, for takes beyond 65535
    frames ``TRIAL:ACTUAL_START_FIELD``/``ACTUAL_END_FIELD`` or
    ``POINT:LONG_FRAMES``) where the file holds that data, else the header's
    copy where it does. ``Subject:Marker`` labels (Vicon Nexus, ART) lose the
    prefix, kept in :attr:`MarkerSequence.subjects`, when the labels stay
    unique without it; a repeated label gets a ``_2``, ``_3`` suffix (with a
    :class:`~facecap.errors.FacecapWarning`); an empty one is
    ``unlabeled_point_<column>``. The SMPTE timecode of the first frame, kept
    in :attr:`MarkerSequence.timecode`, comes from a ``TIMECODE`` group, the
    layout Vicon writes: ``FIRST_FRAME`` (hours, minutes, seconds, frames and
    perhaps a subframe, or the timecode as text) and ``DROP_FRAMES``. C3D has
    no standard place for a timecode; a file without that group has none.
``.trc``
    The tab-separated text format of Motion Analysis and OpenSim: a
    ``PathFileType`` line, a line of header keys (``DataRate``,
    ``CameraRate``, ``NumFrames``, ``NumMarkers``, ``Units``, ...) and one of
    their values, a ``Frame#  Time  name1      name2 ...`` line, an
    ``X1 Y1 Z1 X2 ...`` line, then one row per frame. Empty cells are gaps.
``.tsv``
    Qualisys Track Manager's 3D export: tab-separated header lines
    ``NO_OF_FRAMES``, ``NO_OF_CAMERAS``, ``NO_OF_MARKERS``, ``FREQUENCY``
    (Hz), ``NO_OF_ANALOG``, ``ANALOG_FREQUENCY``, ``DESCRIPTION``,
    ``TIME_STAMP``, ``DATA_INCLUDED``, ``MARKER_NAMES`` (one name per cell,
    and newer ``TRAJECTORY_TYPES``), then optionally a column row
    ``Frame  Time  A X  A Y  A Z ...`` and one row per frame (``Frame`` counts
    from 1; without the column row a data row is just X Y Z per marker).
    Coordinates are in mm; an occluded marker is empty or 0, 0, 0. The date
    and time in ``TIME_STAMP`` (the capture's start by QTM's clock) is kept in
    :attr:`MarkerSequence.capture_start`.
``.csv`` from OptiTrack Motive
    Recognised by its first line, ``Format Version,<v>,Take Name,...`` with
    key/value pairs among them ``Capture Frame Rate``, ``Export Frame Rate``
    (the rate used) and ``Length Units`` (``Meters``, ``Centimeters`` or
    ``Millimeters``; metres if absent). Then a blank row, a ``Type`` row
    (``Marker``, ``Rigid Body``, ``Rigid Body Marker``, ``Bone``, ...), a
    ``Name`` row, an ``ID`` row, perhaps a ``Parent`` row, a row saying
    ``Position``/``Rotation``/``Mean Marker Error`` per column and the
    ``Frame,Time (Seconds),X,Y,Z,...`` row; then one row per frame (``Frame``
    from 0). Only the ``Marker`` columns' ``Position`` X, Y, Z are read (not
    rigid bodies or their markers); a blank cell is a gap. ``Capture Start
    Time`` is kept in :attr:`MarkerSequence.capture_start`.
``.csv``
    facecap's own simple format, comma separated::

        # rate=120
        # unit=mm
        frame,time,Chin_x,Chin_y,Chin_z,NoseTop_x,NoseTop_y,NoseTop_z
        0,0.0,12.5,-3.0,101.2,,,
        1,0.008333333333333333,12.6,-3.1,101.0,0.5,40.1,120.0

    Optional leading comment lines ``# key=value`` give ``rate`` (Hz) and
    ``unit`` (``mm``, ``cm``, ``m`` or ``in``; default ``mm``); other comment
    lines are ignored. The header row is ``frame,time`` followed by three
    columns ``<label>_x,<label>_y,<label>_z`` per marker (a label may itself
    contain ``_`` but not ``,``). ``frame`` holds consecutive integers, the
    first being :attr:`MarkerSequence.first_frame`; ``time`` is in seconds.
    An empty cell is a gap. Without ``# rate=`` the rate is inferred from the
    ``time`` column, which must then be evenly spaced.

Frame numbering: :attr:`MarkerSequence.first_frame` is the 0-based number of
the take's first frame in the capture's own frame count. C3D headers and TRC
``Frame#`` columns count from 1, so a take starting at C3D frame 1 or TRC
``Frame#`` 1 has ``first_frame == 0``; the CSV ``frame`` column is already
0-based.
"""

from __future__ import annotations

import math
import os
import struct
import tempfile
import warnings
from pathlib import Path

import numpy as np

from ..errors import FacecapWarning, FileFormatError, InputError
from ..structures import MarkerSequence
from ..typing import FloatArray
from ..units import mm_per_unit, normalize_unit
from ._c3d_big_endian import big_endian_to_intel
from ._capture_exports import ParsedExport, is_motive_csv, parse_motive_csv, parse_qualisys_tsv
from ._c3d_check import DEC, MIPS, C3DLayout, c3d_layout

__all__ = ["read_markers", "MARKER_FORMATS", "MARKER_SUFFIXES"]

MARKER_FORMATS: dict[str, str] = {
    ".c3d": "C3D",
    ".trc": "TRC",
    ".tsv": "Qualisys QTM TSV",
    ".csv": "OptiTrack Motive or facecap CSV",
}
"""File suffix -> the formats :func:`read_markers` reads with it (``facecap --help`` lists these)."""

MARKER_SUFFIXES = tuple(MARKER_FORMATS)
"""File suffixes :func:`read_markers` reads (the format is chosen by the suffix; ``.csv`` is sniffed)."""


def read_markers(path: str | os.PathLike[str], *, unit: str | None = None) -> MarkerSequence:
    """Read a marker take from a ``.c3d``, ``.trc``, ``.tsv`` or ``.csv`` file, in millimetres.

    The format is chosen by the file's suffix (case-insensitive), and for
    ``.csv`` by its first line (OptiTrack Motive or facecap's own); see the
    module docstring for what each format holds and how gaps are written.

    Parameters
    ----------
    path : str or os.PathLike
        The file to read.
    unit : {'mm', 'cm', 'm', 'in'} or None, optional
        Length unit of the coordinates in the file. Default None takes the
        unit the file states (C3D ``POINT:UNITS``, TRC ``Units``, Motive
        ``Length Units``, CSV ``# unit=``; QTM ``.tsv`` is mm), or ``'mm'`` if
        it states none (Motive: ``'m'``). Give it to override a file whose
        stated unit is wrong.

    Returns
    -------
    markers : MarkerSequence
        ``positions`` (T, M, 3) float64 in mm with NaN at gaps, ``labels`` in
        file order, ``rate`` in Hz, ``source_unit`` the unit the file was read
        in, ``source_path``, ``first_frame`` (0-based, see module docstring),
        and for C3D ``residuals`` (T, M) float64 in mm, NaN at gaps (None for
        TRC and CSV, which hold no residuals) and ``subjects`` (see the module
        docstring; None when the labels carry none); ``timecode`` and
        ``capture_start`` where the file states them (see the module docstring).

    Raises
    ------
    FileFormatError
        If the file is missing, empty, truncated, corrupt, has an unknown
        suffix, or its header disagrees with its data; the message names the
        file and, for text formats, the line.

    Warns
    -----
    FacecapWarning
        For a C3D file with repeated labels (renamed), one that ends after
        fewer whole frames than it declares (the frames it holds are read), or
        one whose ``TIMECODE:FIRST_FRAME`` is no timecode (read without one).
    InputError
        If ``unit`` is not a known length unit.

    Notes
    -----
    C3D files are checked in Python (header, parameter section, the data the
    counts imply) before ezc3d parses them, following ezc3d's own parser, so
    that a file ezc3d would crash on, hang on, or silently read other frames
    or markers from is refused or corrected: a truncated file (one that ends
    inside a frame) is refused; one that ends exactly after a whole frame,
    short of the declared count (an export whose writer stopped early), is read
    with a warning; a stale ``POINT:USED`` or ``POINT:FRAMES`` that the data do
    not fit gives way to the header's copy that they do fit.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "take.csv"
    >>> _ = p.write_text("# rate=100\\n# unit=cm\\nframe,time,a_x,a_y,a_z\\n0,0,1,2,3\\n1,0.01,,,\\n")
    >>> take = read_markers(p)
    >>> take.positions[0, 0].tolist(), take.rate, take.source_unit
    ([10.0, 20.0, 30.0], 100.0, 'cm')
    >>> bool(np.isnan(take.positions[1, 0]).all())
    True
    """
    unit_override = None if unit is None else normalize_unit(unit, name="unit")
    p = Path(os.fspath(path))
    name = str(p)
    suffix = p.suffix.lower()
    if suffix not in MARKER_SUFFIXES:
        raise FileFormatError(
            f"unsupported marker file suffix {p.suffix!r}; expected one of {', '.join(MARKER_SUFFIXES)}",
            path=name,
        )
    if not p.exists():
        raise FileFormatError("file not found", path=name)
    if not p.is_file():
        raise FileFormatError("not a regular file", path=name)
    if suffix == ".c3d":
        return _read_c3d(p, unit_override)
    text = _read_text(p)
    if suffix == ".trc":
        return _read_trc(text, name, unit_override)
    if suffix == ".tsv":
        return _from_export(parse_qualisys_tsv(text, name), name, unit_override, "the QTM export (mm)")
    if is_motive_csv(text):
        return _from_export(parse_motive_csv(text, name), name, unit_override, "line 1: Length Units")
    return _read_csv(text, name, unit_override)


def _from_export(parsed: ParsedExport, path: str, unit_override: str | None, where: str) -> MarkerSequence:
    labels, subjects = _c3d_labels(parsed.labels, path)
    file_unit = _file_unit(parsed.unit, unit_override, path, where)
    return _make_sequence(parsed.positions, labels, parsed.rate, file_unit, path, parsed.first_frame, None, subjects,
                          capture_start=parsed.capture_start)


# --------------------------------------------------------------------------- shared


def _make_sequence(
    positions_file_unit: FloatArray,
    labels: list[str],
    rate: float,
    file_unit: str,
    path: str,
    first_frame: int,
    residuals_file_unit: FloatArray | None = None,
    subjects: tuple[str, ...] | None = None,
    *,
    timecode: str | None = None,
    capture_start: str | None = None,
) -> MarkerSequence:
    """Convert to mm and build the record; problems become FileFormatError naming ``path``."""
    blank = [i for i, s in enumerate(labels) if not s.strip()]
    if blank:
        raise FileFormatError(f"marker(s) at column(s) {blank} have an empty label", path=path)
    counts: dict[str, int] = {}
    for s in labels:
        counts[s] = counts.get(s, 0) + 1
    dup = sorted(s for s, n in counts.items() if n > 1)
    if dup:
        raise FileFormatError(f"duplicate marker labels {dup}", path=path)
    if not (math.isfinite(rate) and rate > 0):
        raise FileFormatError(f"frame rate must be a positive number of Hz, got {rate!r}", path=path)
    scale = mm_per_unit(file_unit)
    P = np.asarray(positions_file_unit, dtype=np.float64) * scale
    if np.isinf(P).any():
        raise FileFormatError("marker coordinates contain infinite values", path=path)
    R = None if residuals_file_unit is None else np.asarray(residuals_file_unit, dtype=np.float64) * scale
    try:
        return MarkerSequence(
            positions=P,
            labels=tuple(labels),
            rate=rate,
            source_unit=file_unit,
            source_path=path,
            first_frame=int(first_frame),
            residuals=R,
            subjects=subjects,
            timecode=timecode,
            capture_start=capture_start,
        )
    except InputError as exc:
        raise FileFormatError(exc.message, path=path) from None


def _file_unit(stated: str | None, override: str | None, path: str, where: str) -> str:
    """The unit to read in: the override, else the file's statement, else mm."""
    if override is not None:
        return override
    if stated is None or not stated.strip():
        return "mm"
    try:
        return normalize_unit(stated.strip())
    except InputError:
        raise FileFormatError(
            f"{where} gives unit {stated.strip()!r}, not one of mm, cm, m, in; "
            "pass unit= to read it in a known unit",
            path=path,
        ) from None


def _read_text(p: Path) -> str:
    """File text (UTF-8, else Latin-1), refusing binary content."""
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"cannot read the file ({exc.strerror})", path=str(p)) from None
    if not data.strip():
        raise FileFormatError("the file is empty", path=str(p))
    if b"\x00" in data[:65536]:
        raise FileFormatError("the file is binary, not a text marker file", path=str(p))
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _to_float_rows(rows: list[list[str]], line_numbers: list[int], path: str) -> FloatArray:
    """Parse string cells to float64 (empty cell -> NaN), naming the line of a bad cell."""
    cleaned = [[c.strip() or "nan" for c in row] for row in rows]
    try:
        return np.array(cleaned, dtype=np.float64)
    except ValueError:
        pass
    out = np.empty((len(cleaned), len(cleaned[0])), dtype=np.float64)
    for i, (row, line) in enumerate(zip(cleaned, line_numbers)):
        for j, cell in enumerate(row):
            try:
                out[i, j] = float(cell)
            except ValueError:
                raise FileFormatError(
                    f"line {line}, column {j + 1}: expected a number, got {cell!r}", path=path
                ) from None
    return out


def _consecutive_frames(frames: FloatArray, line_numbers: list[int], path: str, column: str) -> int:
    """Check the frame-number column holds consecutive integers; return the first one."""
    bad = ~np.isfinite(frames) | (frames != np.round(frames))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise FileFormatError(f"line {line_numbers[i]}: {column} must be an integer", path=path)
    step = np.diff(frames)
    if (step != 1).any():
        i = int(np.flatnonzero(step != 1)[0]) + 1
        raise FileFormatError(
            f"line {line_numbers[i]}: {column} {int(frames[i])} does not follow "
            f"{int(frames[i - 1])}; frames must be consecutive",
            path=path,
        )
    return int(frames[0])


# --------------------------------------------------------------------------- TRC


def _split_trc(line: str) -> list[str]:
    return line.split("\t") if "\t" in line else line.split()


def _read_trc(text: str, path: str, unit_override: str | None) -> MarkerSequence:
    lines = text.splitlines()
    if len(lines) < 5 or not lines[0].lstrip().startswith("PathFileType"):
        raise FileFormatError(
            "not a TRC file: line 1 must start with 'PathFileType' and five header lines must follow",
            path=path,
        )
    keys = [k.strip() for k in _split_trc(lines[1])]
    values = [v.strip() for v in _split_trc(lines[2])]
    keys = [k for k in keys if k]
    if len(values) < len(keys):
        raise FileFormatError(
            f"line 3: {len(values)} header values for the {len(keys)} header keys on line 2", path=path
        )
    header = {k.lower(): v for k, v in zip(keys, values)}
    for required in ("datarate", "numframes", "nummarkers"):
        if required not in header:
            raise FileFormatError(f"line 2: TRC header lacks the {required!r} key", path=path)

    def number(key: str, kind: type) -> float:
        try:
            value = float(header[key])
        except ValueError:
            raise FileFormatError(f"line 3: {key} value {header[key]!r} is not a number", path=path) from None
        if kind is int and (not math.isfinite(value) or value != round(value) or value < 0):
            raise FileFormatError(f"line 3: {key} must be a non-negative integer, got {header[key]!r}", path=path)
        return value

    rate = number("datarate", float)
    n_frames = int(number("numframes", int))
    n_markers = int(number("nummarkers", int))
    if not (math.isfinite(rate) and rate > 0):
        raise FileFormatError(f"line 3: DataRate must be positive, got {header['datarate']!r}", path=path)
    file_unit = _file_unit(header.get("units"), unit_override, path, "line 3: Units")

    name_cells = [c.strip() for c in _split_trc(lines[3])]
    if len(name_cells) < 2 or name_cells[0].lower() != "frame#" or name_cells[1].lower() != "time":
        raise FileFormatError("line 4: expected 'Frame#', 'Time' and the marker names", path=path)
    labels = [c for c in name_cells[2:] if c]
    if len(labels) != n_markers:
        raise FileFormatError(
            f"line 4 names {len(labels)} markers but the header (line 3) says NumMarkers={n_markers}",
            path=path,
        )
    if n_markers == 0:
        raise FileFormatError("the file holds no markers (NumMarkers=0)", path=path)
    coords = [c for c in (c.strip() for c in _split_trc(lines[4])) if c]
    if coords and len(coords) != 3 * n_markers:
        raise FileFormatError(
            f"line 5 has {len(coords)} coordinate labels, expected {3 * n_markers} (X/Y/Z for "
            f"{n_markers} markers)",
            path=path,
        )

    width = 2 + 3 * n_markers
    rows: list[list[str]] = []
    line_numbers: list[int] = []
    for k in range(5, len(lines)):
        line = lines[k]
        if not line.strip():
            continue
        cells = line.split("\t") if "\t" in line else line.split()
        if len(cells) < width:
            raise FileFormatError(
                f"line {k + 1}: {len(cells)} tab-separated values, expected {width} "
                f"(Frame#, Time and X/Y/Z for {n_markers} markers)",
                path=path,
            )
        if len(cells) > width and any(c.strip() for c in cells[width:]):
            raise FileFormatError(
                f"line {k + 1}: {len(cells)} values, more than the {width} the header implies",
                path=path,
            )
        rows.append(cells[:width])
        line_numbers.append(k + 1)
    if len(rows) != n_frames:
        raise FileFormatError(
            f"the header (line 3) says NumFrames={n_frames} but the file holds {len(rows)} data rows",
            path=path,
        )
    if n_frames == 0:
        raise FileFormatError("the file holds no frames", path=path)
    data = _to_float_rows(rows, line_numbers, path)
    first = _consecutive_frames(data[:, 0], line_numbers, path, "Frame#")
    times = data[:, 1]
    if n_frames >= 2 and np.isfinite(times).all():
        span = float(times[-1] - times[0])
        expected = (n_frames - 1) / rate
        if abs(span - expected) > 0.01 * expected + 1e-3:
            raise FileFormatError(
                f"the Time column spans {span:.6g} s over {n_frames} frames but DataRate={rate:g} Hz "
                f"(line 3) implies {expected:.6g} s",
                path=path,
            )
    P = data[:, 2:].reshape(n_frames, n_markers, 3)
    return _make_sequence(P, labels, rate, file_unit, path, first - 1)


# --------------------------------------------------------------------------- CSV


def _read_csv(text: str, path: str, unit_override: str | None) -> MarkerSequence:
    lines = text.splitlines()
    meta: dict[str, tuple[str, int]] = {}
    k = 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        body = lines[k].strip().lstrip("#").strip()
        if "=" in body:
            key, value = body.split("=", 1)
            meta[key.strip().lower()] = (value.strip(), k + 1)
        k += 1
    if k == len(lines):
        raise FileFormatError("no header row 'frame,time,<label>_x,...' found", path=path)
    header_line = k + 1
    columns = [c.strip() for c in lines[k].split(",")]
    if len(columns) < 2 or columns[0].lower() != "frame" or columns[1].lower() != "time":
        raise FileFormatError(
            f"line {header_line}: the header must start with 'frame,time', got {lines[k][:40]!r}",
            path=path,
        )
    if len(columns) == 2 or (len(columns) - 2) % 3:
        raise FileFormatError(
            f"line {header_line}: after 'frame,time' expected three columns <label>_x,<label>_y,"
            f"<label>_z per marker, got {len(columns) - 2} columns",
            path=path,
        )
    labels: list[str] = []
    for j in range(2, len(columns), 3):
        triple = columns[j : j + 3]
        label = triple[0][:-2]
        expected = [f"{label}_{axis}".lower() for axis in "xyz"]
        if not label or [c.lower() for c in triple] != expected:
            raise FileFormatError(
                f"line {header_line}, columns {j + 1}-{j + 3}: expected <label>_x,<label>_y,<label>_z, "
                f"got {','.join(triple)!r}",
                path=path,
            )
        labels.append(label)

    rows: list[list[str]] = []
    line_numbers: list[int] = []
    for i in range(k + 1, len(lines)):
        if not lines[i].strip():
            continue
        cells = lines[i].split(",")
        if len(cells) != len(columns):
            raise FileFormatError(
                f"line {i + 1}: {len(cells)} values, expected {len(columns)} as in the header (line {header_line})",
                path=path,
            )
        rows.append(cells)
        line_numbers.append(i + 1)
    if not rows:
        raise FileFormatError("the file holds no frames", path=path)
    data = _to_float_rows(rows, line_numbers, path)
    first = _consecutive_frames(data[:, 0], line_numbers, path, "frame")
    n_frames = data.shape[0]

    if "rate" in meta:
        value, line = meta["rate"]
        try:
            rate = float(value)
        except ValueError:
            raise FileFormatError(f"line {line}: rate {value!r} is not a number", path=path) from None
        if not (math.isfinite(rate) and rate > 0):
            raise FileFormatError(f"line {line}: rate must be positive, got {value!r}", path=path)
    else:
        rate = _rate_from_times(data[:, 1], line_numbers, path)
    stated_unit = meta.get("unit", meta.get("units", (None, 0)))
    file_unit = _file_unit(stated_unit[0], unit_override, path, f"line {stated_unit[1]}: unit")
    P = data[:, 2:].reshape(n_frames, len(labels), 3)
    return _make_sequence(P, labels, rate, file_unit, path, first)


def _rate_from_times(times: FloatArray, line_numbers: list[int], path: str) -> float:
    """Rate in Hz from an evenly spaced time column, or FileFormatError."""
    hint = "add a '# rate=<Hz>' line"
    if times.size < 2:
        raise FileFormatError(f"cannot infer the frame rate from a single frame; {hint}", path=path)
    if not np.isfinite(times).all():
        i = int(np.flatnonzero(~np.isfinite(times))[0])
        raise FileFormatError(f"line {line_numbers[i]}: empty time, so the rate cannot be inferred; {hint}", path=path)
    dt = (times[-1] - times[0]) / (times.size - 1)
    if not dt > 0:
        raise FileFormatError(f"the time column does not increase; {hint}", path=path)
    steps = np.arange(times.size)
    deviation = np.abs(times - (times[0] + dt * steps))
    if deviation.max() > 0.1 * dt:
        i = int(np.argmax(deviation))
        raise FileFormatError(
            f"line {line_numbers[i]}: the time column is not evenly spaced, so the rate cannot be inferred; {hint}",
            path=path,
        )
    # Times written with few decimals make 1 / dt slightly off a whole rate (240 -> 239.995);
    # take the whole rate when it explains the times as well as the fitted one does.
    whole = round(1.0 / dt)
    if whole > 0:
        whole_deviation = np.abs(times - (times[0] + steps / whole)).max()
        if whole_deviation <= 2.0 * deviation.max() + 1e-9:
            return float(whole)
    return float(1.0 / dt)


# --------------------------------------------------------------------------- C3D


def _read_c3d(p: Path, unit_override: str | None) -> MarkerSequence:
    path = str(p)
    try:
        layout = c3d_layout(p)
    except OSError as exc:
        raise FileFormatError(f"cannot read the file ({exc.strerror})", path=path) from None
    import ezc3d

    if layout.note:
        warnings.warn(f"{path}: {layout.note}", FacecapWarning, stacklevel=3)
    # Where ezc3d on its own would read other markers or fewer frames than the file
    # holds, it reads a corrected copy (POINT:USED set to the file's marker count,
    # POINT:FRAMES to -1 so that it reads to the end) and the take is cut to length.
    patch_used = layout.n_points != layout.ezc3d_points
    patch_frames = patch_used or layout.ezc3d_frames < layout.n_frames
    if (patch_used and layout.used_param is None) or (patch_frames and layout.frames_param is None):
        raise FileFormatError(
            f"the file holds {layout.n_frames} frames of {layout.n_points} markers but ezc3d would read "
            f"{layout.ezc3d_frames} of {layout.ezc3d_points}, and a parameter to correct is missing",
            path=path,
        )
    if layout.drop_analogs and layout.analog_used_param is None:
        raise FileFormatError("ANALOG:SCALE or ANALOG:OFFSET is missing for the analog channels", path=path)
    try:
        if layout.processor == MIPS or patch_frames or layout.drop_analogs:
            data = p.read_bytes()
            if layout.processor == MIPS:
                data = big_endian_to_intel(data, layout)
            if patch_frames:
                data = _corrected_counts(data, layout, patch_used)
            if layout.drop_analogs:
                data = _points_only(data, layout)
            with tempfile.TemporaryDirectory(prefix="facecap-c3d-") as folder:
                copy = Path(folder) / "intel.c3d"
                copy.write_bytes(data)
                c3d = ezc3d.c3d(str(copy))
        else:
            c3d = ezc3d.c3d(path)
        points = np.asarray(c3d["data"]["points"], dtype=np.float64)
        residual = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64)
        point_params = c3d["parameters"]["POINT"]
        timecode_params = next((c3d["parameters"][g] for g in c3d["parameters"].keys() if g.upper() == "TIMECODE"),
                               None)
        header = c3d["header"]["points"]
    except Exception as exc:  # ezc3d raises OSError, ValueError, RuntimeError, IndexError, ...
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"not a readable C3D file ({reason})", path=path) from None

    n_points = layout.n_points
    n_frames = layout.n_frames
    if points.ndim != 3 or points.shape[0] < 3 or points.shape[1] != n_points:
        raise FileFormatError(
            f"the C3D reader returned point data of shape {points.shape} for {n_points} markers", path=path
        )
    if points.shape[2] < n_frames:
        raise FileFormatError(
            f"the file declares {n_frames} frames but only {points.shape[2]} could be read "
            "(truncated or corrupt)",
            path=path,
        )
    if n_frames == 0:
        raise FileFormatError("the file holds no frames", path=path)
    # ezc3d reads to the end of the file when POINT:FRAMES is negative as a signed word
    # (takes of 32768-65535 frames, or patched above): drop what follows the take.
    points = points[:, :, :n_frames]

    labels: list[str] = []
    k = 1
    while True:
        key = "LABELS" if k == 1 else f"LABELS{k}"
        if key not in point_params:
            break
        labels.extend(str(s).strip() for s in point_params[key]["value"])
        k += 1
    labels = labels[:n_points] + [""] * (n_points - len(labels))
    labels = [s if s else f"unlabeled_point_{i}" for i, s in enumerate(labels)]
    labels, subjects = _c3d_labels(labels, path)

    rate = float(np.ravel(point_params["RATE"]["value"])[0]) if np.size(point_params["RATE"]["value"]) else 0.0
    if not (math.isfinite(rate) and rate > 0):
        rate = float(header.get("frame_rate", 0.0))
    if not (math.isfinite(rate) and rate > 0):
        raise FileFormatError("neither POINT:RATE nor the header gives a positive frame rate", path=path)

    stated = None
    if "UNITS" in point_params:
        units = [str(u).strip() for u in np.ravel(point_params["UNITS"]["value"])]
        stated = next((u for u in units if u), None)
    file_unit = _file_unit(_c3d_unit(stated), unit_override, path, "POINT:UNITS")

    xyz = np.ascontiguousarray(points[:3].transpose(2, 1, 0))  # (T, M, 3)
    if residual.ndim == 3 and residual.shape[1] == n_points and residual.shape[2] >= n_frames:
        res = residual[0, :, :n_frames].T
    else:
        res = np.zeros((n_frames, n_points))
    occluded = (res < 0) | np.isnan(xyz).any(axis=2) | (xyz == 0.0).all(axis=2)
    xyz[occluded] = np.nan
    res = np.where(occluded, np.nan, res)
    first_frame = int(header.get("first_frame", 0))
    timecode = None if timecode_params is None else _c3d_timecode(timecode_params, path)
    return _make_sequence(xyz, labels, rate, file_unit, path, first_frame, res, subjects, timecode=timecode)


def _c3d_timecode(group: dict, path: str) -> str | None:
    """``'HH:MM:SS:FF'`` from a C3D ``TIMECODE`` group, or None (with a notice when it is unreadable).

    ``FIRST_FRAME`` holds hours, minutes, seconds, frames and perhaps a subframe
    (numbers), or the timecode as text; ``DROP_FRAMES`` nonzero marks drop-frame
    timecode, written with ``;`` before the frames as SMPTE does.
    """

    def value(name: str) -> object:
        entry = group.get(name)
        return entry.get("value") if isinstance(entry, dict) else None

    first, drop_frames = value("FIRST_FRAME"), value("DROP_FRAMES")
    if first is None or np.size(first) == 0:
        return None
    drop = drop_frames is not None and np.size(drop_frames) > 0 and bool(np.ravel(drop_frames)[0])
    if isinstance(first, list) and isinstance(first[0], str):  # the timecode as text
        text = first[0].strip()
        drop = drop or ";" in text
        cells = text.replace(";", ":").replace(".", ":").split(":")
        fields = [float(c) for c in cells] if all(c.isdigit() for c in cells) else []
    else:
        fields = [float(v) for v in np.ravel(np.asarray(first, dtype=np.float64))]
    whole = len(fields) >= 4 and all(math.isfinite(v) and v == round(v) and v >= 0 for v in fields[:5])
    if not whole or not (fields[0] < 24 and fields[1] < 60 and fields[2] < 60):
        warnings.warn(f"{path}: TIMECODE:FIRST_FRAME holds {first!r}, not a timecode; the take is read without one",
                      FacecapWarning, stacklevel=4)
        return None
    hh, mm, ss, ff = (int(v) for v in fields[:4])
    subframe = f".{int(fields[4])}" if len(fields) > 4 and fields[4] else ""
    return f"{hh:02d}:{mm:02d}:{ss:02d}{';' if drop else ':'}{ff:02d}{subframe}"


def _corrected_counts(data: bytes, layout: C3DLayout, patch_used: bool) -> bytes:
    """A copy whose POINT:FRAMES makes ezc3d read to the end of the file (and POINT:USED
    the file's marker count if ``patch_used``).

    ezc3d takes ``POINT:FRAMES`` as a signed word (a take of 70000 frames wraps to
    4464); -1 makes it read every frame to the end, and the caller keeps the first
    ``layout.n_frames``. The values are written in Intel order: ``data`` is an Intel
    or DEC file, or already converted from big-endian.
    """
    buf = bytearray(data)
    if layout.frames_param is not None:
        at, ptype = layout.frames_param
        if ptype == 2:
            buf[at : at + 2] = struct.pack("<h", -1)
        elif ptype == 4:  # a float POINT:FRAMES (DEC floats are not written: ezc3d reads -1 too)
            buf[at : at + 4] = struct.pack("<f", -1.0) if layout.processor != DEC else bytes([0x80, 0xC0, 0, 0])
        else:
            buf[at : at + 1] = b"\xff"
    if patch_used and layout.used_param is not None:
        at, ptype = layout.used_param
        if ptype == 2:
            buf[at : at + 2] = struct.pack("<h", layout.n_points)
        elif ptype == 1:
            buf[at : at + 1] = bytes([layout.n_points & 0xFF])
    return bytes(buf)


def _points_only(data: bytes, layout: C3DLayout) -> bytes:
    """A copy without analog samples (ANALOG:USED and the header's analog count 0).

    For files whose analog parameters would crash ezc3d; the markers are unchanged.
    ``data`` is in Intel or DEC order (converted from big-endian before).
    """
    buf = bytearray(data)
    struct.pack_into("<H", buf, 4, 0)  # header: analog samples per frame
    if layout.analog_used_param is not None:
        at, ptype = layout.analog_used_param
        buf[at : at + (2 if ptype == 2 else 1)] = bytes(2 if ptype == 2 else 1)
    point_bytes = 4 * layout.n_points * (4 if layout.points_are_float else 2)
    start, step = layout.data_offset, layout.frame_bytes
    n = (len(buf) - start) // step if step else 0
    frames = np.frombuffer(bytes(buf[start : start + n * step]), dtype=np.uint8).reshape(n, step)
    return bytes(buf[:start]) + frames[:, :point_bytes].tobytes()


def _c3d_unit(stated: str | None) -> str | None:
    """POINT:UNITS, completed where a writer cut the word to the parameter's width.

    Some writers (c3d.org sample15, from an AMTI/Peak system) store ``'mete'`` in a
    4-character POINT:UNITS; a cut word that starts only one unit's names is that unit.
    """
    if stated is None:
        return None
    try:
        return normalize_unit(stated.strip())
    except InputError:
        pass
    word = stated.strip().lower()
    spelled = {"millimeter": "mm", "millimetre": "mm", "centimeter": "cm", "centimetre": "cm",
               "meter": "m", "metre": "m", "inch": "in"}
    matches = {unit for name, unit in spelled.items() if len(word) >= 3 and name.startswith(word)}
    return matches.pop() if len(matches) == 1 else stated


def _c3d_labels(raw: list[str], path: str) -> tuple[list[str], tuple[str, ...] | None]:
    """Labels after facecap's handling, and the per-marker subject prefixes.

    Vicon Nexus, ART and OptiTrack Motive write ``Subject:Marker``; the prefix is
    split off into the subjects when the labels stay unique without it. Duplicate
    labels (some Motion Analysis, Vicon Workstation and C3D editor exports repeat names)
    get a ``_2``, ``_3``, ... suffix, with a warning.
    """
    subjects: tuple[str, ...] | None = None
    labels = list(raw)
    if any(":" in s for s in raw):
        parts = [s.partition(":") if ":" in s else ("", "", s) for s in raw]
        stripped = [marker.strip() for _, _, marker in parts]
        if all(stripped) and len(set(stripped)) == len(stripped):
            labels = stripped
            subjects = tuple(subject.strip() for subject, _, _ in parts)
    seen = set(labels)
    counts: dict[str, int] = {}
    renamed: list[str] = []
    out: list[str] = []
    for s in labels:
        counts[s] = counts.get(s, 0) + 1
        if counts[s] == 1:
            out.append(s)
            continue
        k = counts[s]
        while f"{s}_{k}" in seen:
            k += 1
        new = f"{s}_{k}"
        seen.add(new)
        out.append(new)
        renamed.append(f"{s}->{new}")
    if renamed:
        shown = ", ".join(renamed[:6]) + (", ..." if len(renamed) > 6 else "")
        warnings.warn(
            f"{path}: {len(renamed)} duplicate marker label(s) renamed ({shown})",
            FacecapWarning,
            stacklevel=4,
        )
    return out, subjects
