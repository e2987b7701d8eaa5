import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from facecap.deform.factor_spd import SpdFactor, available_backends
from facecap.errors import InputError, SolverError


def _spd(n, seed):
    R = sp.random(n, n, density=0.01, random_state=seed)
    return (R @ R.T + 0.1 * sp.eye(n)).tocsr()


@pytest.mark.parametrize("backend", available_backends())
def test_solves_like_scipy_spsolve(backend):
    A = _spd(400, 0)
    b = np.random.default_rng(0).normal(size=(400, 5))
    x = SpdFactor(A, backend=backend).solve(b)
    np.testing.assert_allclose(x, spsolve(A.tocsc(), b), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(A @ x, b, atol=1e-8)


def test_pardiso_is_the_default_where_available():
    assert "pardiso" in available_backends()
    assert SpdFactor(_spd(50, 1)).backend == "pardiso"


def test_bad_arguments():
    with pytest.raises(InputError):
        SpdFactor(np.eye(3))
    with pytest.raises(InputError):
        SpdFactor(_spd(10, 2), backend="cholmod")


def test_singular_matrix_is_an_error_not_garbage():
    A = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(SolverError):
        SpdFactor(A, backend="scipy").solve(np.ones(2))
