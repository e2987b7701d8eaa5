"""control_penalty: zero on the feasible set, analytic values, gradient and Hessian against finite differences."""

from __future__ import annotations

import numpy as np

from facecap.muscles import JawConstraints, MuscleControls, control_penalty

K = 3
JAW = JawConstraints(np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.array([0.0, 30.0, -50.0]), 100.0,
                     track_length_mm=15.0, max_opening_rad=np.radians(35.0))


def test_zero_on_the_feasible_set() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        from scipy.spatial.transform import Rotation

        R = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        c = MuscleControls(rng.uniform(size=K), np.hstack([R, rng.normal(size=(3, 1))]),
                           JAW.transform(rng.uniform(0, 0.5), rng.uniform(0, 15), rng.uniform(0, 15)))
        p = control_penalty(c.as_vector(), K, JAW)
        assert p.value < 1e-20 and np.abs(p.gradient).max() < 1e-9


def test_analytic_values() -> None:
    c = MuscleControls(np.array([-0.5, 0.5, 1.25]), 2.0 * np.eye(3, 4), np.eye(3, 4))
    # activations 0.25 + 0.0625; rigidity of 2 I: |4 I - I|^2 = 27
    assert np.isclose(control_penalty(c.as_vector(), K, JAW).value, 0.25 + 0.0625 + 27.0)
    opened = MuscleControls(np.zeros(K), np.eye(3, 4), JAW.transform(np.radians(45.0)))
    excess = np.sin(np.radians(45.0)) - np.sin(np.radians(35.0))
    assert np.isclose(control_penalty(opened.as_vector(), K, JAW).value, excess**2)


def _random_vector(rng: np.random.Generator) -> np.ndarray:
    c = MuscleControls(rng.uniform(-0.5, 1.5, K), np.eye(3, 4) + 0.2 * rng.normal(size=(3, 4)),
                       JAW.transform(0.7, -2.0, 18.0) + 0.05 * rng.normal(size=(3, 4)))
    return c.as_vector()


def test_gradient_matches_finite_differences() -> None:
    rng = np.random.default_rng(1)
    for _ in range(3):
        v = _random_vector(rng)
        p = control_penalty(v, K, JAW)
        h = 1e-6
        fd = np.array([(control_penalty(v + h * e, K, JAW).value - control_penalty(v - h * e, K, JAW).value) / (2 * h)
                       for e in np.eye(v.size)])
        assert np.allclose(p.gradient, fd, rtol=1e-6, atol=1e-6)


def test_hessian_is_psd_and_exact_where_convex() -> None:
    rng = np.random.default_rng(2)
    h = 1e-6
    for _ in range(3):
        v = _random_vector(rng)
        H = control_penalty(v, K, JAW).hessian
        assert np.allclose(H, H.T) and np.linalg.eigvalsh(H).min() > -1e-9
    # near rigid frames the rigidity Hessian needs no projection: it equals the finite-difference one
    c = MuscleControls(np.array([-0.2, 0.4, 1.1]), np.eye(3, 4) + 1e-3 * rng.normal(size=(3, 4)),
                       JAW.transform(0.7, 1.0, 16.0) + 1e-3 * rng.normal(size=(3, 4)))
    v = c.as_vector()
    H = control_penalty(v, K, JAW).hessian
    fd = np.stack([(control_penalty(v + h * e, K, JAW).gradient - control_penalty(v - h * e, K, JAW).gradient) / (2 * h)
                   for e in np.eye(v.size)], axis=1)
    assert np.abs(H - fd).max() < 1e-4 * np.abs(H).max()
