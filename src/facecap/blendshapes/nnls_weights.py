"""Non-negative least squares for many right-hand sides at once (blendshape weights, eq. 12)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import BoolArray, FloatArray, IntArray
from .lawson_hanson import SharedGram, lawson_hanson, refine_on_passive

__all__ = ["NnlsWeights", "nnls_weights"]

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


def _gradient_tolerance(diag_G: FloatArray, target_sq_norms: FloatArray, tol: float) -> FloatArray:
    """(n, K) threshold above which a gradient ``b_i . r`` counts as positive."""
    return tol * np.sqrt(np.maximum(target_sq_norms, 0.0))[:, None] * np.sqrt(np.maximum(diag_G, 0.0))[None, :]


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
    lawson_hanson(SharedGram(G), C, W, P, R, count, tolg, max_iter=max_iter)
    return W, P, R, count


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
            W = refine_on_passive(B, Xc.T, W, P, R, count)
        weights[:, lo : lo + chunk] = W.T
    residuals = np.linalg.norm(B @ weights - X, axis=0)
    if single:
        return NnlsWeights(weights[:, 0], float(residuals[0]))
    return NnlsWeights(weights, residuals)
