"""The default region: seen well by every camera, lit, away from the open edges."""

import numpy as np

from facecap.sfs.select_detail_region import BOUNDARY_RINGS, select_detail_region

from sfs_patch import dome_patch


def test_the_region_leaves_out_unseen_unlit_and_edge_vertices():
    V, F = dome_patch(30, 30, step=1.0)
    n = V.shape[0]
    weight = np.ones((2, n))
    weight[1, V[:, 0] < 8] = 0.2  # the second camera sees the left side badly
    direct = np.ones(n)
    direct[V[:, 1] > 22] = 0.0  # the top is in shadow
    chosen = select_detail_region(weight, direct, F)
    inner = (V[:, 0] >= BOUNDARY_RINGS + 1) & (V[:, 0] <= 29 - BOUNDARY_RINGS - 1) & \
        (V[:, 1] >= BOUNDARY_RINGS + 1) & (V[:, 1] <= 29 - BOUNDARY_RINGS - 1)
    expected = inner & (V[:, 0] >= 8) & (V[:, 1] <= 22)
    np.testing.assert_array_equal(chosen, expected)
    mask = V[:, 0] > 15
    np.testing.assert_array_equal(select_detail_region(weight, direct, F, mask=mask), expected & mask)
