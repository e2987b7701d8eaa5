"""check_take_units: a scan stored in another length unit is caught by its size against the take's markers at the rest
frame (paired through the map), named, or converted; the right unit passes unchanged (the case is in conftest.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from facecap.errors import FacecapWarning, MeshError
from facecap.io import read_correspondence, read_markers, read_mesh
from facecap.markers import check_take_units


def _read(files, unit="mm"):
    scan = read_mesh(files.scan, unit=unit)
    take = read_markers(files.markers)
    return scan, take, read_correspondence(files.map, scan)


@pytest.mark.parametrize(("stored", "name"), [("m", "metres"), ("cm", "centimetres"), ("in", "inches")])
def test_wrong_unit_names_the_likely_one(written, stored, name):
    scan, take, corr = _read(written[stored])
    with pytest.raises(MeshError, match=rf"it looks like {name}; pass --scan-units {stored}$") as info:
        check_take_units(scan, take, corr)
    assert info.value.path == str(written[stored].scan)
    assert "\n" not in str(info.value)


def test_a_scan_in_mm_read_as_metres_is_caught(written):
    scan, take, corr = _read(written["mm"], unit="m")
    with pytest.raises(MeshError, match="it looks like millimetres; pass --scan-units mm"):
        check_take_units(scan, take, corr)


def test_convert_matches_the_right_unit(written):
    scan, take, corr = _read(written["m"])
    with pytest.warns(FacecapWarning, match="read as metres"):
        fixed = check_take_units(scan, take, corr, convert=True)
    right, _, _ = _read(written["m"], unit="m")
    assert fixed.source_unit == "m"
    np.testing.assert_allclose(fixed.vertices, right.vertices, rtol=1e-12)


@pytest.mark.parametrize("stored", ["mm", "cm", "m", "in"])
def test_right_unit_passes_unchanged(written, stored):
    scan, take, corr = _read(written[stored], unit=stored)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_take_units(scan, take, corr) is scan


def test_robust_to_gaps_and_stray_markers(written):
    scan, take, corr = _read(written["m"])
    P = take.positions.copy()
    P[0, :10] = np.nan                       # occluded at the rest frame
    P[0, 10:13] = [[5000.0, 0, 0], [0, -4000.0, 0], [0, 0, 9000.0]]  # strays (a prop, a mislabel)
    take = type(take)(P, take.labels, take.rate, source_path=take.source_path)
    with pytest.raises(MeshError, match="metres"):
        check_take_units(scan, take, corr)
    right, _, _ = _read(written["m"], unit="m")
    assert check_take_units(right, take, corr) is right
