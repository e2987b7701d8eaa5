"""The compiled normal-equations product equals scipy's composition of the same sparse matrices."""

import numpy as np
import scipy.sparse as sp

from facecap.sfs.camera_blur import camera_blur
from facecap.sfs.normal_product import FrameNormalProduct, OneRingPattern, compile_blur
from facecap.sfs.solve_heights import _one_ring_average
from facecap.sfs.vertex_gradient import vertex_gradient

from sfs_patch import dome_patch


def _setup(blurred, seed=0):
    V, F = dome_patch(40, 30)
    r = V.shape[0]
    rng = np.random.default_rng(seed)
    order = rng.permutation(r)  # a scattered numbering, as a refined scan has
    V = V[order]
    F = np.argsort(order)[F]
    G = vertex_gradient(V, F)
    S = _one_ring_average(G) * np.sqrt(2.0)
    b = rng.normal(size=(2, r, 3))
    w = rng.uniform(0.0, 1.0, size=(2, r))
    blur = [camera_blur(V[:, :2] / 0.2 + rng.normal(scale=0.1, size=(r, 2)), rng.uniform(0.5, 1.5, r), 0.7)
            for _ in range(2)] if blurred else None
    return G, S, b, w, blur, rng


def _scipy_product(G, S, b, w, blur, x):
    g = G.apply(x)
    q = np.zeros_like(g)
    for c in range(b.shape[0]):
        u = np.sum(b[c] * g, axis=1)
        v = w[c] * (u if blur is None else blur[c] @ u)
        q += (v if blur is None else blur[c].T @ v)[:, None] * b[c]
    return G.x.T @ q[:, 0] + G.y.T @ q[:, 1] + G.z.T @ q[:, 2] + S.T @ (S @ x)


def test_the_product_matches_scipy_with_and_without_the_blur():
    for blurred in (False, True):
        G, S, b, w, blur, rng = _setup(blurred)
        product = FrameNormalProduct(OneRingPattern(G, S), b, w, None if blur is None else compile_blur(blur))
        x = rng.normal(size=b.shape[1])
        expected = _scipy_product(G, S, b, w, blur, x)
        # the blur is kept in float32 (its passes are bound by memory): 1e-7 relative
        assert np.abs(product(x) - expected).max() <= (2e-7 if blurred else 1e-12) * np.abs(expected).max()


def test_the_product_is_symmetric_and_positive():
    G, S, b, w, blur, rng = _setup(True, seed=3)
    product = FrameNormalProduct(OneRingPattern(G, S), b, w, compile_blur(blur))
    x, y = rng.normal(size=(2, b.shape[1]))
    assert abs(x @ product(y) - y @ product(x)) < 1e-10 * abs(x @ product(y))
    assert x @ product(x) > 0


def test_a_one_ring_operator_with_entries_outside_the_gradient_pattern_is_kept():
    G, S, b, w, _, rng = _setup(False)
    r = b.shape[1]
    extra = sp.csr_matrix(([0.5], ([0], [r - 1])), shape=(r, r))  # a pair the gradient never couples
    product = FrameNormalProduct(OneRingPattern(G, S + extra), b, w, None)
    x = rng.normal(size=r)
    assert np.allclose(product(x), _scipy_product(G, S + extra, b, w, None, x), rtol=0, atol=1e-10)
