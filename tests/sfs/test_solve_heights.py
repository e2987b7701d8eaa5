"""The space-time height solve recovers known lines from their shading (the model's own rendering, with noise)."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.sfs.solve_heights import HeightWeights, solve_heights

from sfs_patch import dome_patch, lined_frames, valley


def _truth(V, T=5):
    truth = np.zeros((T, V.shape[0]))
    for t in range(T):
        s = t / (T - 1)
        truth[t] = valley(V[:, 1] - 5.0, 0.3, 0.08 * s) + valley(V[:, 1] - 10.0, 0.5, 0.15 * s) \
            + valley(V[:, 0] - 12.0, 0.25, 0.04 * s)
    return truth


def test_lines_are_recovered_and_nothing_is_invented_between_them():
    V, F = dome_patch()
    truth = _truth(V)
    frames = lined_frames(V, F, truth, albedo=0.6)
    out = solve_heights(frames, albedo=0.6, k_s=0.05, alpha=12.0, ambient=0.05)
    on = np.abs(truth) > 0.03
    off = np.abs(truth) < 1e-4
    ratio = np.abs(out.heights - truth)[on].mean() / np.abs(truth)[on].mean()
    assert ratio < 0.45  # measured 0.33 with 1 % noise
    assert np.abs(out.heights)[off].mean() < 0.01  # measured 0.003 mm
    assert np.all(out.residual[1:] < out.residual_before[1:])
    assert out.residual[-1] < 0.015  # the noise is 1 %


def test_the_temporal_term_steadies_a_held_expression():
    V, F = dome_patch(48, 40)
    held = valley(V[:, 1] - 5.0, 0.4, 0.1)
    truth = np.tile(held, (7, 1))
    frames = lined_frames(V, F, truth, albedo=0.6, noise=0.03, seed=4)
    still = solve_heights(frames, albedo=0.6, k_s=0.05, alpha=12.0, ambient=0.05,
                          weights=HeightWeights(temporal=10.0))
    alone = solve_heights(frames, albedo=0.6, k_s=0.05, alpha=12.0, ambient=0.05,
                          weights=HeightWeights(temporal=0.0))
    change = lambda h: np.sqrt(np.mean(np.diff(h, axis=0) ** 2))  # noqa: E731
    assert change(still.heights) < 0.5 * change(alone.heights)


def test_frames_over_different_samples_are_refused():
    V, F = dome_patch(20, 20)
    a = lined_frames(V, F, np.zeros((1, V.shape[0])), albedo=0.5)
    V2, F2 = dome_patch(21, 20)
    b = lined_frames(V2, F2, np.zeros((1, V2.shape[0])), albedo=0.5)
    with pytest.raises(InputError, match="same samples"):
        solve_heights(a + b, albedo=0.5)
