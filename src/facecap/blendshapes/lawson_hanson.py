"""Batched Lawson-Hanson non-negative least squares on Gram matrices, continued in place."""

from __future__ import annotations

import numpy as np

from ..errors import SolverError
from ..typing import BoolArray, FloatArray, IntArray

__all__ = ["lawson_hanson", "SharedGram", "BorderedGram", "solve_on_passive", "refine_on_passive"]

_EPS = float(np.finfo(np.float64).eps)


# --------------------------------------------------------------------------- the kernel
#
# Batched Lawson-Hanson on the Gram matrix. Each of n problems ("rows") has its own
# passive set P (the variables allowed to be non-zero) and keeps a factor R with
# R G_PP R^T = I, so that the least-squares solution on P is R^T R c. R is stored as
# (n, K, K): row s of R (a "slot") is filled when a variable enters P, columns are the
# variables. Adding a variable borders the factor (one O(pK) update); removing one is a
# Householder reflection that moves the variable's column onto the last used slot,
# which is then dropped. No system is ever re-factorised from scratch.


class SharedGram:
    """The Gram matrix ``G = B^T B`` of one basis shared by every problem (row), for :func:`lawson_hanson`.

    Parameters
    ----------
    G : (K, K) float64 array
        Symmetric positive semi-definite, in the squared units of the basis.
    """

    def __init__(self, G: FloatArray) -> None:
        self.G = G
        self.d = np.diag(G).copy()

    def times(self, W: FloatArray, rows: IntArray) -> FloatArray:
        """``W @ G`` for the rows ``rows`` (``W`` holds those rows)."""
        return W @ self.G

    def column(self, rows: IntArray, j: IntArray) -> FloatArray:
        """(m, K): column ``j[i]`` of row ``rows[i]``'s Gram matrix."""
        return self.G[j]

    def diag(self, rows: IntArray, j: IntArray) -> FloatArray:
        """(m,): ``G[j[i], j[i]]`` for row ``rows[i]``."""
        return self.d[j]


class BorderedGram:
    """Per-row Gram matrices ``[[Gs, a_t], [a_t^T, g_t]]`` (K = k + 1), for :func:`lawson_hanson`.

    A block shared by every row, bordered by one basis vector that differs from row to row (the
    scan planner's candidate frame), without forming the n matrices.

    Parameters
    ----------
    Gs : (k, k) float64 array
        The shared block: Gram matrix of the k shared basis vectors.
    a : (n, k) float64 array
        Row t's extra basis vector's products with the shared ones.
    g : (n,) float64 array
        Row t's extra basis vector's squared norm.
    """

    def __init__(self, Gs: FloatArray, a: FloatArray, g: FloatArray) -> None:
        self.Gs, self.a, self.g = Gs, a, g
        self.k = Gs.shape[0]
        self.d = np.diag(Gs).copy()

    def times(self, W: FloatArray, rows: IntArray) -> FloatArray:
        """(m, K): ``W[i] @ G_t`` for ``t = rows[i]`` (``W`` holds those rows)."""
        k, a = self.k, self.a[rows]
        out = np.empty_like(W)
        out[:, :k] = W[:, :k] @ self.Gs + W[:, k:] * a
        out[:, k] = np.einsum("tk,tk->t", W[:, :k], a) + W[:, k] * self.g[rows]
        return out

    def column(self, rows: IntArray, j: IntArray) -> FloatArray:
        """(m, K): column ``j[i]`` of row ``rows[i]``'s Gram matrix."""
        k = self.k
        out = np.empty((rows.size, k + 1))
        last = j == k
        if k:
            jj = np.minimum(j, k - 1)
            out[:, :k] = np.where(last[:, None], self.a[rows], self.Gs[jj])
            out[:, k] = np.where(last, self.g[rows], self.a[rows, jj])
        else:
            out[:, 0] = self.g[rows]
        return out

    def diag(self, rows: IntArray, j: IntArray) -> FloatArray:
        """(m,): entry ``(j[i], j[i])`` of row ``rows[i]``'s Gram matrix."""
        if not self.k:
            return self.g[rows]
        return np.where(j == self.k, self.g[rows], self.d[np.minimum(j, self.k - 1)])


_Gram = SharedGram | BorderedGram


def _factor_rows(R: FloatArray, rows: IntArray, pm: int) -> FloatArray:
    """``R[rows, :pm]``: a view when ``rows`` is every row, else a copy."""
    if rows.size == R.shape[0]:
        return R[:, :pm]
    return R[rows, :pm]


