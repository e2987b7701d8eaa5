"""The nonlinear discrete shell of Grinspun et al. (2003), eq. 8 of Bickel et al. (2007), and its minimiser.

    E = sum_e  k_e (|e| - |e_r|)^2 / (|e_r| l)  +  k_b |e_r| (theta - theta_r)^2 / h_r
      + sum_t  k_a (|t| - |t_r|)^2 / (|t_r| l^2)

over the edges ``e`` (lengths ``|e|``, dihedral angles ``theta`` across the
interior ones) and triangles ``t`` (areas ``|t|``), about a rest state ``r``;
``h_r`` is a third of the mean height of the edge's two triangles (Grinspun's
weight for irregular meshes). The paper writes the energy without ``l``: its
constants ``k_b = 2, k_e = 300, k_a = 30,000`` then hold for lengths in its own
unit, and the three terms scale as ``L^1``, ``L^0`` and ``L^2`` with the unit.
Here lengths are measured in units of ``length_mm`` (default 1 mm), so the
paper's constants mean the same whatever unit the scan came in (facecap works
in mm inside; ``length_mm=10`` would read them as the paper's constants in cm).

The minimiser is Gauss-Newton on the weighted residuals (``J^T J``, which is
positive semi-definite by construction: no definiteness fix is needed) with a
Levenberg-Marquardt damping that grows on a rejected step and shrinks on an
accepted one, as the issue's measured note warned undamped Gauss-Newton
diverges from a poor start. The linear solves use the project's sparse
factorisation (:class:`~facecap.mesh.factor_spd.SpdFactor`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..mesh.factor_spd import SpdFactor
from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_vertices

__all__ = ["DiscreteShell", "ShellMinimum", "minimize_shell"]

STRETCH = 300.0
"""``k_e``: the paper's edge-length stiffness."""
BEND = 2.0
"""``k_b``: the paper's bending stiffness."""
AREA = 30_000.0
"""``k_a``: the paper's area stiffness."""


def _interior_edges(faces: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """Unique edges (e, 2), and for the edges shared by two triangles: their index and the two opposite vertices."""
    F = np.asarray(faces, dtype=np.int64)
    half = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # half-edge i -> j of its face
    opposite = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    key = np.sort(half, axis=1)
    edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)])
    shared = np.flatnonzero(counts == 2)
    first, second = order[starts[shared]], order[starts[shared] + 1]
    # orient every shared edge as the first half-edge runs (a -> b), so its triangle is (a, b, c) and the
    # other (b, a, d): the dihedral angle's sign is then the same convention for every edge
    a, b = half[first, 0], half[first, 1]
    c, d = opposite[first], opposite[second]
    hinges = np.stack([a, b, c, d], axis=1)
    return edges, shared, hinges


