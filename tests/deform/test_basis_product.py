import numpy as np
import pytest

from facecap._mkl import mkl_blas
from facecap.deform.basis_product import BasisProduct
from facecap.deform.thin_shell import ThinShellSolver
from facecap.errors import InputError

HAVE_MKL = mkl_blas() is not None


def _shell_like_weights(n, k, seed):
    """Smooth-ish weights with a partition of unity and some negative lobes, like a thin-shell basis."""
    rng = np.random.default_rng(seed)
    W = rng.random((n, k)) ** 4
    W /= W.sum(axis=1, keepdims=True)
    return W - 0.02 * rng.random((n, k)) + 0.02 / 2


def _reference(W, D, rest):
    return np.einsum("nk,fka->fna", W.astype(np.float64), D.astype(np.float64)) + rest


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("frames", [1, 5, 32])
def test_float32_product_matches_float64_einsum(workers, frames):
    # 2500 vertices in blocks of 256: a partial last block and many blocks per worker
    W = _shell_like_weights(2500, 17, 0)
    rng = np.random.default_rng(1)
    D = rng.normal(scale=5.0, size=(frames, 17, 3)).astype(np.float32)
    rest = rng.normal(scale=80.0, size=(2500, 3)).astype(np.float32)
    out = np.full((frames, 2500, 3), np.nan, np.float32)
    BasisProduct(W, workers=workers, block_vertices=256).apply_into(D, rest, out)
    np.testing.assert_allclose(out, _reference(W, D, rest), rtol=0, atol=1e-4)


def test_numpy_fallback_matches_float64_einsum(monkeypatch):
    import facecap.deform.basis_product as module

    W = _shell_like_weights(1000, 9, 2)
    rng = np.random.default_rng(3)
    D = rng.normal(size=(4, 9, 3)).astype(np.float32)
    rest = np.zeros((1000, 3), np.float32)
    monkeypatch.setattr(module, "mkl_blas", lambda: None)  # what a machine without MKL runs
    product = BasisProduct(W, block_vertices=300)
    assert product.backend == "numpy" and product.workers == 1  # numpy's BLAS threads itself
    out = np.empty((4, 1000, 3), np.float32)
    np.testing.assert_allclose(product.apply_into(D, rest, out), _reference(W, D, rest), atol=1e-5)


@pytest.mark.skipif(not HAVE_MKL, reason="the int16 path runs on MKL's integer GEMM")
def test_int16_product_within_its_error_bound():
    W = _shell_like_weights(3000, 90, 4)
    rng = np.random.default_rng(5)
    D = rng.normal(scale=8.0, size=(16, 90, 3)).astype(np.float32)
    rest = rng.normal(scale=80.0, size=(3000, 3)).astype(np.float32)
    product = BasisProduct(W, precision="int16", block_vertices=512)
    out = np.empty((16, 3000, 3), np.float32)
    err = np.abs(product.apply_into(D, rest, out) - _reference(W, D, rest))
    bound = product.error_bound_mm(float(np.abs(D).max()))
    assert err.max() <= bound + 1e-4  # + float32 rounding of the ~80 mm positions
    assert np.sqrt(np.mean(err**2)) < 2e-4 * float(np.abs(D).max())  # typical error far inside the bound


@pytest.mark.skipif(not HAVE_MKL, reason="the int16 path runs on MKL's integer GEMM")
def test_int16_sums_do_not_overflow_in_the_worst_case():
    # Every weight at its largest allowed magnitude with the same sign, and every
    # displacement at the batch maximum: the int32 sums reach their design limit.
    K = 240
    W = np.full((64, K), 1.0 / K)
    W[1] = 1.0  # a row whose |sum| is K: the scale is limited by the row sum, not the entry
    D = np.full((2, K, 3), 50.0, np.float32)
    D[1] *= -1
    product = BasisProduct(W, precision="int16", workers=1)
    out = np.empty((2, 64, 3), np.float32)
    rest = np.zeros((64, 3), np.float32)
    err = np.abs(product.apply_into(D, rest, out) - _reference(W, D, rest))
    assert err.max() <= product.error_bound_mm(50.0) + 1e-3
    # the invariant itself: |quantised weights| summed over markers, times the largest
    # quantised displacement, stays below 2**31 for every vertex
    assert int(np.abs(product._blocks.astype(np.int64)).sum(axis=1).max()) * 32767 < 2**31


@pytest.mark.skipif(not HAVE_MKL, reason="the int16 path runs on MKL's integer GEMM")
def test_int16_bound_ignores_vertices_that_never_move():
    # rows of zeros are what --unmarked-pieces rigid leaves in the thin-shell weights
    W = _shell_like_weights(400, 20, 9)
    W[::7] = 0.0
    product = BasisProduct(W, precision="int16", block_vertices=128)
    D = np.random.default_rng(10).normal(scale=4.0, size=(3, 20, 3)).astype(np.float32)
    out = np.empty((3, 400, 3), np.float32)
    err = np.abs(product.apply_into(D, np.zeros((400, 3), np.float32), out) - _reference(W, D, 0.0))
    bound = product.error_bound_mm(float(np.abs(D).max()))
    assert np.all(out[:, ::7] == 0.0)
    assert err.max() <= bound + 1e-6 and bound < 1e-3 * float(np.abs(D).max())


