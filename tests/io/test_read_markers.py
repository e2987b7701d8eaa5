"""Tests for facecap.io.read_markers: C3D (via ezc3d), TRC and facecap CSV; real vendor C3D files; Qualisys QTM .tsv and
OptiTrack Motive .csv exports."""

from __future__ import annotations

import math
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import ezc3d
import numpy as np
import pytest

from facecap.errors import FacecapWarning, FileFormatError, InputError
from facecap.io.read_markers import read_markers
from facecap.units import mm_per_unit

# --------------------------------------------------------------------------- helpers


def _ezc3d_file(path, xyz, labels, rate, *, units="mm", residuals=None, first_frame=0, scale=-0.01):
    """Write a float C3D with ezc3d itself (independent of facecap's writer).

    xyz : (T, M, 3) in ``units``; residuals : (T, M), negative marks a gap.
    """
    T, M, _ = xyz.shape
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = [units] if units else []
    c["parameters"]["POINT"]["SCALE"]["value"] = [scale]
    c["header"]["points"]["first_frame"] = first_frame
    data = np.ones((4, M, T))
    data[:3] = np.transpose(xyz, (2, 1, 0))
    c["data"]["points"] = data
    res = np.zeros((T, M)) if residuals is None else residuals
    c["data"]["meta_points"] = {"residuals": res.T[None]}
    c.write(str(path))
    return path


def _take(rng, T=12, M=4):
    xyz = rng.uniform(-200.0, 200.0, size=(T, M, 3))
    return xyz, [f"m{i}" for i in range(M)]


