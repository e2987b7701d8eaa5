"""read_markers on Qualisys QTM .tsv and OptiTrack Motive .csv exports.

The files are written here from known arrays in the layouts the two vendors
document (QTM's "TSV export" and Motive's "CSV export" manual pages), then read
back; no public sample with a clear licence was found to keep beside them.
"""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import FileFormatError
from facecap.io.read_markers import read_markers


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
