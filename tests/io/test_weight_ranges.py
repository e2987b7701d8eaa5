"""Blend-shape weights moved into [0, 1] play the same frames."""

from __future__ import annotations

import numpy as np

from facecap.io import to_unit_range


def test_every_frame_is_kept_and_every_weight_lies_in_unit_range():
    rng = np.random.default_rng(0)
    targets = rng.normal(size=(6, 40, 3)).astype(np.float32)
    weights = rng.normal(scale=12.0, size=(25, 6))  # marker displacements in mm: far outside [0, 1]
    weights[:, 1] = rng.random(25)  # already in range: left alone
    weights[:, 4] = -3.0  # never changes: goes into the base
    unit = to_unit_range(targets, weights)
    before = np.einsum("tm,mnc->tnc", weights, targets.astype(np.float64))
    after = unit.base_offset[None] + np.einsum("tm,mnc->tnc", unit.weights.astype(np.float64), unit.targets)
    assert np.abs(after - before).max() < 1e-5 * np.abs(before).max()
    assert unit.weights.min() == 0.0 and unit.weights.max() == 1.0
    np.testing.assert_array_equal(unit.targets[1], targets[1])
    np.testing.assert_array_equal(unit.weights[:, 1], weights[:, 1].astype(np.float32))
    assert np.all(unit.weights[:, 4] == 0)
    # the rest shape (all original weights zero) is at rest_weights
    rest = unit.base_offset + np.einsum("m,mnc->nc", unit.rest_weights, unit.targets)
    assert np.abs(rest).max() < 1e-5
    changing = [0, 2, 3, 5]
    assert np.all((unit.rest_weights[changing] > 0) & (unit.rest_weights[changing] < 1))


def test_overwriting_the_targets_gives_the_same_animation_without_a_copy():
    rng = np.random.default_rng(1)
    targets = rng.normal(size=(4, 30, 3)).astype(np.float32)
    weights = rng.normal(scale=5.0, size=(12, 4))
    copied = to_unit_range(targets, weights)
    mine = targets.copy()
    in_place = to_unit_range(mine, weights, overwrite_targets=True)
    assert in_place.targets is mine  # rescaled where it lay
    np.testing.assert_array_equal(in_place.targets, copied.targets)
    np.testing.assert_array_equal(in_place.weights, copied.weights)
    np.testing.assert_array_equal(in_place.base_offset, copied.base_offset)
    # without the flag (or for an array it may not write) the caller's targets are left as they were
    frozen = targets.copy()
    frozen.setflags(write=False)
    assert to_unit_range(frozen, weights, overwrite_targets=True).targets is not frozen
    np.testing.assert_array_equal(frozen, targets)