def _int_c3d_bytes(counts, occluded, scale, labels, rate, unit):
    """A minimal integer-format C3D built byte by byte from the C3D specification."""
    T, M, _ = counts.shape

    def group(name, gid):
        return bytes([len(name), (-gid) & 0xFF]) + name.encode() + struct.pack("<h", 3) + b"\x00"

    def param(name, gid, ptype, dims, payload):
        body = struct.pack("<bB", ptype, len(dims)) + bytes(dims) + payload + b"\x00"
        return bytes([len(name), gid]) + name.encode() + struct.pack("<h", 2 + len(body)) + body

    width = max(len(s) for s in labels)
    records = [
        group("POINT", 1),
        param("USED", 1, 2, (), struct.pack("<h", M)),
        param("SCALE", 1, 4, (), struct.pack("<f", scale)),
        param("RATE", 1, 4, (), struct.pack("<f", rate)),
        param("FRAMES", 1, 2, (), struct.pack("<h", T)),
        param("LABELS", 1, -1, (width, M), b"".join(s.ljust(width).encode() for s in labels)),
        param("UNITS", 1, -1, (len(unit), 1), unit.encode()),
    ]
    section = bytearray([1, 0x50, 0, 84]) + b"".join(records) + b"\x00\x00"
    n_blocks = -(-len(section) // 512)
    section[2] = n_blocks
    section += bytes(n_blocks * 512 - len(section))
    data_start = 2 + n_blocks

    header = bytearray(512)
    header[0], header[1] = 2, 0x50
    struct.pack_into("<5H", header, 2, M, 0, 1, T, 10)
    struct.pack_into("<f", header, 12, scale)
    struct.pack_into("<2H", header, 16, data_start, 0)
    struct.pack_into("<f", header, 20, rate)

    frames = bytearray()
    for t in range(T):
        for m in range(M):
            if occluded[t, m]:
                frames += struct.pack("<3hh", 0, 0, 0, -1)
            else:
                frames += struct.pack("<3hh", *counts[t, m].tolist(), 0)
    return bytes(header) + bytes(section) + bytes(frames)


def _assert_one_clear_line(exc_info, path):
    err = exc_info.value
    assert err.path == str(path)
    assert "\n" not in str(err) and str(err).startswith(str(path) + ": ")


# --------------------------------------------------------------------------- C3D


def test_c3d_positions_labels_rate_unit_and_first_frame():
    rng = np.random.default_rng(0)
    xyz, labels = _take(rng)
    with _tmp() as folder:
        path = _ezc3d_file(folder / "take.c3d", xyz, labels, 120.0, units="cm", first_frame=41)
        take = read_markers(path)
    assert take.labels == tuple(labels)
    assert take.rate == 120.0
    assert take.source_unit == "cm"
    assert take.first_frame == 41
    assert take.source_path == str(path)
    # C3D stores float32; the reader converts cm -> mm.
    np.testing.assert_allclose(take.positions, xyz.astype(np.float32).astype(np.float64) * 10.0, rtol=0, atol=0)
    assert take.positions.dtype == np.float64 and take.positions.flags.c_contiguous


def test_c3d_gaps_from_negative_residual_and_from_all_zero_xyz(tmp_path):
    rng = np.random.default_rng(1)
    xyz, labels = _take(rng, T=10, M=3)
    residuals = np.full((10, 3), 0.5 + 0.0025)  # ezc3d truncates to multiples of |POINT:SCALE| = 0.01
    residuals[2, 1] = -1.0  # a C3D gap
    xyz[5, 2] = 0.0  # how ezc3d and others store a gap they were given as NaN
    xyz[7, 0] = [0.0, 0.0, 3.0]  # one zero coordinate is a real position, not a gap
    path = _ezc3d_file(tmp_path / "gaps.c3d", xyz, labels, 60.0, units="mm", residuals=residuals)
    take = read_markers(path)
    expected_gaps = np.zeros((10, 3), bool)
    expected_gaps[2, 1] = expected_gaps[5, 2] = True
    np.testing.assert_array_equal(take.gap_mask, expected_gaps)
    assert np.isnan(take.positions[expected_gaps]).all()
    np.testing.assert_allclose(take.positions[7, 0], [0.0, 0.0, 3.0])
    assert take.residuals.shape == (10, 3)
    np.testing.assert_array_equal(np.isnan(take.residuals), expected_gaps)
    np.testing.assert_allclose(take.residuals[~expected_gaps], 0.5, atol=1e-6)


def test_c3d_residuals_are_converted_to_mm(tmp_path):
    xyz = np.ones((3, 1, 3))
    residuals = np.array([[0.0], [0.1], [0.25]]) + 0.00025  # in cm, |POINT:SCALE| = 0.001 cm steps
    path = _ezc3d_file(tmp_path / "r.c3d", xyz, ["a"], 30.0, units="cm", residuals=residuals, scale=-0.001)
    take = read_markers(path)
    np.testing.assert_allclose(take.residuals[:, 0], [0.0, 1.0, 2.5], atol=1e-5)


def test_c3d_unit_override_and_default_unit(tmp_path):
    xyz = np.full((2, 1, 3), 1.5)
    path = _ezc3d_file(tmp_path / "lying.c3d", xyz, ["a"], 100.0, units="mm")
    take = read_markers(path, unit="m")
    assert take.source_unit == "m"
    np.testing.assert_allclose(take.positions, 1500.0)
    blank = _ezc3d_file(tmp_path / "nounit.c3d", xyz, ["a"], 100.0, units=None)
    take = read_markers(blank)
    assert take.source_unit == "mm"
    np.testing.assert_allclose(take.positions, 1.5)
    weird = _ezc3d_file(tmp_path / "weird.c3d", xyz, ["a"], 100.0, units="furlong")
    with pytest.raises(FileFormatError, match="POINT:UNITS.*furlong.*unit="):
        read_markers(weird)
    np.testing.assert_allclose(read_markers(weird, unit="cm").positions, 15.0)
    with pytest.raises(InputError, match="unit"):
        read_markers(path, unit="parsec")


def test_c3d_more_than_255_labels_uses_labels2(tmp_path):
    M = 300
    xyz = np.arange(2 * M * 3, dtype=float).reshape(2, M, 3) + 1.0
    labels = [f"marker_{i:03d}" for i in range(M)]
    path = _ezc3d_file(tmp_path / "many.c3d", xyz, labels, 60.0)
    assert "LABELS2" in ezc3d.c3d(str(path))["parameters"]["POINT"]  # the case under test
    take = read_markers(path)
    assert take.labels == tuple(labels)
    np.testing.assert_allclose(take.positions, xyz)


def test_c3d_integer_format_built_from_the_specification(tmp_path):
    rng = np.random.default_rng(2)
    counts = rng.integers(-3000, 3000, size=(6, 3, 3)).astype(np.int16)
    occluded = np.zeros((6, 3), bool)
    occluded[1, 2] = occluded[4, 0] = True
    path = tmp_path / "int.c3d"
    path.write_bytes(_int_c3d_bytes(counts, occluded, 0.05, ["a", "bb", "c"], 200.0, "cm"))
    take = read_markers(path)
    assert take.labels == ("a", "bb", "c")
    assert take.rate == 200.0 and take.source_unit == "cm"
    np.testing.assert_array_equal(take.gap_mask, occluded)
    expected = counts.astype(np.float64) * np.float32(0.05) * 10.0
    np.testing.assert_allclose(take.positions[~occluded], expected[~occluded], rtol=1e-6)


def test_c3d_truncated_file_raises_instead_of_returning_fewer_frames(tmp_path):
    rng = np.random.default_rng(3)
    xyz, labels = _take(rng, T=200, M=5)
    whole = _ezc3d_file(tmp_path / "whole.c3d", xyz, labels, 60.0).read_bytes()
    header_words = struct.unpack_from("<10H", whole, 0)
    data_end = (header_words[8] - 1) * 512 + 200 * 5 * 16
    # ezc3d on its own reads such files silently, with fewer frames:
    half = tmp_path / "half.c3d"
    half.write_bytes(whole[: len(whole) // 2])
    assert ezc3d.c3d(str(half))["data"]["points"].shape[2] < 200
    for name, cut in [("half", len(whole) // 2), ("last_byte", data_end - 1), ("header_only", 600)]:
        path = tmp_path / f"{name}.c3d"
        path.write_bytes(whole[:cut])
        with pytest.raises(FileFormatError, match="truncated") as info:
            read_markers(path)
        _assert_one_clear_line(info, path)
    exact = tmp_path / "exact.c3d"  # cut right after the data: every frame is there
    exact.write_bytes(whole[:data_end])
    assert read_markers(exact).n_frames == 200


@pytest.mark.parametrize(
    "content, message",
    [
        (b"", "empty"),
        (b"PathFileType\t4\n", "too short"),
        (np.random.default_rng(4).bytes(4096), "not a C3D file"),
        (b"\x02\x50" + bytes(510), "parameter section"),
    ],
    ids=["empty", "text", "random", "header_without_parameters"],
)
def test_c3d_garbage_raises_one_clear_error(tmp_path, content, message):
    path = tmp_path / "bad.c3d"
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=message) as info:
        read_markers(path)
    _assert_one_clear_line(info, path)


def test_c3d_corrupt_parameter_sections_never_crash(tmp_path):
    # Unchecked, ezc3d segfaults or hangs on some of these (seen while developing);
    # every one must either read or raise FileFormatError.
    rng = np.random.default_rng(5)
    xyz, labels = _take(rng, T=20, M=3)
    whole = bytearray(_ezc3d_file(tmp_path / "src.c3d", xyz, labels, 60.0).read_bytes())
    param_end = (struct.unpack_from("<H", whole, 16)[0] - 1) * 512
    outcomes = {"read": 0, "rejected": 0}
    for k in range(60):
        b = bytearray(whole)
        for _ in range(rng.integers(1, 4)):
            b[rng.integers(512, param_end)] = rng.integers(0, 256)
        path = tmp_path / f"fuzz{k}.c3d"
        path.write_bytes(bytes(b))
        try:
            read_markers(path)
            outcomes["read"] += 1
        except FileFormatError as err:
            assert err.path == str(path) and "\n" not in str(err)
            outcomes["rejected"] += 1
    assert outcomes["rejected"] > 0 and sum(outcomes.values()) == 60


def test_c3d_header_copies_yield_to_the_parameters_and_the_data(tmp_path):
    # The header's counts are copies of POINT:USED and POINT:FRAMES (C3D User Guide);
    # ezc3d reads by the parameters, and so does facecap where the file holds that data.
    rng = np.random.default_rng(6)
    xyz = rng.uniform(-100.0, 100.0, size=(4, 2, 3))
    whole = bytearray(_ezc3d_file(tmp_path / "ok.c3d", xyz, ["a", "b"], 60.0).read_bytes())
    expected = xyz.astype(np.float32).astype(np.float64)
    more_points = bytearray(whole)
    struct.pack_into("<H", more_points, 2, 3)  # header says 3 markers, POINT:USED says 2
    (tmp_path / "points.c3d").write_bytes(bytes(more_points))
    np.testing.assert_array_equal(read_markers(tmp_path / "points.c3d").positions, expected)
    inverted = bytearray(whole)
    struct.pack_into("<2H", inverted, 6, 9, 3)  # first frame 9, last frame 3; POINT:FRAMES says 4
    (tmp_path / "frames.c3d").write_bytes(bytes(inverted))
    np.testing.assert_array_equal(read_markers(tmp_path / "frames.c3d").positions, expected)


def test_c3d_inverted_header_without_point_frames_is_rejected(tmp_path):
    counts = np.full((3, 2, 3), 100, dtype=np.int64)
    data = bytearray(_int_c3d_bytes(counts, np.zeros((3, 2), bool), 0.1, ["a", "b"], 50.0, "mm"))
    # Rename POINT:FRAMES to POINT:FRAMEZ so that only the header gives the count.
    at = data.index(b"FRAMES")
    data[at : at + 6] = b"FRAMEZ"
    struct.pack_into("<2H", data, 6, 9, 3)
    path = tmp_path / "inverted.c3d"
    path.write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match="inverted") as info:
        read_markers(path)
    _assert_one_clear_line(info, path)


def test_c3d_stale_point_used_is_read_by_the_header_count_that_fits(tmp_path):
    # POINT:USED one too many for the data (c3d.org's kyowadengyo.c3d): ezc3d reads
    # misaligned frames; facecap reads the header's count, which the file holds.
    rng = np.random.default_rng(7)
    counts = rng.integers(-3000, 3000, size=(40, 3, 3))
    occluded = np.zeros((40, 3), bool)
    data = bytearray(_int_c3d_bytes(counts, occluded, 0.1, ["a", "b", "c"], 50.0, "mm"))
    data_start = struct.unpack_from("<H", data, 16)[0]
    data = data[: (data_start - 1) * 512 + 40 * 3 * 8]  # no padding after the last frame
    used = data.index(b"USED") + 4 + 2 + 2
    struct.pack_into("<h", data, used, 4)
    path = tmp_path / "stale_used.c3d"
    path.write_bytes(bytes(data))
    assert ezc3d.c3d(str(path))["data"]["points"].shape[1:] == (4, 30)  # silently wrong
    take = read_markers(path)
    assert take.labels == ("a", "b", "c") and take.n_frames == 40
    np.testing.assert_allclose(take.positions, counts * 0.1, rtol=1e-6)


def test_c3d_unfinished_export_reads_the_whole_frames_with_a_warning(tmp_path):
    rng = np.random.default_rng(8)
    xyz, labels = _take(rng, T=30, M=3)
    whole = _ezc3d_file(tmp_path / "whole.c3d", xyz, labels, 60.0).read_bytes()
    data_start = struct.unpack_from("<H", whole, 16)[0]
    path = tmp_path / "unfinished.c3d"
    path.write_bytes(whole[: (data_start - 1) * 512 + 12 * 3 * 16])  # 12 whole frames of 30
    with pytest.warns(FacecapWarning, match="declares 30 frames but ends exactly after frame 12"):
        take = read_markers(path)
    np.testing.assert_array_equal(take.positions, xyz[:12].astype(np.float32).astype(np.float64))


def test_c3d_duplicate_labels_get_a_suffix_with_a_warning(tmp_path):
    rng = np.random.default_rng(9)
    xyz, _ = _take(rng, T=5, M=4)
    path = _ezc3d_file(tmp_path / "dup.c3d", xyz, ["LANK", "RANK", "LANK", "LANK_2"], 100.0)
    with pytest.warns(FacecapWarning, match="duplicate"):
        take = read_markers(path)
    assert take.labels == ("LANK", "RANK", "LANK_3", "LANK_2")


def test_c3d_subject_prefix_split_only_when_unambiguous(tmp_path):
    rng = np.random.default_rng(10)
    xyz, _ = _take(rng, T=5, M=3)
    one = read_markers(_ezc3d_file(tmp_path / "one.c3d", xyz, ["Ann:Chin", "Ann:Nose", "Brow"], 100.0))
    assert one.labels == ("Chin", "Nose", "Brow") and one.subjects == ("Ann", "Ann", "")
    two = read_markers(_ezc3d_file(tmp_path / "two.c3d", xyz, ["Ann:Chin", "Bob:Chin", "Brow"], 100.0))
    assert two.labels == ("Ann:Chin", "Bob:Chin", "Brow") and two.subjects is None


def _with_timecode(source, path, **params):
    """``source`` rewritten by ezc3d with a TIMECODE group holding ``params`` (the layout Vicon writes)."""
    c = ezc3d.c3d(str(source))
    for name, value in params.items():
        c.add_parameter("TIMECODE", name, value)
    c.write(str(path))
    return path


@pytest.mark.parametrize("params, expected", [
    ({"FIRST_FRAME": [10, 22, 31, 12], "DROP_FRAMES": [0], "SUBFRAMESPERFRAME": [4]}, "10:22:31:12"),
    ({"FIRST_FRAME": [1, 0, 0, 2], "DROP_FRAMES": [1]}, "01:00:00;02"),  # drop frame: ';' as SMPTE writes it
    ({"FIRST_FRAME": [23, 59, 59, 29, 3]}, "23:59:59:29.3"),  # a subframe
    ({"FIRST_FRAME": "09:08:07:06"}, "09:08:07:06"),  # as text
    ({"FIRST_FRAME": "09:08:07;06"}, "09:08:07;06"),
])
def test_c3d_timecode_written_by_ezc3d_is_kept(tmp_path, params, expected):
    rng = np.random.default_rng(7)
    xyz, labels = _take(rng)
    plain = _ezc3d_file(tmp_path / "plain.c3d", xyz, labels, 120.0)
    assert read_markers(plain).timecode is None  # no TIMECODE group: no timecode
    take = read_markers(_with_timecode(plain, tmp_path / "tc.c3d", **params))
    assert take.timecode == expected and take.capture_start is None
    np.testing.assert_allclose(take.positions, xyz, rtol=1e-6)  # the rest of the take unchanged
    assert take.select(labels[:2]).timecode == expected  # it travels with the take


@pytest.mark.parametrize("first_frame", [[25, 0, 0, 0], [10, 61, 0, 0], [1, 2, 3], [1.5, 2, 3, 4], "noon"])
def test_c3d_timecode_that_is_no_timecode_is_dropped_with_a_notice(tmp_path, first_frame):
    rng = np.random.default_rng(8)
    xyz, labels = _take(rng)
    plain = _ezc3d_file(tmp_path / "plain.c3d", xyz, labels, 120.0)
    with pytest.warns(FacecapWarning, match="TIMECODE:FIRST_FRAME .* not a timecode"):
        take = read_markers(_with_timecode(plain, tmp_path / "bad.c3d", FIRST_FRAME=first_frame))
    assert take.timecode is None
    np.testing.assert_allclose(take.positions, xyz, rtol=1e-6)


def test_every_listed_format_is_read(tmp_path):
    """MARKER_FORMATS (what --help lists) and read_markers agree: each suffix reads; another does not."""
    from facecap.io.read_markers import MARKER_FORMATS, MARKER_SUFFIXES
    from facecap.io.write_markers import write_markers
    from facecap.structures import MarkerSequence

    rng = np.random.default_rng(9)
    xyz, labels = _take(rng, T=3, M=2)
    take = MarkerSequence(xyz, labels, 100.0)
    files = {suffix: tmp_path / f"take{suffix}" for suffix in MARKER_FORMATS}
    for suffix in (".c3d", ".trc", ".csv"):
        write_markers(take, files[suffix])
    rows = ["\t".join(f"{v:.6f}" for v in frame.ravel()) for frame in xyz]
    files[".tsv"].write_text("\n".join(["NO_OF_FRAMES\t3", "NO_OF_MARKERS\t2", "FREQUENCY\t100",
                                        "MARKER_NAMES\t" + "\t".join(labels), *rows]) + "\n")
    assert MARKER_SUFFIXES == tuple(MARKER_FORMATS) and set(MARKER_FORMATS) == set(files)
    for path in files.values():
        np.testing.assert_allclose(read_markers(path).positions, xyz, rtol=1e-5, atol=1e-4)
    with pytest.raises(FileFormatError, match="expected one of") as info:
        read_markers(tmp_path / "take.bvh")
    assert all(suffix in str(info.value) for suffix in MARKER_FORMATS)


# --------------------------------------------------------------------------- TRC

_TRC = (
    "PathFileType\t4\t(X/Y/Z)\ttake.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
    "50.00\t50.00\t3\t2\tcm\t50.00\t11\t3\n"
    "Frame#\tTime\tBrow L\t\t\tNose\t\t\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
    "\n"
    "11\t0.200\t1\t2\t3\t4\t5\t6\n"
    "12\t0.220\t1.5\t2.5\t3.5\t\t\t\n"
    "13\t0.240\t2\t3\t4\t7\t8\t9\n"
)


def test_trc_reads_header_names_gaps_and_converts_to_mm(tmp_path):
    path = tmp_path / "take.trc"
    path.write_text(_TRC)
    take = read_markers(path)
    assert take.labels == ("Brow L", "Nose")
    assert take.rate == 50.0 and take.source_unit == "cm"
    assert take.first_frame == 10  # Frame# 11 counted from 1
    assert take.residuals is None
    expected = np.array(
        [[[1, 2, 3], [4, 5, 6]], [[1.5, 2.5, 3.5], [np.nan] * 3], [[2, 3, 4], [7, 8, 9]]]
    ) * 10.0
    np.testing.assert_array_equal(take.positions, expected)
    assert read_markers(path, unit="mm").positions[0, 0].tolist() == [1.0, 2.0, 3.0]


def test_trc_suffix_is_case_insensitive_and_crlf_is_fine(tmp_path):
    path = tmp_path / "TAKE.TRC"
    path.write_bytes(_TRC.replace("\n", "\r\n").encode())
    assert read_markers(path).n_frames == 3


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("13\t0.240\t2\t3\t4\t7\t8\t9\n", "13\t0.240\t2\t3\t4\t7\n", "line 9: 6 tab-separated values, expected 8"),
        ("50.00\t50.00\t3\t2", "50.00\t50.00\t4\t2", "NumFrames=4 but the file holds 3 data rows"),
        ("50.00\t50.00\t3\t2", "50.00\t50.00\t3\t3", "line 4 names 2 markers but the header .* NumMarkers=3"),
        ("50.00\t50.00\t3", "100.0\t50.00\t3", "Time column spans 0.04 s .* DataRate=100 Hz"),
        ("12\t0.220\t1.5", "12\t0.220\tabc", "line 8, column 3: expected a number, got 'abc'"),
        ("13\t0.240", "14\t0.240", "line 9: Frame# 14 does not follow 12"),
        ("\tcm\t", "\tfurlong\t", "Units gives unit 'furlong'"),
        ("13\t0.240\t2\t3\t4\t7\t8\t9\n", "13\t0.240\t2\t3\t4\t7\t8\t9\t10\n", "line 9: 9 values, more than the 8"),
        ("PathFileType", "PathType", "not a TRC file"),
    ],
    ids=["short_row", "numframes", "nummarkers", "datarate", "not_a_number", "frame_gap", "unit", "long_row", "magic"],
)
def test_trc_errors_name_the_line(tmp_path, old, new, message):
    assert old in _TRC
    path = tmp_path / "bad.trc"
    path.write_text(_TRC.replace(old, new, 1))
    with pytest.raises(FileFormatError, match=message) as info:
        read_markers(path)
    _assert_one_clear_line(info, path)


def test_trc_blank_padded_rows_are_gaps_not_errors(tmp_path):
    text = _TRC.replace("13\t0.240\t2\t3\t4\t7\t8\t9\n", "13\t0.240\t2\t3\t4\t\t\t\t\n")
    path = tmp_path / "padded.trc"
    path.write_text(text)
    assert read_markers(path).gap_mask[2].tolist() == [False, True]


# --------------------------------------------------------------------------- CSV

_CSV = (
    "# exported by hand\n"
    "# rate=120\n"
    "# unit=cm\n"
    "frame,time,Chin_L1_x,Chin_L1_y,Chin_L1_z,nose_x,nose_y,nose_z\n"
    "5,0.0,1,2,3,,,\n"
    "6,0.008333,4,5,6,7,8,9\n"
)


def test_csv_reads_comments_labels_with_underscores_and_gaps(tmp_path):
    path = tmp_path / "take.csv"
    path.write_text(_CSV)
    take = read_markers(path)
    assert take.labels == ("Chin_L1", "nose")
    assert take.rate == 120.0 and take.source_unit == "cm" and take.first_frame == 5
    expected = np.array([[[1, 2, 3], [np.nan] * 3], [[4, 5, 6], [7, 8, 9]]]) * 10.0
    np.testing.assert_array_equal(take.positions, expected)


def test_csv_rate_inferred_from_time_and_unit_defaults_to_mm(tmp_path):
    times = np.arange(5) / 240.0
    rows = "\n".join(f"{i},{t:.6f},{i},0,0" for i, t in enumerate(times))
    path = tmp_path / "plain.csv"
    path.write_text(f"frame,time,a_x,a_y,a_z\n{rows}\n")
    take = read_markers(path)
    assert take.source_unit == "mm"
    assert take.rate == 240.0  # 1 / mean step is 239.995 from the 6-decimal rounding
    assert read_markers(path, unit="in").positions[4, 0, 0] == pytest.approx(4 * 25.4)
    odd = np.arange(100) / 59.94  # an NTSC rate written exactly is not rounded to 60
    rows = "\n".join(f"{i},{t!r},0,0,0" for i, t in enumerate(odd.tolist()))
    path.write_text(f"frame,time,a_x,a_y,a_z\n{rows}\n")
    assert math.isclose(read_markers(path).rate, 59.94, rel_tol=1e-12)


@pytest.mark.parametrize(
    "text, message",
    [
        ("frame,time,a_x,a_y\n0,0,1,2\n", "three columns"),
        ("frame,time,a_x,b_y,a_z\n0,0,1,2,3\n", "columns 3-5: expected <label>_x"),
        ("# rate=10\nframe,time,a_x,a_y,a_z\n0,0,1,2\n", "line 3: 4 values, expected 5"),
        ("frame,time,a_x,a_y,a_z\n0,0,1,2,3\n1,0.1,1,2,3\n2,0.5,1,2,3\n", "line 3: the time column is not evenly"),
        ("frame,time,a_x,a_y,a_z\n0,0,1,2,3\n", "single frame"),
        ("# rate=fast\nframe,time,a_x,a_y,a_z\n0,0,1,2,3\n", "line 1: rate 'fast'"),
        ("# rate=10\nframe,time,a_x,a_y,a_z,a_x,a_y,a_z\n0,0,1,2,3,4,5,6\n", "duplicate marker labels \\['a'\\]"),
        ("# only comments\n", "no header row"),
        ("time,frame,a_x,a_y,a_z\n", "must start with 'frame,time'"),
    ],
    ids=["columns", "triple", "row_width", "uneven_time", "one_frame", "rate", "duplicate", "no_header", "order"],
)
def test_csv_errors(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=message) as info:
        read_markers(path)
    _assert_one_clear_line(info, path)


# --------------------------------------------------------------------------- dispatch


def test_unknown_suffix_missing_file_and_binary_text(tmp_path):
    with pytest.raises(FileFormatError, match="suffix '.bvh'"):
        read_markers(tmp_path / "take.bvh")
    with pytest.raises(FileFormatError, match="file not found") as info:
        read_markers(tmp_path / "missing.c3d")
    _assert_one_clear_line(info, tmp_path / "missing.c3d")
    (tmp_path / "bin.csv").write_bytes(b"\x00\x01\x02frame")
    with pytest.raises(FileFormatError, match="binary"):
        read_markers(tmp_path / "bin.csv")
    (tmp_path / "empty.trc").write_text("  \n")
    with pytest.raises(FileFormatError, match="empty"):
        read_markers(tmp_path / "empty.trc")
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(FileFormatError, match="not a regular file"):
        read_markers(tmp_path / "dir.csv")


# A tiny context manager so the first test shows the plain-folder use too.
class _tmp:
    def __enter__(self):
        import tempfile
        from pathlib import Path

        self._d = tempfile.TemporaryDirectory()
        return Path(self._d.name)

    def __exit__(self, *exc):
        self._d.cleanup()


def test_c3d_qualisys_style_parameter_section_reads(tmp_path):
    # Qualisys Track Manager writes 0, 0 as the parameter section's first two bytes (the
    # specification's "first parameter block" and key byte) and parameter names with lower-case
    # letters and spaces; ezc3d ignores both, and so must the pre-check (it refused such files).
    rng = np.random.default_rng(11)
    xyz, labels = _take(rng, T=20, M=3)
    data = bytearray(_ezc3d_file(tmp_path / "plain.c3d", xyz, labels, 100.0).read_bytes())
    section = (data[0] - 1) * 512
    data[section], data[section + 1] = 0, 0
    name = data.index(b"DESCRIPTIONS")  # a name ezc3d reads but facecap does not need
    data[name : name + 12] = b"Descr iption"
    path = tmp_path / "qualisys_style.c3d"
    path.write_bytes(bytes(data))
    reference = ezc3d.c3d(str(path))["data"]["points"]
    take = read_markers(path)
    assert take.labels == tuple(labels) and take.n_frames == 20
    np.testing.assert_allclose(take.positions, np.transpose(reference[:3], (2, 1, 0)), rtol=1e-6)


# --------------------------------------------------------------------------- real vendor C3D files
# read_markers on real vendor C3D files (tests/io/data/c3d_corpus, see its README.md).
#
# The independent truth is ezc3d's own reading of each file, with facecap's documented
# handling applied to ezc3d's raw arrays here (unit scale from POINT:UNITS, a gap where
# the residual is negative or x, y, z are all zero, Subject: prefixes split off when the
# labels stay unique). Big-endian (SGI) files, which ezc3d refuses, are checked against
# the Intel copy of the same take that c3d.org publishes beside them.

CORPUS = Path(__file__).parent / "data" / "c3d_corpus"
FILES = sorted(p.name for p in CORPUS.glob("*.c3d"))

# File -> (frames ezc3d returns, frames facecap returns, why they differ).
FRAME_FIXES = {
    # POINT:USED says 12 markers, the header 11; only 11 fit the file's data for the
    # 152 frames both counts state: ezc3d reads 145 misaligned frames of 12 markers.
    "kyowadengyo.c3d": (145, 152, "POINT:USED"),
}
# Files ezc3d refuses (processor type 86) -> their Intel (PC) copy in the corpus.
BIG_ENDIAN = {
    "c3dorg_s01_Eb015si.c3d": "c3dorg_s01_Eb015pi.c3d",
    "c3dorg_s02_sgi_int.c3d": "c3dorg_s02_pc_int.c3d",
    "c3dorg_s02_sgi_real.c3d": "c3dorg_s02_pc_real.c3d",
    "motionanalysis_MACsample_sgi.c3d": None,  # no PC copy published
}
# Files read with a FacecapWarning, and what it says.
WARNS = {
    "motionanalysis_Walk1.c3d": "duplicate marker label",
    "motionanalysis_MACsample_sgi.c3d": "duplicate marker label",
    "c3dorg_s28_dynamic.c3d": "duplicate marker label",
}
UNIT_WORDS = {"mm": "mm", "cm": "cm", "m": "m", "": "mm"}


def _read(name):
    path = CORPUS / name
    if name in WARNS:
        with pytest.warns(FacecapWarning, match=WARNS[name]):
            return read_markers(path)
    return read_markers(path)


def _ezc3d_truth(path):
    """What facecap should return, from ezc3d's raw arrays and facecap's documented rules."""
    c = ezc3d.c3d(str(path))
    P = np.asarray(c["data"]["points"], dtype=np.float64)[:3].transpose(2, 1, 0)
    R = np.asarray(c["data"]["meta_points"]["residuals"], dtype=np.float64)[0].T
    point = c["parameters"]["POINT"]
    units = [u.strip() for u in point["UNITS"]["value"] if u.strip()] if "UNITS" in point else []
    scale = mm_per_unit(UNIT_WORDS.get(units[0] if units else "", units[0] if units else "mm"))
    gaps = (R < 0) | (P == 0).all(axis=2)
    labels = []
    k = 1
    while ("LABELS" if k == 1 else f"LABELS{k}") in point:
        labels += [s.strip() for s in point["LABELS" if k == 1 else f"LABELS{k}"]["value"]]
        k += 1
    labels = labels[: P.shape[1]]
    return P * scale, R * scale, gaps, labels, float(point["RATE"]["value"][0])


@pytest.mark.parametrize("name", [n for n in FILES if n not in BIG_ENDIAN])
def test_corpus_file_reads_as_ezc3d_reads_it(name):
    path = CORPUS / name
    take = _read(name)
    P, R, gaps, raw_labels, rate = _ezc3d_truth(path)
    if name in FRAME_FIXES:
        ez_frames, fc_frames, _ = FRAME_FIXES[name]
        assert P.shape[0] == ez_frames and take.n_frames == fc_frames
        return
    assert take.n_frames == P.shape[0] and take.n_markers == P.shape[1]
    assert take.rate == pytest.approx(rate, rel=1e-12)
    np.testing.assert_array_equal(take.gap_mask, gaps)
    np.testing.assert_allclose(take.positions[~gaps], P[~gaps], rtol=1e-6, atol=0)
    np.testing.assert_allclose(take.residuals[~gaps], R[~gaps], rtol=1e-6, atol=0)
    assert np.isnan(take.residuals[gaps]).all()
    # Labels: the file's, with a Subject: prefix split off into take.subjects, and
    # duplicates made unique by a suffix (first occurrence unchanged).
    if take.subjects is not None:
        rebuilt = [f"{s}:{m}" if s else m for s, m in zip(take.subjects, take.labels)]
    else:
        rebuilt = list(take.labels)
    assert len(set(take.labels)) == len(take.labels)
    for got, want in zip(rebuilt, raw_labels):
        assert got == want or (want and got.startswith(want + "_") and got[len(want) + 1 :].isdigit()) or (
            not want and got.startswith("unlabeled_point_")
        )


@pytest.mark.parametrize("name", sorted(BIG_ENDIAN))
def test_big_endian_file_agrees_with_its_pc_copy(name):
    with pytest.raises(Exception, match="MIPS"):
        ezc3d.c3d(str(CORPUS / name))  # why facecap converts it first
    take = _read(name)
    assert take.n_frames > 0 and np.isfinite(take.positions).any()
    pc_name = BIG_ENDIAN[name]
    if pc_name is None:
        return
    pc = _read(pc_name)
    assert take.labels == pc.labels and take.rate == pc.rate and take.first_frame == pc.first_frame
    np.testing.assert_array_equal(take.gap_mask, pc.gap_mask)
    np.testing.assert_array_equal(take.positions, pc.positions)
    np.testing.assert_array_equal(take.residuals, pc.residuals)


def test_dec_files_agree_with_their_pc_copies():
    for dec, pc, tolerance in [
        ("c3dorg_s01_Eb015vi.c3d", "c3dorg_s01_Eb015pi.c3d", 0.0),
        ("c3dorg_s02_dec_real.c3d", "c3dorg_s02_pc_real.c3d", 0.0),
        # c3d.org's DEC integer copy differs from the PC one by one count (POINT:SCALE,
        # 0.28 mm) in 59 of 9612 samples: a rounding in their conversion, seen by ezc3d too.
        ("c3dorg_s02_dec_int.c3d", "c3dorg_s02_pc_int.c3d", 0.2812),
    ]:
        a, b = read_markers(CORPUS / dec), read_markers(CORPUS / pc)
        assert a.labels == b.labels and a.rate == b.rate
        np.testing.assert_array_equal(a.gap_mask, b.gap_mask)
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=tolerance)


