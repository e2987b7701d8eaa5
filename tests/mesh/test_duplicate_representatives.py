"""Tests for facecap.mesh.duplicate_representatives."""

from __future__ import annotations

import numpy as np

from facecap.mesh.duplicate_representatives import duplicate_representatives


def _brute_force(V: np.ndarray, tolerance: float) -> np.ndarray:
    """Every pair's distance, groups joined until nothing changes, each named by its lowest vertex."""
    close = np.linalg.norm(V[:, None] - V[None], axis=2) <= tolerance
    rep = np.arange(len(V))
    while True:
        new = np.array([rep[close[i]].min() for i in range(len(V))])
        new = new[new]
        if np.array_equal(new, rep):
            return rep
        rep = new


def test_matches_all_pairs_with_chains_and_seams():
    rng = np.random.default_rng(5)
    base = rng.uniform(-10, 10, size=(60, 3))
    copies = base[rng.integers(0, 60, size=40)] + rng.normal(scale=1e-4, size=(40, 3))  # seam splits
    chain = np.array([[20.0, 0, 0], [20.0 + 0.8e-3, 0, 0], [20.0 + 1.6e-3, 0, 0]])  # ends 1.6e-3 apart
    V = np.concatenate([copies, base, chain])[rng.permutation(103)]
    rep = duplicate_representatives(V, 1e-3)
    assert rep.dtype == np.int64
    np.testing.assert_array_equal(rep, _brute_force(V, 1e-3))
    assert np.all(rep <= np.arange(len(V))) and np.array_equal(rep[rep], rep)
    at = np.flatnonzero(V[:, 0] >= 19.0)
    assert np.unique(rep[at]).size == 1  # the chain is one group though its ends are beyond tolerance


def test_no_duplicates_and_exact_copies():
    V = np.eye(3)
    np.testing.assert_array_equal(duplicate_representatives(V, 1e-6), [0, 1, 2])
    np.testing.assert_array_equal(duplicate_representatives(np.concatenate([V, V]), 0.0), [0, 1, 2, 0, 1, 2])
