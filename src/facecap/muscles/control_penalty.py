"""The penalty ``phi_p`` that keeps the controls feasible (Sifakis et al. 2005, sec. 7 and 8)."""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ..typing import FloatArray
from .jaw_constraints import JawConstraints

__all__ = ["ControlPenalty", "control_penalty"]


class ControlPenalty(NamedTuple):
    """The penalty and its derivatives at one control vector.

    Attributes
    ----------
    value : float
        ``phi_p(c)``.
    gradient : (k + 24,) float64 array
    hessian : (k + 24, k + 24) float64 array
        Positive semi-definite (the rigidity blocks projected, the rest convex already).
    """

    value: float
    gradient: FloatArray
    hessian: FloatArray


@numba.njit(nogil=True)
def _add_rigidity(c: FloatArray, start: int, grad: FloatArray, hess: FloatArray) -> float:
    """``|M^T M - I|_F^2`` of ``M = c[start:start + 9]`` (row-major); its gradient and its Hessian, projected to
    PSD, added into ``grad`` and ``hess`` at ``start``."""
    M = c[start:start + 9].copy().reshape(3, 3)
    E = M.T @ M - np.eye(3)
    value = 0.0
    for i in range(3):
        for j in range(3):
            value += E[i, j] * E[i, j]
    g = 4.0 * (M @ E)
    # column q of the Hessian: d(grad)[dM] = 4 dM E + 4 M (dM^T M + M^T dM) for the unit matrix dM = B_q
    H = np.empty((9, 9))
    for a in range(3):
        for b in range(3):
            B = np.zeros((3, 3))
            B[a, b] = 1.0
            D = 4.0 * (B @ E + M @ (B.T @ M + M.T @ B))
            for r in range(9):
                H[r, 3 * a + b] = D[r // 3, r % 3]
    H = 0.5 * (H + H.T)
    lam, Q = np.linalg.eigh(H)
    lam = np.maximum(lam, 0.0)
    P = (Q * lam) @ Q.T
    for r in range(9):
        grad[start + r] += g[r // 3, r % 3]
        for q in range(9):
            hess[start + r, start + q] += P[r, q]
    return value


@numba.njit(nogil=True)
def _penalty(c: FloatArray, k: int, G: FloatArray, g0: FloatArray, track_mm: float,
             max_sine: float) -> tuple[float, FloatArray, FloatArray]:
    n = c.shape[0]
    grad = np.zeros(n)
    hess = np.zeros((n, n))
    value = 0.0
    for i in range(k):  # min(0, a, 1 - a)^2
        if c[i] < 0.0:
            value += c[i] * c[i]
            grad[i] = 2.0 * c[i]
            hess[i, i] = 2.0
        elif c[i] > 1.0:
            value += (c[i] - 1.0) ** 2
            grad[i] = 2.0 * (c[i] - 1.0)
            hess[i, i] = 2.0
    value += _add_rigidity(c, k, grad, hess)
    value += _add_rigidity(c, k + 12, grad, hess)
    psi = G @ c[k + 12:] + g0
    lo = np.array([0.0, 0.0, 0.0, 0.0, 0.0, -max_sine])
    hi = np.array([0.0, 0.0, 0.0, track_mm, track_mm, 0.0])
    j0 = k + 12
    for i in range(6):  # psi1-psi3 equalities (psi^2), psi4-psi6 boxes (min(0, psi - lo, hi - psi)^2)
        if i < 3:
            excess = psi[i]
        elif psi[i] < lo[i]:
            excess = psi[i] - lo[i]
        elif psi[i] > hi[i]:
            excess = psi[i] - hi[i]
        else:
            continue
        value += excess * excess
        for a in range(12):
            grad[j0 + a] += 2.0 * excess * G[i, a]
            for b in range(12):
                hess[j0 + a, j0 + b] += 2.0 * G[i, a] * G[i, b]
    return value, grad, hess


try:  # compiled once per machine and kept; where no cache folder is writable, compiled per process
    _penalty.enable_caching()
    _add_rigidity.enable_caching()
except RuntimeError:
    pass


def control_penalty(vector: FloatArray, n_muscles: int, jaw: JawConstraints) -> ControlPenalty:
    """The feasibility penalty of a control vector and its derivatives.

    Parameters
    ----------
    vector : (k + 24,) float64 array
        ``[a, vec(M_c), t_c, vec(M_m), t_m]`` (:meth:`MuscleControls.as_vector`).
    n_muscles : int
        ``k``.
    jaw : JawConstraints

    Returns
    -------
    ControlPenalty

    Notes
    -----
    ``phi_p = sum_i min(0, a_i, 1 - a_i)^2`` (sec. 7) ``+ phi_kin`` (sec. 8)::

        phi_kin = |M_c^T M_c - I|_F^2 + |M_m^T M_m - I|_F^2 + psi1^2 + psi2^2 + psi3^2
                  + min(0, psi4, d - psi4)^2 + min(0, psi5, d - psi5)^2 + min(0, -psi6, s + psi6)^2

    The rigidity terms are not convex; their 9 x 9 Hessians are projected onto the
    positive semi-definite cone by an eigen-decomposition, as the paper advises. The
    piecewise quadratic terms are C1 with a Hessian that jumps at the bounds.

    Examples
    --------
    >>> from facecap.muscles import MuscleControls
    >>> jaw = JawConstraints(np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.zeros(3), 100.0)
    >>> p = control_penalty(MuscleControls.rest(2).as_vector(), 2, jaw)
    >>> p.value, bool(np.all(p.gradient == 0))
    (0.0, True)
    """
    c = np.ascontiguousarray(vector, dtype=np.float64).reshape(-1)
    G, g0 = jaw.affine_terms
    # compiled (numba): the Gauss-Newton continuation calls this a few hundred times a step (sec. 7); the
    # same arithmetic in numpy cost 160 us a call, 70 % of the step, against 45 us
    value, grad, hess = _penalty(c, int(n_muscles), G, g0, float(jaw.track_length_mm), float(np.sin(jaw.max_opening_rad)))
    return ControlPenalty(float(value), grad, hess)
