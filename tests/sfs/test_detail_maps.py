"""DetailMaps: the displacement map and the tangent-space normal map against closed forms on a plane."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.sfs.detail_maps import FLAT_ENCODED, DetailMaps

L = 40.0  # mm


def plane(k=9):
    """A k x k grid on [0, L]^2 (z = 0), its triangles, and per-vertex positions."""
    x = np.linspace(0, L, k)
    X, Y = np.meshgrid(x, x)
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(k * k)], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return V, F


def texel_centres(size):
    u = (np.arange(size) + 0.5) / size
    U, Vv = np.meshgrid(u, 1.0 - u)
    return U, Vv


def test_displacement_is_the_analytic_height_at_texel_centres():
    V, F = plane()
    UV = 0.1 + 0.8 * V[:, :2] / L  # linear UVs, a margin of empty texels round the island
    region = np.arange(V.shape[0])
    maps = DetailMaps(UV, F, F, region, 64, padding=0)
    h = 0.3 + 0.02 * V[:, 0] - 0.05 * V[:, 1]
    got = maps.displacement(h)
    assert got.dtype == np.float32 and got.shape == (64, 64)
    U, W = texel_centres(64)
    x, y = (U - 0.1) / 0.8 * L, (W - 0.1) / 0.8 * L
    inside = maps.raster.triangle.reshape(64, 64) >= 0
    assert inside.sum() > 0.6 * 64 * 64 * 0.64
    np.testing.assert_allclose(got[inside], (0.3 + 0.02 * x - 0.05 * y)[inside], atol=2e-6)
    assert np.all(got[~inside] == 0)
    assert np.all(np.isfinite(got))


@pytest.mark.parametrize("uv_of_xy, expected_of_slope", [
    (lambda x, y: (x, y), lambda s: (-s, 0.0)),        # u along x, v along y
    (lambda x, y: (y, 1 - x), lambda s: (0.0, s)),      # rotated: u along y, v along -x
    (lambda x, y: (1 - x, y), lambda s: (s, 0.0)),      # mirrored island (left-handed UVs)
])
def test_height_ramp_gives_the_analytic_tangent_space_normal(uv_of_xy, expected_of_slope):
    V, F = plane()
    u, v = uv_of_xy(V[:, 0] / L, V[:, 1] / L)
    UV = 0.05 + 0.9 * np.stack([u, v], axis=1)
    slope = 0.15
    maps = DetailMaps(UV, F, F, np.arange(V.shape[0]), 32, padding=0)
    n = maps.tangent_normals(V, slope * V[:, 0])
    inside = maps.raster.triangle.reshape(32, 32) >= 0
    ex, ey = expected_of_slope(slope)
    expected = np.array([ex, ey, 1.0]) / np.sqrt(1 + slope ** 2)
    np.testing.assert_allclose(n[inside], np.broadcast_to(expected, n[inside].shape), atol=1e-6)
    np.testing.assert_array_equal(n[~inside], np.broadcast_to([0.0, 0.0, 1.0], n[~inside].shape))
    encoded = maps.normal_map(V, slope * V[:, 0])
    assert encoded.dtype == np.uint16
    np.testing.assert_allclose(encoded[inside] / 65535.0 * 2 - 1, n[inside], atol=2e-5)


def test_tilted_plane_keeps_the_tangent_frame():
    # the same ramp on a plane rotated in space: the tangent-space normal does not change
    V, F = plane()
    UV = 0.05 + 0.9 * V[:, :2] / L
    angle = 0.7
    R = np.array([[1, 0, 0], [0, np.cos(angle), -np.sin(angle)], [0, np.sin(angle), np.cos(angle)]])
    R = R @ np.array([[np.cos(1.1), -np.sin(1.1), 0], [np.sin(1.1), np.cos(1.1), 0], [0, 0, 1]])
    maps = DetailMaps(UV, F, F, np.arange(V.shape[0]), 32, padding=0)
    h = 0.1 * V[:, 1]
    flat = maps.tangent_normals(V, h)
    moved = maps.tangent_normals(V @ R.T + [5.0, -3.0, 7.0], h)
    np.testing.assert_allclose(moved, flat, atol=1e-6)  # float32 texel arithmetic
    inside = maps.raster.triangle.reshape(32, 32) >= 0
    np.testing.assert_allclose(flat[inside][0], np.array([0.0, -0.1, 1.0]) / np.sqrt(1.01), atol=1e-6)


def test_seam_keeps_each_sides_values():
    # one plane, its left and right halves on separate UV islands; the right one rotated in UV
    V, F = plane()
    k = 9
    col = np.tile(np.arange(k), k)
    centre = V[F].mean(axis=1)
    right = centre[:, 0] > L / 2
    # left island: u in [0.05, 0.45] for x in [0, L/2]; right island rotated: u along y, v along -x
    UV_left = np.stack([0.05 + 0.4 * V[:, 0] / (L / 2), 0.05 + 0.9 * V[:, 1] / L], 1)
    xr = (V[:, 0] - L / 2) / (L / 2)
    UV_right = np.stack([0.55 + 0.4 * V[:, 1] / L, 0.95 - 0.9 * xr], 1)
    UV = np.vstack([UV_left, UV_right])
    uv_triangles = np.where(right[:, None], F + V.shape[0], F)
    assert np.any((col[F] == k // 2).any(axis=1) & right)  # the seam's vertices have two UVs
    maps = DetailMaps(UV, uv_triangles, F, np.arange(V.shape[0]), 64, padding=3)
    slope = 0.1
    h = slope * V[:, 0]
    disp = maps.displacement(h)
    n = maps.tangent_normals(V, h)
    tri = maps.raster.triangle.reshape(64, 64)
    U, W = texel_centres(64)
    left_texels, right_texels = (tri >= 0) & ~right[tri], (tri >= 0) & right[tri]
    assert left_texels.sum() > 100 and right_texels.sum() > 100
    x_left = (U - 0.05) / 0.4 * (L / 2)
    x_right = L / 2 + (0.95 - W) / 0.9 * (L / 2)
    np.testing.assert_allclose(disp[left_texels], slope * x_left[left_texels], atol=1e-5)
    np.testing.assert_allclose(disp[right_texels], slope * x_right[right_texels], atol=1e-5)
    c = np.sqrt(1 + slope ** 2)
    np.testing.assert_allclose(n[left_texels], np.broadcast_to(np.array([-slope, 0, 1]) / c, (left_texels.sum(), 3)),
                               atol=1e-6)
    np.testing.assert_allclose(n[right_texels], np.broadcast_to(np.array([0, slope, 1]) / c, (right_texels.sum(), 3)),
                               atol=1e-6)
    # the padding between the islands copies each side's own value
    row = disp[32]
    assert row[29] == pytest.approx(row[28]) and row[35] == pytest.approx(row[36])
    assert abs(row[29] - row[35]) > 0.5


def test_outside_the_region_and_empty_texels_are_zero_and_flat():
    V, F = plane()
    UV = 0.2 + 0.6 * V[:, :2] / L
    region = np.flatnonzero(V[:, 0] < L / 4)
    maps = DetailMaps(UV, F, F, region, 48, padding=2)
    h = np.full(region.size, 0.7)
    disp = maps.displacement(h)
    encoded = maps.normal_map(V, 0.5 * V[region, 1])
    far = np.zeros((48, 48), bool)
    far[:, 30:] = True  # x > L / 2: triangles without a region vertex, and the empty margin
    assert np.all(disp[far] == 0) and np.all(encoded[far] == FLAT_ENCODED)
    assert disp.max() == pytest.approx(0.7)
    assert np.all(np.isfinite(disp))
    assert np.all(encoded[:3] == FLAT_ENCODED)  # the empty margin beyond the padding
    assert np.array_equal(FLAT_ENCODED, np.round((np.array([0.0, 0.0, 1.0]) + 1) / 2 * 65535))


def test_bad_heights_are_named():
    V, F = plane()
    maps = DetailMaps(V[:, :2] / L, F, F, np.arange(5), 8)
    with pytest.raises(InputError, match="heights"):
        maps.displacement(np.zeros(4))
    with pytest.raises(InputError, match="heights"):
        maps.displacement(np.full(5, np.nan))
    with pytest.raises(InputError, match="uv_triangles"):
        DetailMaps(V[:, :2] / L, F[:3], F, np.arange(5), 8)