def solve_on_passive(R: FloatArray, count: IntArray, rows: IntArray, C: FloatArray) -> FloatArray:
    """The least-squares solution ``R^T R c`` on each row's passive set, from its factor.

    Parameters
    ----------
    R : (n, K, K) float64 array
        Each row's factor, ``R G_PP R^T = I`` (rows ``>= count`` zero), as :func:`lawson_hanson` keeps it.
    count : (n,) int64 array
        Each row's passive-set size.
    rows : (m,) int64 array
        The rows to solve.
    C : (m, K) float64 array
        Their right-hand sides ``B^T x`` (or any vector to apply ``G_PP^-1`` to).

    Returns
    -------
    (m, K) float64 array
        ``G_PP^-1 c_P`` on each passive set, zero off it (the factor's columns there are zero).
    """
    pm = int(count[rows].max()) if rows.size else 0
    if pm == 0:
        return np.zeros((rows.size, C.shape[1]))
    Rr = _factor_rows(R, rows, pm)
    return np.einsum("tsk,ts->tk", Rr, np.einsum("tsk,tk->ts", Rr, C))


def _downdate(R: FloatArray, count: IntArray, P: BoolArray, rows: IntArray, q: IntArray) -> None:
    """Remove variable ``q[i]`` from the passive set and factor of row ``rows[i]``, in place.

    A Householder reflection Q with ``Q (R e_q) = -+||R e_q|| e_m`` (m the last used
    slot) gives ``(QR)^T (QR) = R^T R`` with column q living in slot m alone; dropping
    slot m leaves ``R'^T R' = H - H e_q e_q^T H / H_qq``, the inverse of G without q.
    """
    m = rows.size
    ar = np.arange(m)
    pm = int(count[rows].max())
    Rb = R[rows, :pm]
    col = Rb[ar, :, q]
    nrm = np.sqrt(np.einsum("ts,ts->t", col, col))
    nrm[nrm == 0.0] = 1.0
    v = col / nrm[:, None]
    last = count[rows] - 1
    sigma = np.where(v[ar, last] >= 0.0, 1.0, -1.0)
    v[ar, last] += sigma
    vv = np.einsum("ts,ts->t", v, v)
    vR = np.einsum("ts,tsk->tk", v, Rb)
    Rb -= (2.0 / vv)[:, None, None] * v[:, :, None] * vR[:, None, :]
    Rb[ar, last, :] = 0.0
    Rb[ar, :, q] = 0.0
    R[rows, :pm] = Rb
    count[rows] -= 1
    P[rows, q] = False


def _add(
    gram: _Gram,
    W: FloatArray,
    P: BoolArray,
    R: FloatArray,
    count: IntArray,
    rows: IntArray,
    j: IntArray,
    gj: FloatArray,
) -> tuple[IntArray, FloatArray, BoolArray]:
    """Border the factors of ``rows`` with variable ``j`` (gradient ``gj`` > 0), in place.

    Returns the rows that took the variable, their least-squares solution on the
    enlarged passive set (the new variable is positive there, ``gj / d``), and a mask
    over the input rows of those refused because the variable is (numerically) in the
    span of their passive set.
    """
    K = W.shape[1]
    m = rows.size
    pm = int(count[rows].max())
    a = gram.column(rows, j)  # (m, K): column j of the symmetric G, per row
    gjj = gram.diag(rows, j)
    if pm:
        Rr = _factor_rows(R, rows, pm)
        l = np.einsum("tsk,tk->ts", Rr, a)
        d = gjj - np.einsum("ts,ts->t", l, l)
    else:
        d = np.array(gjj, dtype=np.float64)
    refused = ~(d > 16.0 * K * _EPS * gjj)
    if refused.any():
        keep = ~refused
        rows, j, gj, d = rows[keep], j[keep], gj[keep], d[keep]
        if pm:
            Rr, l = Rr[keep], l[keep]
        m = rows.size
    s = np.sqrt(d)
    rho = np.einsum("tsk,ts->tk", Rr, l) if pm else np.zeros((m, K))
    rho /= -s[:, None]
    ar = np.arange(m)
    rho[ar, j] = 1.0 / s
    R[rows, count[rows], :] = rho
    count[rows] += 1
    P[rows, j] = True
    Z = W[rows] + rho * (gj / s)[:, None]
    return rows, Z, refused


