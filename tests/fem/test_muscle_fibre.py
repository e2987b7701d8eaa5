import numpy as np
import pytest
from scipy.integrate import quad

from facecap.errors import InputError
from facecap.fem.muscle_fibre import MuscleFibre, active_force_length, fibre_response, passive_force_length


def test_active_curve_values_of_blemker_et_al():
    s = np.array([0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.4, 1.5, 1.6, 1.8])
    value, slope, _ = active_force_length(s)
    expected = [0.0, 0.0, 9 * 0.01, 0.36, 1 - 4 * 0.04, 1.0, 1 - 4 * 0.04, 0.36, 9 * 0.01, 0.0, 0.0]
    np.testing.assert_allclose(value, expected, atol=1e-12)
    assert slope[5] == 0.0 and slope[4] > 0 > slope[6]


def test_passive_curve_values_and_its_c1_linear_continuation():
    fibre = MuscleFibre()
    value, slope, _ = passive_force_length(np.array([0.5, 1.0, 1.2]), fibre)
    np.testing.assert_allclose(value, [0.0, 0.0, 0.05 * (np.exp(6.6 * 0.2) - 1)], rtol=1e-12)
    join = fibre.passive_linear_stretch
    v, d, _ = passive_force_length(np.array([join - 1e-9, join + 1e-9]), fibre)
    np.testing.assert_allclose(v[0], v[1], rtol=1e-7)
    np.testing.assert_allclose(d[0], d[1], rtol=1e-7)
    v2, d2, _ = passive_force_length(np.array([2.0, 2.5]), fibre)
    assert d2[0] == pytest.approx(d2[1]) and v2[1] - v2[0] == pytest.approx(0.5 * d2[0])


@pytest.mark.parametrize("curve", ["active", "passive"])
def test_integrals_match_numerical_quadrature(curve):
    fn = active_force_length if curve == "active" else (lambda s: passive_force_length(s, MuscleFibre()))
    for s in [0.3, 0.5, 0.7, 0.95, 1.1, 1.45, 1.7, 2.2]:
        _, _, integral = fn(np.array(s))
        reference, _ = quad(lambda t: float(fn(np.array(t))[0]), 1.0, s, points=[0.4, 0.6, 1.4, 1.6], limit=200)
        assert float(integral) == pytest.approx(reference, abs=1e-10)


def _fd(F, d, pw, aw, fibre, h=1e-6):
    P = np.zeros(9)
    A = np.zeros((9, 9))
    for q in range(9):
        e = np.zeros(9)
        e[q] = h
        e = e.reshape(3, 3)
        up = fibre_response((F + e)[None], d[None], pw, aw, fibre)
        down = fibre_response((F - e)[None], d[None], pw, aw, fibre)
        P[q] = (up.energy_density[0] - down.energy_density[0]) / (2 * h)
        A[:, q] = (up.stress[0] - down.stress[0]).reshape(-1) / (2 * h)
    return P, A


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stress_and_derivative_are_the_derivatives_of_the_energy(seed):
    rng = np.random.default_rng(seed)
    fibre = MuscleFibre(max_stress_kpa=50.0)
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    # A stretch of 1.15 along the fibre plus a small random part: away from the curves' joins.
    F = np.eye(3) + 0.15 * np.outer(d, d) + 0.02 * rng.normal(size=(3, 3))
    pw, aw = np.array([0.7]), np.array([0.4])
    r = fibre_response(F[None], d[None], pw, aw, fibre)
    P_fd, A_fd = _fd(F, d, pw, aw, fibre)
    np.testing.assert_allclose(r.stress[0].reshape(-1), P_fd, atol=1e-6 * np.abs(P_fd).max())
    np.testing.assert_allclose(r.stress_derivative[0], A_fd, atol=1e-6 * np.abs(A_fd).max())


def test_stretch_along_the_fibre_gives_the_curve_times_the_weights():
    fibre = MuscleFibre(max_stress_kpa=100.0)
    d = np.array([0.0, 0.6, 0.8])
    for stretch in [0.7, 1.0, 1.25]:
        F = np.eye(3) + (stretch - 1.0) * np.outer(d, d)
        r = fibre_response(F[None], d[None], np.array([0.5]), np.array([0.3]), fibre)
        fa, _, _ = active_force_length(np.array(stretch))
        fp, _, _ = passive_force_length(np.array(stretch), fibre)
        np.testing.assert_allclose(r.stress[0], 100.0 * (0.5 * fp + 0.3 * fa) * np.outer(d, d), atol=1e-12)
        # No stress across the fibre: shearing perpendicular to d changes nothing.
        side = np.array([1.0, 0.0, 0.0])
        sheared = fibre_response((F + 0.3 * np.outer(side, side))[None], d[None], np.array([0.5]), np.array([0.3]),
                                 fibre)
        np.testing.assert_allclose(sheared.energy_density, r.energy_density, atol=1e-12)


def test_bad_constants():
    with pytest.raises(InputError):
        MuscleFibre(max_stress_kpa=-1.0)
    with pytest.raises(InputError):
        MuscleFibre(passive_linear_stretch=0.9)
