"""Tests for facecap.blendshapes.lawson_hanson."""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from facecap.blendshapes.lawson_hanson import (BorderedGram, SharedGram, lawson_hanson, refine_on_passive,
                                               solve_on_passive)


def _state(n: int, K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return np.zeros((n, K)), np.zeros((n, K), dtype=bool), np.zeros((n, K, K)), np.zeros(n, dtype=np.int64)


def test_matches_scipy_nnls_on_many_targets_at_once():
    rng = np.random.default_rng(2)
    D, K, n = 30, 8, 25
    B = rng.normal(size=(D, K))
    X = rng.normal(size=(n, D))
    G, C = B.T @ B, X @ B
    W, P, R, count = _state(n, K)
    lawson_hanson(SharedGram(G), C, W, P, R, count, np.full((n, K), 1e-12))
    for t in range(n):
        np.testing.assert_allclose(W[t], nnls(B, X[t])[0], atol=1e-10)
    assert np.array_equal(P, W > 0) and np.array_equal(count, P.sum(axis=1))
    # the factor inverts each passive Gram block: solve_on_passive is the least squares there
    Z = solve_on_passive(R, count, np.arange(n), C)
    for t in range(n):
        p = P[t]
        np.testing.assert_allclose(Z[t, p], np.linalg.solve(G[np.ix_(p, p)], C[t, p]), rtol=1e-9, atol=1e-12)
        assert np.all(Z[t, ~p] == 0.0)
    # refinement with the residual in the original space keeps the solution
    np.testing.assert_allclose(refine_on_passive(B, X, W, P, R, count), W, atol=1e-12)


def test_the_bordered_gram_is_the_dense_one():
    rng = np.random.default_rng(3)
    D, k, n = 20, 4, 6
    shared = rng.normal(size=(D, k))
    extra = rng.normal(size=(n, D))
    gram = BorderedGram(shared.T @ shared, extra @ shared, np.einsum("nd,nd->n", extra, extra))
    dense = [np.column_stack([shared, extra[t]]).T @ np.column_stack([shared, extra[t]]) for t in range(n)]
    rows = np.arange(n)
    W = rng.normal(size=(n, k + 1))
    np.testing.assert_allclose(gram.times(W, rows), [W[t] @ dense[t] for t in rows], rtol=1e-12)
    j = np.array([0, 4, 2, 4, 1, 3])
    np.testing.assert_allclose(gram.column(rows, j), [dense[t][:, j[t]] for t in rows], rtol=1e-12)
    np.testing.assert_allclose(gram.diag(rows, j), [dense[t][j[t], j[t]] for t in rows], rtol=1e-12)
    # and the kernel on it solves each bordered problem as SciPy does
    X = rng.normal(size=(n, D))
    C = np.column_stack([X @ shared, np.einsum("nd,nd->n", X, extra)])
    Wb, P, R, count = _state(n, k + 1)
    lawson_hanson(gram, C, Wb, P, R, count, np.full((n, k + 1), 1e-12))
    for t in range(n):
        np.testing.assert_allclose(Wb[t], nnls(np.column_stack([shared, extra[t]]), X[t])[0], atol=1e-10)
