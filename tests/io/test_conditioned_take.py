"""Tests for facecap.io.conditioned_take: the conditioned take written once and read back exactly."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import FileFormatError
from facecap.io.conditioned_take import file_sha256, read_conditioned_take, write_conditioned_take
from facecap.markers import condition_take
from facecap.synth import generate_performance


def test_round_trip_is_exact(tmp_path):
    case = generate_performance(n_frames=60, n_markers=20, seed=4)
    conditioned = condition_take(case.markers, stabilize=True)
    path = tmp_path / "take.conditioned.npz"
    write_conditioned_take(path, conditioned, labels=case.markers.labels, rate=60.0,
                           settings={"stabilize": "auto"}, source_sha256="ab" * 32)
    back, meta = read_conditioned_take(path)
    np.testing.assert_array_equal(back.positions, conditioned.positions)
    np.testing.assert_array_equal(back.filled, conditioned.filled)
    np.testing.assert_array_equal(back.head_rotations, conditioned.head_rotations)
    np.testing.assert_array_equal(back.head_translations, conditioned.head_translations)
    assert back.stable_labels == conditioned.stable_labels
    assert meta["labels"] == case.markers.labels and meta["rate"] == 60.0 and meta["source_sha256"] == "ab" * 32
    assert not list(tmp_path.glob(".*partial*"))  # written under a temporary name, renamed


def test_unstabilised_take_and_bad_files(tmp_path):
    case = generate_performance(n_frames=30, n_markers=10, seed=5)
    conditioned = condition_take(case.markers, stabilize=False)
    path = tmp_path / "c.npz"
    write_conditioned_take(path, conditioned, labels=case.markers.labels, rate=60.0, settings={},
                           source_sha256=None)
    back, _ = read_conditioned_take(path)
    assert back.head_rotations is None and back.head_translations is None
    np.save(tmp_path / "other.npy", np.zeros(3))
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    for bad in (tmp_path / "missing.npz", tmp_path / "junk.npz"):
        with pytest.raises(FileFormatError):
            read_conditioned_take(bad)


def test_sha256_names_the_bytes(tmp_path):
    import hashlib

    p = tmp_path / "f.bin"
    p.write_bytes(b"facecap" * 1000)
    assert file_sha256(p) == hashlib.sha256(b"facecap" * 1000).hexdigest()