def test_kyowadengyo_reads_the_header_marker_count_the_data_fit():
    take = read_markers(CORPUS / "kyowadengyo.c3d")
    assert take.n_markers == 11 and take.n_frames == 152
    # Misaligned frames would jump by metres between frames; the real take moves smoothly.
    steps = np.abs(np.diff(take.positions, axis=0))
    assert np.nanmax(steps) < 100.0


def test_vicon_subject_prefix_is_split_off():
    take = read_markers(CORPUS / "vicon_gait-pig.c3d")
    assert take.subjects is not None and set(take.subjects) == {"A22"}
    assert "RKNE" in take.labels and not any(":" in s for s in take.labels)
    sub = take.select(["LKNE", "RKNE"])
    assert sub.subjects == ("A22", "A22")


def test_facecap_info_succeeds_on_every_corpus_file():
    from facecap.report.describe import describe_file

    paths = [CORPUS / n for n in FILES]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        for path in paths:
            info = describe_file(path)
            take = read_markers(path)
            assert info["frames"] == take.n_frames and info["labels"] == list(take.labels)
    # and through the command line itself, on a big-endian file
    cli = subprocess.run(
        [sys.executable, "-W", "ignore", "-m", "facecap.cli", "info", str(CORPUS / "c3dorg_s02_sgi_real.c3d")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert cli.returncode == 0 and "89" in cli.stdout, cli.stderr[-2000:]


# --------------------------------------------------------------------------- QTM .tsv and Motive .csv exports
# read_markers on Qualisys QTM .tsv and OptiTrack Motive .csv exports.
#
# The files are written here from known arrays in the layouts the two vendors
# document (QTM's "TSV export" and Motive's "CSV export" manual pages), then read
# back; no public sample with a clear licence was found to keep beside them.


def _known_take(rng, T=6, M=3):
    P = np.round(rng.uniform(-500.0, 500.0, size=(T, M, 3)), 3)
    gaps = np.zeros((T, M), bool)
    gaps[1, 0] = gaps[4, 2] = gaps[5, 1] = True
    return P, gaps


def _qtm_tsv(P, gaps, labels, rate, *, column_row=True, gap_as_zero=True):
    T, M, _ = P.shape
    lines = [
        f"NO_OF_FRAMES\t{T}", "NO_OF_CAMERAS\t8", f"NO_OF_MARKERS\t{M}", f"FREQUENCY\t{rate:g}",
        "NO_OF_ANALOG\t0", "ANALOG_FREQUENCY\t0", "DESCRIPTION\t--",
        "TIME_STAMP\t2019-03-04, 10:22:31.123\t12345.678", "DATA_INCLUDED\t3D",
        "MARKER_NAMES\t" + "\t".join(labels),
    ]
    if column_row:
        lines.append("Frame\tTime\t" + "\t".join(f"{s} {a}" for s in labels for a in "XYZ"))
    for t in range(T):
        cells = []
        for m in range(M):
            cells += (["0.000"] * 3 if gap_as_zero else [""] * 3) if gaps[t, m] else [f"{v:.3f}" for v in P[t, m]]
        lead = [str(t + 1), f"{t / rate:.5f}"] if column_row else []
        lines.append("\t".join(lead + cells))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("column_row, gap_as_zero", [(True, True), (True, False), (False, True)])
def test_qualisys_tsv_round_trip(tmp_path, column_row, gap_as_zero):
    rng = np.random.default_rng(0)
    P, gaps = _known_take(rng)
    labels = ["Chin", "Nose Tip", "L_Brow"]
    path = tmp_path / "take.tsv"
    path.write_text(_qtm_tsv(P, gaps, labels, 200.0, column_row=column_row, gap_as_zero=gap_as_zero))
    take = read_markers(path)
    assert take.labels == tuple(labels) and take.rate == 200.0 and take.source_unit == "mm"
    np.testing.assert_array_equal(take.gap_mask, gaps)
    np.testing.assert_allclose(take.positions[~gaps], P[~gaps], rtol=1e-12)
    assert take.first_frame == 0 and take.residuals is None
    # TIME_STAMP: the capture's start by QTM's clock, then seconds since the PC started (not kept)
    assert take.capture_start == "2019-03-04, 10:22:31.123" and take.timecode is None


def test_qualisys_tsv_header_disagreeing_with_data_is_one_clear_line(tmp_path):
    rng = np.random.default_rng(1)
    P, gaps = _known_take(rng)
    text = _qtm_tsv(P, gaps, ["a", "b", "c"], 100.0).replace("NO_OF_FRAMES\t6", "NO_OF_FRAMES\t7")
    path = tmp_path / "bad.tsv"
    path.write_text(text)
    with pytest.raises(FileFormatError, match="NO_OF_FRAMES says 7") as info:
        read_markers(path)
    assert "\n" not in str(info.value) and info.value.path == str(path)


def _motive_csv(P, gaps, labels, rate, units, scale):
    """A Motive 2.x export: one rigid body (rotation + position + error), its markers, then markers."""
    T, M, _ = P.shape
    head = (
        f"Format Version,1.23,Take Name,Take 2020-01-01,Capture Frame Rate,{rate:.6f},"
        f"Export Frame Rate,{rate:.6f},Capture Start Time,2020-01-01 10.00.00.000 AM,"
        f"Total Frames in Take,{T},Total Exported Frames,{T},Rotation Type,Quaternion,"
        f"Length Units,{units},Coordinate Space,Global"
    )
    types = ["", "Type"] + ["Rigid Body"] * 8 + ["Rigid Body Marker"] * 3
    names = ["", "Name"] + ["Head"] * 8 + ["Head:Marker1"] * 3
    ids = ["", "ID"] + ["1"] * 8 + ["1"] * 3
    kinds = ["", ""] + ["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"] + ["Position"] * 3
    axes = ["Frame", "Time (Seconds)"] + list("XYZW") + list("XYZ") + [""] + list("XYZ")
    for s in labels:
        types += ["Marker"] * 3
        names += [s] * 3
        ids += ["1:" + s] * 3
        kinds += ["Position"] * 3
        axes += list("XYZ")
    rows = [head, "", ",".join(types), ",".join(names), ",".join(ids), ",".join(kinds), ",".join(axes)]
    for t in range(T):
        cells = [str(t), f"{t / rate:.6f}"] + ["0.1"] * 4 + ["9.0"] * 3 + ["0.0002"] + ["8.0"] * 3
        for m in range(M):
            cells += [""] * 3 if gaps[t, m] else [repr(float(v) / scale) for v in P[t, m]]
        rows.append(",".join(cells))
    return "\n".join(rows) + "\n"


@pytest.mark.parametrize("units, scale", [("Meters", 1000.0), ("Millimeters", 1.0), ("Centimeters", 10.0)])
def test_motive_csv_round_trip_keeps_marker_positions_only(tmp_path, units, scale):
    rng = np.random.default_rng(2)
    P, gaps = _known_take(rng)
    path = tmp_path / "motive.csv"
    path.write_text(_motive_csv(P, gaps, ["Actor:Chin", "Actor:Nose", "Actor:Brow"], 120.0, units, scale))
    take = read_markers(path)
    assert take.labels == ("Chin", "Nose", "Brow") and take.subjects == ("Actor",) * 3
    assert take.rate == 120.0 and take.source_unit == {"Meters": "m", "Millimeters": "mm", "Centimeters": "cm"}[units]
    np.testing.assert_array_equal(take.gap_mask, gaps)
    np.testing.assert_allclose(take.positions[~gaps], P[~gaps], rtol=1e-12)
    assert take.capture_start == "2020-01-01 10.00.00.000 AM" and take.timecode is None


def test_facecap_csv_still_read_beside_motive_sniffing(tmp_path):
    path = tmp_path / "own.csv"
    path.write_text("# rate=100\nframe,time,a_x,a_y,a_z\n0,0,1,2,3\n1,0.01,4,5,6\n")
    take = read_markers(path)
    assert take.labels == ("a",) and take.positions[1, 0].tolist() == [4.0, 5.0, 6.0]


def test_facecap_info_describes_a_qtm_tsv(tmp_path, capsys):
    from facecap.cli import main

    rng = np.random.default_rng(12)
    P, gaps = _known_take(rng)
    labels = ["Chin", "NoseTip", "BrowL"]
    path = tmp_path / "take.tsv"
    path.write_text(_qtm_tsv(P, gaps, labels, 100.0))
    capsys.readouterr()
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "100" in out and all(label in out for label in labels)
