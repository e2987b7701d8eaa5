"""Quasistatic equilibrium ``f(X(a, b), a) = 0`` (Sifakis et al. 2005, eq. 2) by projected Newton.

Each Newton step assembles the stiffness with every tetrahedron's stress derivative
projected onto the positive semi-definite cone (so the step is a descent direction even
for inverted or strongly compressed tetrahedra), factors it once with a sparse Cholesky-
type solver, and backtracks along the step until the energy decreases enough (Armijo).
The factor of the last stiffness stays available for the Jacobians of eq. 5 and 6.

An optional external energy (:class:`ExternalEnergy`, e.g. the penalty contact of a
kinematic sphere, :class:`~facecap.fem.SphereContact`) joins the elastic energy, its
forces and its (positive semi-definite) stiffness in every step; without one the solve
is exactly the elastic one.
"""

from __future__ import annotations

import time
import warnings
from typing import Any, Literal, NamedTuple, Protocol

import numpy as np
import scipy.sparse as sp

from ..mesh.factor_spd import SpdFactor
from ..errors import FacecapWarning, InputError, SolverError
from ..typing import FloatArray
from .flesh_model import ElementResponse, FleshModel

__all__ = ["QuasistaticSolver", "QuasistaticResult", "solve_quasistatic", "ExternalEnergy", "ExternalResponse"]


# The projected steps' Marquardt damping (see QuasistaticSolver.solve): the first weight, its factor up
# and down, the step length below which a step counts as overshooting, and the weight past which a
# step that finds no decrease ends the solve
_FIRST_DAMPING = 1e-3
_DAMPING_GROWTH = 4.0
_OVERSHOOT_ALPHA = 0.1
_MAX_DAMPING = 1e3


class ExternalResponse(NamedTuple):
    """An external energy term evaluated at one configuration.

    Attributes
    ----------
    energy : float, uJ
    forces : (n, 3) float64 array, mN
        ``-dE_ext/dx`` on every node (Dirichlet rows included; the solver reads the free ones).
    stiffness : (3n, 3n) scipy.sparse matrix, mN / mm, or None
        ``d2E_ext/dx2``, positive semi-definite, coordinates interleaved (row ``3 i + c`` is
        node ``i``, axis ``c``); None when not asked for.
    """

    energy: float
    forces: FloatArray
    stiffness: Any


class ExternalEnergy(Protocol):
    """What :meth:`QuasistaticSolver.solve` accepts as ``external``: an energy of the node positions.

    ``evaluate(x, stiffness=...)`` returns an :class:`ExternalResponse`; its stiffness must be
    positive semi-definite (the Newton steps stay descent directions) and is asked for only
    where a step needs it.
    """

    def evaluate(self, x: FloatArray, *, stiffness: bool = True) -> ExternalResponse: ...


class QuasistaticResult(NamedTuple):
    """The outcome of one quasistatic solve.

    Attributes
    ----------
    positions : (n, 3) float64 array, mm
        Equilibrium node positions (Dirichlet nodes at their prescribed positions).
    converged : bool
        Whether the largest free nodal residual fell below the tolerance.
    iterations : int
        Newton steps taken.
    residual : float, mN
        Largest free nodal residual force norm at ``positions``.
    energy : float, uJ
        Elastic energy at ``positions`` (plus the external energy, when the solve had one).
    inverted_tets : int
        Tetrahedra with ``det F <= 0`` at ``positions``.
    inverted_tets_initial : int
        The same at the initial guess.
    timings : dict of str to float, s
        ``assembly`` (element stiffness, projection, CSR refill), ``factorisation``
        (including attempts on an exact stiffness that was not positive definite),
        ``solves`` and ``line_search`` (energy and forces at the trial points), summed
        over the steps. The stiffness at the solution is assembled only when a Jacobian
        asks for it (:meth:`QuasistaticSolver.factor`).
    projected_steps : int
        Steps that used the projected stiffness (the others used the exact one).
    """

    positions: FloatArray
    converged: bool
    iterations: int
    residual: float
    energy: float
    inverted_tets: int
    inverted_tets_initial: int
    timings: dict[str, float]
    projected_steps: int


