import igl
import numpy as np

from facecap.mesh.laplacian import laplace_operators


def _grid(n=12):
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    V = np.stack([u.ravel() * 50, v.ravel() * 30, np.zeros(n * n)], 1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def test_psd_sign_constants_in_kernel_and_total_area():
    V, F = _grid()
    ops = laplace_operators(V, F)
    np.testing.assert_allclose(ops.L @ np.ones(len(V)), 0, atol=1e-12)
    x = np.random.default_rng(0).normal(size=len(V))
    assert x @ (ops.L @ x) > 0
    np.testing.assert_allclose(ops.mass.sum(), 50 * 30, rtol=1e-12)
    np.testing.assert_allclose(ops.L.toarray(), -igl.cotmatrix(V, F).toarray(), atol=1e-12)


def test_linear_functions_are_harmonic_at_interior_vertices():
    V, F = _grid()
    ops = laplace_operators(V, F)
    f = 2 * V[:, 0] - 3 * V[:, 1]
    interior = (V[:, 0] > 0) & (V[:, 0] < 50) & (V[:, 1] > 0) & (V[:, 1] < 30)
    np.testing.assert_allclose((ops.L @ f)[interior], 0, atol=1e-9)


def test_dirichlet_energy_of_a_linear_function_on_a_flat_grid():
    # x^T L x / 2 = integral of |grad f|^2 / 2 ... i.e. x^T L x = |grad f|^2 * area for linear f
    V, F = _grid()
    ops = laplace_operators(V, F)
    f = 2 * V[:, 0] - 3 * V[:, 1]
    np.testing.assert_allclose(f @ (ops.L @ f), (4 + 9) * 50 * 30, rtol=1e-10)


def test_vertices_after_the_last_triangle_get_zero_rows_and_no_area():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 5, 5]])
    F = np.array([[0, 1, 2]])
    ops = laplace_operators(V, F)
    assert ops.L.shape == (5, 5) and ops.mass.shape == (5,)
    assert ops.mass[3:].tolist() == [0.0, 0.0] and abs(ops.mass.sum() - 0.5) < 1e-12
    assert abs(ops.L[3:]).sum() == 0.0 and abs(ops.L[:, 3:]).sum() == 0.0
