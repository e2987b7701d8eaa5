"""A kinematic sphere pressing on the flesh: a penalty contact energy (Sifakis et al. 2005, sec. 9, fig. 9).

The paper shows the face "interacting with a kinematic sphere" in a quasistatic simulation
driven by the extracted controls, and handles its own collisions "with the penalty force
formulation of [Teran et al. 2005a]". Here: contact points (mesh nodes, or points embedded
in the tetrahedra by barycentric weights, such as the scan's vertices) are pushed out of a
sphere by the energy ``k/2 sum_i max(0, r - |p_i - c|)^2``, an
:class:`~facecap.fem.ExternalEnergy` of :meth:`QuasistaticSolver.solve`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..typing import FloatArray
from .solve_quasistatic import ExternalResponse

__all__ = ["SphereContact"]


class SphereContact:
    """Penalty contact of a rigid sphere with points carried by the flesh nodes.

    Parameters
    ----------
    points : (p, n) scipy.sparse matrix or array, float64
        Each contact point as weights over the ``n`` nodes, ``p_i = sum_j W_ij x_j`` (a node
        is a row with a single 1; a point embedded in a tetrahedron has its four
        barycentric weights).
    centre : (3,) float64 array, mm
        The sphere's centre, in the nodes' coordinates.
    radius_mm : float
        Positive.
    stiffness : float, mN / mm
        The penalty stiffness ``k`` of every point (positive). A point pressed by a force
        ``f`` stays about ``f / k`` inside the sphere.

    Notes
    -----
    With ``d_i = |p_i - c|``, ``n_i = (p_i - c) / d_i`` and the penetration
    ``phi_i = max(0, r - d_i)``:

    - energy ``E = k/2 sum_i phi_i^2`` (uJ),
    - forces ``f = -dE/dx = W^T (k phi_i n_i)`` (mN, pushing each point out along ``n_i``),
    - stiffness ``W^T diag(k n_i n_i^T) W`` (mN / mm): the exact Hessian minus its
      tangential part ``-k phi_i / d_i (I - n_i n_i^T)``, which is negative; dropping it
      projects the Hessian onto the positive semi-definite cone (as the solver's own
      elements are projected), and it is small (``phi / d``, below 1e-2 for a penetration
      under 1 % of the radius), so Newton's convergence stays close to quadratic.

    The energy is continuously differentiable (its stiffness jumps where a point reaches
    the surface). A point exactly at the centre is pushed along +z.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> contact = SphereContact(sp.identity(2, format="csr"), [0.0, 0.0, 0.0], 1.0, stiffness=10.0)
    >>> x = np.array([[0.0, 0.0, 0.9], [3.0, 0.0, 0.0]])
    >>> round(contact.evaluate(x).energy, 6), contact.penetration(x).round(6).tolist()
    (0.05, [0.1, 0.0])
    """

    def __init__(self, points: Any, centre: Any, radius_mm: float, *, stiffness: float) -> None:
        W = sp.csr_matrix(points, dtype=np.float64)
        if W.ndim != 2 or W.shape[0] < 1:
            raise InputError(f"points: expected a (p, n) matrix with p >= 1, got shape {W.shape}")
        c = np.asarray(centre, dtype=np.float64).reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise InputError(f"centre: expected 3 finite coordinates, got {np.asarray(centre).shape}")
        if not (np.isfinite(radius_mm) and radius_mm > 0):
            raise InputError(f"radius_mm: expected a positive value, got {radius_mm!r}")
        if not (np.isfinite(stiffness) and stiffness > 0):
            raise InputError(f"stiffness: expected a positive value, mN/mm, got {stiffness!r}")
        self.points = W
        self.centre: FloatArray = c
        self.radius_mm = float(radius_mm)
        self.stiffness = float(stiffness)

    @property
    def n_points(self) -> int:
        """p."""
        return int(self.points.shape[0])

    def _contact(self, x: Any) -> tuple[FloatArray, FloatArray]:
        """Penetration ``phi (p,)`` mm and outward unit normal ``n (p, 3)`` of every point."""
        X = np.asarray(x, dtype=np.float64)
        if X.ndim != 2 or X.shape != (self.points.shape[1], 3):
            raise InputError(f"x: expected shape ({self.points.shape[1]}, 3), got {X.shape}")
        offset = self.points @ X - self.centre
        distance = np.sqrt((offset**2).sum(axis=1))
        normal = np.zeros_like(offset)
        normal[:, 2] = 1.0
        away = distance > 0
        normal[away] = offset[away] / distance[away, None]
        return np.maximum(self.radius_mm - distance, 0.0), normal

    def penetration(self, x: FloatArray) -> FloatArray:
        """How deep each point is inside the sphere, ``max(0, r - |p_i - c|)``: (p,) float64, mm."""
        return self._contact(x)[0]

    def point_forces(self, x: FloatArray) -> FloatArray:
        """The sphere's force on each point, ``k phi_i n_i``: (p, 3) float64, mN."""
        phi, normal = self._contact(x)
        return self.stiffness * phi[:, None] * normal

    def evaluate(self, x: FloatArray, *, stiffness: bool = True) -> ExternalResponse:
        """Energy (uJ), nodal forces ``(n, 3)`` mN and, if asked, the PSD stiffness ``(3n, 3n)`` mN/mm.

        Parameters
        ----------
        x : (n, 3) float64 array, mm
            Node positions.
        stiffness : bool, default True

        Returns
        -------
        ExternalResponse
        """
        phi, normal = self._contact(x)
        k = self.stiffness
        energy = 0.5 * k * float(phi @ phi)
        point_forces = k * phi[:, None] * normal
        forces = np.asarray(self.points.T @ point_forces)
        if not stiffness:
            return ExternalResponse(energy, forces, None)
        n_dofs = 3 * self.points.shape[1]
        active = np.flatnonzero(phi > 0)
        if active.size == 0:
            return ExternalResponse(energy, forces, sp.csr_matrix((n_dofs, n_dofs)))
        Wa = self.points[active].tocoo()
        # kron(W_a, I_3): point i, axis c -> node j, axis c
        rows = (3 * Wa.row[:, None] + np.arange(3)).reshape(-1)
        cols = (3 * Wa.col[:, None] + np.arange(3)).reshape(-1)
        vals = np.repeat(Wa.data, 3)
        Wd = sp.csr_matrix((vals, (rows, cols)), shape=(3 * active.size, n_dofs))
        nn = normal[active]
        blocks = k * nn[:, :, None] * nn[:, None, :]
        B = sp.bsr_matrix((blocks, np.arange(active.size), np.arange(active.size + 1)),
                          shape=(3 * active.size, 3 * active.size)).tocsr()
        return ExternalResponse(energy, forces, (Wd.T @ B @ Wd).tocsr())
