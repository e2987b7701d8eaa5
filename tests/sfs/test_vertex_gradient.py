"""The vertex gradient: exact for linear functions, consistent with libigl's per-triangle gradient."""

import numpy as np

from facecap.sfs.vertex_gradient import vertex_gradient


def _sphere_cap(step=0.5, radius=40.0, size=20):
    x, y = np.meshgrid(np.arange(-size, size + 1e-9, step), np.arange(-size, size + 1e-9, step))
    z = np.sqrt(radius ** 2 - x ** 2 - y ** 2)
    V = np.c_[x.ravel(), y.ravel(), z.ravel()]
    nx = x.shape[1]
    idx = np.arange(V.shape[0]).reshape(x.shape)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return V, np.r_[np.c_[a, b, d], np.c_[a, d, c]], nx


def test_the_gradient_of_a_linear_function_on_a_plane_is_exact():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(0, 10, 300), rng.uniform(0, 10, 300)
    from scipy.spatial import Delaunay

    F = Delaunay(np.c_[x, y]).simplices.astype(np.int64)
    V = np.c_[x, y, np.zeros_like(x)]
    g = vertex_gradient(V, F).apply(2.0 * x - 0.5 * y + 1.0)
    np.testing.assert_allclose(g, np.tile([2.0, -0.5, 0.0], (300, 1)), atol=1e-9)


def test_on_a_curved_surface_the_gradient_is_tangent_and_converges():
    errors = []
    for step in (1.0, 0.5, 0.25):
        V, F, _ = _sphere_cap(step)
        f = V[:, 0] ** 2 * 0.01 + V[:, 1]  # its surface gradient: the 3D gradient projected onto the tangent plane
        N = V / np.linalg.norm(V, axis=1, keepdims=True)
        full = np.c_[0.02 * V[:, 0], np.ones(len(V)), np.zeros(len(V))]
        expected = full - np.sum(full * N, axis=1, keepdims=True) * N
        g = vertex_gradient(V, F).apply(f)
        inner = np.linalg.norm(V[:, :2], axis=1) < 15.0
        errors.append(np.abs(g - expected)[inner].max())
        assert np.abs(np.sum(g * N, axis=1))[inner].max() < 0.02
    assert errors[2] < errors[1] < errors[0] and errors[2] < 2e-3


def test_rows_and_columns_select_a_region_with_zero_outside():
    V, F, _ = _sphere_cap(1.0)
    rng = np.random.default_rng(1)
    f = rng.normal(size=len(V))
    region = np.flatnonzero(V[:, 0] > 0)
    full = vertex_gradient(V, F)
    part = vertex_gradient(V, F, rows=region, columns=region)
    outside_zero = f.copy()
    outside_zero[V[:, 0] <= 0] = 0.0
    np.testing.assert_allclose(part.apply(f[region]), full.apply(outside_zero)[region], atol=1e-12)
