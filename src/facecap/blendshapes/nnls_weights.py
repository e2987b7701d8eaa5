"""Non-negative least squares for many right-hand sides at once (blendshape weights, eq. 12)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError, SolverError
from ..typing import BoolArray, FloatArray, IntArray

__all__ = ["NnlsWeights", "nnls_weights"]

_EPS = float(np.finfo(np.float64).eps)
_CHUNK_BYTES = 64 * 2**20  # per-chunk size of the (n, K, K) factor array


class NnlsWeights(NamedTuple):
    """Result of :func:`nnls_weights`.

    Attributes
    ----------
    weights : (K, T) float64 array, or (K,) for a single target
        Non-negative weights; ``bases @ weights`` is the fit.
    residuals : (T,) float64 array, or float for a single target
        Euclidean norm of ``bases @ weights - targets`` per target, in the
        units of the inputs.
    """

    weights: FloatArray
    residuals: FloatArray | float


# --------------------------------------------------------------------------- the kernel
#
# Batched Lawson-Hanson on the Gram matrix. Each of n problems ("rows") has its own
# passive set P (the variables allowed to be non-zero) and keeps a factor R with
# R G_PP R^T = I, so that the least-squares solution on P is R^T R c. R is stored as
# (n, K, K): row s of R (a "slot") is filled when a variable enters P, columns are the
# variables. Adding a variable borders the factor (one O(pK) update); removing one is a
# Householder reflection that moves the variable's column onto the last used slot,
# which is then dropped. No system is ever re-factorised from scratch.


def _gradient_tolerance(diag_G: FloatArray, target_sq_norms: FloatArray, tol: float) -> FloatArray:
    """(n, K) threshold above which a gradient ``b_i . r`` counts as positive."""
    return tol * np.sqrt(np.maximum(target_sq_norms, 0.0))[:, None] * np.sqrt(np.maximum(diag_G, 0.0))[None, :]


class _SharedGram:
    """The Gram matrix G (K, K) of one basis shared by all rows."""

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
        return self.d[j]


class _BorderedGram:
    """Per-row Gram matrices ``[[Gs, a_t], [a_t^T, g_t]]`` (K = k + 1): a shared block
    Gs (k, k) bordered by one basis that differs from row to row (a candidate frame)."""

    def __init__(self, Gs: FloatArray, a: FloatArray, g: FloatArray) -> None:
        self.Gs, self.a, self.g = Gs, a, g
        self.k = Gs.shape[0]
        self.d = np.diag(Gs).copy()

    def times(self, W: FloatArray, rows: IntArray) -> FloatArray:
        k, a = self.k, self.a[rows]
        out = np.empty_like(W)
        out[:, :k] = W[:, :k] @ self.Gs + W[:, k:] * a
        out[:, k] = np.einsum("tk,tk->t", W[:, :k], a) + W[:, k] * self.g[rows]
        return out

    def column(self, rows: IntArray, j: IntArray) -> FloatArray:
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
        if not self.k:
            return self.g[rows]
        return np.where(j == self.k, self.g[rows], self.d[np.minimum(j, self.k - 1)])


_Gram = _SharedGram | _BorderedGram


def _factor_rows(R: FloatArray, rows: IntArray, pm: int) -> FloatArray:
    """``R[rows, :pm]``: a view when ``rows`` is every row, else a copy."""
    if rows.size == R.shape[0]:
        return R[:, :pm]
    return R[rows, :pm]


def _ls_on_passive(R: FloatArray, count: IntArray, rows: IntArray, C: FloatArray) -> FloatArray:
    """(m, K) least-squares solution ``R^T R c`` on each row's passive set (zero elsewhere)."""
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
        Z = _ls_on_passive(R, count, rows, C[rows])
        Z[~P[rows]] = 0.0


