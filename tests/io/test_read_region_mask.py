"""Tests for facecap/io/read_region_mask.py: a region file read into a vertex mask, bad files named."""

import json

import numpy as np
import pytest

from facecap.errors import FacecapError
from facecap.io import read_region_mask


def test_a_list_of_indices_and_a_bool_array_give_the_same_mask(tmp_path):
    listed = tmp_path / "region.json"
    listed.write_text(json.dumps([4, 0, 4, 2]))  # repeats and any order
    expected = np.array([True, False, True, False, True, False])
    np.testing.assert_array_equal(read_region_mask(listed, 6), expected)
    stored = tmp_path / "region.npy"
    np.save(stored, expected)
    mask = read_region_mask(stored, 6)
    assert mask.dtype == bool and mask.shape == (6,)
    np.testing.assert_array_equal(mask, expected)


@pytest.mark.parametrize("content, needle", [
    ("[0, 6]", "indices in 0..5"),
    ("[-1]", "indices in 0..5"),
    ("[]", "indices in 0..5"),
    ("[0, true]", "(integers)"),
    ('{"a": 1}', "(integers)"),
    ("[0, 1", "a JSON list"),
])
def test_a_bad_list_is_one_error_naming_the_file(tmp_path, content, needle):
    path = tmp_path / "region.json"
    path.write_text(content)
    with pytest.raises(FacecapError) as caught:
        read_region_mask(path, 6)
    assert str(caught.value).startswith(f"{path}: ") and needle in str(caught.value)


@pytest.mark.parametrize("array, needle", [
    (np.ones(5, dtype=bool), "6 vertices, got bool (5,)"),
    (np.ones(6, dtype=np.int64), "6 vertices, got int64 (6,)"),
])
def test_a_bad_array_is_one_error_naming_the_file(tmp_path, array, needle):
    path = tmp_path / "region.npy"
    np.save(path, array)
    with pytest.raises(FacecapError, match=f"^{path}: .*{needle.replace('(', '[(]').replace(')', '[)]')}"):
        read_region_mask(path, 6)
    path.write_text("not an array")
    with pytest.raises(FacecapError, match="not a NumPy array file"):
        read_region_mask(path, 6)
