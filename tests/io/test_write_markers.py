"""Tests for facecap.io.write_markers: round trips through read_markers, and the C3D conventions."""

from __future__ import annotations

import struct

import ezc3d
import numpy as np
import pytest

from facecap.errors import FacecapWarning, InputError
from facecap.io.read_markers import read_markers
from facecap.io.write_markers import write_markers
from facecap.structures import MarkerSequence


def _take(seed=0, T=30, M=5, *, residuals=True, first_frame=17):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-150.0, 150.0, size=(T, M, 3))
    gaps = rng.random((T, M)) < 0.15
    gaps[0, 0] = gaps[-1, -1] = True  # gaps at both ends too
    P[gaps] = np.nan
    R = None
    if residuals:
        R = rng.uniform(0.0, 2.0, size=(T, M))
        R[gaps] = np.nan
    labels = tuple(f"marker_{i}" for i in range(M))
    return MarkerSequence(P, labels, 119.88, first_frame=first_frame, residuals=R)


def _raw_c3d_points(path):
    """(T, M, 4) float32 data block of an ezc3d-written float C3D, straight from the bytes."""
    data = path.read_bytes()
    n_points, _, first, last = struct.unpack_from("<4H", data, 2)
    data_start = struct.unpack_from("<H", data, 16)[0]
    T = last - first + 1
    block = np.frombuffer(data, dtype="<f4", count=T * n_points * 4, offset=(data_start - 1) * 512)
    return block.reshape(T, n_points, 4)


@pytest.mark.parametrize("suffix", [".c3d", ".trc", ".csv"])
@pytest.mark.parametrize("unit", ["mm", "cm", "m", "in"])
def test_round_trip_positions_labels_rate_gaps_and_unit(tmp_path, suffix, unit):
    take = _take()
    path = tmp_path / f"take{suffix}"
    write_markers(take, path, unit=unit)
    back = read_markers(path)
    assert back.labels == take.labels
    assert back.rate == pytest.approx(take.rate, rel=1e-7 if suffix == ".c3d" else 0)
    assert back.source_unit == unit
    assert back.first_frame == take.first_frame
    np.testing.assert_array_equal(back.gap_mask, take.gap_mask)
    seen = ~take.gap_mask
    if suffix == ".c3d":  # float32 in the file: relative precision 2**-24
        np.testing.assert_allclose(back.positions[seen], take.positions[seen], rtol=2**-23, atol=1e-12)
    else:  # text keeps every digit; only the unit conversion rounds
        np.testing.assert_allclose(back.positions[seen], take.positions[seen], rtol=1e-14, atol=1e-12)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no partial file left


def test_c3d_gaps_are_written_the_c3d_way_and_units_recorded(tmp_path):
    take = _take(1)
    path = tmp_path / "take.c3d"
    write_markers(take, path, unit="cm")
    raw = _raw_c3d_points(path)
    gaps = take.gap_mask
    assert (raw[gaps, :3] == 0.0).all()
    assert (raw[gaps, 3] < 0).all()  # negative residual word: "not seen"
    assert (raw[~gaps, 3] >= 0).all()
    np.testing.assert_allclose(raw[~gaps, :3], take.positions[~gaps] / 10.0, rtol=2**-23)
    params = ezc3d.c3d(str(path))["parameters"]["POINT"]
    assert list(params["UNITS"]["value"]) == ["cm"]
    assert float(params["RATE"]["value"][0]) == pytest.approx(119.88)
    assert list(params["LABELS"]["value"]) == list(take.labels)


def test_c3d_residuals_round_trip_to_the_stored_resolution(tmp_path):
    take = _take(2)
    path = tmp_path / "take.c3d"
    write_markers(take, path, unit="m")
    back = read_markers(path)
    seen = ~take.gap_mask
    step = np.nanmax(take.residuals) / 255.0  # one byte per residual, scaled to the largest
    assert np.isnan(back.residuals[~seen]).all()
    np.testing.assert_allclose(back.residuals[seen], take.residuals[seen], rtol=0, atol=0.5 * step * (1 + 1e-5))


