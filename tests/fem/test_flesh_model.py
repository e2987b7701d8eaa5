import numpy as np
import pytest
import scipy.sparse as sp
from fem_reference import box_tets, linear_elastic_stiffness
from scipy.spatial.transform import Rotation

from facecap.errors import InputError, MeshError
from facecap.fem import FleshModel, MooneyRivlin, MuscleFibre


def _two_muscle_box(counts=(2, 2, 3), fibre_stress=20.0):
    X, T = box_tets(counts, (10.0, 10.0, 15.0))
    m = T.shape[0]
    rng = np.random.default_rng(7)
    fractions = np.zeros((m, 2))
    fractions[:, 0] = 1.0
    fractions[::2, 1] = rng.uniform(0.2, 0.9, size=fractions[::2, 1].shape)  # overlapping, partial
    directions = np.zeros((m, 2, 3))
    directions[:, 0] = [0.0, 0.0, 2.0]  # not unit: the model normalises
    directions[:, 1] = [1.0, 1.0, 0.3]
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    model = FleshModel(X, T, fractions, directions, bottom, fibre=MuscleFibre(max_stress_kpa=fibre_stress),
                       muscle_strength=np.array([1.0, 0.5]))
    return model, X


def _deformed(X, seed, amplitude=0.4):
    # A smooth stretch along the fibres (z) plus node noise: fibre stretches near 1.15, away
    # from the force-length curves' joins (0.6, 1, 1.4), and no inverted tetrahedra.
    rng = np.random.default_rng(seed)
    x = X * [1.0, 1.0, 1.15] + amplitude * rng.normal(size=X.shape)
    return x


def test_forces_are_minus_the_energy_gradient():
    model, X = _two_muscle_box()
    x = _deformed(X, 0)
    a = np.array([0.3, 0.8])
    assert not model.inverted_tets(x).any()
    f = model.forces(x, a)
    h = 1e-5
    grad = np.zeros(x.size)
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = h
        e = e.reshape(x.shape)
        grad[i] = (model.energy(x + e, a) - model.energy(x - e, a)) / (2 * h)
    np.testing.assert_allclose(-grad, f.reshape(-1), rtol=0, atol=1e-6 * np.abs(f).max())


def test_stiffness_is_the_force_jacobian_before_the_definiteness_fix():
    model, X = _two_muscle_box()
    x = _deformed(X, 1)
    a = np.array([0.6, 0.2])
    K = model.stiffness(x, a, definiteness_fix=False).toarray()
    h = 1e-6
    jac = np.zeros_like(K)
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = h
        e = e.reshape(x.shape)
        jac[:, i] = -(model.forces(x + e, a) - model.forces(x - e, a)).reshape(-1) / (2 * h)
    np.testing.assert_allclose(K, jac, rtol=0, atol=1e-6 * np.abs(K).max())
    np.testing.assert_allclose(K, K.T, atol=1e-12 * np.abs(K).max())


def test_forces_are_affine_in_the_activations_with_the_force_basis():
    model, X = _two_muscle_box()
    x = _deformed(X, 2)
    basis = model.force_basis(x)
    f0 = model.forces(x, np.zeros(2))
    scale = np.abs(basis).max()
    for a in [np.array([1.0, 0.0]), np.array([0.25, 0.75]), np.array([0.9, 1.0])]:
        np.testing.assert_allclose(model.forces(x, a), f0 + np.einsum("k,knc->nc", a, basis), atol=1e-12 * scale)
    # the basis is the derivative of the force along each activation, by differences of the whole model
    for k in range(2):
        e = np.zeros(2)
        e[k] = 0.5
        np.testing.assert_allclose((model.forces(x, e) - f0) / 0.5, basis[k], atol=1e-12 * scale)
    assert np.abs(basis[0]).max() > 0 and np.abs(basis[1]).max() > 0


def test_rest_and_rigid_motions_give_no_energy_or_force():
    model, X = _two_muscle_box()
    R = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    for x in [X, X @ R.T + [5.0, -3.0, 12.0]]:
        assert abs(model.energy(x, np.zeros(2))) < 1e-10
        assert np.abs(model.forces(x, np.zeros(2))).max() < 1e-10
    # deformed and activated: the energy is invariant and the forces rotate with the body
    x = _deformed(X, 3)
    a = np.array([0.5, 0.5])
    moved = x @ R.T + [1.0, 2.0, 3.0]
    assert model.energy(moved, a) == pytest.approx(model.energy(x, a), rel=1e-12)
    np.testing.assert_allclose(model.forces(moved, a), model.forces(x, a) @ R.T,
                               atol=1e-11 * np.abs(model.forces(x, a)).max())


