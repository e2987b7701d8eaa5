"""The default region: seen by every camera and well by one, lit, away from the open edges."""

import numpy as np

from facecap.sfs.select_detail_region import BOUNDARY_RINGS, select_detail_region

from sfs_patch import dome_patch


def test_the_region_leaves_out_unseen_unlit_and_edge_vertices():
    V, F = dome_patch(30, 30, step=1.0)
    n = V.shape[0]
    weight = np.ones((2, n))
    weight[1, V[:, 0] < 8] = 0.0  # the second camera does not see the left side
    weight[1, (V[:, 0] >= 8) & (V[:, 0] < 12)] = 0.2  # it sees this band badly; the first camera sees it well
    weight[:, (V[:, 0] >= 20) & (V[:, 0] < 22)] = 0.3  # neither sees this band well
    direct = np.ones(n)
    direct[V[:, 1] > 22] = 0.0  # the top is in shadow
    chosen = select_detail_region(weight, direct, F)
    inner = (V[:, 0] >= BOUNDARY_RINGS + 1) & (V[:, 0] <= 29 - BOUNDARY_RINGS - 1) & \
        (V[:, 1] >= BOUNDARY_RINGS + 1) & (V[:, 1] <= 29 - BOUNDARY_RINGS - 1)
    expected = inner & (V[:, 0] >= 8) & (V[:, 1] <= 22) & ~((V[:, 0] >= 20) & (V[:, 0] < 22))
    np.testing.assert_array_equal(chosen, expected)
    mask = V[:, 0] > 15
    np.testing.assert_array_equal(select_detail_region(weight, direct, F, mask=mask), expected & mask)


def test_the_locality_order_is_a_permutation_that_narrows_the_band():
    from facecap.sfs.select_detail_region import locality_order

    V, F = dome_patch(30, 30, step=1.0)
    scatter = np.random.default_rng(0).permutation(V.shape[0])
    F = np.argsort(scatter)[F]  # vertex k of the new numbering was vertex scatter[k]
    region = np.flatnonzero(V[scatter][:, 0] < 20)
    order = locality_order(region, F)
    assert np.array_equal(np.sort(order), np.arange(region.size))

    def bandwidth(numbering):
        index = np.full(V.shape[0], -1)
        index[numbering] = np.arange(numbering.size)
        local = index[F[np.all(index[F] >= 0, axis=1)]]
        return int(np.abs(local - np.roll(local, 1, axis=1)).max())

    # a 20 x 30 grid: the band of a good order is about one row of the grid (30), scattered it is the region
    assert bandwidth(region[order]) <= 45 < region.size / 2 < bandwidth(region)