@pytest.mark.skipif(not HAVE_MKL, reason="MKL's thread setting")
def test_mkl_threads_of_the_calling_thread_are_restored():
    import ctypes

    from facecap._mkl import locate_mkl_runtime

    get_threads = ctypes.CDLL(locate_mkl_runtime()).MKL_Get_Max_Threads
    before = get_threads()
    W = _shell_like_weights(300, 5, 11)
    BasisProduct(W, workers=1).apply_into(np.ones((2, 5, 3), np.float32), np.zeros((300, 3), np.float32),
                                          np.empty((2, 300, 3), np.float32))
    assert get_threads() == before


@pytest.mark.parametrize("precision", ["float32", "int16"])
def test_nan_displacements_are_refused(precision):
    if precision == "int16" and not HAVE_MKL:
        pytest.skip("the int16 path runs on MKL's integer GEMM")
    product = BasisProduct(_shell_like_weights(50, 4, 12), precision=precision)
    D = np.ones((2, 4, 3), np.float32)
    D[1, 2, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        product.apply_into(D, np.zeros((50, 3), np.float32), np.empty((2, 50, 3), np.float32))


def test_int16_without_mkl_or_too_many_markers_is_a_clear_error(monkeypatch):
    import facecap.deform.basis_product as module

    if HAVE_MKL:
        with pytest.raises(InputError, match="at most 240 markers"):
            BasisProduct(np.ones((10, 241)), precision="int16")
    monkeypatch.setattr(module, "mkl_blas", lambda: None)
    with pytest.raises(InputError, match="needs Intel MKL"):
        BasisProduct(np.ones((10, 3)), precision="int16")


def test_vertex_rows_equal_an_indexed_copy():
    W = _shell_like_weights(300, 6, 14)
    rows = np.random.default_rng(15).integers(0, 300, size=700)
    D = np.random.default_rng(16).normal(size=(3, 6, 3)).astype(np.float32)
    rest = np.zeros((700, 3), np.float32)
    indexed = BasisProduct(W, vertex_rows=rows, block_vertices=128)
    copied = BasisProduct(W[rows], block_vertices=128)
    assert indexed.n_vertices == 700
    np.testing.assert_array_equal(indexed.apply_into(D, rest, np.empty((3, 700, 3), np.float32)),
                                  copied.apply_into(D, rest, np.empty((3, 700, 3), np.float32)))
    with pytest.raises(InputError, match="vertex_rows"):
        BasisProduct(W, vertex_rows=np.array([0, 300]))


@pytest.mark.parametrize("precision", ["float32", "int16"])
def test_dense_weights_round_trip(precision):
    if precision == "int16" and not HAVE_MKL:
        pytest.skip("the int16 path runs on MKL's integer GEMM")
    W = _shell_like_weights(700, 12, 6)
    product = BasisProduct(W, precision=precision, block_vertices=128)
    tolerance = 1e-7 if precision == "float32" else np.abs(W).sum(axis=1).max() / 65000
    np.testing.assert_allclose(product.dense_weights(), W, atol=tolerance)


@pytest.mark.parametrize("precision", ["float32", "int16"])
def test_weight_rows_are_rows_of_the_dense_weights(precision):
    if precision == "int16" and not HAVE_MKL:
        pytest.skip("the int16 path runs on MKL's integer GEMM")
    W = _shell_like_weights(300, 6, 14)
    rows = np.random.default_rng(17).integers(0, 700, size=50)
    product = BasisProduct(W, precision=precision, block_vertices=128,
                           vertex_rows=np.random.default_rng(18).integers(0, 300, size=700))
    np.testing.assert_array_equal(product.weight_rows(rows), product.dense_weights()[rows])
    with pytest.raises(InputError, match="vertices"):
        product.weight_rows(np.array([700]))


def test_bad_arguments_are_named():
    W = np.ones((10, 3))
    with pytest.raises(InputError, match="weights"):
        BasisProduct(np.ones(5))
    with pytest.raises(InputError, match="NaN"):
        BasisProduct(np.full((4, 2), np.nan))
    with pytest.raises(InputError, match="precision"):
        BasisProduct(W, precision="float16")
    product = BasisProduct(W)
    with pytest.raises(InputError, match="marker_displacements"):
        product.apply_into(np.zeros((2, 4, 3)), np.zeros((10, 3)), np.empty((2, 10, 3), np.float32))
    with pytest.raises(InputError, match="out"):
        product.apply_into(np.zeros((2, 3, 3)), np.zeros((10, 3)), np.empty((2, 10, 3), np.float64))


@pytest.mark.skipif(not HAVE_MKL, reason="the int16 path runs on MKL's integer GEMM")
def test_thin_shell_int16_agrees_with_float32():
    u, v = np.meshgrid(np.linspace(0, 100, 30), np.linspace(0, 100, 30))
    V = np.stack([u.ravel(), v.ravel(), 0.003 * (u.ravel() - 50) ** 2], axis=1)
    a = (np.arange(29)[:, None] * 30 + np.arange(29)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + 30], 1), np.stack([a + 1, a + 31, a + 30], 1)])
    c = np.random.default_rng(7).choice(len(V), 40, replace=False)
    d = np.random.default_rng(8).normal(scale=4.0, size=(6, 40, 3))
    exact = ThinShellSolver(V, F, c).displacements(d)
    fixed = ThinShellSolver(V, F, c, precision="int16")
    err = np.abs(fixed.displacements(d) - exact).max()
    assert err <= fixed.product.error_bound_mm(float(np.abs(d).max())) + 1e-5