def _lawson_hanson(
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
    gram : _SharedGram or _BorderedGram
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


def _solve_gram(
    G: FloatArray, C: FloatArray, target_sq_norms: FloatArray, tol: float, max_iter: int | None
) -> tuple[FloatArray, BoolArray, FloatArray, IntArray]:
    """Solve from scratch; returns (W, P, R, count)."""
    n, K = C.shape
    W = np.zeros((n, K))
    P = np.zeros((n, K), dtype=bool)
    R = np.zeros((n, K, K))
    count = np.zeros(n, dtype=np.int64)
    tolg = _gradient_tolerance(np.diag(G), target_sq_norms, tol)
    _lawson_hanson(_SharedGram(G), C, W, P, R, count, tolg, max_iter=max_iter)
    return W, P, R, count


def _refine(
    B: FloatArray, XT: FloatArray, W: FloatArray, P: BoolArray, R: FloatArray, count: IntArray
) -> FloatArray:
    """One step of iterative refinement of ``W`` (n, K) with the residual of ``XT`` (n, D)
    taken in the original space (not through G); the passive sets stay as they are."""
    Cr = (XT - W @ B.T) @ B
    dW = _ls_on_passive(R, count, np.arange(W.shape[0]), Cr)
    dW[~P] = 0.0
    return np.maximum(W + dW, 0.0)


# --------------------------------------------------------------------------- public


def _as_matrix(a: Any, name: str) -> FloatArray:
    try:
        A = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a numeric array ({exc})") from None
    if not np.all(np.isfinite(A)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return A


def nnls_weights(
    bases: FloatArray,
    targets: FloatArray,
    *,
    tol: float = 1e-12,
    refine: bool = True,
    max_iter: int | None = None,
) -> NnlsWeights:
    """Non-negative least-squares weights for many targets at once.

    Solves, for every column ``x_t`` of ``targets``,
    ``min_w ||B w - x_t||^2  subject to  w >= 0``, exactly (an active-set
    method, not an iterative approximation), all columns together.

    Parameters
    ----------
    bases : (D, K) float64 array
        The basis vectors as columns, e.g. the stacked marker coordinates
        (D = 3 M, mm) of K blendshapes in the mocap marker space. May be
        rank-deficient or have repeated columns.
    targets : (D, T) or (D,) float64 array
        What to fit, one column per frame, in the units of ``bases``.
    tol : float, default 1e-12
        Optimality tolerance: a variable enters the passive set when its
        gradient ``b_i . r`` exceeds ``tol * ||b_i|| * ||x_t||``. The result
        satisfies the KKT conditions to about this relative accuracy.
    refine : bool, default True
        Finish with one step of iterative refinement in which the residual
        is computed from ``bases`` and ``targets`` themselves rather than
        through the Gram matrix, which restores the digits the normal
        equations lose on ill-conditioned bases (markers far from the
        origin give nearly parallel columns).
    max_iter : int or None, optional
        Limit on the variables entering per target; default ``3 K + 20``.

    Returns
    -------
    NnlsWeights
        ``weights`` (K, T) >= 0 and ``residuals`` (T,), the Euclidean norm of
        each fit's error (a (K,) array and a float for a 1-D ``targets``).

    Raises
    ------
    InputError
        On shapes that do not match, empty arrays, or NaN / inf values.
    SolverError
        If a target does not converge within ``max_iter`` iterations.

    Notes
    -----
    The problem is eq. (12) of Huang et al. 2011 (and the inner solve of
    eq. (3)). With ``G = B^T B`` (K x K) and ``c_t = B^T x_t``, the Lawson-Hanson
    active-set method [1]_ runs on all T problems in lock step: each step adds
    to every unfinished problem's passive set P the variable of largest
    positive gradient ``c - G w``, solves the unconstrained least squares on P
    and, if a weight there went negative, steps back to the feasible boundary
    and drops it. The solves are never done from scratch: each problem keeps
    a factor R with ``R G_PP R^T = I``, bordered in O(pK) when a variable
    enters and updated by one Householder reflection when one leaves, so a
    step costs O(T K^2) array operations for all problems together.
    Because a variable only enters with a positive gradient, and a variable
    whose column is (to rounding) in the span of the passive columns is
    refused, rank-deficient and repeated bases are handled; the weights are
    then one of the optimal solutions (the fit ``B w`` is unique, the
    weights need not be).

    Measured on 1500 frames of 100 markers (D = 300) with K = 30 bases
    (frames of the same take): see ``benchmarks/RESULTS_blendshapes.md``.

    References
    ----------
    .. [1] C. L. Lawson and R. J. Hanson, *Solving Least Squares Problems*,
       SIAM 1995, ch. 23, doi:10.1137/1.9781611971217.
    .. [2] H. Huang, J. Chai, X. Tong and H.-T. Wu, "Leveraging motion
       capture and 3D scanning for high-fidelity facial performance
       acquisition", ACM Trans. Graph. 30(4), 2011, eqs. (3) and (12).

    Examples
    --------
    >>> import numpy as np
    >>> B = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> w, r = nnls_weights(B, np.array([2.0, 1.0, -1.0]))
    >>> w.tolist(), round(r, 6)
    ([1.5, 0.0], 1.224745)
    """
    B = _as_matrix(bases, "bases")
    X = _as_matrix(targets, "targets")
    if B.ndim != 2 or B.shape[0] < 1 or B.shape[1] < 1:
        raise InputError(f"bases: expected a non-empty (D, K) array, got shape {B.shape}")
    single = X.ndim == 1
    if single:
        X = X[:, None]
    if X.ndim != 2 or X.shape[0] != B.shape[0]:
        raise InputError(
            f"targets: expected shape ({B.shape[0]}, T) or ({B.shape[0]},) to match bases {B.shape}, got {X.shape}"
        )
    if X.shape[1] == 0:
        raise InputError("targets: expected at least one column, got none")
    if not (np.isfinite(tol) and tol >= 0):
        raise InputError(f"tol: expected a non-negative number, got {tol!r}")
    if max_iter is not None and (int(max_iter) != max_iter or max_iter < 1):
        raise InputError(f"max_iter: expected a positive integer or None, got {max_iter!r}")

    K = B.shape[1]
    T = X.shape[1]
    G = B.T @ B
    weights = np.empty((K, T))
    chunk = max(1, _CHUNK_BYTES // (8 * K * K))
    for lo in range(0, T, chunk):
        Xc = X[:, lo : lo + chunk]
        C = Xc.T @ B
        W, P, R, count = _solve_gram(G, C, np.einsum("dt,dt->t", Xc, Xc), tol, max_iter)
        if refine:
            W = _refine(B, Xc.T, W, P, R, count)
        weights[:, lo : lo + chunk] = W.T
    residuals = np.linalg.norm(B @ weights - X, axis=0)
    if single:
        return NnlsWeights(weights[:, 0], float(residuals[0]))
    return NnlsWeights(weights, residuals)
