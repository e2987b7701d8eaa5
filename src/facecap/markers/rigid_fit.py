"""Least-squares rigid motion between two point sets (Kabsch / Horn), batched and NaN-aware."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["RigidTransform", "rigid_fit"]

_MIN_POINTS = 3


class RigidTransform(NamedTuple):
    """A proper rigid motion ``x -> rotation @ x + translation``, possibly batched.

    Attributes
    ----------
    rotation : (..., 3, 3) float64 array
        Rotation matrices, orthonormal with determinant +1; NaN where the
        fit was undetermined.
    translation : (..., 3) float64 array, mm
        Translations; NaN where the fit was undetermined.
    rms : (...,) float64 array, mm
        Root-mean-square residual of the fitted points (weighted by the
        fit weights); NaN where the fit was undetermined.
    """

    rotation: FloatArray
    translation: FloatArray
    rms: FloatArray

    def apply(self, points: FloatArray) -> FloatArray:
        """Move ``points`` (..., n, 3) mm by this transform, broadcasting the leading axes.

        Examples
        --------
        >>> import numpy as np
        >>> T = RigidTransform(np.eye(3), np.array([1.0, 0.0, 0.0]), np.float64(0.0))
        >>> T.apply(np.zeros((1, 3)))
        array([[1., 0., 0.]])
        """
        P = np.asarray(points, dtype=np.float64)
        return np.matmul(P, np.swapaxes(self.rotation, -1, -2)) + self.translation[..., None, :]


def _as_point_batch(X: Any, *, name: str) -> FloatArray:
    try:
        A = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a numeric (..., n, 3) array ({exc})") from None
    if A.ndim < 2 or A.shape[-1] != 3:
        raise InputError(f"{name}: expected shape (..., n, 3), got {A.shape}")
    if np.any(np.isinf(A)):
        raise InputError(f"{name}: contains infinite values (use NaN for missing points)")
    return A


def rigid_fit(
    source: FloatArray,
    target: FloatArray,
    *,
    weights: FloatArray | None = None,
) -> RigidTransform:
    """Best rigid motion (rotation and translation) mapping ``source`` onto ``target``.

    Minimises ``sum_k w_k |R s_k + t - y_k|^2`` over proper rotations ``R``
    (det +1) and translations ``t``, independently for every item of the
    leading (batch) axes. Rows with a NaN in either point set are ignored.

    Parameters
    ----------
    source : (..., n, 3) float64 array, mm
        Points to move. NaN rows mark missing points.
    target : (..., n, 3) float64 array, mm
        Where the points should land, row for row. The leading axes of
        ``source`` and ``target`` broadcast against each other, so a single
        (n, 3) configuration can be fitted to a (T, n, 3) sequence.
    weights : (..., n) float64 array or None, optional
        Non-negative weight of each correspondence, broadcast against the
        batch; None (default) weighs every visible row equally.

    Returns
    -------
    RigidTransform
        ``rotation`` (..., 3, 3), ``translation`` (..., 3) mm and ``rms``
        (...,) mm, the (weighted) root-mean-square residual. Batch items
        with fewer than 3 rows of positive weight are undetermined and come
        back as NaN. With 3 or more collinear points the rotation about the
        line is not determined; one of the minimisers is returned.

    Raises
    ------
    InputError
        If the arrays are not (..., n, 3), do not broadcast, hold infinite
        values, or the weights are negative or not finite.

    Notes
    -----
    Kabsch's algorithm [1]_ in Horn's weighted form [2]_: with weighted
    centroids ``s0``, ``y0`` and cross-covariance
    ``H = sum_k w_k (s_k - s0)(y_k - y0)^T = U S V^T``,

    ``R = V diag(1, 1, d) U^T``, ``d = sign det(V U^T)``, ``t = y0 - R s0``.

    The ``d`` term rejects reflections, so the result is always a proper
    rotation, even when the best orthogonal map would be a mirror. The 3x3
    SVDs are computed batched with :func:`numpy.linalg.svd`.

    References
    ----------
    .. [1] W. Kabsch, "A solution for the best rotation to relate two sets of
       vectors", Acta Cryst. A32 (1976) 922-923.
    .. [2] B. K. P. Horn, "Closed-form solution of absolute orientation using
       unit quaternions", J. Opt. Soc. Am. A 4 (1987) 629-642.

    Examples
    --------
    >>> import numpy as np
    >>> src = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> fit = rigid_fit(src, src @ Rz.T + [5.0, 0, 0])
    >>> bool(np.allclose(fit.rotation, Rz)), bool(np.allclose(fit.translation, [5, 0, 0]))
    (True, True)
    """
    S = _as_point_batch(source, name="source")
    Y = _as_point_batch(target, name="target")
    if S.shape[-2] != Y.shape[-2]:
        raise InputError(
            f"target: expected {S.shape[-2]} points to match source, got {Y.shape[-2]}"
        )
    n = S.shape[-2]
    try:
        batch = np.broadcast_shapes(S.shape[:-2], Y.shape[:-2])
    except ValueError:
        raise InputError(
            f"source and target: batch shapes {S.shape[:-2]} and {Y.shape[:-2]} do not broadcast"
        ) from None

    # a NaN coordinate makes its point's sum NaN (infinities are refused above); summing the three strided
    # coordinates is 10x faster than any() over the last axis of length 3 on a long take
    valid = ~np.isnan(S[..., 0] + S[..., 1] + S[..., 2] + Y[..., 0] + Y[..., 1] + Y[..., 2])
    if weights is None:
        W = np.broadcast_to(valid, batch + (n,)).astype(np.float64)
    else:
        try:
            W = np.asarray(weights, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"weights: expected a numeric (..., {n}) array ({exc})") from None
        if not np.all(np.isfinite(W)) or np.any(W < 0):
            raise InputError("weights: expected finite non-negative values")
        try:
            batch = np.broadcast_shapes(batch, W.shape[:-1]) if W.ndim else batch
            W = np.broadcast_to(W, batch + (n,))
        except ValueError:
            raise InputError(
                f"weights: expected shape broadcastable to {batch + (n,)}, got {W.shape}"
            ) from None
        W = np.where(valid, W, 0.0)
    S = np.where(valid[..., None], S, 0.0)
    Y = np.where(valid[..., None], Y, 0.0)

    wsum = W.sum(axis=-1)
    enough = np.count_nonzero(W > 0, axis=-1) >= _MIN_POINTS
    safe = np.where(enough, wsum, 1.0)
    # batched matrix products (BLAS) rather than einsum: 3x faster on a 10,000-frame take of 90 markers
    s0 = np.matmul(W[..., None, :], S)[..., 0, :] / safe[..., None]
    y0 = np.matmul(W[..., None, :], Y)[..., 0, :] / safe[..., None]
    Sc = S - s0[..., None, :]
    Yc = Y - y0[..., None, :]
    H = np.matmul(np.swapaxes(Sc * W[..., None], -1, -2), Yc)

    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(np.matmul(V, np.swapaxes(U, -1, -2))))
    d = np.where(d == 0, 1.0, d)
    V[..., :, 2] *= d[..., None]
    R = np.matmul(V, np.swapaxes(U, -1, -2))
    t = y0 - np.einsum("...ij,...j->...i", R, s0)

    resid = np.matmul(S, np.swapaxes(R, -1, -2)) + t[..., None, :] - Y
    sq = np.sum(W * np.sum(resid * resid, axis=-1), axis=-1)
    rms = np.sqrt(np.maximum(sq, 0.0) / safe)

    R = np.where(enough[..., None, None], R, np.nan)
    t = np.where(enough[..., None], t, np.nan)
    rms = np.where(enough, rms, np.nan)
    return RigidTransform(rotation=R, translation=t, rms=rms)