def test_rest_stiffness_is_the_linear_elasticity_stiffness():
    X, T = box_tets((2, 2, 2), (4.0, 5.0, 6.0))
    material = MooneyRivlin(mu10_kpa=2.0, mu01_kpa=0.5, bulk_modulus_kpa=100.0)
    model = FleshModel(X, T, None, None, np.arange(4), material=material)
    K = model.stiffness(X, np.zeros(0)).toarray()
    reference = linear_elastic_stiffness(X, T, material.lame_lambda_kpa, material.shear_modulus_kpa)
    np.testing.assert_allclose(K, reference, rtol=0, atol=1e-10 * np.abs(reference).max())


def test_definiteness_fix_makes_the_stiffness_positive_semidefinite():
    model, X = _two_muscle_box()
    # Strong compression along z with shear: Mooney-Rivlin tetrahedra lose definiteness here.
    rng = np.random.default_rng(4)
    x = X * [1.0, 1.0, 0.55] + 0.6 * rng.normal(size=X.shape)
    a = np.array([1.0, 1.0])
    exact = model.stiffness(x, a, definiteness_fix=False).toarray()
    fixed = model.stiffness(x, a).toarray()
    scale = np.abs(exact).max()
    assert np.linalg.eigvalsh(exact).min() < -1e-3 * scale
    assert np.linalg.eigvalsh(fixed).min() > -1e-10 * scale
    # where nothing is indefinite (the rest state) the fix changes nothing
    np.testing.assert_allclose(model.stiffness(X, np.zeros(2)).toarray(),
                               model.stiffness(X, np.zeros(2), definiteness_fix=False).toarray(), atol=1e-12 * scale)


def test_assembly_into_the_reused_pattern_matches_scipy_coo_summation():
    model, X = _two_muscle_box()
    rng = np.random.default_rng(5)
    blocks = rng.normal(size=(model.n_tets, 12, 12))
    dofs = (3 * model.tets[:, :, None] + np.arange(3)).reshape(-1, 12)
    rows = np.repeat(dofs, 12, axis=1).reshape(-1)
    cols = np.tile(dofs, (1, 12)).reshape(-1)
    n = 3 * model.n_nodes
    reference = sp.coo_matrix((blocks.reshape(-1), (rows, cols)), shape=(n, n)).toarray()
    np.testing.assert_allclose(model.assemble(blocks, free_only=False).toarray(), reference, atol=1e-12)
    free = model.free_dofs
    np.testing.assert_allclose(model.assemble(blocks, free_only=True).toarray(), reference[np.ix_(free, free)],
                               atol=1e-12)
    # the pattern is reused: a second fill with other values is still right
    blocks2 = rng.normal(size=blocks.shape)
    reference2 = sp.coo_matrix((blocks2.reshape(-1), (rows, cols)), shape=(n, n)).toarray()
    np.testing.assert_allclose(model.assemble(blocks2, free_only=False).toarray(), reference2, atol=1e-12)


def test_force_length_scale_scales_the_whole_fibre_response():
    model, X = _two_muscle_box()
    x = _deformed(X, 6)
    a = np.array([0.4, 0.9])
    flesh_only = FleshModel(X, model.tets, None, None, model.dirichlet_nodes)
    fibre_force = model.forces(x, a) - flesh_only.forces(x, np.zeros(0))
    doubled = model.with_force_length_scale(2.0)
    np.testing.assert_allclose(doubled.forces(x, a) - flesh_only.forces(x, np.zeros(0)), 2.0 * fibre_force,
                               atol=1e-12 * np.abs(fibre_force).max())
    assert model.force_length_scale == 1.0


def test_inverted_tets_are_counted():
    model, X = _two_muscle_box()
    x = X.copy()
    top = np.flatnonzero(X[:, 2] == X[:, 2].max())
    x[top, 2] = 0.5 * X[:, 2].max() - 1.0  # the top layer pushed through the layer below
    count = int(model.inverted_tets(x).sum())
    F = model.deformation_gradients(x)
    assert count == int((np.linalg.det(F) <= 0).sum()) > 0
    assert model.evaluate(x, np.zeros(2)).inverted == count


def test_bad_input():
    X, T = box_tets((1, 1, 1), (1.0, 1.0, 1.0))
    with pytest.raises(MeshError, match="negatively oriented"):
        FleshModel(X, T[:, [1, 0, 2, 3]], None, None, np.arange(4))
    with pytest.raises(MeshError):
        FleshModel(X, T + 100, None, None, np.arange(4))
    m = T.shape[0]
    with pytest.raises(InputError, match="muscle_fractions"):
        FleshModel(X, T, np.full((m, 1), 1.5), np.ones((m, 1, 3)), np.arange(4))
    with pytest.raises(InputError, match="no direction"):
        FleshModel(X, T, np.full((m, 1), 0.5), np.zeros((m, 1, 3)), np.arange(4))
    with pytest.raises(InputError, match="one line"):
        FleshModel(X, T, None, None, np.array([0, 1]))
    with pytest.raises(InputError, match="twice"):
        FleshModel(X, T, None, None, np.array([0, 1, 2, 2]))
    model = FleshModel(X, T, None, None, np.arange(4))
    with pytest.raises(InputError, match="activations"):
        model.forces(X, np.ones(3))
