from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from facecap.mesh.factor_spd import SpdFactor, available_backends, load_backend
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


@pytest.mark.parametrize("backend", available_backends())
def test_refactor_solves_the_new_matrix_whether_or_not_its_pattern_is_the_old_one(backend):
    A = _spd(400, 0)
    b = np.random.default_rng(1).normal(size=(400, 3))
    factor = SpdFactor(A, backend=backend)
    factor.solve(b)
    same_pattern = A.copy()
    same_pattern.data *= np.random.default_rng(2).uniform(0.5, 1.5, A.nnz)
    same_pattern = (same_pattern + same_pattern.T) / 2 + sp.eye(400) * 5.0  # symmetric, definite, pattern unchanged
    assert same_pattern.nnz == A.nnz
    i, j = (c[0] for c in sp.triu(same_pattern, k=1).nonzero())
    fewer = same_pattern.tolil()
    fewer[i, j] = fewer[j, i] = 0.0  # a sum that cancelled: a non-zero less, within the analysed pattern
    fewer = fewer.tocsr()
    fewer.eliminate_zeros()
    assert fewer.nnz == A.nnz - 2
    for M in (same_pattern, fewer, _spd(400, 3)):  # then one with other non-zeros
        factor.refactor(M)
        np.testing.assert_allclose(factor.solve(b), spsolve(M.tocsc(), b), rtol=1e-8, atol=1e-10)
    with pytest.raises(InputError):
        factor.refactor(_spd(10, 4))
    factor.free()



@pytest.mark.skipif("pardiso" not in available_backends(), reason="needs MKL PARDISO (x86)")
def test_refactor_falls_back_to_a_whole_factorisation_when_pypardiso_moves_its_internals():
    A = _spd(300, 5)
    b = np.ones((300, 2))
    factor = SpdFactor(A, backend="pardiso")

    solver = factor._impl[0]
    call = solver._call_pardiso

    def moved(*args):  # the numeric phase alone goes through pypardiso's internals; say they changed
        if solver.phase == 22:
            raise TypeError("_call_pardiso() takes 2 positional arguments")
        return call(*args)

    solver._call_pardiso = moved
    B = A + sp.eye(300)
    factor.refactor(B)
    np.testing.assert_allclose(factor.solve(b), spsolve(B.tocsc(), b), rtol=1e-8, atol=1e-10)
    factor.free()


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


def _resident_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs Linux /proc to read resident memory")
@pytest.mark.parametrize("backend", available_backends())
def test_free_gives_the_memory_back(backend):
    # A 40k-vertex grid Laplacian: before free() released MKL's whole PARDISO handle, each
    # factor-and-free cycle kept ~18 MB here (216 MB over 12; 180 MB per 78k-vertex registration,
    # 7 GB for 40 of them); now the resident size stays flat, up to allocator noise.
    grid = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(200, 200))
    A = (sp.kronsum(grid, grid) + 1e-3 * sp.eye(40_000)).tocsr()
    b = np.ones((40_000, 3))
    for _ in range(2):  # warm up allocator pools and MKL's one-time buffers
        f = SpdFactor(A, backend=backend)
        f.solve(b)
        f.free()
    before = _resident_bytes()
    for _ in range(12):
        f = SpdFactor(A, backend=backend)
        x = f.solve(b)
        f.free()
    growth_mb = (_resident_bytes() - before) / 1e6
    np.testing.assert_allclose(A @ x, b, atol=1e-6)
    assert growth_mb < 80, f"{growth_mb:.0f} MB kept over 12 factor/free cycles"


@pytest.mark.parametrize("backend", available_backends())
def test_an_indefinite_matrix_is_refused_by_every_backend(backend):
    """Both backends refuse what is not SPD (the FEM solver then falls back on the projected stiffness):
    SuperLU used to factor an indefinite stiffness, so the baseline ran another algorithm than PARDISO."""
    A = _spd(300, 3)
    eigenvalues = np.linalg.eigvalsh(A.toarray())
    shift = 2.0 * float(eigenvalues[0])
    assert (eigenvalues < shift).any() and (eigenvalues > shift).any()  # A - shift I is indefinite
    with pytest.raises(SolverError, match="positive definite|factorisation failed"):
        SpdFactor((A - shift * sp.eye(300)).tocsr(), backend=backend)
    SpdFactor((A + shift * sp.eye(300)).tocsr(), backend=backend)  # the same sparsity, definite: factored


def test_load_backend_loads_every_library_a_factorisation_needs():
    # a fresh interpreter: after load_backend, factoring and solving a real system loads no other shared
    # object (what lets animate run its second thread beside the set-up without two threads loading at once)
    import subprocess
    import sys

    code = (
        "import numpy as np, scipy.sparse as sp\n"
        "from facecap.mesh.factor_spd import SpdFactor, load_backend\n"
        "libs = lambda: {l.split()[-1] for l in open('/proc/self/maps') if '.so' in l}\n"
        "before = libs()\n"
        "print(load_backend('auto'))\n"
        "loaded = libs()\n"
        "A = sp.diags([4.0] * 300).tocsr() + sp.eye(300, k=1) + sp.eye(300, k=-1)\n"
        "x = SpdFactor(A).solve(np.ones((300, 4)))\n"
        "print(sorted(libs() - loaded))\n"
        "print(any('mkl_core' in p for p in loaded - before))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "pardiso"
    assert out[1] == "[]", f"libraries loaded by the first factorisation after load_backend: {out[1]}"
    assert out[2] == "True"  # MKL's computational library, which import alone does not load


def test_load_backend_refuses_unknown_names():
    assert load_backend("scipy") == "scipy"
    with pytest.raises(InputError):
        load_backend("cholmod")
