"""Read a labelled marker take from C3D, TRC or facecap CSV.

Formats
-------
``.c3d``
    The binary motion-capture standard (https://www.c3d.org), read with
    ezc3d. Labels come from ``POINT:LABELS`` (then ``LABELS2``, ...), the rate
    from ``POINT:RATE``, the unit from ``POINT:UNITS``. A sample is occluded
    when its residual is negative or its x, y, z are all exactly zero (how
    C3D writers, ezc3d included, store a gap).
``.trc``
    The tab-separated text format of Motion Analysis and OpenSim: a
    ``PathFileType`` line, a line of header keys (``DataRate``,
    ``CameraRate``, ``NumFrames``, ``NumMarkers``, ``Units``, ...) and one of
    their values, a ``Frame#  Time  name1      name2 ...`` line, an
    ``X1 Y1 Z1 X2 ...`` line, then one row per frame. Empty cells are gaps.
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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..structures import MarkerSequence
from ..typing import FloatArray
from ..units import mm_per_unit, normalize_unit

__all__ = ["read_markers"]

_SUFFIXES = (".c3d", ".trc", ".csv")


def read_markers(path: str | os.PathLike[str], *, unit: str | None = None) -> MarkerSequence:
    """Read a marker take from a ``.c3d``, ``.trc`` or ``.csv`` file, in millimetres.

    The format is chosen by the file's suffix (case-insensitive); see the
    module docstring for what each format holds and how gaps are written.

    Parameters
    ----------
    path : str or os.PathLike
        The file to read.
    unit : {'mm', 'cm', 'm', 'in'} or None, optional
        Length unit of the coordinates in the file. Default None takes the
        unit the file states (C3D ``POINT:UNITS``, TRC ``Units``, CSV
        ``# unit=``), or ``'mm'`` if it states none. Give it to override a file
        whose stated unit is wrong.

    Returns
    -------
    markers : MarkerSequence
        ``positions`` (T, M, 3) float64 in mm with NaN at gaps, ``labels`` in
        file order, ``rate`` in Hz, ``source_unit`` the unit the file was read
        in, ``source_path``, ``first_frame`` (0-based, see module docstring),
        and for C3D ``residuals`` (T, M) float64 in mm, NaN at gaps (None for
        TRC and CSV, which hold no residuals).

    Raises
    ------
    FileFormatError
        If the file is missing, empty, truncated, corrupt, has an unknown
        suffix, or its header disagrees with its data; the message names the
        file and, for text formats, the line.
    InputError
        If ``unit`` is not a known length unit.

    Notes
    -----
    C3D files are checked in Python (header, parameter section layout and
    the file size the header implies) before ezc3d parses them, because
    ezc3d silently drops frames missing from a truncated file and can crash
    the interpreter on a corrupt parameter section. C3D files whose header
    frame range is saturated (last frame 65535, the convention for longer
    takes) are read as ezc3d reads them, without the truncation check.

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
    if suffix not in _SUFFIXES:
        raise FileFormatError(
            f"unsupported marker file suffix {p.suffix!r}; expected one of {', '.join(_SUFFIXES)}",
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
    return _read_csv(text, name, unit_override)


# --------------------------------------------------------------------------- shared


def _make_sequence(
    positions_file_unit: FloatArray,
    labels: list[str],
    rate: float,
    file_unit: str,
    path: str,
    first_frame: int,
    residuals_file_unit: FloatArray | None = None,
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


@dataclass(frozen=True)
class _C3DLayout:
    """What the Python-side check of a C3D file found."""

    n_points: int
    declared_frames: int | None  # None when the header frame range is saturated (> 65535 frames)


_TYPE_SIZES = {-1: 1, 1: 1, 2: 2, 4: 4}


def _c3d_layout(p: Path) -> _C3DLayout:
    """Check a C3D file's header and parameter section before ezc3d sees it.

    Raises FileFormatError for anything that would make ezc3d fail, crash,
    hang, or silently read fewer frames than the header declares.
    """
    path = str(p)

    def bad(message: str) -> FileFormatError:
        return FileFormatError(message, path=path)

    size = p.stat().st_size
    if size == 0:
        raise bad("the file is empty")
    if size < 512:
        raise bad(f"the file is too short to be a C3D file ({size} bytes; a C3D header alone is 512)")
    with open(p, "rb") as handle:
        head = handle.read(512)
        if head[0] == 0:
            raise bad("not a C3D file: the header's first byte (parameter block number) is 0")
        if head[1] != 0x50:
            raise bad("not a C3D file: the header lacks the C3D key byte 0x50")
        param_block = head[0]
        section = (param_block - 1) * 512
        if param_block < 2 or section + 4 > size:
            raise bad(
                f"the header puts the parameter section at block {param_block}, outside the file "
                "(truncated or corrupt)"
            )
        handle.seek(section)
        sec_head = handle.read(4)
        processor = sec_head[3]
        if processor == 86:
            raise bad("big-endian (MIPS) C3D files are not supported; re-export it as Intel/PC C3D")
        if processor not in (84, 85):
            raise bad(f"corrupt parameter section: unknown processor type byte {processor}")
        qualisys = sec_head[0] == 0 and sec_head[1] == 0
        if not qualisys and sec_head[1] != 0x50:
            raise bad("corrupt parameter section: missing the C3D key byte 0x50")
        start = 1 if qualisys else sec_head[0]
        n_blocks = sec_head[2]
        end = min(size, section + n_blocks * 512) if n_blocks else size
        handle.seek(section)
        params_bytes = handle.read(end - section)
    section_cut = bool(n_blocks) and section + n_blocks * 512 > size

    def corrupt(detail: str) -> FileFormatError:
        if section_cut:
            return bad("the file is truncated inside its parameter section")
        return bad(f"the parameter section is corrupt ({detail})")

    word = struct.Struct("<H")
    sword = struct.Struct("<h")
    n_points, n_analog, first, last = struct.unpack_from("<4H", head, 2)
    data_start, analog_per_frame = struct.unpack_from("<2H", head, 16)

    # Walk the parameter records exactly as ezc3d will, bounds-checking each one.
    groups: dict[int, str] = {}
    params: dict[tuple[int, str], tuple[int, tuple[int, ...], bytes]] = {}
    pos = 4 + start - 1
    limit = len(params_bytes)
    for _ in range(100000):
        if pos + 2 > limit:
            raise corrupt("it ends without an end marker")
        n_char = struct.unpack_from("<b", params_bytes, pos)[0]
        if n_char == 0:
            break
        gid = struct.unpack_from("<b", params_bytes, pos + 1)[0]
        n_char = abs(n_char)
        name_end = pos + 2 + n_char
        if gid == 0 or name_end + 2 > limit:
            raise corrupt("bad record header")
        raw_name = params_bytes[pos + 2 : name_end]
        if not all(0x20 < c < 0x7F for c in raw_name):
            raise corrupt("a name holds non-printable bytes")
        name = raw_name.decode("ascii").upper()
        offset = sword.unpack_from(params_bytes, name_end)[0]
        if offset < 0 or (offset > 0 and name_end + offset > limit):
            raise corrupt(f"record {name!r} points outside it")
        record_end = name_end + offset if offset else limit
        cur = name_end + 2
        if gid < 0:
            if cur + 1 > record_end:
                raise corrupt(f"group {name!r}")
            cur += 1 + params_bytes[cur]
            groups[-gid] = name
        else:
            if cur + 2 > record_end:
                raise corrupt(f"parameter {name!r}")
            ptype = struct.unpack_from("<b", params_bytes, cur)[0]
            n_dims = params_bytes[cur + 1]
            if ptype not in _TYPE_SIZES or n_dims > 7:
                raise corrupt(f"parameter {name!r} has type {ptype}, {n_dims} dimensions")
            cur += 2
            if cur + n_dims > record_end:
                raise corrupt(f"parameter {name!r}")
            dims = tuple(params_bytes[cur : cur + n_dims])
            cur += n_dims
            n_bytes = int(np.prod(dims, dtype=np.int64)) * _TYPE_SIZES[ptype]
            if cur + n_bytes + 1 > record_end:
                raise corrupt(f"parameter {name!r} overruns its record")
            params[(gid, name)] = (ptype, dims, params_bytes[cur : cur + n_bytes])
            cur += n_bytes
            cur += 1 + params_bytes[cur]
        if cur > record_end:
            raise corrupt(f"record {name!r} overruns its space")
        if offset == 0:
            break
        pos = name_end + offset
    else:
        raise corrupt("too many records")

    by_group: dict[str, dict[str, tuple[int, tuple[int, ...], bytes]]] = {}
    for (gid, pname), value in params.items():
        by_group.setdefault(groups.get(gid, ""), {})[pname] = value

    def count(group: str, pname: str) -> int | None:
        entry = by_group.get(group, {}).get(pname)
        if entry is None:
            return None
        ptype, dims, _ = entry
        if ptype == -1:  # strings: first dimension is the length of each
            return int(np.prod(dims[1:], dtype=np.int64)) if dims else 1
        return int(np.prod(dims, dtype=np.int64))

    def int_value(group: str, pname: str) -> int | None:
        entry = by_group.get(group, {}).get(pname)
        if entry is None or not entry[2]:
            return None
        ptype, _, raw = entry
        if ptype == 2:
            return word.unpack_from(raw, 0)[0]
        if ptype == 1:
            return raw[0]
        return None

    # Parameters ezc3d reads element [0] of without checking they are non-empty.
    for group, pname in (
        ("POINT", "USED"), ("POINT", "SCALE"), ("POINT", "RATE"), ("POINT", "FRAMES"),
        ("POINT", "DATA_START"), ("ANALOG", "USED"), ("ANALOG", "GEN_SCALE"), ("ANALOG", "RATE"),
    ):
        n = count(group, pname)
        if n is not None and n < 1:
            raise bad(f"the {group}:{pname} parameter is empty")
    if n_points == 0:
        raise bad("the file holds no 3D marker data (header point count is 0)")
    used = int_value("POINT", "USED")
    if used is not None and used != n_points:
        raise bad(f"the header says {n_points} markers but POINT:USED says {used}")
    n_analogs = 0
    if n_analog:
        if analog_per_frame == 0 or n_analog % analog_per_frame:
            raise bad(
                f"the header's analog counts are inconsistent ({n_analog} samples, {analog_per_frame} per frame)"
            )
        n_analogs = n_analog // analog_per_frame
        for pname in ("SCALE", "OFFSET"):
            n = count("ANALOG", pname)
            if n is None or n < n_analogs:
                raise bad(f"ANALOG:{pname} has {n or 0} entries for {n_analogs} analog channels")
        analog_used = int_value("ANALOG", "USED")
        if analog_used is not None and analog_used != n_analogs:
            raise bad(f"the header implies {n_analogs} analog channels but ANALOG:USED says {analog_used}")
    if data_start <= param_block:
        raise bad(f"the header puts the data at block {data_start}, not after the parameters (corrupt)")
    data_offset = (data_start - 1) * 512
    if data_offset > size:
        raise bad(f"the header puts the data at block {data_start}, beyond the end of the file (truncated)")
    if (int_value("ROTATION", "USED") or 0) > 0:
        rot_start = int_value("ROTATION", "DATA_START") or 0
        rot_ratio = int_value("ROTATION", "RATIO") or 0
        if not (data_start <= rot_start and (rot_start - 1) * 512 <= size) or rot_ratio < 1:
            raise bad("the ROTATION parameters point outside the file (truncated or corrupt)")
    if last < first:
        raise bad(f"the header's frame range {first}..{last} is inverted (corrupt)")

    if last == 0xFFFF:
        return _C3DLayout(n_points=n_points, declared_frames=None)
    # ezc3d stores points as float when POINT:SCALE is negative (-1 when the parameter is
    # missing), whatever the header's copy of the scale says; size the frames the same way.
    scale_entry = by_group.get("POINT", {}).get("SCALE")
    if scale_entry is None:
        scale_is_float = True
    elif scale_entry[0] == 4:
        scale_is_float = bool(scale_entry[2][3 if processor == 84 else 1] & 0x80)
    else:
        scale_is_float = sword.unpack_from(scale_entry[2].ljust(2, b"\0"), 0)[0] < 0
    n_frames = (last - first + 1) if first != 0 else last + 1
    frame_bytes = (4 * n_points + n_analog) * (4 if scale_is_float else 2)
    needed = data_offset + n_frames * frame_bytes
    if size < needed:
        complete = (size - data_offset) // frame_bytes if frame_bytes else 0
        raise bad(
            f"the file is truncated: its header declares {n_frames} frames ({needed} bytes) "
            f"but the file has {size} bytes, {complete} complete frames"
        )
    return _C3DLayout(n_points=n_points, declared_frames=n_frames)


def _read_c3d(p: Path, unit_override: str | None) -> MarkerSequence:
    path = str(p)
    try:
        layout = _c3d_layout(p)
    except OSError as exc:
        raise FileFormatError(f"cannot read the file ({exc.strerror})", path=path) from None
    import ezc3d

    try:
        c3d = ezc3d.c3d(path)
        points = np.asarray(c3d["data"]["points"], dtype=np.float64)
        residual = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64)
        point_params = c3d["parameters"]["POINT"]
        header = c3d["header"]["points"]
    except Exception as exc:  # ezc3d raises OSError, ValueError, RuntimeError, IndexError, ...
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"not a readable C3D file ({reason})", path=path) from None

    n_points = layout.n_points
    if points.ndim != 3 or points.shape[0] < 3 or points.shape[1] != n_points:
        raise FileFormatError(
            f"the C3D reader returned point data of shape {points.shape} for {n_points} markers", path=path
        )
    n_frames = points.shape[2]
    if layout.declared_frames is not None and n_frames != layout.declared_frames:
        raise FileFormatError(
            f"the header declares {layout.declared_frames} frames but only {n_frames} could be read "
            "(truncated or corrupt)",
            path=path,
        )
    if n_frames == 0:
        raise FileFormatError("the file holds no frames", path=path)

    labels: list[str] = []
    k = 1
    while True:
        key = "LABELS" if k == 1 else f"LABELS{k}"
        if key not in point_params:
            break
        labels.extend(str(s).strip() for s in point_params[key]["value"])
        k += 1
    labels = labels[:n_points] + [f"unlabeled_point_{i}" for i in range(len(labels), n_points)]

    rate = float(np.ravel(point_params["RATE"]["value"])[0]) if np.size(point_params["RATE"]["value"]) else 0.0
    if not (math.isfinite(rate) and rate > 0):
        rate = float(header.get("frame_rate", 0.0))
    if not (math.isfinite(rate) and rate > 0):
        raise FileFormatError("neither POINT:RATE nor the header gives a positive frame rate", path=path)

    stated = None
    if "UNITS" in point_params:
        units = [str(u).strip() for u in np.ravel(point_params["UNITS"]["value"])]
        stated = next((u for u in units if u), None)
    file_unit = _file_unit(stated, unit_override, path, "POINT:UNITS")

    xyz = np.ascontiguousarray(points[:3].transpose(2, 1, 0))  # (T, M, 3)
    res = residual[0].T if residual.ndim == 3 and residual.shape[1:] == (n_points, n_frames) else np.zeros(
        (n_frames, n_points)
    )
    occluded = (res < 0) | np.isnan(xyz).any(axis=2) | (xyz == 0.0).all(axis=2)
    xyz[occluded] = np.nan
    res = np.where(occluded, np.nan, res)
    first_frame = int(header.get("first_frame", 0))
    return _make_sequence(xyz, labels, rate, file_unit, path, first_frame, res)
