import importlib

import numpy as np
import pytest
from fem_reference import box_tets, linear_elastic_stiffness
from scipy.optimize import brentq
from scipy.sparse.linalg import spsolve

from facecap.errors import InputError
from facecap.fem import FleshModel, MooneyRivlin, MuscleFibre, QuasistaticSolver, solve_quasistatic
from facecap.fem.mooney_rivlin import mooney_rivlin_response
from facecap.fem.muscle_fibre import active_force_length

C10, C01 = 2.5, 1.175


def _uniaxial_nominal_stress(stretch):
    # incompressible Mooney-Rivlin under uniaxial load: P = 2 (l - l^-2) (C10 + C01 / l)
    return 2.0 * (stretch - stretch**-2) * (C10 + C01 / stretch)


def _end_faces_bar(counts=(2, 2, 6), size=(6.0, 6.0, 18.0), mirrored=False):
    X, T = box_tets(counts, size, mirrored=mirrored)
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    top = np.flatnonzero(X[:, 2] == size[2])
    return X, T, bottom, top


@pytest.mark.parametrize("stretch", [0.8, 1.3])
def test_uniaxial_bar_is_homogeneous_with_the_closed_form_stress(stretch):
    # End faces placed on the homogeneous uniaxial state, lateral faces free: linear
    # tetrahedra reproduce it exactly, and the reaction on the end is P33 * A0.
    material = MooneyRivlin(mu10_kpa=C10, mu01_kpa=C01, bulk_modulus_kpa=1e5)
    X, T, bottom, top = _end_faces_bar()
    ends = np.concatenate([bottom, top])
    model = FleshModel(X, T, None, None, ends, material=material)

    # The compressible homogeneous state: lateral stretch t with zero lateral stress (about l^-1/2).
    def lateral_stress(t):
        return mooney_rivlin_response(np.diag([t, t, stretch])[None], material).stress[0, 0, 0]

    t = brentq(lateral_stress, 0.5 * stretch**-0.5, 2.0 * stretch**-0.5, xtol=1e-15)
    centre = np.array([3.0, 3.0, 0.0])
    homogeneous = centre + (X - centre) * [t, t, stretch]
    result = solve_quasistatic(model, np.zeros(0), homogeneous[ends], tolerance=1e-10)
    assert result.converged and result.inverted_tets == 0
    np.testing.assert_allclose(result.positions, homogeneous, atol=1e-7)
    reaction = -model.forces(result.positions, np.zeros(0))[top, 2].sum()
    assert reaction / 36.0 == pytest.approx(_uniaxial_nominal_stress(stretch), rel=1e-4)


def test_small_strains_match_linear_elasticity():
    material = MooneyRivlin(mu10_kpa=C10, mu01_kpa=C01, bulk_modulus_kpa=100.0)
    X, T, bottom, top = _end_faces_bar(counts=(2, 2, 4), size=(6.0, 6.0, 12.0))
    ends = np.concatenate([bottom, top])
    model = FleshModel(X, T, None, None, ends, material=material)
    eps = 1e-4
    u_top = eps * 12.0 * np.array([1.0, -0.5, 0.7])  # shear and stretch of the top face
    prescribed = X[ends].copy()
    prescribed[bottom.size:] += u_top
    result = solve_quasistatic(model, np.zeros(0), prescribed, tolerance=1e-10)
    assert result.converged
    K = linear_elastic_stiffness(X, T, material.lame_lambda_kpa, material.shear_modulus_kpa)
    u = np.zeros(X.shape)
    u[top] = u_top
    free = model.free_dofs
    fixed = np.setdiff1d(np.arange(X.size), free)
    u_flat = u.reshape(-1)
    u_flat[free] = np.linalg.solve(K[np.ix_(free, free)], -K[np.ix_(free, fixed)] @ u_flat[fixed])
    displacement = result.positions - X
    error = np.abs(displacement - u).max() / np.abs(u).max()
    assert error < 1e-3  # the nonlinear terms are O(strain) = 1e-4 relative
    assert np.abs(u[model.free_nodes]).max() > 0.1 * np.abs(u_top).max()


