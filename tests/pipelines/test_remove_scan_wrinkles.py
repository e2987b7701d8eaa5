"""Tests for facecap/pipelines/remove_scan_wrinkles.py: the files read, the solver's result written, the
destination refused first. The command's own test is in tests/test_cli_anatomy_and_removal.py."""

import json

import numpy as np
import pytest

from facecap.errors import FacecapError
from facecap.io import read_mesh, write_mesh
from facecap.pipelines import remove_scan_wrinkles
from facecap.structures import Mesh
from facecap.wrinkles import remove_wrinkles


def _wrinkled_sheet(tmp_path):
    """A 40 x 40 mm sheet, 1 mm apart, with 0.3 mm deep furrows 4 mm apart in its middle, and that middle."""
    x, y = np.meshgrid(np.arange(41.0), np.arange(41.0), indexing="ij")
    middle = (np.abs(x - 20) < 10) & (np.abs(y - 20) < 10)
    z = np.where(middle, -0.3 * np.cos(np.pi * (x - 20) / 10) ** 2 * np.sin(2 * np.pi * y / 4) ** 2, 0.0)
    V = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    k = np.arange(41 * 41).reshape(41, 41)[:-1, :-1].ravel()
    F = np.concatenate([np.column_stack([k, k + 41, k + 1]), np.column_stack([k + 1, k + 41, k + 42])])
    scan = tmp_path / "scan.ply"
    write_mesh(Mesh(V, F), scan)
    region = tmp_path / "region.json"
    region.write_text(json.dumps(np.flatnonzero(middle.ravel()).tolist()))
    return scan, region, middle.ravel()


def test_the_scan_is_written_as_the_solver_returns_it(tmp_path):
    scan, region, middle = _wrinkled_sheet(tmp_path)
    out = tmp_path / "smooth.ply"
    mask = remove_scan_wrinkles(scan, region, out)
    np.testing.assert_array_equal(mask, middle)
    expected = remove_wrinkles(read_mesh(scan), middle).vertices
    written = read_mesh(out).vertices
    np.testing.assert_allclose(written, expected, atol=1e-5)
    before = read_mesh(scan).vertices
    np.testing.assert_allclose(written[~middle], before[~middle], atol=1e-6)
    assert np.abs(written[middle, 2] - before[middle, 2]).max() > 0.05  # the furrows are smoothed


def test_an_existing_output_is_refused_before_anything_is_read(tmp_path):
    out = tmp_path / "smooth.ply"
    out.write_text("kept")
    with pytest.raises(FacecapError, match="pass --overwrite"):
        remove_scan_wrinkles(tmp_path / "missing.ply", tmp_path / "missing.json", out)
    assert out.read_text() == "kept"
