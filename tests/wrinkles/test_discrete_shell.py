"""The discrete shell of eq. 8 (Grinspun et al. 2003) and its Gauss-Newton minimiser."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.wrinkles.discrete_shell import DiscreteShell, minimize_shell


def _grid(n: int = 7, spacing: float = 1.0, rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    z = np.zeros(n * n) if rng is None else 0.05 * spacing * rng.standard_normal(n * n)
    V = np.column_stack([xs.ravel(), ys.ravel(), z])
    F = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            F += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return V, np.array(F)


def _numeric_jacobian(shell: DiscreteShell, X: np.ndarray, h: float = 1e-6) -> np.ndarray:
    J = np.zeros((shell.n_residuals, X.size))
    for k in range(X.size):
        plus, minus = X.copy().ravel(), X.copy().ravel()
        plus[k] += h
        minus[k] -= h
        J[:, k] = (shell.residuals(plus.reshape(-1, 3)) - shell.residuals(minus.reshape(-1, 3))) / (2 * h)
    return J


def test_jacobian_matches_central_differences_for_every_term() -> None:
    rng = np.random.default_rng(3)
    V, F = _grid(6, rng=rng)
    shell = DiscreteShell(V, F)
    X = V + 0.15 * rng.standard_normal(V.shape)
    analytic = shell.jacobian(X).toarray()
    numeric = _numeric_jacobian(shell, X)
    n_e, n_h = len(shell.edges), len(shell.hinges)
    for rows in (slice(0, n_e), slice(n_e, n_e + n_h), slice(n_e + n_h, None)):
        scale = np.abs(numeric[rows]).max()
        assert np.abs(analytic[rows] - numeric[rows]).max() < 1e-6 * scale


def test_energy_is_zero_at_rest_and_invariant_under_rigid_motion() -> None:
    rng = np.random.default_rng(0)
    V, F = _grid(6, rng=rng)
    shell = DiscreteShell(V, F)
    assert shell.energy(V) == pytest.approx(0.0, abs=1e-20)
    angle = 0.7
    R = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    assert shell.energy(V @ R.T + [3.0, -2.0, 5.0]) == pytest.approx(0.0, abs=1e-18)
    assert shell.energy(V * 1.01) > 0


def test_dihedral_angle_of_a_folded_hinge_is_the_fold_angle() -> None:
    # two triangles on edge (0, 1); the second folded up by 30 degrees about the x axis
    fold = np.deg2rad(30.0)
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -np.cos(fold), np.sin(fold)]])
    F = np.array([[0, 1, 2], [1, 0, 3]])
    flat = V.copy()
    flat[3] = [0.5, -1.0, 0.0]
    shell = DiscreteShell(flat, F, stretch=0.0, area=0.0, bend=1.0)
    r = shell.residuals(V)
    h = (0.5 * 1.0 + 0.5 * 1.0) / 1.0 / 3.0  # a third of the mean height of the two unit-height triangles
    # folding the wing towards the normals' side (+z, the triangles wind counter-clockwise seen from +z)
    # is a negative angle in this convention
    assert r[len(shell.edges)] == pytest.approx(-np.sqrt(1.0 / h) * fold, rel=1e-9)


def test_energy_scales_with_the_stated_unit() -> None:
    # the same shape in cm (every length / 10) with the unit 0.1 cm has the energy of the shape in mm with 1 mm
    rng = np.random.default_rng(1)
    V, F = _grid(5, spacing=1.0, rng=rng)
    X = V + 0.1 * rng.standard_normal(V.shape)
    in_mm = DiscreteShell(V, F, length_mm=1.0).energy(X)
    in_cm = DiscreteShell(V / 10, F, length_mm=0.1).energy(X / 10)
    assert in_cm == pytest.approx(in_mm, rel=1e-10)


def test_minimiser_returns_a_perturbed_sheet_to_rest_with_its_boundary_fixed() -> None:
    rng = np.random.default_rng(2)
    V, F = _grid(8, rng=rng)
    shell = DiscreteShell(V, F)
    inner = (V[:, 0] > 0.5) & (V[:, 0] < 6.5) & (V[:, 1] > 0.5) & (V[:, 1] < 6.5)
    start = V.copy()
    start[inner] += 0.2 * rng.standard_normal((inner.sum(), 3))
    found = minimize_shell(shell, start, inner, iterations=50, tolerance_mm=1e-9, relative_decrease=0.0)
    assert found.energy < 1e-12 * found.initial_energy
    assert np.abs(found.vertices - V).max() < 1e-5
    assert np.array_equal(found.vertices[~inner], V[~inner])


def test_minimiser_along_normals_moves_only_along_them() -> None:
    V, F = _grid(8)
    shell = DiscreteShell(V, F, stretch=30.0, area=300.0)
    middle = int(np.argmin(np.linalg.norm(V[:, :2] - 3.0, axis=1)))
    start = V.copy()
    start[middle, 2] -= 0.3  # a dent imposed at one vertex
    ring = np.linalg.norm(V[:, :2] - V[middle, :2], axis=1)
    free = (ring > 0) & (ring < 2.6)
    normals = np.tile([0.0, 0.0, 1.0], (len(V), 1))
    found = minimize_shell(shell, start, free, directions=normals)
    assert found.energy < found.initial_energy
    assert np.array_equal(found.vertices[:, :2], V[:, :2])
    # the neighbours follow the dent down (a smooth surface, not a spike)
    assert found.vertices[free & (ring < 1.1), 2].max() < -0.02


def test_bad_input_is_refused() -> None:
    V, F = _grid(3)
    with pytest.raises(InputError, match="degenerate"):
        DiscreteShell(np.zeros_like(V), F)
    with pytest.raises(InputError, match="faces"):
        DiscreteShell(V, F + 100)
    with pytest.raises(InputError, match="stretch"):
        DiscreteShell(V, F, stretch=-1.0)
    with pytest.raises(InputError, match="x:"):
        DiscreteShell(V, F).energy(V[:-1])