class QuasistaticSolver:
    """Solve the flesh's quasistatic equilibrium, then reuse the factorisation.

    Parameters
    ----------
    model : FleshModel
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
        Sparse factorisation (:class:`facecap.mesh.SpdFactor`): MKL PARDISO where it
        loads, else SciPy's SuperLU.
    tolerance : float, default 1e-4
        Converged when every free node's residual force is below
        ``tolerance * mu * h^2`` (``mu`` the small-strain shear modulus, ``h`` the mean
        rest edge length): the force a strain of ``tolerance`` puts on one element face.
        On the benchmark slab (2 mm cubes) the next Newton step at that residual moves no
        node more than about 1e-5 mm, far below marker noise.
    max_iterations : int, default 30
    max_halvings : int, default 30
        Line-search halvings of the step before giving up.
    exact_jacobians : bool, default True
        The Jacobians (:meth:`solve_linear` and what uses it) factor the exact stiffness at
        the solution, which is positive definite at a stable equilibrium (Sifakis et al.
        2005, section 6), so they are the true derivatives of the equilibrium. Where it is
        not (PARDISO reports it), they fall back to the projected stiffness of the Newton
        steps with a :class:`FacecapWarning`. False: always the projected one (approximate
        derivatives wherever a tetrahedron was projected).

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0., 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10], [4, 4, 4]])
    >>> T = np.array([[0, 1, 2, 4], [0, 1, 4, 3], [0, 4, 2, 3], [1, 2, 3, 4]])
    >>> model = FleshModel(X, T, None, None, np.array([0, 1, 2, 3]))
    >>> result = QuasistaticSolver(model).solve(np.zeros(0), X[:4], x0=X + [0, 0, 3])
    >>> result.converged, bool(np.abs(result.positions - X).max() < 1e-6)
    (True, True)
    """

    def __init__(self, model: FleshModel, *, backend: Literal["auto", "pardiso", "scipy"] = "auto",
                 tolerance: float = 1e-4, max_iterations: int = 30, max_halvings: int = 30,
                 exact_jacobians: bool = True) -> None:
        if not isinstance(model, FleshModel):
            raise InputError(f"model: expected a FleshModel, got {type(model).__name__}")
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise InputError(f"tolerance: expected a positive value, got {tolerance!r}")
        self.model = model
        self.backend = backend
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.max_halvings = int(max_halvings)
        self.exact_jacobians = bool(exact_jacobians)
        self.jacobian_stiffness: str | None = None  # 'exact' or 'projected' once factored
        self.force_tolerance_mn = self.tolerance * model.material.shear_modulus_kpa * model.mean_edge_mm**2
        self._factor: SpdFactor | None = None
        self._stiffness: Any = None
        self._element_stiffness: FloatArray | None = None  # the blocks of the factored matrix
        self._state: ElementResponse | None = None
        self._positions: FloatArray | None = None
        self._activations: FloatArray | None = None
        self._external: ExternalEnergy | None = None

    def _initial_positions(self, dirichlet_positions: Any, x0: Any) -> FloatArray:
        model = self.model
        xc = np.asarray(dirichlet_positions, dtype=np.float64)
        if xc.shape != (model.dirichlet_nodes.size, 3) or not np.all(np.isfinite(xc)):
            raise InputError(f"dirichlet_positions: expected finite shape ({model.dirichlet_nodes.size}, 3), "
                             f"got {xc.shape}")
        if x0 is None:
            x = model.rest_positions.copy()
        else:
            x = np.array(x0, dtype=np.float64)
            if x.shape != model.rest_positions.shape or not np.all(np.isfinite(x)):
                raise InputError(f"x0: expected finite shape {model.rest_positions.shape}, got {x.shape}")
        x[model.dirichlet_nodes] = xc
        return x

    def solve(self, activations: FloatArray, dirichlet_positions: FloatArray,
              x0: FloatArray | None = None, *, external: ExternalEnergy | None = None) -> QuasistaticResult:
        """Equilibrium positions under ``activations`` with the Dirichlet nodes at ``dirichlet_positions``.

        Parameters
        ----------
        activations : (k,) float64 array
            Muscle activations (physically in [0, 1]).
        dirichlet_positions : (d, 3) float64 array, mm
            Positions of ``model.dirichlet_nodes``, in that order.
        x0 : (n, 3) float64 array, mm, optional
            Initial guess (the previous frame's solution, interpolated states in a line
            search); default the rest positions. Its Dirichlet rows are replaced.
        external : ExternalEnergy, optional
            An energy added to the elastic one (a contact penalty, say): its forces join the
            residual, its energy the line search, its stiffness every Newton step and the
            factor of :meth:`factor` (so the Jacobians are those of the total energy). None
            (default): the elastic solve, unchanged.

        Returns
        -------
        QuasistaticResult
            Not converged is reported there, not raised; the positions are the last iterate.

        Raises
        ------
        SolverError
            If the factorisation fails (no Dirichlet support for some part of the mesh).

        Notes
        -----
        Each step first tries the exact stiffness: where it is positive definite (PARDISO
        factors it, and the step descends) the step is a full Newton step, with quadratic
        convergence near a stable equilibrium. Where it is not (far from equilibrium,
        inverted or strongly compressed tetrahedra), the step uses the projected stiffness
        (every tetrahedron's ``d2 psi / dF2`` clamped to positive semi-definite), and the
        exact one is tried again after the next full (alpha = 1) projected step. The
        projected stiffness alone converges only linearly here, since at the equilibrium of
        a compressed, nearly incompressible flesh many tetrahedra are projected. Where a
        projected step overshoots (the line search keeps under a tenth of it, or finds no
        decrease), the next ones are damped (``K + mu diag(K)``, ``mu`` from ``1e-3`` up by
        4x each time, down by 4x after each full step but not below ``1e-3`` again); an exact
        step that finds no decrease is followed by a projected one from the same point.
        """
        model = self.model
        a = model._activations(activations)
        x = self._initial_positions(dirichlet_positions, x0)
        free = model.free_dofs
        timings = {"assembly": 0.0, "factorisation": 0.0, "solves": 0.0, "line_search": 0.0}
        self._drop_factor()
        self._external = external
        t = time.perf_counter()
        state = model.evaluate(x, a, definiteness_fix=False)
        extra = None  # the external stiffness on the free dofs, where a step needs it
        if external is not None:
            state, extra = self._with_external(state, x, stiffness=True)
        timings["assembly"] += time.perf_counter() - t
        inverted_initial = state.inverted
        iterations = projected_steps = 0
        converged = False
        wait_before_exact = 0  # steps to take with the projected stiffness before trying the exact one
        damping = 0.0  # Marquardt weight on the projected stiffness's diagonal: raised where its steps overshoot
        damping_floor = 0.0  # once a step overshot, the damping stays at least the first weight
        while True:
            residual = state.forces[model.free_nodes]
            residual_max = float(np.sqrt((residual**2).sum(axis=1)).max(initial=0.0))
            if residual_max <= self.force_tolerance_mn:
                converged = True
                break
            if iterations >= self.max_iterations:
                break
            if state.element_stiffness is None:  # the line search's state has forces, not stiffness
                t = time.perf_counter()
                state = model.evaluate(x, a, definiteness_fix=False)
                if external is not None:
                    state, extra = self._with_external(state, x, stiffness=True)
                timings["assembly"] += time.perf_counter() - t
            r = residual.reshape(-1)
            step = None
            exact = False
            if wait_before_exact == 0:
                assert state.element_stiffness is not None
                step = self._newton_step(state.element_stiffness, r, timings, extra=extra)
                exact = step is not None
                if step is None:
                    wait_before_exact = 1
            if step is None:
                assert state.stress_derivative is not None
                t = time.perf_counter()
                projected = model.element_stiffness(state.stress_derivative, definiteness_fix=True)
                timings["assembly"] += time.perf_counter() - t
                step = self._newton_step(projected, r, timings, must_succeed=True, extra=extra, damping=damping)
                assert step is not None
                projected_steps += 1
            t = time.perf_counter()
            x, alpha, trial = self._line_search(x, a, state.energy, r, step, free)
            timings["line_search"] += time.perf_counter() - t
            iterations += 1
            if not exact:
                # The projection sets an active fibre's negative stiffness (the force-length curve's
                # descending limb) to zero; where little else holds a node in that direction the
                # projected step is far too long there, and the line search crawls (steps of 1e-9 of
                # it, seen on an occasional fTetWild mesh, then no decrease at all). A Marquardt
                # damping shortens such a step where it overshoots and fades once full steps are taken.
                if alpha < _OVERSHOOT_ALPHA:  # no decrease at all (alpha 0) included
                    damping = max(_DAMPING_GROWTH * damping, _FIRST_DAMPING)
                    damping_floor = _FIRST_DAMPING  # taken off, the overshoot came back at once (seen)
                elif alpha == 1.0:
                    damping = max(damping / _DAMPING_GROWTH, damping_floor)
            if alpha == 0.0 or trial is None:
                if exact:
                    # An exact step that positive definiteness let through can still point where the energy
                    # does not decrease within the halvings (an indefinite region the factor did not see):
                    # take the projected step from the same point rather than end the solve there
                    wait_before_exact = 1
                    continue
                if damping <= _MAX_DAMPING:  # retry from the same point, damped further
                    continue
                break
            state = trial  # energy and forces at the new x; its stiffness only if another step follows
            if alpha == 1.0 and wait_before_exact > 0:
                wait_before_exact -= 1
        self._positions, self._activations, self._state = x, a, state
        return QuasistaticResult(x, converged, iterations, residual_max, state.energy, state.inverted,
                                 inverted_initial, timings, projected_steps)

    def _with_external(self, state: ElementResponse, x: FloatArray, *,
                       stiffness: bool) -> tuple[ElementResponse, Any]:
        """The elastic state plus the external term's energy and forces, and its free-dof stiffness (or None)."""
        assert self._external is not None
        response = self._external.evaluate(x, stiffness=stiffness)
        forces = np.asarray(response.forces, dtype=np.float64)
        if forces.shape != state.forces.shape:
            raise InputError(f"external: forces of shape {forces.shape}, expected {state.forces.shape}")
        state = state._replace(energy=state.energy + float(response.energy), forces=state.forces + forces)
        if not stiffness or response.stiffness is None:
            return state, None
        free = self.model.free_dofs
        return state, sp.csr_matrix(response.stiffness)[free][:, free]

    def _newton_step(self, element_stiffness: FloatArray, r: FloatArray, timings: dict[str, float], *,
                     must_succeed: bool = False, extra: Any = None, damping: float = 0.0) -> FloatArray | None:
        """Solve ``K step = r``; None where ``K`` is not positive definite (unless ``must_succeed``).

        ``extra``: the external energy's free-dof stiffness, added to ``K``. ``damping``: ``K``
        becomes ``K + damping * diag(K)`` (Marquardt; the diagonal floored at ``1e-8`` of its mean).
        """
        t = time.perf_counter()
        K = self.model.assemble(element_stiffness, free_only=True)
        if extra is not None:
            K = (K + extra).tocsr()
        if damping > 0.0:
            diagonal = np.abs(K.diagonal())
            diagonal = np.maximum(diagonal, 1e-8 * (float(diagonal.mean()) or 1.0))
            K = (K + sp.diags(damping * diagonal)).tocsr()
        timings["assembly"] += time.perf_counter() - t
        t = time.perf_counter()
        try:
            factor = SpdFactor(K, backend=self.backend)
        except SolverError:
            if not must_succeed:
                return None
            factor = self._shifted_factor(K)
        finally:
            timings["factorisation"] += time.perf_counter() - t
        t = time.perf_counter()
        step = factor.solve(r)  # K step = f: a descent direction of E when K is positive definite
        factor.free()
        timings["solves"] += time.perf_counter() - t
        # SuperLU factors indefinite matrices too: a step that does not descend is rejected here.
        if not must_succeed and float(np.dot(r, step)) <= 0.0:
            return None
        return step

    def _shifted_factor(self, K: sp.csr_matrix) -> SpdFactor:
        """Factor the projected stiffness ``K + mu I`` for the smallest ``mu`` that works.

        The projected stiffness is positive semi-definite by construction, but where every element
        round a node is flattened its projection can leave that node without stiffness in some
        direction: singular, and refused by the factorisation (PARDISO's zero pivot, seen once in a
        few dozen jaw sweeps on fTetWild meshes, which differ from run to run). A shift of
        ``1e-10``-``1e-4`` of the mean diagonal makes it definite and keeps the step a descent
        direction (Levenberg); the line search then decides how far to go.
        """
        scale = float(np.abs(K.diagonal()).mean()) or 1.0
        identity = sp.identity(K.shape[0], format="csr")
        for shift in (1e-10, 1e-8, 1e-6, 1e-4):
            try:
                return SpdFactor((K + (shift * scale) * identity).tocsr(), backend=self.backend)
            except SolverError:
                continue
        raise SolverError("the projected stiffness cannot be factored even shifted by 1e-4 of its mean diagonal")

    def _line_search(self, x: FloatArray, a: FloatArray, energy: float, r: FloatArray, step: FloatArray,
                     free: Any) -> tuple[FloatArray, float, ElementResponse | None]:
        """Backtracking (Armijo) on the energy along ``step``.

        Returns the new positions, the step length (0: no decrease found) and the model's
        energy and forces there (the forces come almost free with the energy and decide
        convergence without assembling a stiffness that would not be used).
        """
        slope = -float(np.dot(r, step))  # dE/dalpha at 0, negative for a descent step
        # The energy is a sum of element terms: below this difference the comparison is round-off.
        noise = 1e-12 * (abs(energy) + 1.0) + 1e-9 * self.force_tolerance_mn * float(np.abs(step).max(initial=0.0))
        alpha = 1.0
        flat = x.reshape(-1)
        for _ in range(self.max_halvings + 1):
            trial = flat.copy()
            trial[free] += alpha * step
            trial_x = trial.reshape(x.shape)
            response = self.model.evaluate(trial_x, a, derivatives=1)
            if self._external is not None:
                response = self._with_external(response, trial_x, stiffness=False)[0]
            if np.isfinite(response.energy) and response.energy <= energy + 1e-4 * alpha * slope + noise:
                return trial_x, alpha, response
            alpha *= 0.5
        return x, 0.0, None

    # -- reuse of the factorisation (eq. 5 and 6) ----------------------------------------------
    def _drop_factor(self) -> None:
        if self._factor is not None:
            self._factor.free()
        self._factor = None
        self._stiffness = None
        self.jacobian_stiffness = None

    def factor(self) -> SpdFactor:
        """The factorised free-node stiffness at the last solution (factored on first use).

        The exact stiffness where it is positive definite (see ``exact_jacobians``), else
        the projected one (shifted as in :meth:`_shifted_factor` where it is singular);
        ``jacobian_stiffness`` says which.
        """
        if self._state is None or self._positions is None or self._activations is None:
            raise InputError("no solution yet: call solve() first")
        if self._state.element_stiffness is None:  # the solve ended on the line search's forces
            self._state = self.model.evaluate(self._positions, self._activations, definiteness_fix=False)
        state = self._state
        assert state.element_stiffness is not None and state.stress_derivative is not None
        if self._factor is None:
            extra = None
            if self._external is not None:
                extra = self._with_external(state, self._positions, stiffness=True)[1]
            if self.exact_jacobians:
                stiffness = self.model.assemble(state.element_stiffness, free_only=True)
                if extra is not None:
                    stiffness = (stiffness + extra).tocsr()
                try:
                    self._factor = SpdFactor(stiffness, backend=self.backend)
                    self._element_stiffness, self._stiffness = state.element_stiffness, stiffness
                    self.jacobian_stiffness = "exact"
                    return self._factor
                except SolverError:
                    warnings.warn("the stiffness at the solution is not positive definite (an unstable "
                                  "equilibrium, or inverted tetrahedra); the Jacobians use the projected "
                                  "stiffness and are approximate", FacecapWarning, stacklevel=2)
            self._element_stiffness = self.model.element_stiffness(state.stress_derivative, definiteness_fix=True)
            self._stiffness = self.model.assemble(self._element_stiffness, free_only=True)
            if extra is not None:
                self._stiffness = (self._stiffness + extra).tocsr()
            try:
                self._factor = SpdFactor(self._stiffness, backend=self.backend)
            except SolverError:  # singular where every element round a node is flattened: see _shifted_factor
                self._factor = self._shifted_factor(self._stiffness)
            self.jacobian_stiffness = "projected"
        return self._factor

    def solve_linear(self, rhs: FloatArray) -> FloatArray:
        """Solve ``K_UU u = rhs_U`` with the stiffness at the last solution, reusing its factor.

        Parameters
        ----------
        rhs : (n, 3) or (c, n, 3) float64 array, mN
            Nodal right-hand side(s); the Dirichlet rows are ignored.

        Returns
        -------
        float64 array like ``rhs``, mm
            ``u`` on the free nodes, zero on the Dirichlet nodes.
        """
        model = self.model
        b = np.asarray(rhs, dtype=np.float64)
        single = b.ndim == 2
        B = b[None] if single else b
        if B.ndim != 3 or B.shape[1:] != (model.n_nodes, 3):
            raise InputError(f"rhs: expected shape ({model.n_nodes}, 3) or (c, {model.n_nodes}, 3), got {b.shape}")
        cols = B.reshape(B.shape[0], -1)[:, model.free_dofs].T
        u_free = self.factor().solve(np.ascontiguousarray(cols))
        out = np.zeros(B.shape)  # C-contiguous, so the reshape below is a view
        out.reshape(B.shape[0], -1)[:, model.free_dofs] = np.asarray(u_free).reshape(cols.shape).T
        return out[0] if single else out

    def activation_jacobian(self) -> FloatArray:
        """``dX/da_k`` at the last solution (eq. 5): ``K_UU dX_U/da_k = f_k(X)``, (k, n, 3) mm."""
        if self._positions is None:
            raise InputError("no solution yet: call solve() first")
        return self.solve_linear(self.model.force_basis(self._positions))

    def boundary_jacobian(self, dirichlet_velocity: FloatArray) -> FloatArray:
        """``dX/db`` for motions of the Dirichlet nodes (eq. 6): ``K_UU dX_U = -K_UC dX_C``.

        Parameters
        ----------
        dirichlet_velocity : (d, 3) or (c, d, 3) float64 array, mm per unit of the control
            ``dX_C/db_i`` for ``model.dirichlet_nodes``; several controls at once share one
            solve with ``c`` right-hand sides.

        Returns
        -------
        (n, 3) or (c, n, 3) float64 array, mm per unit of the control
            Free rows from the solve, Dirichlet rows equal to ``dirichlet_velocity``.
        """
        model = self.model
        self.factor()  # fixes which stiffness (exact or projected) the Jacobians use
        assert self._element_stiffness is not None
        v = np.asarray(dirichlet_velocity, dtype=np.float64)
        single = v.ndim == 2
        V = v[None] if single else v
        if V.ndim != 3 or V.shape[1:] != (model.dirichlet_nodes.size, 3):
            raise InputError(f"dirichlet_velocity: expected shape ({model.dirichlet_nodes.size}, 3) or "
                             f"(c, {model.dirichlet_nodes.size}, 3), got {v.shape}")
        rhs = np.empty((V.shape[0], model.n_nodes, 3))
        u = np.zeros((model.n_nodes, 3))
        external = None
        if self._external is not None and self._positions is not None:
            external = self._external.evaluate(self._positions, stiffness=True).stiffness
        for i, vi in enumerate(V):
            u[model.dirichlet_nodes] = vi
            rhs[i] = -model.element_action(self._element_stiffness, u)
            if external is not None:  # the external term's coupling of the free nodes to the moved ones
                rhs[i] -= (external @ u.reshape(-1)).reshape(-1, 3)
        out = self.solve_linear(rhs)
        out[:, model.dirichlet_nodes] = V
        return out[0] if single else out


def solve_quasistatic(model: FleshModel, activations: FloatArray, dirichlet_positions: FloatArray,
                      x0: FloatArray | None = None, **options: Any) -> QuasistaticResult:
    """One-shot :meth:`QuasistaticSolver.solve` (``options`` go to :class:`QuasistaticSolver`).

    Parameters
    ----------
    model : FleshModel
    activations : (k,) float64 array
    dirichlet_positions : (d, 3) float64 array, mm
    x0 : (n, 3) float64 array, mm, optional

    Returns
    -------
    QuasistaticResult
    """
    return QuasistaticSolver(model, **options).solve(activations, dirichlet_positions, x0)
