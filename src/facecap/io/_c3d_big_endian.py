"""Convert a big-endian (SGI/MIPS, processor type 86) C3D file to Intel byte order.

Private to :mod:`facecap.io`. ezc3d refuses processor type 86; the C3D User
Guide (c3d.org) defines it as the Intel layout with every 16-bit integer and
32-bit IEEE float stored most significant byte first. Converting the bytes and
letting ezc3d read the Intel copy keeps one parsing path for every C3D file.

What is swapped:

- header: words 2-5 (point count, analog samples, first and last frame),
  word 6 (max interpolation gap), the scale (float), the data start and
  analog samples per frame (words), the rate (float), words 148-152 (label and
  event flags and counts) and the 18 event times (floats); the event
  display flags and labels are bytes and stay;
- parameter section: each record's 16-bit offset (recomputed from the
  record's content) and each value by its type
  (2-byte integers and 4-byte floats; bytes and characters stay); the
  processor byte becomes 84 (Intel);
- data: each frame's 4 point words (x, y, z and the residual/camera word, as
  2-byte integers or 4-byte floats as ``POINT:SCALE`` says) and its analog
  samples (by the header scale's sign, as ezc3d reads them).
"""

from __future__ import annotations

import struct

import numpy as np

from ._c3d_check import INTEL, C3DLayout

__all__ = ["big_endian_to_intel"]

_TYPE_SIZES = {-1: 1, 1: 1, 2: 2, 4: 4}


def _swap(buf: bytearray, start: int, count: int, width: int) -> None:
    """Reverse the bytes of ``count`` items of ``width`` bytes from ``start``, in place."""
    if count <= 0 or width == 1:
        return
    end = start + count * width
    a = np.frombuffer(bytes(buf[start:end]), dtype=np.uint8).reshape(count, width)
    buf[start:end] = a[:, ::-1].tobytes()


def big_endian_to_intel(data: bytes, layout: C3DLayout) -> bytes:
    """The same C3D file in Intel (processor 84) byte order.

    Parameters
    ----------
    data : bytes
        The whole big-endian file, already checked by ``c3d_layout``.
    layout : C3DLayout
        What the check found (frame layout of the data section).

    Returns
    -------
    bytes
        The converted file, the same length.
    """
    buf = bytearray(data)
    # Header (block 1).
    _swap(buf, 2, 5, 2)  # points, analog samples, first, last frame, max gap
    _swap(buf, 12, 1, 4)  # scale
    _swap(buf, 16, 2, 2)  # data start, analog samples per frame
    _swap(buf, 20, 1, 4)  # rate
    _swap(buf, 294, 5, 2)  # label/range flag, its block, 4-char flag, event count, reserved
    _swap(buf, 304, 18, 4)  # event times

    # Parameter section: walk the records as c3d_layout did (it has validated them).
    section = (buf[0] - 1) * 512
    buf[section + 3] = INTEL
    pos = section + 4
    while pos + 2 <= len(buf):
        n_char = struct.unpack_from("b", buf, pos)[0]
        if n_char == 0:
            break
        gid = struct.unpack_from("b", buf, pos + 1)[0]
        name_end = pos + 2 + abs(n_char)
        offset = struct.unpack_from(">H", buf, name_end)[0]
        cur = name_end + 2
        if gid < 0:
            cur += 1 + buf[cur]
        else:
            ptype, n_dims = struct.unpack_from("bb", buf, cur)
            cur += 2
            dims = tuple(buf[cur : cur + n_dims])
            cur += n_dims
            width = _TYPE_SIZES[ptype]
            count = int(np.prod(dims, dtype=np.int64))
            _swap(buf, cur, count, width)
            cur += count * width
            cur += 1 + buf[cur]
        # The offset, recomputed from the content (c3d_layout found them to agree, or
        # the offset written little-endian by mistake).
        struct.pack_into("<H", buf, name_end, 0 if offset == 0 else cur - name_end)
        if offset == 0:
            break
        pos = cur

    # Data section: every complete frame the file holds.
    point_width = 4 if layout.points_are_float else 2
    analog_width = 4 if layout.analogs_are_float else 2
    n_point_items = 4 * layout.n_points
    if layout.frame_bytes:
        n_frames = (len(buf) - layout.data_offset) // layout.frame_bytes
        block = bytes(buf[layout.data_offset : layout.data_offset + n_frames * layout.frame_bytes])
        frames = np.frombuffer(block, dtype=np.uint8).reshape(n_frames, layout.frame_bytes)
        point_bytes = n_point_items * point_width
        points = frames[:, :point_bytes].reshape(n_frames, n_point_items, point_width)[:, :, ::-1]
        analogs = frames[:, point_bytes:].reshape(n_frames, -1, analog_width)[:, :, ::-1]
        out = np.concatenate(
            [points.reshape(n_frames, -1), analogs.reshape(n_frames, -1)], axis=1
        )
        buf[layout.data_offset : layout.data_offset + n_frames * layout.frame_bytes] = out.tobytes()
    return bytes(buf)