def test_activated_muscle_contracts_along_its_fibres_to_the_uniaxial_equilibrium():
    # A slender bar, one muscle filling it with fibres along z, fixed at the bottom face.
    # Far from the fixed end the bar is in uniaxial stress, where the flesh's nominal
    # stress balances the fibres': P_MR(l) + sigma_max a f_active(l) = 0.
    sigma = 10.0
    material = MooneyRivlin(mu10_kpa=C10, mu01_kpa=C01, bulk_modulus_kpa=5000.0)
    # The mirrored subdivision: on the plain one, whose cubes all share one diagonal, the
    # clamped bar also leans by about 6 degrees (a mesh artefact; the fibre stretch |F d|
    # in the middle is the same).
    X, T, bottom, _ = _end_faces_bar(counts=(2, 2, 16), size=(4.0, 4.0, 32.0), mirrored=True)
    m = T.shape[0]
    directions = np.zeros((m, 1, 3))
    directions[:, 0, 2] = 1.0
    model = FleshModel(X, T, np.ones((m, 1)), directions, bottom, material=material,
                       fibre=MuscleFibre(max_stress_kpa=sigma))
    solver = QuasistaticSolver(model)
    lengths, x = [], None
    lower, upper = np.isclose(X[:, 2], 12.0), np.isclose(X[:, 2], 24.0)
    for a in [0.0, 0.25, 0.5, 1.0]:
        result = solver.solve(np.array([a]), X[bottom], x0=x)
        assert result.converged and result.inverted_tets == 0
        x = result.positions
        lengths.append(x[:, 2].max())
        # symmetric mesh, symmetric load: the bar stays on its axis
        np.testing.assert_allclose(x[X[:, 2] == 32.0, :2].mean(axis=0), [2.0, 2.0], atol=1e-6)
        if a == 1.0:
            mid_stretch = (x[upper, 2].mean() - x[lower, 2].mean()) / 12.0
    assert lengths[0] == pytest.approx(32.0, abs=1e-9)
    assert np.all(np.diff(lengths) < -0.1)

    def balance(s):
        return _uniaxial_nominal_stress(s) + sigma * float(active_force_length(np.array(s))[0])

    expected = brentq(balance, 0.5, 1.0)
    assert 0.7 < expected < 0.85
    assert mid_stretch == pytest.approx(expected, abs=1e-3)


@pytest.mark.parametrize("how", ["mirrored", "some_flipped"])
def test_newton_recovers_from_inverted_tetrahedra(how):
    X, T = box_tets((3, 3, 3), (9.0, 9.0, 9.0))
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    model = FleshModel(X, T, None, None, bottom)
    x0 = X.copy()
    if how == "mirrored":  # every free node reflected through the fixed face: the whole mesh inside out
        x0[:, 2] = -X[:, 2]
    else:  # two interior nodes pushed far through their neighbours
        interior = np.flatnonzero(np.all((X > 0) & (X < 9), axis=1))
        x0[interior[:2]] += [[0.0, 0.0, 7.0], [5.0, -4.0, 0.0]]
    result = solve_quasistatic(model, np.zeros(0), X[bottom], x0=x0, tolerance=1e-8)
    assert result.inverted_tets_initial > 0
    assert result.projected_steps > 0  # the exact stiffness of an inverted mesh is not positive definite
    assert result.converged and result.inverted_tets == 0
    assert np.all(np.isfinite(result.positions))
    np.testing.assert_allclose(result.positions, X, atol=1e-6)


