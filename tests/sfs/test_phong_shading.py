"""Phong's model against hand-worked values and its derivative against finite differences."""

import numpy as np

from facecap.sfs.phong_shading import phong_shading


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def test_values_match_the_formula_by_hand():
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    L = np.array([[[0.0, 0.6, 0.8], [0.0, 0.6, -0.8]]])  # the second light is behind the surface
    e = np.array([[0.0, -0.6, 0.8], [0.0, -0.6, 0.8]])
    out = phong_shading(n, L, np.array([[2.0, 2.0]]), e, albedo=0.5, k_s=0.1, alpha=4.0, ambient=0.2)
    np.testing.assert_allclose(out.diffuse, [0.2 + 1.6, 0.2])
    np.testing.assert_allclose(out.specular, [2.0, 0.0])  # r = e exactly for the first; none from behind
    np.testing.assert_allclose(out.radiance, [0.5 * 1.8 + 0.2, 0.1])


def test_derivative_along_the_normal_matches_finite_differences():
    rng = np.random.default_rng(3)
    k = 200
    n = _unit(rng.normal(size=(k, 3)) + [0, 0, 2.5])
    L = _unit(rng.normal(size=(2, k, 3)) + [0.3, 0.2, 2.0])
    E = rng.uniform(0.5, 2.0, size=(2, k))
    e = _unit(rng.normal(size=(k, 3)) + [0, 0, 2.0])
    args = dict(albedo=rng.uniform(0.3, 0.8, k), k_s=0.2, alpha=9.0, ambient=0.1)
    out = phong_shading(n, L, E, e, gradient=True, **args)
    step = 1e-6
    for axis in range(3):
        dn = np.zeros(3)
        dn[axis] = step
        plus = phong_shading(n + dn, L, E, e, **args).radiance
        minus = phong_shading(n - dn, L, E, e, **args).radiance
        numeric = (plus - minus) / (2 * step)
        # away from the kinks (n.l = 0, r.e = 0) the derivative is smooth
        np.testing.assert_allclose(out.d_normal[:, axis], numeric, rtol=1e-5, atol=1e-6)
