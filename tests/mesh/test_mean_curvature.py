import igl
import numpy as np
import pytest
import trimesh

from facecap.errors import InputError
from facecap.mesh.mean_curvature import mean_curvature


def _grid(nx, ny, x_range, y_range):
    u, v = np.meshgrid(np.linspace(*x_range, nx), np.linspace(*y_range, ny))
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + nx], 1), np.stack([a + 1, a + nx + 1, a + nx], 1)])
    return u.ravel(), v.ravel(), F


def _sphere(radius, subdivisions=4):
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(s.vertices, dtype=np.float64), np.asarray(s.faces, dtype=np.int64)


def test_sphere_is_one_over_radius_and_flips_sign_with_the_normals():
    V, F = _sphere(10.0)
    H = mean_curvature(V, F, threshold=0.0)
    np.testing.assert_allclose(H, 0.1, rtol=0.01)  # outward normals: positive
    H_in = mean_curvature(V, F[:, ::-1], threshold=0.0)
    np.testing.assert_allclose(H_in, -0.1, rtol=0.01)


def test_plane_is_zero():
    x, y, F = _grid(21, 15, (-10, 10), (-7, 7))
    V = np.stack([x, y, np.zeros_like(x)], 1)
    R = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    H = mean_curvature(V @ R.T + [5.0, -3.0, 2.0], F, threshold=0.0)
    np.testing.assert_allclose(H, 0.0, atol=1e-9)


def test_cylinder_is_one_over_twice_the_radius():
    R = 20.0
    nt, nh = 180, 61
    th, z = np.meshgrid(np.linspace(0, 2 * np.pi, nt, endpoint=False), np.linspace(-30, 30, nh))
    V = np.stack([R * np.cos(th.ravel()), R * np.sin(th.ravel()), z.ravel()], 1)
    a = (np.arange(nh - 1)[:, None] * nt + np.arange(nt)[None]).ravel()
    b = (np.arange(nh - 1)[:, None] * nt + (np.arange(nt)[None] + 1) % nt).ravel()
    F = np.concatenate([np.stack([a, b, a + nt], 1), np.stack([b, b + nt, a + nt], 1)])
    H = mean_curvature(V, F, threshold=0.0)
    inner = np.abs(V[:, 2]) < 25  # away from the open rims
    np.testing.assert_allclose(H[inner], 1 / (2 * R), rtol=0.01)


def test_paraboloid_matches_the_monge_formula_including_slope():
    # z = a x^2 + c y^2, normals +z: the surface bends towards its normals, so H < 0;
    # at (x, y) the exact mean curvature is -((1+zy^2) zxx + (1+zx^2) zyy) / (2 (1+zx^2+zy^2)^1.5)
    a, c = 0.02, 0.05
    x, y, F = _grid(81, 81, (-20, 20), (-20, 20))
    V = np.stack([x, y, a * x**2 + c * y**2], 1)
    H = mean_curvature(V, F, threshold=0.0, radius_mm=1.6)
    zx, zy = 2 * a * x, 2 * c * y
    exact = -((1 + zy**2) * 2 * a + (1 + zx**2) * 2 * c) / (2 * (1 + zx**2 + zy**2) ** 1.5)
    inner = (np.abs(x) < 17) & (np.abs(y) < 17)
    np.testing.assert_allclose(H[inner], exact[inner], rtol=0.02)


def test_agrees_with_libigl_principal_curvature_on_a_smooth_surface():
    V, F = _sphere(1.0, subdivisions=4)
    # a smooth, non-umbilic surface: an ellipsoid with a gentle bump, in mm
    d = np.array([40.0, 30.0, 20.0])
    V = V * d * (1 + 0.05 * np.sin(3 * V[:, [0]]) * np.cos(2 * V[:, [1]]))
    _, _, k1, k2, bad = igl.principal_curvature(V, F, radius=5)
    H_igl = (k1 + k2) / 2
    H = mean_curvature(V, F, threshold=0.0)
    good = np.ones(len(V), bool)
    good[np.asarray(bad, dtype=np.int64)] = False
    assert np.corrcoef(H[good], H_igl[good])[0, 1] > 0.99
    assert np.median(np.abs(H[good] - H_igl[good]) / np.abs(H_igl[good])) < 0.03


def test_hard_and_soft_thresholds():
    V, F = _sphere(1.0, subdivisions=4)
    V = V * [30.0, 15.0, 8.0]  # mean curvatures from about 0.01 to 0.25 per mm
    raw = mean_curvature(V, F, threshold=0.0)
    assert raw.min() < 0.05 < raw.max()
    hard = mean_curvature(V, F, threshold=0.05)
    np.testing.assert_array_equal(hard, np.where(np.abs(raw) < 0.05, 0.0, raw))
    soft = mean_curvature(V, F, threshold=0.05, threshold_mode="soft")
    np.testing.assert_allclose(soft, np.sign(raw) * np.maximum(np.abs(raw) - 0.05, 0.0), atol=1e-15)


@pytest.mark.parametrize(
    "kwargs",
    [dict(threshold=-1.0), dict(threshold_mode="median"), dict(max_neighbours=3), dict(radius_mm=0.0)],
)
def test_rejects_bad_options(kwargs):
    V, F = _sphere(10.0, subdivisions=1)
    with pytest.raises(InputError):
        mean_curvature(V, F, **kwargs)


def test_given_neighbour_lists_match_the_search():
    from scipy.spatial import cKDTree

    V, F = _sphere(10.0)
    radius = 2.0
    _, idx = cKDTree(V).query(V, k=32, distance_upper_bound=radius)
    H = mean_curvature(V, F, threshold=0.0, radius_mm=radius)
    np.testing.assert_array_equal(mean_curvature(V, F, threshold=0.0, radius_mm=radius, neighbours=idx), H)
    # lists from a wider search are cut back to the radius: same result; -1 pads are ignored
    _, wide = cKDTree(V).query(V, k=32, distance_upper_bound=1.5 * radius)
    wide = np.where(wide >= len(V), -1, wide)
    np.testing.assert_allclose(mean_curvature(V, F, threshold=0.0, radius_mm=radius, neighbours=wide), H, rtol=0.02)
    with pytest.raises(InputError):
        mean_curvature(V, F, neighbours=idx[:10])