def _dihedral(X: FloatArray, hinges: IntArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Signed dihedral angles (0 for a flat hinge; negative when the wings fold towards the normals' side).

    Returns the angle, the edge vector, and the unnormalised normals of the two triangles.
    """
    xa, xb, xc, xd = (X[hinges[:, i]] for i in range(4))
    e = xb - xa
    n1 = np.cross(xb - xa, xc - xa)  # triangle (a, b, c)
    n2 = np.cross(xd - xa, xb - xa)  # triangle (b, a, d), same orientation as (a, b, c) on a flat sheet
    e_len = np.linalg.norm(e, axis=1)
    cos = np.einsum("ij,ij->i", n1, n2)
    sin = np.einsum("ij,ij->i", np.cross(n1, n2), e) / np.maximum(e_len, 1e-300)
    return np.arctan2(sin, cos), e, n1, n2


class DiscreteShell:
    """Eq. 8 of a triangle mesh about a rest state: residuals, their Jacobian, the energy.

    Parameters
    ----------
    rest : (n, 3) float array, mm
        The rest state (its edge lengths, dihedral angles and areas are what the energy keeps).
    faces : (m, 3) int array
        Consistently oriented triangles.
    stretch, bend, area : float, default :data:`STRETCH`, :data:`BEND`, :data:`AREA`
        ``k_e``, ``k_b``, ``k_a`` (>= 0).
    length_mm : float, default 1
        The unit the constants are stated in (see the module docstring).

    Raises
    ------
    InputError
        On bad arrays, a degenerate rest triangle, or negative constants.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> shell = DiscreteShell(V, [[0, 1, 2], [2, 1, 3]])
    >>> float(shell.energy(V)), float(shell.energy(2 * V)) > 0
    (0.0, True)
    """

    def __init__(self, rest: Any, faces: Any, *, stretch: float = STRETCH, bend: float = BEND, area: float = AREA,
                 length_mm: float = 1.0) -> None:
        X = as_vertices(rest, name="rest")
        F = as_faces(faces, len(X), name="faces")
        for name, value in (("stretch", stretch), ("bend", bend), ("area", area)):
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name}: expected a finite constant >= 0, got {value!r}")
        if not np.isfinite(length_mm) or length_mm <= 0:
            raise InputError(f"length_mm: expected a positive length, got {length_mm!r}")
        self.n_vertices = len(X)
        self.faces = F
        self.edges, shared, self.hinges = _interior_edges(F)
        self.rest_lengths = np.linalg.norm(X[self.edges[:, 1]] - X[self.edges[:, 0]], axis=1)
        self.rest_areas = self._areas(X)
        if self.rest_lengths.min() <= 0 or self.rest_areas.min() <= 1e-12 * length_mm**2:
            raise InputError("rest: the mesh has a degenerate triangle (zero edge or area)")
        self.rest_angles = _dihedral(X, self.hinges)[0]
        # Grinspun: h_e is a third of the average of the heights of the two triangles on the edge
        hinge_len = self.rest_lengths[shared]
        areas1 = 0.5 * np.linalg.norm(np.cross(X[self.hinges[:, 1]] - X[self.hinges[:, 0]],
                                               X[self.hinges[:, 2]] - X[self.hinges[:, 0]]), axis=1)
        areas2 = 0.5 * np.linalg.norm(np.cross(X[self.hinges[:, 3]] - X[self.hinges[:, 0]],
                                               X[self.hinges[:, 1]] - X[self.hinges[:, 0]]), axis=1)
        height = (areas1 + areas2) / hinge_len / 3.0  # (2 A1 / e + 2 A2 / e) / 2 / 3
        l = float(length_mm)
        self.length_mm = l
        self.constants = {"stretch": float(stretch), "bend": float(bend), "area": float(area)}
        self._w_edge = np.sqrt(stretch / (self.rest_lengths * l))
        self._w_bend = np.sqrt(bend * hinge_len / height)
        self._w_area = np.sqrt(area / (self.rest_areas * l * l))
        self.n_residuals = len(self.edges) + len(self.hinges) + len(F)

    def _areas(self, X: FloatArray) -> FloatArray:
        F = self.faces
        return 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)

    def _check(self, x: Any) -> FloatArray:
        X = np.asarray(x, dtype=np.float64)
        if X.shape != (self.n_vertices, 3):
            raise InputError(f"x: expected ({self.n_vertices}, 3) positions, got {X.shape}")
        return X

    def residuals(self, x: Any) -> FloatArray:
        """The weighted residuals ``r`` (edges, hinges, triangles), ``E = r . r``."""
        X = self._check(x)
        lengths = np.linalg.norm(X[self.edges[:, 1]] - X[self.edges[:, 0]], axis=1)
        angles = _dihedral(X, self.hinges)[0]
        # the angle change wrapped to (-pi, pi]: a hinge folding through flat stays continuous
        turn = np.angle(np.exp(1j * (angles - self.rest_angles)))
        return np.concatenate([self._w_edge * (lengths - self.rest_lengths), self._w_bend * turn,
                               self._w_area * (self._areas(X) - self.rest_areas)])

    def energy(self, x: Any) -> float:
        """Eq. 8 at ``x``."""
        r = self.residuals(x)
        return float(r @ r)

    def jacobian(self, x: Any) -> sp.csr_matrix:
        """``d r / d x`` as a sparse (residuals, 3 n) matrix (columns ``3 i + axis``)."""
        X = self._check(x)
        rows, cols, vals = [], [], []

        def put(row0: int, vertex_cols: list[IntArray], grads: list[FloatArray], weight: FloatArray) -> None:
            k = len(weight)
            r = row0 + np.arange(k)
            for v, g in zip(vertex_cols, grads):
                for axis in range(3):
                    rows.append(r)
                    cols.append(3 * v + axis)
                    vals.append(weight * g[:, axis])

        E = self.edges
        d = X[E[:, 1]] - X[E[:, 0]]
        u = d / np.linalg.norm(d, axis=1, keepdims=True)
        put(0, [E[:, 0], E[:, 1]], [-u, u], self._w_edge)

        H = self.hinges
        _, e, n1, n2 = _dihedral(X, H)
        e_len = np.linalg.norm(e, axis=1)
        q1 = n1 / np.einsum("ij,ij->i", n1, n1)[:, None]
        q2 = n2 / np.einsum("ij,ij->i", n2, n2)[:, None]
        xa, xc, xd = X[H[:, 0]], X[H[:, 2]], X[H[:, 3]]
        # Bridson et al. 2003: a wing vertex moving along its triangle's normal turns the triangle about the
        # edge by |e| / |n|^2 per unit; an edge vertex carries the wings' gradients by the wing's foot point
        # along the edge (translation and rotation invariance). Checked against finite differences in the tests.
        grad_c = -e_len[:, None] * q1
        grad_d = -e_len[:, None] * q2
        foot_c = np.einsum("ij,ij->i", xc - xa, e) / (e_len * e_len)
        foot_d = np.einsum("ij,ij->i", xd - xa, e) / (e_len * e_len)
        grad_a = -(1.0 - foot_c)[:, None] * grad_c - (1.0 - foot_d)[:, None] * grad_d
        grad_b = -foot_c[:, None] * grad_c - foot_d[:, None] * grad_d
        put(len(E), [H[:, 0], H[:, 1], H[:, 2], H[:, 3]], [grad_a, grad_b, grad_c, grad_d], self._w_bend)

        F = self.faces
        x0, x1, x2 = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
        n = np.cross(x1 - x0, x2 - x0)
        nh = n / np.linalg.norm(n, axis=1, keepdims=True)
        # d|t|/dx_i = 1/2 n_hat x (the edge opposite i, running counter-clockwise)
        grads = [0.5 * np.cross(nh, x2 - x1), 0.5 * np.cross(nh, x0 - x2), 0.5 * np.cross(nh, x1 - x0)]
        put(len(E) + len(H), [F[:, 0], F[:, 1], F[:, 2]], grads, self._w_area)

        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.n_residuals, 3 * self.n_vertices))


class ShellMinimum(NamedTuple):
    """What :func:`minimize_shell` found.

    Attributes
    ----------
    vertices : (n, 3) float64 array, mm
    energy : float
        Eq. 8 there.
    initial_energy : float
    iterations : int
    converged : bool
        The last step moved no vertex more than ``tolerance_mm``, or lowered the energy by less than
        ``relative_decrease`` of it, or no step at any damping lowered it (a stall: a minimum to round-off
        or a direction the Gauss-Newton model cannot see). False: ``iterations`` ran out.
    """

    vertices: FloatArray
    energy: float
    initial_energy: float
    iterations: int
    converged: bool


def minimize_shell(shell: DiscreteShell, x0: Any, free: Any, *, directions: Any = None, iterations: int = 20,
                   tolerance_mm: float = 1e-4, relative_decrease: float = 1e-4, damping: float = 1e-3,
                   backend: str = "auto") -> ShellMinimum:
    """Minimise eq. 8 over the ``free`` vertices, the others fixed where ``x0`` has them.

    Parameters
    ----------
    shell : DiscreteShell
    x0 : (n, 3) float array, mm
        The start (the large-scale result with the valleys imposed) and the fixed positions.
    free : (n,) bool array or int array
        Vertices that move.
    directions : (n, 3) float array, optional
        Unit directions: each free vertex then moves along its own only (one unknown per vertex, e.g. the
        surface normals for a height field). Default: free in 3D.
    iterations : int, default 20
    tolerance_mm : float, default 1e-4
        Stop once no free vertex moves more than this in a step,
    relative_decrease : float, default 1e-4
        or once a step lowers the energy by less than this fraction.
    damping : float, default 1e-3
        Initial Levenberg-Marquardt factor on the diagonal of ``J^T J``.
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
        The sparse factorisation.

    Returns
    -------
    ShellMinimum
    """
    X = shell._check(x0).copy()
    mask = np.zeros(shell.n_vertices, dtype=bool)
    mask[np.asarray(free)] = True
    idx = np.flatnonzero(mask)
    energy = initial = shell.energy(X)
    if idx.size == 0:
        return ShellMinimum(X, energy, initial, 0, True)
    dofs = (3 * idx[:, None] + np.arange(3)).ravel()
    if directions is None:
        basis = None
    else:
        D = np.asarray(directions, dtype=np.float64)[idx]
        # x_free = x0 + D s: the chain rule is J D, with D block-diagonal (one column per vertex)
        basis = sp.csr_matrix((D.ravel(), (np.arange(dofs.size), np.repeat(np.arange(idx.size), 3))),
                              shape=(dofs.size, idx.size))
    mu = float(damping)
    converged = False
    it = 0
    for it in range(1, int(iterations) + 1):
        r = shell.residuals(X)
        J = shell.jacobian(X)[:, dofs]
        if basis is not None:
            J = J @ basis
        J = J.tocsc()
        g = J.T @ r
        H = (J.T @ J).tocsr()
        diag = H.diagonal()
        floor = 1e-12 * max(float(diag.max()), 1e-300)
        while True:
            A = H + sp.diags(mu * diag + floor)
            step = -SpdFactor(A, backend=backend).solve(g)  # type: ignore[arg-type]
            move = step.reshape(-1, 3) if basis is None else step[:, None] * D
            trial = X.copy()
            trial[idx] += move
            e_trial = shell.energy(trial)
            if e_trial <= energy or mu > 1e8:
                break
            mu *= 4.0
        if e_trial > energy:  # no step lowers the energy at any damping: a minimum to round-off
            converged = True
            break
        moved = float(np.abs(move).max())
        decrease = (energy - e_trial) / max(energy, 1e-300)
        X, energy = trial, e_trial
        mu = max(mu / 3.0, 1e-9)
        if moved <= tolerance_mm or decrease < relative_decrease:
            converged = True
            break
    return ShellMinimum(X, energy, initial, it, converged)
