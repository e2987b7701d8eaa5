"""The flesh finite element model: linear tetrahedra, Mooney-Rivlin flesh, embedded muscles.

Everything is vectorised over tetrahedra with numpy; the stiffness matrix is refilled
into a sparsity pattern computed once per mesh (scatter by ``np.bincount`` into the CSR
value array), so a Newton step never builds a sparse structure.

Units: positions in mm, stresses in kPa, energies in uJ (kPa mm^3), forces in mN
(kPa mm^2), stiffness in mN / mm.
"""

from __future__ import annotations

import copy
from typing import Any, NamedTuple

import numba
import numpy as np
import scipy.sparse as sp

from ..errors import InputError, MeshError
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_vertices
from .mooney_rivlin import MooneyRivlin, mooney_rivlin_response
from .muscle_fibre import MuscleFibre, fibre_response

__all__ = ["FleshModel", "ElementResponse"]


class ElementResponse(NamedTuple):
    """The model evaluated at one configuration (what a Newton step needs).

    Attributes
    ----------
    energy : float, uJ
        Total elastic energy ``E(x, a)``.
    forces : (n, 3) float64 array, mN
        Nodal forces ``f(x, a) = -dE/dx`` (Dirichlet rows included).
    element_stiffness : (m, 12, 12) float64 array, mN / mm, or None
        Per-tetrahedron ``d2E_e / dx_e^2``, corner-major (row ``3 a + i`` is corner ``a``,
        axis ``i``); made positive semi-definite when the definiteness fix is on.
    inverted : int
        Tetrahedra with ``det F <= 0``.
    stress_derivative : (m, 9, 9) float64 array, kPa, or None
        The exact ``d2 psi / dF2`` of each tetrahedron (flesh plus fibres, before any
        fix), for :meth:`FleshModel.element_stiffness`.
    """

    energy: float
    forces: FloatArray
    element_stiffness: FloatArray | None
    inverted: int
    stress_derivative: FloatArray | None = None


