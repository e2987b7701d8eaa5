"""The penalty ``phi_p`` that keeps the controls feasible (Sifakis et al. 2005, sec. 7 and 8)."""

from __future__ import annotations

from typing import NamedTuple

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


_BASIS = np.eye(9).reshape(9, 3, 3)


def _rigidity(M: FloatArray) -> tuple[float, FloatArray, FloatArray]:
    """``|M^T M - I|_F^2``, its gradient (9,) and its Hessian (9, 9) projected to PSD."""
    E = M.T @ M - np.eye(3)
    value = float((E**2).sum())
    grad = 4.0 * M @ E
    # d(grad)[dM] = 4 dM E + 4 M (dM^T M + M^T dM), for the 9 unit matrices dM at once
    B = _BASIS
    H = 4.0 * (B @ E + M @ (B.transpose(0, 2, 1) @ M + M.T @ B))
    H = H.reshape(9, 9).T
    H = 0.5 * (H + H.T)
    lam, Q = np.linalg.eigh(H)
    return value, grad.ravel(), (Q * np.maximum(lam, 0.0)) @ Q.T


def _box(value: float, lo: float, hi: float) -> tuple[float, float, float]:
    """``min(0, x - lo, hi - x)^2`` as (value, d/dx, d2/dx2)."""
    if value < lo:
        return (value - lo) ** 2, 2.0 * (value - lo), 2.0
    if value > hi:
        return (value - hi) ** 2, 2.0 * (value - hi), 2.0
    return 0.0, 0.0, 0.0


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
    c = np.asarray(vector, dtype=np.float64).reshape(-1)
    k = int(n_muscles)
    n = k + 24
    grad = np.zeros(n)
    hess = np.zeros((n, n))
    value = 0.0
    a = c[:k]
    below, above = a < 0.0, a > 1.0
    value += float((a[below] ** 2).sum() + ((a[above] - 1.0) ** 2).sum())
    grad[:k] = np.where(below, 2.0 * a, 0.0) + np.where(above, 2.0 * (a - 1.0), 0.0)
    hess[np.arange(k), np.arange(k)] = np.where(below | above, 2.0, 0.0)
    for start in (k, k + 12):
        v, g, H = _rigidity(c[start:start + 9].reshape(3, 3))
        value += v
        grad[start:start + 9] += g
        hess[start:start + 9, start:start + 9] += H
    G, g0 = jaw.affine_terms
    psi = G @ c[k + 12:] + g0
    d, s = jaw.track_length_mm, np.sin(jaw.max_opening_rad)
    terms = [(psi[0] ** 2, 2 * psi[0], 2.0), (psi[1] ** 2, 2 * psi[1], 2.0), (psi[2] ** 2, 2 * psi[2], 2.0),
             _box(psi[3], 0.0, d), _box(psi[4], 0.0, d), _box(psi[5], -s, 0.0)]
    jaw_slice = slice(k + 12, n)
    for i, (v, dv, d2v) in enumerate(terms):
        value += v
        grad[jaw_slice] += dv * G[i]
        if d2v:
            hess[jaw_slice, jaw_slice] += d2v * np.outer(G[i], G[i])
    return ControlPenalty(float(value), grad, hess)
