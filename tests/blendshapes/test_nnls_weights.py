"""Tests for facecap.blendshapes.nnls_weights: an analytic case, then scipy.optimize.nnls column by column."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

from facecap.blendshapes import NnlsWeights, nnls_weights
from facecap.errors import InputError


def _kkt_violation(B: np.ndarray, x: np.ndarray, w: np.ndarray) -> float:
    """Largest violation of the NNLS optimality conditions, relative to |B|_2 |x|.

    With g = B^T (x - B w): w >= 0, g <= 0 where w = 0, g = 0 where w > 0.
    """
    g = B.T @ (x - B @ w)
    worst = max(float(np.max(np.where(w > 0, np.abs(g), np.maximum(g, 0.0)))), float(-min(w.min(), 0.0)))
    return worst / (np.linalg.norm(B, 2) * np.linalg.norm(x))


def _check_against_scipy(B: np.ndarray, X: np.ndarray, *, unique: bool) -> None:
    W, res = nnls_weights(B, X)
    assert W.shape == (B.shape[1], X.shape[1]) and res.shape == (X.shape[1],)
    assert np.all(W >= 0)
    for t in range(X.shape[1]):
        x = X[:, t]
        w_ref, r_ref = nnls(B, x, maxiter=50 * B.shape[1])
        scale = np.linalg.norm(x)
        assert abs(res[t] - r_ref) <= 1e-10 * scale
        assert abs(res[t] - np.linalg.norm(B @ W[:, t] - x)) <= 1e-12 * scale
        # the fit B w is unique even when w is not
        np.testing.assert_allclose(B @ W[:, t], B @ w_ref, rtol=0, atol=1e-9 * scale)
        assert _kkt_violation(B, x, W[:, t]) <= 1e-10
        if unique:
            np.testing.assert_allclose(W[:, t], w_ref, rtol=0, atol=1e-8 * max(1.0, np.abs(w_ref).max()))


def test_analytic_two_bases() -> None:
    # x = (2, 1, -1): the first basis takes the mean 1.5 of the first two entries,
    # the second would need a negative weight and stays at 0
    B = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    out = nnls_weights(B, np.array([2.0, 1.0, -1.0]))
    assert isinstance(out, NnlsWeights)
    np.testing.assert_allclose(out.weights, [1.5, 0.0], atol=1e-15)
    assert out.residuals == pytest.approx(np.sqrt(0.25 + 0.25 + 1.0), rel=1e-14)
    # a target inside the cone is reproduced exactly; one opposite every basis gets w = 0
    W, res = nnls_weights(B, np.array([[3.0, -1.0], [3.0, -1.0], [2.0, -4.0]]))
    np.testing.assert_allclose(W, [[3.0, 0.0], [2.0, 0.0]], atol=1e-14)
    np.testing.assert_allclose(res, [0.0, np.sqrt(18.0)], atol=1e-13)


@pytest.mark.parametrize("K", [1, 5, 30, 60])
def test_full_rank_matches_scipy(K: int) -> None:
    rng = np.random.default_rng(K)
    D, T = 150, 120
    B = rng.normal(size=(D, K))
    X = rng.normal(size=(D, T)) + B @ rng.normal(size=(K, T))  # about half the weights active
    _check_against_scipy(B, X, unique=True)


def test_recovers_known_weights_inside_the_cone() -> None:
    rng = np.random.default_rng(1)
    B = rng.random((90, 12))
    W_true = rng.random((12, 200)) * (rng.random((12, 200)) < 0.6)
    W, res = nnls_weights(B, B @ W_true)
    np.testing.assert_allclose(W, W_true, atol=1e-10)
    assert res.max() < 1e-11 * np.linalg.norm(B @ W_true, axis=0).max()


def test_rank_deficient_bases_match_scipy() -> None:
    rng = np.random.default_rng(2)
    B = rng.normal(size=(60, 6)) @ rng.random((6, 14))  # 14 bases spanning 6 dimensions
    X = B @ rng.random((14, 80)) + rng.normal(size=(60, 80))
    _check_against_scipy(B, X, unique=False)


def test_repeated_and_scaled_columns_match_scipy() -> None:
    rng = np.random.default_rng(3)
    B = rng.normal(size=(45, 10))
    B[:, 1] = B[:, 0]
    B[:, 4] = 2.5 * B[:, 3]
    B[:, 7] = B[:, 5] + B[:, 6]
    X = rng.normal(size=(45, 100)) + B @ rng.random((10, 100))
    _check_against_scipy(B, X, unique=False)


def test_ill_conditioned_marker_bases_far_from_the_origin() -> None:
    """Bases that are frames of a smooth take 1.5 m from the origin are nearly parallel
    (cond(B) ~ 7e4, cond(G) ~ 5e9): the normal equations alone lose ~10 digits."""
    rng = np.random.default_rng(4)
    T, M = 160, 30
    t = np.linspace(0.0, 4.0, T)
    layout = rng.normal(size=(M, 3)) * 40.0 + [300.0, -200.0, 1500.0]
    modes = rng.normal(size=(4, M, 3)) * 3.0
    amps = np.stack([np.sin(2 * np.pi * f * t + p) for f, p in zip([0.3, 0.5, 0.7, 1.1], rng.uniform(0, 6, 4))], 1)
    take = layout + np.einsum("tk,kmc->tmc", amps, modes) + rng.normal(size=(T, M, 3)) * 0.1
    X = take.reshape(T, -1).T
    B = X[:, rng.choice(T, 20, replace=False)]
    assert np.linalg.cond(B) > 1e4
    _check_against_scipy(B, X, unique=False)


def test_one_target_and_refinement_off() -> None:
    rng = np.random.default_rng(5)
    B = rng.normal(size=(20, 4))
    x = rng.normal(size=20)
    w, r = nnls_weights(B, x, refine=False)
    w_ref, r_ref = nnls(B, x)
    assert w.shape == (4,) and isinstance(r, float)
    np.testing.assert_allclose(w, w_ref, atol=1e-12)
    assert r == pytest.approx(r_ref, rel=1e-12)


def test_rejects_bad_input() -> None:
    B = np.ones((6, 2))
    with pytest.raises(InputError, match="targets"):
        nnls_weights(B, np.ones((5, 3)))
    with pytest.raises(InputError, match="bases"):
        nnls_weights(np.ones(6), np.ones(6))
    with pytest.raises(InputError, match="NaN"):
        nnls_weights(B, np.full((6, 2), np.nan))
    with pytest.raises(InputError, match="targets"):
        nnls_weights(B, np.ones((6, 0)))
    with pytest.raises(InputError, match="tol"):
        nnls_weights(B, np.ones(6), tol=-1.0)
    with pytest.raises(InputError, match="max_iter"):
        nnls_weights(B, np.ones(6), max_iter=0)