def _activated_block():
    X, T = box_tets((2, 2, 3), (6.0, 6.0, 9.0))
    m = T.shape[0]
    fractions = np.zeros((m, 2))
    fractions[:, 0] = 1.0
    fractions[: m // 2, 1] = 0.6
    directions = np.zeros((m, 2, 3))
    directions[:, 0] = [0.0, 0.0, 1.0]
    directions[:, 1] = [1.0, 0.0, 0.0]
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    model = FleshModel(X, T, fractions, directions, bottom, fibre=MuscleFibre(max_stress_kpa=5.0))
    return model, X, bottom


@pytest.mark.parametrize("exact", [True, False])
def test_factorisation_solves_match_scipy_spsolve(exact):
    model, X, bottom = _activated_block()
    solver = QuasistaticSolver(model, exact_jacobians=exact)
    a = np.array([0.7, 0.4])
    result = solver.solve(a, X[bottom])
    assert result.converged
    rhs = np.random.default_rng(0).normal(size=(3, model.n_nodes, 3))
    u = solver.solve_linear(rhs)
    assert solver.jacobian_stiffness == ("exact" if exact else "projected")
    K = model.stiffness(result.positions, a, free_only=True, definiteness_fix=not exact)
    for c in range(3):
        reference = spsolve(K.tocsc(), rhs[c].reshape(-1)[model.free_dofs])
        np.testing.assert_allclose(u[c].reshape(-1)[model.free_dofs], reference, rtol=1e-9,
                                   atol=1e-12 * np.abs(reference).max())
    assert np.all(u[:, model.dirichlet_nodes] == 0.0)
    np.testing.assert_allclose(solver.solve_linear(rhs[1]), u[1])


def test_jacobians_match_finite_differences_of_the_equilibrium():
    # eq. 5: dX/da_k = K^-1 f_k; eq. 6: a Dirichlet motion's effect; both against re-solving.
    model, X, bottom = _activated_block()
    solver = QuasistaticSolver(model, tolerance=1e-11)
    a = np.array([0.5, 0.3])
    base = solver.solve(a, X[bottom]).positions
    jacobian = solver.activation_jacobian()
    velocity = np.tile([0.2, -0.1, 0.3], (bottom.size, 1)) * X[bottom, :1] / 6.0  # a shear of the base
    boundary = solver.boundary_jacobian(velocity)
    h = 1e-4
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        up = solve_quasistatic(model, a + e, X[bottom], x0=base, tolerance=1e-11).positions
        down = solve_quasistatic(model, a - e, X[bottom], x0=base, tolerance=1e-11).positions
        fd = (up - down) / (2 * h)
        np.testing.assert_allclose(jacobian[k], fd, atol=1e-4 * np.abs(fd).max())
    up = solve_quasistatic(model, a, X[bottom] + h * velocity, x0=base, tolerance=1e-11).positions
    down = solve_quasistatic(model, a, X[bottom] - h * velocity, x0=base, tolerance=1e-11).positions
    fd = (up - down) / (2 * h)
    np.testing.assert_allclose(boundary, fd, atol=1e-4 * np.abs(fd).max())


def test_exaggeration_by_the_force_length_scale_grows_the_displacement_monotonically():
    # Section 9: scaling the force-length curve (not activations above 1) exaggerates an expression.
    model, X, bottom = _activated_block()
    a = np.array([0.6, 0.3])
    displacement, x = [], None
    for scale in [1.0, 1.5, 2.0, 4.0]:
        result = solve_quasistatic(model.with_force_length_scale(scale), a, X[bottom], x0=x)
        assert result.converged and result.inverted_tets == 0
        x = result.positions
        displacement.append(np.linalg.norm(x - X, axis=1).max())
    assert np.all(np.diff(displacement) > 0.05 * displacement[0])


def test_unconverged_solve_is_reported_and_bad_input_raises():
    model, X, bottom = _activated_block()
    result = solve_quasistatic(model, np.array([1.0, 1.0]), X[bottom], max_iterations=1)
    assert not result.converged and result.iterations == 1 and result.residual > 0
    with pytest.raises(InputError, match="dirichlet_positions"):
        solve_quasistatic(model, np.zeros(2), X[bottom[:-1]])
    with pytest.raises(InputError, match="x0"):
        solve_quasistatic(model, np.zeros(2), X[bottom], x0=X[:-1])
    with pytest.raises(InputError, match="solve"):
        QuasistaticSolver(model).activation_jacobian()


@pytest.mark.parametrize("backend", ["pardiso", "scipy"])
def test_a_singular_projected_stiffness_is_shifted_until_it_factors(backend):
    """A positive semi-definite but singular stiffness (a free chain: a path graph's Laplacian, whose
    constant vector is a null mode) is factored shifted by a small multiple of its mean diagonal (SuperLU
    refuses it as is); the step solves the shifted system and descends. One that no small shift makes
    definite is an error."""
    import scipy.sparse as sp

    from facecap.mesh.factor_spd import SpdFactor
    from facecap.errors import SolverError

    X, T = box_tets((1, 1, 1), (1.0, 1.0, 1.0))
    solver = QuasistaticSolver(FleshModel(X, T, None, None, np.arange(4)), backend=backend)
    n = 300
    K = sp.diags([-np.ones(n - 1), np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1)], [-1, 0, 1]).tocsr()
    if backend == "scipy":
        with pytest.raises(SolverError):
            SpdFactor(K, backend=backend)
    r = np.random.default_rng(0).normal(size=n)
    r -= r.mean()  # in the range of K: the shifted solve stays bounded
    step = solver._shifted_factor(K).solve(r)
    scale = np.abs(K.diagonal()).mean()
    residuals = [np.abs((K + mu * scale * sp.identity(n)) @ step - r).max() for mu in (1e-10, 1e-8, 1e-6, 1e-4)]
    assert min(residuals) < 1e-6 * np.abs(r).max()
    assert float(r @ step) > 0  # a descent direction of the energy
    with pytest.raises(SolverError, match="even shifted"):
        solver._shifted_factor(-sp.identity(n, format="csr"))