def _settle(
    C: FloatArray,
    W: FloatArray,
    P: BoolArray,
    R: FloatArray,
    count: IntArray,
    rows: IntArray,
    Z: FloatArray,
) -> int:
    """Lawson-Hanson inner loop: move from the feasible W toward the LS solution Z.

    While Z has a non-positive passive entry, step from W toward Z as far as
    feasibility allows, drop the variables that reach zero and re-solve. Returns
    the number of variables dropped.
    """
    dropped = 0
    while True:
        neg = P[rows] & (Z <= 0.0)
        bad = neg.any(axis=1)
        if not bad.all():
            W[rows[~bad]] = Z[~bad]
        if not bad.any():
            return dropped
        rows, Z, neg = rows[bad], Z[bad], neg[bad]
        Wb = W[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(neg, Wb / (Wb - Z), np.inf)
        q = np.argmin(ratio, axis=1)
        ar = np.arange(rows.size)
        alpha = ratio[ar, q]
        alpha = np.where(np.isfinite(alpha), alpha, 0.0)
        Wn = Wb + alpha[:, None] * (Z - Wb)
        Wn[ar, q] = 0.0
        drop = P[rows] & (Wn <= 0.0)
        Wn[~P[rows] | drop] = 0.0
        W[rows] = Wn
        dropped += int(drop.sum())
        while drop.any():
            idx = np.flatnonzero(drop.any(axis=1))
            qq = np.argmax(drop[idx], axis=1)
            _downdate(R, count, P, rows[idx], qq)
            drop[idx, qq] = False
        Z = solve_on_passive(R, count, rows, C[rows])
        Z[~P[rows]] = 0.0


def lawson_hanson(
    gram: _Gram,
    C: FloatArray,
    W: FloatArray,
    P: BoolArray,
    R: FloatArray,
    count: IntArray,
    tolg: FloatArray,
    *,
    rows: IntArray | None = None,
    max_iter: int | None = None,
) -> int:
    """Batched Lawson-Hanson NNLS on the Gram matrix, continued in place.

    Parameters
    ----------
    gram : SharedGram or BorderedGram
        The Gram matrix ``B^T B`` (shared, or bordered per problem).
    C : (n, K) float64 array
        ``B^T x`` per problem.
    W, P, R, count : the state, modified in place
        (n, K) weights, (n, K) passive masks, (n, K, K) factors and (n,) passive
        counts. On entry each row must be a Lawson-Hanson point: W the
        least-squares solution on P, positive there, zero elsewhere, and R with
        ``R G_PP R^T = I`` (rows ``>= count`` zero). All zero is such a point.
    tolg : (n, K) float64 array
        A gradient ``c - G w`` above this makes its variable enter.
    rows : (m,) int64 array, optional
        Only these problems are advanced (default all).
    max_iter : int, optional
        Limit on variables entering per problem; default ``3 K + 20``.

    Returns
    -------
    int
        Outer iterations taken.
    """
    n, K = C.shape
    rows = np.arange(n) if rows is None else rows
    blocked = np.zeros((n, K), dtype=bool)
    max_iter = 3 * K + 20 if max_iter is None else max_iter
    for it in range(max_iter):
        if rows.size == 0:
            return it
        grad = C[rows] - gram.times(W[rows], rows)
        cand = ~P[rows] & ~blocked[rows] & (grad > tolg[rows])
        has = cand.any(axis=1)
        rows = rows[has]
        if rows.size == 0:
            return it
        grad, cand = grad[has], cand[has]
        j = np.argmax(np.where(cand, grad, -np.inf), axis=1)
        gj = grad[np.arange(rows.size), j]
        took, Z, refused = _add(gram, W, P, R, count, rows, j, gj)
        if refused.any():
            blocked[rows[refused], j[refused]] = True
        if took.size:
            blocked[took] = False
            _settle(C, W, P, R, count, took, Z)
    raise SolverError(f"non-negative least squares did not converge in {max_iter} iterations")


def refine_on_passive(
    B: FloatArray, XT: FloatArray, W: FloatArray, P: BoolArray, R: FloatArray, count: IntArray
) -> FloatArray:
    """One step of iterative refinement of NNLS weights, the residual taken in the original space.

    The Gram solve leaves about ``cond(G) eps``; a step with the residual ``x - B w`` computed from
    the basis itself (not through G) makes it orthogonal to the passive bases to the precision of
    the coordinates. The passive sets stay as they are.

    Parameters
    ----------
    B : (D, K) float64 array
        The basis, one column per variable.
    XT : (n, D) float64 array
        The targets, one per row.
    W : (n, K) float64 array
        Weights from :func:`lawson_hanson` (not modified).
    P, R, count : (n, K) bool, (n, K, K) float64, (n,) int64 arrays
        Their passive sets and factors.

    Returns
    -------
    (n, K) float64 array
        The refined weights, non-negative, zero off the passive sets.
    """
    Cr = (XT - W @ B.T) @ B
    dW = solve_on_passive(R, count, np.arange(W.shape[0]), Cr)
    dW[~P] = 0.0
    return np.maximum(W + dW, 0.0)
