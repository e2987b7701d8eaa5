"""Check a C3D file in Python before ezc3d parses it (private to :mod:`facecap.io`).

The walk below mirrors ezc3d 1.x's own parser (``src/Header.cpp``,
``src/Parameters.cpp``, ``src/Group.cpp``, ``src/Parameter.cpp``, the header
update in ``src/ezc3d.cpp`` and ``src/Data.cpp``) so that it refuses only what
would make ezc3d crash, hang, or silently return other data than the file
holds, and states why in one line. What ezc3d refuses cleanly itself (for
example a record whose content does not end where its offset says) is refused
here too, with a clearer message.

Rules taken from ezc3d, where the C3D User Guide (c3d.org) leaves room:

- the first parameter record is at byte 4 of the parameter section whatever
  its first byte says (Qualisys writes 0), and the section's key byte is not
  checked (Vicon Nexus writes other values);
- names are raw bytes up to the first NUL: spaces, lower case and other bytes
  are legal (Qualisys, Motion Analysis and others write them);
- a record's offset is unsigned; the section ends at a zero name length or a
  zero offset, not at the block count the section header states;
- the number of markers is ``POINT:USED``, the frame count ``POINT:FRAMES``
  when it is non-zero (the header's frame range is a copy, often stale), the
  analog samples per frame ``ANALOG:RATE / POINT:RATE`` and the channels
  ``ANALOG:USED``.

Beyond ezc3d, the true frame count of a take longer than 65535 frames comes
from ``TRIAL:ACTUAL_START_FIELD``/``ACTUAL_END_FIELD`` (two 16-bit words each,
low word first) or ``POINT:LONG_FRAMES``, the conventions of Vicon and C3Dserver.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError

__all__ = ["C3DLayout", "c3d_layout", "INTEL", "DEC", "MIPS"]

INTEL, DEC, MIPS = 84, 85, 86
_TYPE_SIZES = {-1: 1, 1: 1, 2: 2, 4: 4}


@dataclass(frozen=True)
class C3DLayout:
    """What the check found: enough to read the take and to convert its byte order."""

    processor: int  # 84 Intel, 85 DEC, 86 MIPS (SGI, big-endian)
    n_points: int  # markers per frame in the file
    n_frames: int  # frames the file holds and the reader must return
    ezc3d_points: int  # POINT:USED, the markers per frame ezc3d reads
    ezc3d_frames: int  # frames ezc3d reads on its own (min of its count and what the file holds)
    points_are_float: bool  # POINT:SCALE < 0
    analogs_are_float: bool  # header scale < 0 (ezc3d's rule for analog samples)
    analog_samples: int  # analog samples per frame (subframes x channels)
    data_offset: int  # byte offset of the first frame
    frame_bytes: int
    frames_param: tuple[int, int] | None  # (byte offset in the file, type) of POINT:FRAMES' value
    used_param: tuple[int, int] | None  # (byte offset in the file, type) of POINT:USED's value
    analog_used_param: tuple[int, int] | None  # (byte offset in the file, type) of ANALOG:USED's value
    drop_analogs: bool  # ezc3d would crash on the analog samples: give it the points only
    note: str | None  # why the take read differs from what the file declares, for a warning
    params: dict  # (group, name) -> (type, dims, raw bytes, offset of raw bytes in the file)


def _unpackers(processor: int):
    order = ">" if processor == MIPS else "<"

    def as_int(raw: bytes, ptype: int) -> list[int]:
        if ptype in (-1, 1):
            return [b - 256 if b > 127 else b for b in raw]
        n = len(raw) // 2
        return list(struct.unpack(f"{order}{n}h", raw[: 2 * n]))

    def as_float(raw: bytes) -> list[float]:
        n = len(raw) // 4
        if processor == DEC:  # VAX F-float: swap the 16-bit halves, then IEEE value / 4
            b = bytearray(raw[: 4 * n])
            b[0::4], b[1::4], b[2::4], b[3::4] = raw[2::4][:n], raw[3::4][:n], raw[0::4][:n], raw[1::4][:n]
            return [v / 4.0 for v in struct.unpack(f"<{n}f", bytes(b))]
        return list(struct.unpack(f"{order}{n}f", raw[: 4 * n]))

    return order, as_int, as_float


def c3d_layout(p: Path) -> C3DLayout:
    """Check a C3D file's header and parameter section before ezc3d sees it.

    Parameters
    ----------
    p : Path
        The ``.c3d`` file.

    Returns
    -------
    C3DLayout

    Raises
    ------
    FileFormatError
        For anything that would make ezc3d fail, crash, hang, or silently read
        other frames than the file holds (truncation included).
    OSError
        If the file cannot be read.
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
        params_bytes = handle.read()
    processor = params_bytes[3]
    if processor not in (INTEL, DEC, MIPS):
        raise bad(f"corrupt parameter section: unknown processor type byte {processor}")
    n_blocks = params_bytes[2]
    section_cut = bool(n_blocks) and section + n_blocks * 512 > size
    order, as_int, as_float = _unpackers(processor)

    def corrupt(detail: str) -> FileFormatError:
        if section_cut:
            return bad("the file is truncated inside its parameter section")
        return bad(f"the parameter section is corrupt ({detail})")

    u16 = struct.Struct(order + "H")
    n_points_h, n_analog_h, first_h, last_h = struct.unpack_from(order + "4H", head, 2)
    data_start, per_frame_h = struct.unpack_from(order + "2H", head, 16)
    header_scale = as_float(head[12:16])[0]

    # Walk the records as ezc3d does: sequentially from byte 4, each one's content
    # must end where its offset points.
    groups: dict[int, str] = {}
    records: dict[tuple[int, str], tuple[int, tuple[int, ...], bytes, int]] = {}
    pos = 4
    limit = len(params_bytes)
    for _ in range(100000):
        if pos + 1 > limit:
            raise corrupt("it ends without an end marker")
        n_char = struct.unpack_from("b", params_bytes, pos)[0]
        if n_char == 0:
            break
        if pos + 2 > limit:
            raise corrupt("it ends without an end marker")
        gid = struct.unpack_from("b", params_bytes, pos + 1)[0]
        name_end = pos + 2 + abs(n_char)
        if gid == 0 or name_end + 2 > limit:
            raise corrupt("bad record header")
        name = params_bytes[pos + 2 : name_end].split(b"\0")[0].decode("latin-1")
        offset = u16.unpack_from(params_bytes, name_end)[0]
        cur = name_end + 2
        if gid < 0:
            if cur + 1 > limit:
                raise corrupt(f"group {name!r} is cut short")
            desc = struct.unpack_from("b", params_bytes, cur)[0]
            if desc < 0:
                raise corrupt(f"group {name!r} has a negative description length")
            cur += 1 + desc
            groups[-gid] = name
        else:
            if cur + 2 > limit:
                raise corrupt(f"parameter {name!r} is cut short")
            ptype, n_dims = struct.unpack_from("bb", params_bytes, cur)
            if ptype not in _TYPE_SIZES:
                raise corrupt(f"parameter {name!r} has type {ptype}")
            if not 0 <= n_dims <= 7 or (ptype == -1 and n_dims == 0):
                raise corrupt(f"parameter {name!r} has {n_dims} dimensions")
            cur += 2
            dims = tuple(params_bytes[cur : cur + n_dims])
            cur += n_dims
            n_bytes = int(np.prod(dims, dtype=np.int64)) * _TYPE_SIZES[ptype]
            if cur + n_bytes + 1 > limit:
                raise corrupt(f"parameter {name!r} overruns the file")
            records[(gid, name)] = (ptype, dims, params_bytes[cur : cur + n_bytes], section + cur)
            cur += n_bytes
            desc = struct.unpack_from("b", params_bytes, cur)[0]
            if desc < 0:
                raise corrupt(f"parameter {name!r} has a negative description length")
            cur += 1 + desc
        if cur > limit:
            raise corrupt(f"record {name!r} overruns the file")
        if offset == 0:
            break
        if name_end + offset != cur:
            swapped = ((offset & 0xFF) << 8) | (offset >> 8)
            # Some SGI writers (c3d.org sample02) store an edited record's offset
            # little-endian; the content is sound and the converted copy gets its
            # offset recomputed.
            if not (processor == MIPS and name_end + swapped == cur):
                raise corrupt(
                    f"record {name!r} ends at byte {cur - 4}, not where its offset points "
                    f"({name_end + offset - 4})"
                )
        pos = cur
    else:
        raise corrupt("too many records")

    params: dict[tuple[str, str], tuple[int, tuple[int, ...], bytes, int]] = {}
    for (gid, pname), value in records.items():
        params.setdefault((groups.get(gid, ""), pname), value)

    def values(group: str, pname: str) -> list | None:
        """The parameter's values as ezc3d holds them, None if absent."""
        entry = params.get((group, pname))
        if entry is None:
            return None
        ptype, _, raw, _ = entry
        if ptype == 4:
            return as_float(raw)
        if ptype == -1:
            return []
        return as_int(raw, ptype)

    def first(group: str, pname: str, default: float) -> float:
        v = values(group, pname)
        if v is None:
            return default
        if not v:
            raise bad(f"the {group}:{pname} parameter is empty")
        return v[0]

    for group, pname in (("POINT", "DATA_START"),):
        first(group, pname, 0)
    n_points = int(first("POINT", "USED", 0))
    point_scale = first("POINT", "SCALE", -1.0)
    point_rate = first("POINT", "RATE", 0.0)
    frames_param = first("POINT", "FRAMES", 0)
    analog_rate = first("ANALOG", "RATE", 0.0)
    n_analogs = int(first("ANALOG", "USED", 0))
    first("ANALOG", "GEN_SCALE", 1.0)
    if n_points < 0:
        raise bad(f"POINT:USED is negative ({n_points})")
    if n_analogs < 0:
        raise bad(f"ANALOG:USED is negative ({n_analogs})")
    if n_points == 0:
        raise bad("the file holds no 3D marker data (POINT:USED is 0 or missing)")
    # ezc3d (updateHeader): analog samples per frame from the rates, 1 when POINT:RATE < 1
    # (it then takes the header's rate for the points), the header's 1 kept for SHADOW files.
    if int(point_rate) == 0:
        per_frame = 1
    elif per_frame_h == 1 and "SHADOW" in groups.values():
        per_frame = 1
    else:
        per_frame = int(analog_rate / point_rate)
    # ezc3d indexes each channel's scale and offset unchecked: with either parameter
    # missing or empty it reads through a null pointer. The markers are still read, from
    # a copy without the analog samples (MACsample.c3d names its offsets ANALOG:OFFSETS).
    drop_analogs = bool(n_analogs) and not all(values("ANALOG", pname) for pname in ("SCALE", "OFFSET"))
    analog_used = params.get(("ANALOG", "USED"))

    if data_start <= param_block:
        raise bad(f"the header puts the data at block {data_start}, not after the parameters (corrupt)")
    data_offset = (data_start - 1) * 512
    if data_offset > size:
        raise bad(f"the header puts the data at block {data_start}, beyond the end of the file (truncated)")
    if (first("ROTATION", "USED", 0) or 0) > 0:
        rot_start = int(first("ROTATION", "DATA_START", 0))
        rot_ratio = int(first("ROTATION", "RATIO", 0))
        if not (data_start <= rot_start and (rot_start - 1) * 512 <= size) or rot_ratio < 1:
            raise bad("the ROTATION parameters point outside the file (truncated or corrupt)")

    # Frames as ezc3d counts them (Header.cpp: 1-based unless the first frame is 0).
    if first_h != 0:
        header_frames = (last_h - 1 if last_h else 0) - (first_h - 1) + 1
    else:
        header_frames = last_h + 1
    ezc3d_declared = int(frames_param)
    if ezc3d_declared == 0:
        ezc3d_declared = header_frames
    if ezc3d_declared < 0:  # size_t in ezc3d: read to the end of the file
        ezc3d_declared = 1 << 62

    # The count the parameters state: POINT:FRAMES as an unsigned word, the long-take
    # conventions beyond 65535.
    entry = params.get(("POINT", "FRAMES"))
    frames_stated = 0
    if entry is not None:
        frames_stated = int(frames_param) & 0xFFFF if entry[0] == 2 else int(frames_param)
    long_count = _long_frames(values)
    if long_count is not None and long_count > 65535 and (
        frames_stated in (0, 0xFFFF) or long_count % 65536 == frames_stated % 65536 or last_h == 0xFFFF
    ):
        frames_stated = long_count
    header_ok = last_h >= first_h

    def frame_size(points: int) -> int:
        return 4 * points * (4 if points_float else 2) + per_frame * n_analogs * (4 if analogs_float else 2)

    points_float = point_scale < 0
    analogs_float = header_scale < 0
    # The parameters are the truth (as for ezc3d) where the file holds what they say;
    # where it does not, the header's copy is taken if the file holds that (writers
    # that store the last frame's number in POINT:FRAMES, or a stale POINT:USED).
    point_options = [n_points] + ([n_points_h] if n_points_h not in (0, n_points) else [])
    frame_options = [f for f in (frames_stated, header_frames if header_ok else 0) if f > 0]
    if not frame_options:
        raise bad(f"the header's frame range {first_h}..{last_h} is inverted and POINT:FRAMES is missing (corrupt)")
    frame_options = list(dict.fromkeys(frame_options))
    chosen = None
    for points in point_options:
        for frames in frame_options:
            if data_offset + frames * frame_size(points) <= size:
                chosen = (points, frames)
                break
        if chosen:
            break
    note = None
    frame_bytes = frame_size(n_points)
    complete = (size - data_offset) // frame_bytes if frame_bytes else 0
    if chosen is None:
        frames = frame_options[0]
        needed = data_offset + frames * frame_bytes
        if complete >= 1 and data_offset + complete * frame_bytes == size:
            # Ends exactly after a whole frame: an export whose writer stopped early and
            # never updated the counts (Optotrak sample: 29 of 1149 frames, no padding).
            # A file cut at a random byte ends inside a frame and is refused below.
            chosen = (n_points, complete)
            note = (
                f"the file declares {frames} frames but ends exactly after frame {complete}; "
                f"reading the {complete} frames it holds"
            )
        else:
            raise bad(
                f"the file is truncated: it declares {frames} frames ({needed} bytes) "
                f"but has {size} bytes, {complete} complete frames"
            )
    n_points_read, n_frames_read = chosen
    frame_bytes = frame_size(n_points_read)
    ezc3d_complete = (size - data_offset) // frame_size(n_points) if frame_size(n_points) else 0
    frames_at = None if entry is None else (entry[3], entry[0])
    used = params.get(("POINT", "USED"))
    return C3DLayout(
        processor=processor,
        n_points=n_points_read,
        n_frames=n_frames_read,
        ezc3d_points=n_points,
        ezc3d_frames=min(ezc3d_declared, ezc3d_complete),
        points_are_float=points_float,
        analogs_are_float=analogs_float,
        analog_samples=per_frame * n_analogs,
        data_offset=data_offset,
        frame_bytes=frame_bytes,
        frames_param=frames_at,
        used_param=None if used is None else (used[3], used[0]),
        analog_used_param=None if analog_used is None else (analog_used[3], analog_used[0]),
        drop_analogs=drop_analogs,
        note=note,
        params=params,
    )


def _long_frames(values) -> int | None:
    """Frame count of a long take from TRIAL:ACTUAL_*_FIELD or POINT:LONG_FRAMES, if given."""
    start = values("TRIAL", "ACTUAL_START_FIELD")
    end = values("TRIAL", "ACTUAL_END_FIELD")
    if start and end and len(start) >= 2 and len(end) >= 2:
        s = (int(start[0]) & 0xFFFF) + 65536 * (int(start[1]) & 0xFFFF)
        e = (int(end[0]) & 0xFFFF) + 65536 * (int(end[1]) & 0xFFFF)
        if e >= s:
            return e - s + 1
    long_frames = values("POINT", "LONG_FRAMES")
    if long_frames:
        return int(long_frames[0])
    return None
