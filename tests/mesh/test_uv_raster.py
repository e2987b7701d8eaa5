"""UVRaster: texel centres, barycentric weights, seams, skipped faces and edge padding."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.mesh.uv_raster import UVRaster


def texel_centres(size):
    j = np.arange(size)
    u = (j + 0.5) / size
    U, Vv = np.meshgrid(u, 1.0 - u)  # row 0 at the top: v near 1
    return U.ravel(), Vv.ravel()


def test_linear_values_are_exact_at_texel_centres():
    rng = np.random.default_rng(0)
    UV = np.array([[0.1, 0.2], [0.9, 0.15], [0.8, 0.85], [0.15, 0.9]])
    T = np.array([[0, 1, 2], [0, 2, 3]])
    raster = UVRaster(UV, T, 32, padding=0)
    a, b, c = rng.normal(size=3)
    values = a + b * UV[:, 0] + c * UV[:, 1]
    got = raster.sample(values[T]).ravel()
    u, v = texel_centres(32)
    inside = raster.triangle >= 0
    assert inside.sum() > 300
    np.testing.assert_allclose(got[inside], (a + b * u + c * v)[inside], atol=1e-12)
    assert np.all(got[~inside] == 0)


def test_matches_matplotlib_trifinder_on_a_delaunay_triangulation():
    from matplotlib.tri import Triangulation
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(1)
    UV = np.vstack([rng.uniform(0.05, 0.95, size=(60, 2)), [[0.05, 0.05], [0.95, 0.05], [0.95, 0.95], [0.05, 0.95]]])
    T = Delaunay(UV).simplices.astype(np.int64)
    size = 64
    raster = UVRaster(UV, T, size, padding=0)
    u, v = texel_centres(size)
    reference = Triangulation(UV[:, 0], UV[:, 1], T).get_trifinder()(u, v)
    # texel centres on a shared edge may go to either side: compare the interpolated coordinates instead
    assert np.array_equal(raster.triangle >= 0, reference >= 0)
    hit = raster.triangle >= 0
    np.testing.assert_allclose(raster.sample(UV[T][:, :, 0]).ravel()[hit], u[hit], atol=1e-12)
    np.testing.assert_allclose(raster.sample(UV[T][:, :, 1]).ravel()[hit], v[hit], atol=1e-12)
    same = hit & (raster.triangle == reference)
    assert same.mean() > 0.95 * hit.mean()


def test_seam_islands_keep_their_own_texels_and_skipped_faces_cover_nothing():
    # one vertex strip, two UV islands (the middle vertices have two UVs each), and a face without UVs
    UV = np.array([[0.05, 0.1], [0.4, 0.1], [0.4, 0.9], [0.05, 0.9],   # left island
                   [0.6, 0.1], [0.95, 0.1], [0.95, 0.9], [0.6, 0.9]])  # right island
    T = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [-1, 0, 1]])
    raster = UVRaster(UV, T, 40, padding=2)
    tri = raster.triangle.reshape(40, 40)
    u, v = (c.reshape(40, 40) for c in texel_centres(40))
    rows = (v > 0.11) & (v < 0.89)
    assert set(np.unique(tri[(u > 0.06) & (u < 0.39) & rows]).tolist()) == {0, 1}
    assert set(np.unique(tri[(u > 0.61) & (u < 0.94) & rows]).tolist()) == {2, 3}
    assert not np.any(raster.triangle == 4)
    # padding: each side's border texels copy that side, the gap's middle stays empty
    values = np.repeat(np.array([1.0, 1.0, 2.0, 2.0, 9.0])[:, None], 3, axis=1)
    sampled = raster.sample(values, background=-1.0)
    row = sampled[20]
    j = np.arange(40)
    assert np.all(row[(j >= 16) & (j <= 17)] == 1.0) and np.all(row[(j >= 22) & (j <= 23)] == 2.0)
    assert np.all(row[(j >= 19) & (j <= 20)] == -1.0)
    assert np.all(np.isin(raster.pad_source, raster.covered))
    assert not np.any(np.isin(raster.pad_target, raster.covered))


def test_pad_texels_copy_their_nearest_covered_texel():
    raster = UVRaster(np.array([[0.3, 0.3], [0.7, 0.3], [0.5, 0.7]]), np.array([[0, 1, 2]]), 50, padding=3)
    s = 50
    ti, tj = np.divmod(raster.pad_target, s)
    si, sj = np.divmod(raster.pad_source, s)
    ci, cj = np.divmod(raster.covered, s)
    distance = np.hypot(ti - si, tj - sj)
    assert distance.max() <= 3 + 1e-9
    nearest = np.min(np.hypot(ti[:, None] - ci[None], tj[:, None] - cj[None]), axis=1)
    np.testing.assert_allclose(distance, nearest)


def test_bad_input_is_named():
    with pytest.raises(InputError, match="uv_triangles"):
        UVRaster(np.zeros((3, 2)), np.array([[0, 1, 5]]), 8)
    with pytest.raises(InputError, match="uvs"):
        UVRaster(np.full((3, 2), np.nan), np.array([[0, 1, 2]]), 8)
    with pytest.raises(InputError, match="size"):
        UVRaster(np.zeros((3, 2)), np.array([[0, 1, 2]]), 0)