def test_c3d_without_residuals_reads_back_zero_residuals(tmp_path):
    take = _take(3, residuals=False)
    write_markers(take, tmp_path / "take.c3d")
    back = read_markers(tmp_path / "take.c3d")
    assert (back.residuals[~take.gap_mask] == 0.0).all()


def test_trc_layout_is_the_standard_one(tmp_path):
    take = _take(4, T=3, M=2, first_frame=0)
    write_markers(take, tmp_path / "take.trc", unit="cm")
    lines = (tmp_path / "take.trc").read_text().split("\n")
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t")))
    assert header["NumFrames"] == "3" and header["NumMarkers"] == "2" and header["Units"] == "cm"
    assert float(header["DataRate"]) == 119.88
    names = lines[3].split("\t")
    assert names[:3] == ["Frame#", "Time", "marker_0"] and names[5] == "marker_1"  # every third column
    assert lines[4].split("\t")[2:] == ["X1", "Y1", "Z1", "X2", "Y2", "Z2"]
    first_row = lines[6].split("\t")
    assert first_row[0] == "1" and float(first_row[1]) == 0.0 and len(first_row) == 8


def test_csv_layout_and_gaps_as_empty_cells(tmp_path):
    P = np.array([[[1.0, 2.0, 3.0], [np.nan] * 3]])
    take = MarkerSequence(P, ("a", "b_c"), 60.0, first_frame=4)
    write_markers(take, tmp_path / "t.csv", unit="cm")
    text = (tmp_path / "t.csv").read_text().splitlines()
    assert "# rate=60.0" in text and "# unit=cm" in text
    assert text[-2] == "frame,time,a_x,a_y,a_z,b_c_x,b_c_y,b_c_z"
    assert text[-1] == "4,0.0,0.1,0.2,0.3,,,"


def test_failed_write_leaves_no_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    take = _take(5)
    path = tmp_path / "take.c3d"
    write_markers(take, path)
    before = path.read_bytes()

    def broken_write(self, *args, **kwargs):
        with open(args[0], "wb") as handle:
            handle.write(b"half a file")
        raise RuntimeError("disk full")

    monkeypatch.setattr(ezc3d.c3d, "write", broken_write)
    with pytest.raises(RuntimeError, match="disk full"):
        write_markers(_take(6), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.c3d"]


def test_upper_case_c3d_suffix(tmp_path):
    take = _take(7)
    write_markers(take, tmp_path / "TAKE.C3D")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["TAKE.C3D"]  # ezc3d did not append .c3d
    assert read_markers(tmp_path / "TAKE.C3D").labels == take.labels


def test_invalid_requests_are_input_errors(tmp_path):
    take = _take(8)
    with pytest.raises(InputError, match="suffix '.bvh'"):
        write_markers(take, tmp_path / "take.bvh")
    with pytest.raises(InputError, match="MarkerSequence"):
        write_markers(take.positions, tmp_path / "take.csv")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="unit"):
        write_markers(take, tmp_path / "take.csv", unit="yd")
    comma = MarkerSequence(np.zeros((1, 1, 3)), ("a,b",), 30.0)
    with pytest.raises(InputError, match="comma"):
        write_markers(comma, tmp_path / "take.csv")
    tab = MarkerSequence(np.zeros((1, 1, 3)), ("a\tb",), 30.0)
    with pytest.raises(InputError, match="tab"):
        write_markers(tab, tmp_path / "take.trc")
    with pytest.raises(InputError, match="does not exist"):
        write_markers(take, tmp_path / "missing" / "take.trc")
    assert list(tmp_path.iterdir()) == []


def test_c3d_frame_limits(tmp_path):
    long = MarkerSequence(np.ones((65536, 1, 3)), ("a",), 1000.0)
    with pytest.raises(InputError, match="65535 frames"):
        write_markers(long, tmp_path / "long.c3d")
    negative = MarkerSequence(np.ones((2, 1, 3)), ("a",), 30.0, first_frame=-1)
    with pytest.warns(FacecapWarning, match="first_frame -1") as record:
        write_markers(negative, tmp_path / "neg.c3d")
    assert record[0].filename == __file__
    assert read_markers(tmp_path / "neg.c3d").first_frame == 0