def test_jacobians_come_from_the_shifted_factor_when_the_projected_stiffness_is_refused(monkeypatch):
    """Where the equilibrium's exact stiffness is not positive definite, the Jacobians use the projected
    one; where that is singular too (every element round a node flattened: PARDISO's zero pivot, error
    -4, seen in the demo on one fTetWild mesh), they come from its smallest working shift instead of
    ending the take. The refusal is simulated on a well-posed block, so the shifted solve can be checked
    against the unshifted one."""
    from facecap.mesh.factor_spd import SpdFactor
    from facecap.errors import SolverError

    module = importlib.import_module("facecap.fem.solve_quasistatic")
    model, X, bottom = _activated_block()
    solver = QuasistaticSolver(model, exact_jacobians=False)
    a = np.array([0.7, 0.4])
    result = solver.solve(a, X[bottom])
    calls = []

    def refuse_the_first(matrix, **kwargs):
        calls.append(matrix)
        if len(calls) == 1:
            raise SolverError("sparse factorisation failed: simulated zero pivot")
        return SpdFactor(matrix, **kwargs)

    monkeypatch.setattr(module, "SpdFactor", refuse_the_first)
    rhs = np.random.default_rng(1).normal(size=(2, model.n_nodes, 3))
    u = solver.solve_linear(rhs)
    assert len(calls) == 2 and solver.jacobian_stiffness == "projected"
    K = model.stiffness(result.positions, a, free_only=True, definiteness_fix=True)
    shift = calls[1] - K
    assert 0 < np.abs(shift.diagonal()).max() <= 1.001e-10 * np.abs(K.diagonal()).mean()  # the smallest shift
    for c in range(2):
        reference = spsolve(K.tocsc(), rhs[c].reshape(-1)[model.free_dofs])
        np.testing.assert_allclose(u[c].reshape(-1)[model.free_dofs], reference, rtol=1e-6,
                                   atol=1e-6 * np.abs(reference).max())
