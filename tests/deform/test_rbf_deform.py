import numpy as np

from facecap.deform.rbf_deform import rbf_deformation_basis
from facecap.deform.triharmonic_warp import TriharmonicWarp


def test_basis_equals_a_warp_fitted_per_frame():
    rng = np.random.default_rng(0)
    centres = rng.normal(size=(30, 3)) * 40
    V = rng.normal(size=(200, 3)) * 40
    d = rng.normal(size=(30, 3))
    basis = rbf_deformation_basis(V, centres)
    expected = TriharmonicWarp(centres, centres + d)(V) - V
    np.testing.assert_allclose(basis.T @ d, expected, atol=1e-4)