class _Pattern:
    """CSR structure of a stiffness matrix over chosen rows/columns and the scatter into it."""

    def __init__(self, T: IntArray, dof_index: IntArray, n_dofs: int) -> None:
        corner_dofs = (3 * T[:, :, None] + np.arange(3)).reshape(-1, 12)  # (m, 12) global dofs
        local = dof_index[corner_dofs]  # -1 where the dof is not in the matrix
        rows = np.broadcast_to(local[:, :, None], (T.shape[0], 12, 12)).reshape(-1)
        cols = np.broadcast_to(local[:, None, :], (T.shape[0], 12, 12)).reshape(-1)
        keep = (rows >= 0) & (cols >= 0)
        keys = rows[keep].astype(np.int64) * n_dofs + cols[keep]
        unique, inverse = np.unique(keys, return_inverse=True)
        self.nnz = int(unique.size)
        self.n = n_dofs
        # Entries outside the matrix go to one extra bin that is dropped after the scatter.
        self.slot = np.full(rows.size, self.nnz, dtype=np.intp)
        self.slot[keep] = inverse
        self.indices = (unique % n_dofs).astype(np.int32)
        self.indptr = np.zeros(n_dofs + 1, dtype=np.int32)
        np.cumsum(np.bincount(unique // n_dofs, minlength=n_dofs), out=self.indptr[1:])

    def assemble(self, element_stiffness: FloatArray) -> sp.csr_matrix:
        data = np.bincount(self.slot, weights=element_stiffness.reshape(-1), minlength=self.nnz + 1)[: self.nnz]
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


@numba.njit(cache=True, nogil=True)
def _not_positive_definite(A: FloatArray, relative_floor: float) -> BoolArray:  # pragma: no cover - compiled
    """Which symmetric 9 x 9 blocks fail a Cholesky factorisation (pivot below ``floor``)."""
    m = A.shape[0]
    bad = np.zeros(m, dtype=np.bool_)
    L = np.empty((9, 9))
    for e in range(m):
        scale = 0.0
        for i in range(9):
            scale = max(scale, abs(A[e, i, i]))
        floor = relative_floor * scale
        for i in range(9):
            for j in range(i + 1):
                v = A[e, i, j]
                for k in range(j):
                    v -= L[i, k] * L[j, k]
                if i == j:
                    if v <= floor:
                        bad[e] = True
                        break
                    L[i, i] = np.sqrt(v)
                else:
                    L[i, j] = v / L[j, j]
            if bad[e]:
                break
    return bad


@numba.njit(cache=True, nogil=True)
def _stiffness_blocks(A: FloatArray, G: FloatArray, volumes: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``K[e, 3a+i, 3b+k] = V_e sum_jl G[e,a,j] A[e, 3i+j, 3k+l] G[e,b,l]`` (about 3x numpy's matmul chain)."""
    m = A.shape[0]
    K = np.empty((m, 12, 12))
    T = np.empty((3, 3, 3, 4))
    for e in range(m):
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for b in range(4):
                        v = 0.0
                        for l in range(3):
                            v += A[e, 3 * i + j, 3 * k + l] * G[e, b, l]
                        T[i, j, k, b] = v
        vol = volumes[e]
        for a in range(4):
            for i in range(3):
                for b in range(4):
                    for k in range(3):
                        v = 0.0
                        for j in range(3):
                            v += G[e, a, j] * T[i, j, k, b]
                        K[e, 3 * a + i, 3 * b + k] = vol * v
    return K


def _project_psd(A: FloatArray) -> int:
    """Clamp the negative eigenvalues of each symmetric 9 x 9 block of ``A`` to zero, in place.

    Returns how many blocks were changed. A compiled Cholesky attempt finds the blocks that
    are already positive definite (most of them, cheaply); only the others go through the
    eigensolver.
    """
    bad = np.flatnonzero(_not_positive_definite(A, 1e-12))
    if bad.size:
        block = A[bad]
        block = 0.5 * (block + block.transpose(0, 2, 1))  # exact symmetry for the eigensolver
        w, V = np.linalg.eigh(block)
        A[bad] = (V * np.maximum(w, 0.0)[:, None, :]) @ V.transpose(0, 2, 1)
    return int(bad.size)


class FleshModel:
    """Linear tetrahedra with Mooney-Rivlin flesh and embedded, activated muscles.

    Sifakis, Neverov and Fedkiw 2005, section 4: the nodal force is affine in the
    activations (eq. 1), ``f(x, a) = f0(x) + sum_k a_k f_k(x)``, where ``f0`` is the flesh's
    isotropic response plus every muscle's passive fibre response and ``f_k`` the active
    force of muscle ``k`` fully activated.

    Parameters
    ----------
    X : (n, 3) float64 array, mm
        Rest node positions.
    T : (m, 4) int64 array
        Tetrahedra, positively oriented (``det[X1-X0, X2-X0, X3-X0] > 0``).
    muscle_fractions : (m, k) float64 array in [0, 1], or None
        Volume fraction of each muscle in each tetrahedron (None: no muscles).
    fibre_directions : (m, k, 3) float64 array, or None
        Rest fibre direction of each muscle in each tetrahedron; normalised here, and
        needed only where the fraction is positive.
    dirichlet_nodes : (d,) int64 array
        Nodes whose positions are prescribed (bone attachments); at least three, not on
        one line, so the free nodes have no rigid motion left.
    material : MooneyRivlin, default MooneyRivlin()
    fibre : MuscleFibre, default MuscleFibre()
    muscle_strength : (k,) float64 array, or None
        Per-muscle multiplier of ``fibre.max_stress_kpa`` (Sifakis et al. scaled each
        muscle by hand); default all ones.
    force_length_scale : float, default 1
        Scales the whole force-length curve, passive and active, of every muscle: the
        paper's exaggeration beyond the attainable (section 9), rather than activations
        above 1. :meth:`with_force_length_scale` makes a copy with another scale.

    Raises
    ------
    MeshError
        Tetrahedra out of range, degenerate or negatively oriented.
    InputError
        Muscle arrays of the wrong shape or range, Dirichlet nodes out of range, repeated,
        too few or collinear.

    Notes
    -----
    With rest shape matrix ``Dm = [X1-X0, X2-X0, X3-X0]``, ``F = Ds Dm^-1`` is
    ``F = sum_a x_a g_a^T`` with shape gradients ``g_1..g_3`` the rows of ``Dm^-1`` and
    ``g_0 = -(g_1 + g_2 + g_3)``. The element energy is ``V_e psi(F)``, its force on corner
    ``a`` is ``-V_e P g_a`` and its stiffness block ``(a, b)`` is
    ``V_e sum_jl dP_ij/dF_kl g_aj g_bl``.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> model = FleshModel(X, np.array([[0, 1, 2, 3]]), None, None, np.array([0, 1, 2]))
    >>> model.energy(X, np.zeros(0)) == 0.0, float(np.abs(model.forces(X, np.zeros(0))).max()) < 1e-12
    (True, True)
    """

    def __init__(self, X: FloatArray, T: IntArray, muscle_fractions: FloatArray | None,
                 fibre_directions: FloatArray | None, dirichlet_nodes: IntArray, *,
                 material: MooneyRivlin = MooneyRivlin(), fibre: MuscleFibre = MuscleFibre(),
                 muscle_strength: FloatArray | None = None, force_length_scale: float = 1.0) -> None:
        self.rest_positions = as_vertices(X, name="X")
        n = self.rest_positions.shape[0]
        self.tets = as_faces(T, n, name="T", corners=4)
        m = self.tets.shape[0]
        self.material = material
        self.fibre = fibre
        Dm = (self.rest_positions[self.tets[:, 1:]] - self.rest_positions[self.tets[:, :1]]).transpose(0, 2, 1)
        det = np.linalg.det(Dm)
        edge = np.linalg.norm(Dm, axis=1).max(axis=1)
        bad = np.flatnonzero(~(det > 1e-12 * edge**3))
        if bad.size:
            first = int(bad[0])
            what = "negatively oriented" if det[first] < 0 else "degenerate (zero volume)"
            raise MeshError(f"T: tetrahedron {first} is {what}; {bad.size} of {m} have det[X1-X0, X2-X0, X3-X0] <= 0")
        self.rest_volumes: FloatArray = det / 6.0
        Dm_inv = np.linalg.inv(Dm)
        G = np.empty((m, 4, 3))
        G[:, 1:] = Dm_inv
        G[:, 0] = -Dm_inv.sum(axis=1)
        self.shape_gradients: FloatArray = G
        self.mean_edge_mm = float(np.mean(np.linalg.norm(Dm, axis=1)))

        self._set_muscles(muscle_fractions, fibre_directions, m)
        k = self.n_muscles
        if muscle_strength is None:
            strength = np.ones(k)
        else:
            strength = np.asarray(muscle_strength, dtype=np.float64).reshape(-1)
            if strength.shape != (k,) or not np.all(np.isfinite(strength)) or np.any(strength < 0):
                raise InputError(f"muscle_strength: expected {k} finite values >= 0, got shape {strength.shape}")
        self.muscle_strength: FloatArray = strength
        self.force_length_scale = self._checked_scale(force_length_scale)

        self._set_dirichlet(dirichlet_nodes, n)
        self._free_pattern: _Pattern | None = None
        self._full_pattern: _Pattern | None = None

    # -- set-up -------------------------------------------------------------------------------
    def _set_muscles(self, fractions: Any, directions: Any, m: int) -> None:
        if fractions is None:
            fr = np.zeros((m, 0))
            dirs = np.zeros((m, 0, 3))
        else:
            fr = np.asarray(fractions, dtype=np.float64)
            if fr.ndim != 2 or fr.shape[0] != m:
                raise InputError(f"muscle_fractions: expected shape ({m}, k), got {fr.shape}")
            if not np.all(np.isfinite(fr)) or fr.min(initial=0.0) < 0 or fr.max(initial=0.0) > 1:
                raise InputError("muscle_fractions: expected values in [0, 1]")
            if directions is None:
                raise InputError("fibre_directions: required with muscle_fractions")
            dirs = np.asarray(directions, dtype=np.float64)
            if dirs.shape != (m, fr.shape[1], 3):
                raise InputError(f"fibre_directions: expected shape ({m}, {fr.shape[1]}, 3), got {dirs.shape}")
        pair_tet, pair_muscle = np.nonzero(fr > 0)  # row-major: sorted by tetrahedron
        d = dirs[pair_tet, pair_muscle]
        length = np.linalg.norm(d, axis=1)
        if np.any(~np.isfinite(length) | (length < 1e-12)):
            bad = int(np.flatnonzero(~np.isfinite(length) | (length < 1e-12))[0])
            raise InputError(f"fibre_directions: tetrahedron {int(pair_tet[bad])}, muscle {int(pair_muscle[bad])} "
                             "has a positive volume fraction but no direction")
        self.n_muscles = int(fr.shape[1])
        self._pair_tet = pair_tet.astype(np.intp)
        self._pair_muscle = pair_muscle.astype(np.intp)
        self._pair_fraction = fr[pair_tet, pair_muscle]
        self._pair_direction = d / length[:, None]
        # Pairs sorted by tetrahedron: their stiffness blocks are summed per tetrahedron with reduceat.
        self._pair_tets_unique, self._pair_starts = np.unique(self._pair_tet, return_index=True)

    def _set_dirichlet(self, nodes: Any, n: int) -> None:
        idx = np.asarray(nodes)
        if idx.ndim != 1 or (idx.size and not np.issubdtype(idx.dtype, np.integer)):
            raise InputError(f"dirichlet_nodes: expected a 1-D integer array, got shape {idx.shape}, dtype {idx.dtype}")
        idx = idx.astype(np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise InputError(f"dirichlet_nodes: indices span {idx.min()}..{idx.max()}, the mesh has {n} nodes")
        if np.unique(idx).size != idx.size:
            raise InputError("dirichlet_nodes: a node is listed twice")
        P = self.rest_positions[idx]
        if idx.size < 3 or np.linalg.matrix_rank(P - P.mean(axis=0), tol=1e-9 * max(self.mean_edge_mm, 1e-12)) < 2:
            raise InputError("dirichlet_nodes: need at least three nodes not on one line (else the flesh "
                             "can move rigidly and the equilibrium is not unique)")
        self.dirichlet_nodes: IntArray = idx
        free = np.ones(n, dtype=bool)
        free[idx] = False
        self.free_nodes: IntArray = np.flatnonzero(free)
        self.free_dofs: IntArray = (3 * self.free_nodes[:, None] + np.arange(3)).reshape(-1)

    @staticmethod
    def _checked_scale(scale: float) -> float:
        scale = float(scale)
        if not (np.isfinite(scale) and scale >= 0):
            raise InputError(f"force_length_scale: expected a finite value >= 0, got {scale!r}")
        return scale

    def with_force_length_scale(self, scale: float) -> FleshModel:
        """A copy of this model with another force-length scale (the arrays are shared, not copied)."""
        other = copy.copy(self)
        other.force_length_scale = self._checked_scale(scale)
        return other

    # -- sizes --------------------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        """Number of nodes ``n``."""
        return int(self.rest_positions.shape[0])

    @property
    def n_tets(self) -> int:
        """Number of tetrahedra ``m``."""
        return int(self.tets.shape[0])

    # -- evaluation -----------------------------------------------------------------------------
    def _positions(self, x: Any) -> FloatArray:
        x = np.asarray(x, dtype=np.float64)
        if x.shape != self.rest_positions.shape:
            raise InputError(f"x: expected shape {self.rest_positions.shape}, got {x.shape}")
        return x

    def _activations(self, activations: Any) -> FloatArray:
        a = np.asarray(activations, dtype=np.float64).reshape(-1)
        if a.shape != (self.n_muscles,) or not np.all(np.isfinite(a)):
            raise InputError(f"activations: expected {self.n_muscles} finite values, got shape {a.shape}")
        return a

    def deformation_gradients(self, x: FloatArray) -> FloatArray:
        """``F`` of every tetrahedron, (m, 3, 3), for node positions ``x`` (n, 3) mm."""
        x = self._positions(x)
        return x[self.tets].transpose(0, 2, 1) @ self.shape_gradients

    def inverted_tets(self, x: FloatArray) -> BoolArray:
        """Mask (m,) of the tetrahedra with ``det F <= 0`` at positions ``x``."""
        return np.linalg.det(self.deformation_gradients(x)) <= 0.0

    def _fibre_weights(self, a: FloatArray) -> tuple[FloatArray, FloatArray]:
        base = self._pair_fraction * self.muscle_strength[self._pair_muscle] * self.force_length_scale
        return base, base * a[self._pair_muscle]

    def _corner_forces(self, P: FloatArray, volumes: FloatArray, G: FloatArray) -> FloatArray:
        """Nodal forces of each element, (e, 4, 3): ``-V_e P g_a``."""
        return -volumes[:, None, None] * (G @ P.transpose(0, 2, 1))

    def _scatter_nodes(self, corner_forces: FloatArray, tets: IntArray) -> FloatArray:
        idx = (3 * tets[:, :, None] + np.arange(3)).reshape(-1)
        return np.bincount(idx, weights=corner_forces.reshape(-1), minlength=3 * self.n_nodes).reshape(-1, 3)

    def evaluate(self, x: FloatArray, activations: FloatArray, *, derivatives: int = 2,
                 definiteness_fix: bool = True) -> ElementResponse:
        """Energy, forces and per-tetrahedron stiffness at ``x`` under ``activations``.

        Parameters
        ----------
        x : (n, 3) float64 array, mm
        activations : (k,) float64 array
            Muscle activations, physically in [0, 1] (values outside are evaluated, for
            optimisers that step outside before a penalty pulls them back).
        derivatives : {0, 1, 2}, default 2
            0: energy only; 1: and forces; 2: and element stiffness.
        definiteness_fix : bool, default True
            Project each tetrahedron's 9 x 9 ``d2 psi / dF2`` onto the positive
            semi-definite cone (negative eigenvalues set to 0) before forming its 12 x 12
            stiffness, so the assembled matrix is positive semi-definite (projected Newton).

        Returns
        -------
        ElementResponse
        """
        x = self._positions(x)
        a = self._activations(activations)
        F = x[self.tets].transpose(0, 2, 1) @ self.shape_gradients  # sum_a x_a g_a^T
        iso = mooney_rivlin_response(F, self.material, derivatives=derivatives)
        vol = self.rest_volumes
        energy_density = iso.energy_density.copy()
        P = iso.stress
        A = iso.stress_derivative
        if self._pair_tet.size:
            passive_w, active_w = self._fibre_weights(a)
            fib = fibre_response(F[self._pair_tet], self._pair_direction, passive_w, active_w, self.fibre,
                                 derivatives=derivatives)
            energy_density += np.bincount(self._pair_tet, weights=fib.energy_density, minlength=self.n_tets)
            if P is not None and fib.stress is not None:
                P = P.copy()
                P[self._pair_tets_unique] += np.add.reduceat(fib.stress, self._pair_starts, axis=0)
            if A is not None and fib.stress_derivative is not None:
                A[self._pair_tets_unique] += np.add.reduceat(fib.stress_derivative, self._pair_starts, axis=0)
        energy = float(np.dot(vol, energy_density))
        inverted = int(np.count_nonzero(np.linalg.det(F) <= 0.0))
        if derivatives == 0 or P is None:
            return ElementResponse(energy, np.zeros_like(x), None, inverted)
        forces = self._scatter_nodes(self._corner_forces(P, vol, self.shape_gradients), self.tets)
        if derivatives == 1 or A is None:
            return ElementResponse(energy, forces, None, inverted)
        return ElementResponse(energy, forces, self.element_stiffness(A, definiteness_fix=definiteness_fix),
                               inverted, A)

    def element_stiffness(self, stress_derivative: FloatArray, *, definiteness_fix: bool = True) -> FloatArray:
        """Per-tetrahedron stiffness ``V_e sum_jl A_(ij)(kl) g_aj g_bl``, (m, 12, 12) mN / mm, corner-major.

        Parameters
        ----------
        stress_derivative : (m, 9, 9) float64 array, kPa
            ``A = d2 psi / dF2`` per tetrahedron (``ElementResponse.stress_derivative``).
        definiteness_fix : bool, default True
            Project a copy of each ``A`` onto the positive semi-definite cone first.
        """
        A = stress_derivative
        if definiteness_fix:
            A = A.copy()
            _project_psd(A)
        return _stiffness_blocks(A, self.shape_gradients, self.rest_volumes)

    def energy(self, x: FloatArray, activations: FloatArray) -> float:
        """Total elastic energy ``E(x, a)``, uJ."""
        return self.evaluate(x, activations, derivatives=0).energy

    def forces(self, x: FloatArray, activations: FloatArray) -> FloatArray:
        """Nodal forces ``f(x, a) = -dE/dx``, (n, 3) mN (eq. 1; Dirichlet rows included)."""
        return self.evaluate(x, activations, derivatives=1).forces

    def force_basis(self, x: FloatArray) -> FloatArray:
        """The per-muscle active forces ``f_k(x)`` of eq. 1, i.e. ``df/da``.

        Parameters
        ----------
        x : (n, 3) float64 array, mm

        Returns
        -------
        (k, n, 3) float64 array, mN
            ``f(x, a) = f(x, 0) + sum_k a_k f_k(x)`` exactly.
        """
        x = self._positions(x)
        k, n = self.n_muscles, self.n_nodes
        if self._pair_tet.size == 0:
            return np.zeros((k, n, 3))
        F = x[self.tets[self._pair_tet]].transpose(0, 2, 1) @ self.shape_gradients[self._pair_tet]
        base, _ = self._fibre_weights(np.zeros(k))
        fib = fibre_response(F, self._pair_direction, np.zeros_like(base), base, self.fibre, derivatives=1)
        assert fib.stress is not None
        pair_volumes = self.rest_volumes[self._pair_tet]
        corner = self._corner_forces(fib.stress, pair_volumes, self.shape_gradients[self._pair_tet])
        tets = self.tets[self._pair_tet]
        idx = ((self._pair_muscle[:, None, None] * n + tets[:, :, None]) * 3 + np.arange(3)).reshape(-1)
        return np.bincount(idx, weights=corner.reshape(-1), minlength=k * n * 3).reshape(k, n, 3)

    def stiffness(self, x: FloatArray, activations: FloatArray, *, definiteness_fix: bool = True,
                  free_only: bool = False) -> sp.csr_matrix:
        """The stiffness matrix ``K = d2E/dx2 = -df/dx``, mN / mm.

        Parameters
        ----------
        x : (n, 3) float64 array, mm
        activations : (k,) float64 array
        definiteness_fix : bool, default True
            See :meth:`evaluate`; False gives the exact Hessian.
        free_only : bool, default False
            True: only the rows and columns of the free nodes' coordinates
            (``free_dofs``), the matrix of the Newton and Jacobian solves.

        Returns
        -------
        scipy.sparse.csr_matrix, (3n, 3n) or (len(free_dofs),) * 2
            Coordinates interleaved: row ``3 i + c`` is node ``i``, axis ``c``.
        """
        response = self.evaluate(x, activations, derivatives=2, definiteness_fix=definiteness_fix)
        assert response.element_stiffness is not None
        return self.assemble(response.element_stiffness, free_only=free_only)

    def assemble(self, element_stiffness: FloatArray, *, free_only: bool = True) -> sp.csr_matrix:
        """Sum per-tetrahedron stiffness blocks (m, 12, 12) into the global CSR matrix.

        The sparsity pattern is computed on first use and reused: each call only refills
        the value array.
        """
        if free_only:
            if self._free_pattern is None:
                index = np.full(3 * self.n_nodes, -1, dtype=np.int64)
                index[self.free_dofs] = np.arange(self.free_dofs.size)
                self._free_pattern = _Pattern(self.tets, index, self.free_dofs.size)
            return self._free_pattern.assemble(element_stiffness)
        if self._full_pattern is None:
            self._full_pattern = _Pattern(self.tets, np.arange(3 * self.n_nodes), 3 * self.n_nodes)
        return self._full_pattern.assemble(element_stiffness)

    def element_action(self, element_stiffness: FloatArray, displacement: FloatArray) -> FloatArray:
        """``K u`` from per-tetrahedron blocks without assembling: (n, 3) for ``u`` (n, 3).

        Used for the boundary term of eq. 6, ``K_UC dX_C``: pass a displacement that is
        non-zero only on Dirichlet nodes and read the free rows.
        """
        u = self._positions(displacement)
        ue = u[self.tets].reshape(-1, 12)
        touched = np.flatnonzero(np.any(ue != 0.0, axis=1))
        Ku = np.einsum("eij,ej->ei", element_stiffness[touched], ue[touched]).reshape(-1, 4, 3)
        return self._scatter_nodes(Ku, self.tets[touched])
