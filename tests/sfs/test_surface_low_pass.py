"""The surface low-pass keeps slow variation and removes fine detail."""

import numpy as np

from facecap.sfs.surface_low_pass import SurfaceLowPass

from sfs_patch import dome_patch


def test_slow_passes_and_fine_is_removed():
    V, F = dome_patch(120, 100, step=0.25)
    low = SurfaceLowPass(V, F, 3.0)
    slow = np.sin(2 * np.pi * V[:, 0] / 40.0)
    fine = np.sin(2 * np.pi * V[:, 0] / 1.0)
    inner = (V[:, 0] > 8) & (V[:, 0] < 22) & (V[:, 1] > 6) & (V[:, 1] < 19)
    # heat step transfer: 1 / (1 + tau k^2), tau = sigma^2 / 2
    k_slow, k_fine = 2 * np.pi / 40.0, 2 * np.pi / 1.0
    np.testing.assert_allclose(low(slow)[inner], (slow / (1 + 4.5 * k_slow ** 2))[inner], atol=0.01)
    assert np.abs(low(fine)[inner]).max() < 2.0 / (1 + 4.5 * k_fine ** 2)


def test_weights_fill_in_where_there_is_no_data():
    V, F = dome_patch(60, 50, step=0.5)
    low = SurfaceLowPass(V, F, 2.0)
    values = np.full(V.shape[0], 1.3)
    weights = (V[:, 0] > 10).astype(float)
    values[weights == 0] = 50.0  # unweighted values must not leak
    out = low(values, weights)
    near = (V[:, 0] > 8) & (V[:, 0] < 12)
    np.testing.assert_allclose(out[near], 1.3, rtol=1e-9)
