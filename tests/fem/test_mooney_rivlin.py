import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.fem.mooney_rivlin import MooneyRivlin, mooney_rivlin_response


def _finite_differences(F, material, h=1e-6):
    """Central differences of the energy (-> stress) and of the stress (-> stress derivative)."""
    P = np.zeros(9)
    A = np.zeros((9, 9))
    for q in range(9):
        d = np.zeros(9)
        d[q] = h
        d = d.reshape(3, 3)
        up = mooney_rivlin_response((F + d)[None], material)
        down = mooney_rivlin_response((F - d)[None], material)
        P[q] = (up.energy_density[0] - down.energy_density[0]) / (2 * h)
        A[:, q] = (up.stress[0] - down.stress[0]).reshape(-1) / (2 * h)
    return P, A


@pytest.mark.parametrize("case", ["stretched", "compressed", "flat", "inverted"])
def test_stress_and_its_derivative_are_the_derivatives_of_the_energy(case):
    rng = np.random.default_rng({"stretched": 0, "compressed": 1, "flat": 2, "inverted": 3}[case])
    base = {"stretched": np.diag([1.3, 0.9, 1.1]), "compressed": np.diag([0.7, 0.8, 0.9]),
            "flat": np.diag([1.0, 1.0, 0.1]), "inverted": np.diag([1.0, 1.2, -0.6])}[case]
    F = base + 0.05 * rng.normal(size=(3, 3))
    material = MooneyRivlin()
    r = mooney_rivlin_response(F[None], material)
    P_fd, A_fd = _finite_differences(F, material)
    np.testing.assert_allclose(r.stress[0].reshape(-1), P_fd, rtol=0, atol=1e-6 * np.abs(P_fd).max())
    np.testing.assert_allclose(r.stress_derivative[0], A_fd, rtol=0, atol=1e-6 * np.abs(A_fd).max())
    np.testing.assert_allclose(r.stress_derivative[0], r.stress_derivative[0].T, atol=1e-13 * np.abs(A_fd).max())


def test_rest_state_has_no_energy_or_stress_and_the_linear_elasticity_tangent():
    material = MooneyRivlin(mu10_kpa=3.0, mu01_kpa=1.0, bulk_modulus_kpa=200.0)
    r = mooney_rivlin_response(np.eye(3)[None], material)
    assert abs(r.energy_density[0]) < 1e-12
    assert np.abs(r.stress).max() < 1e-12
    lam, mu = material.lame_lambda_kpa, material.shear_modulus_kpa
    d = np.eye(3)
    C = (lam * np.einsum("ij,kl->ijkl", d, d) + mu * (np.einsum("ik,jl->ijkl", d, d)
                                                     + np.einsum("il,jk->ijkl", d, d))).reshape(9, 9)
    np.testing.assert_allclose(r.stress_derivative[0], C, atol=1e-12 * mu)
    assert mu == 8.0 and lam == pytest.approx(200.0 - 16.0 / 3.0)


def test_frame_invariance():
    rng = np.random.default_rng(4)
    F = np.eye(3) + 0.3 * rng.normal(size=(6, 3, 3))
    R = Rotation.random(6, random_state=5).as_matrix()
    material = MooneyRivlin()
    r = mooney_rivlin_response(F, material)
    rr = mooney_rivlin_response(R @ F, material)
    np.testing.assert_allclose(rr.energy_density, r.energy_density, rtol=1e-12)
    np.testing.assert_allclose(rr.stress, R @ r.stress, atol=1e-10 * np.abs(r.stress).max())
    rigid = mooney_rivlin_response(R, material)
    assert np.abs(rigid.energy_density).max() < 1e-12 and np.abs(rigid.stress).max() < 1e-11


def _incompressible_uniaxial_nominal_stress(stretch, c10, c01):
    # Incompressible Mooney-Rivlin, F = diag(l, l^-1/2, l^-1/2): P11 = 2 (l - l^-2) (C10 + C01 / l).
    return 2.0 * (stretch - stretch**-2) * (c10 + c01 / stretch)


@pytest.mark.parametrize("stretch", [0.7, 0.9, 1.2, 1.6])
def test_uniaxial_stress_matches_the_closed_form(stretch):
    # Nearly incompressible: the closed form is the limit kappa -> infinity; J - 1 ~ P / kappa.
    material = MooneyRivlin(mu10_kpa=2.5, mu01_kpa=1.175, bulk_modulus_kpa=1e6)

    def lateral_stress(t):
        return mooney_rivlin_response(np.diag([stretch, t, t])[None], material).stress[0, 1, 1]

    t = brentq(lateral_stress, 0.5 * stretch**-0.5, 2.0 * stretch**-0.5, xtol=1e-15)
    P = mooney_rivlin_response(np.diag([stretch, t, t])[None], material).stress[0]
    expected = _incompressible_uniaxial_nominal_stress(stretch, 2.5, 1.175)
    assert P[0, 0] == pytest.approx(expected, rel=1e-4)
    assert t == pytest.approx(stretch**-0.5, rel=1e-5)


def test_energy_defined_and_pushing_back_through_flat_and_inverted_states():
    # Squash one axis from 1 through 0 to -1: the energy stays finite and smooth and keeps
    # growing, so its force always points back towards the uninverted rest state.
    material = MooneyRivlin()
    t = np.linspace(-1.0, 1.0, 2001)
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, 2, 2] = t
    r = mooney_rivlin_response(F, material)
    assert np.all(np.isfinite(r.energy_density)) and np.all(np.isfinite(r.stress_derivative))
    assert np.all(np.diff(r.energy_density) < 0)
    assert np.all(r.stress[:-1, 2, 2] < 0)
    # C1 and C2 at the extension's join J = J_min: no jump in stress or stiffness there.
    Jm = material.inversion_volume_ratio
    around = mooney_rivlin_response(np.stack([np.diag([1.0, 1.0, Jm - 1e-9]), np.diag([1.0, 1.0, Jm + 1e-9])]),
                                    material)
    np.testing.assert_allclose(around.stress[0], around.stress[1], atol=1e-6)
    np.testing.assert_allclose(around.stress_derivative[0], around.stress_derivative[1], atol=1e-5)


def test_bad_constants():
    with pytest.raises(InputError):
        MooneyRivlin(mu10_kpa=-1.0)
    with pytest.raises(InputError):
        MooneyRivlin(mu10_kpa=0.0, mu01_kpa=0.0)
    with pytest.raises(InputError):
        MooneyRivlin(inversion_volume_ratio=1.5)
