"""The face as a function of its controls: the flesh model of an anatomy with its bones moved by two frames."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..fem import FleshModel, MooneyRivlin, MuscleFibre, QuasistaticResult, QuasistaticSolver
from ..typing import FloatArray, IntArray
from .jaw_constraints import JawConstraints

__all__ = ["MuscleModel", "FOLLOWER_WEIGHT_LIMIT"]

FOLLOWER_WEIGHT_LIMIT = 3.0
"""Scan vertices whose embedding weights stay within +-this follow the mesh; the others
(ears, scalp, neck: far outside the meshed region) move rigidly with the cranium."""


def apply_affine(transform: FloatArray, points: FloatArray) -> FloatArray:
    """``M x + t`` for a ``(3, 4)`` transform and points ``(..., 3)``."""
    return points @ transform[:, :3].T + transform[:, 3]


class MuscleModel:
    """The quasistatic face of an anatomy under activations and bone frames (eq. 2, sec. 8).

    The flesh is solved in the cranium's frame (the rest, scan coordinates): cranium nodes
    stay at rest, mandible nodes move by the jaw's transform relative to the cranium, and the
    whole equilibrium then moves with the cranium's frame. For a rigid cranium transform this
    is the equilibrium of the moved bones exactly (the energy is invariant under rotations),
    and it makes the positions linear in the cranium's 12 coefficients, whose Jacobian is
    then analytic (the paper's section 8).

    Parameters
    ----------
    anatomy : FaceAnatomy
    muscle_strength : (k,) float64 array, optional
        Per-muscle strength scale of the flesh model (default 1 for all).
    material : MooneyRivlin, optional
    fibre : MuscleFibre, optional
    force_length_scale : float, default 1
        The paper's exaggeration (sec. 9), see :class:`~facecap.fem.FleshModel`.
    jaw : JawConstraints, optional
        Default :meth:`JawConstraints.from_anatomy`.
    rim : {'bone', 'free'}, default 'bone'
        The rim nodes (where the face region was cut from the head): 'bone' holds each with
        the bone of its nearest bone node (cranium or mandible), 'free' leaves them free.
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
    tolerance : float, default 1e-4
        Of the quasistatic solver (:class:`~facecap.fem.QuasistaticSolver`).

    Attributes
    ----------
    flesh : FleshModel
    solver : QuasistaticSolver
    jaw : JawConstraints
    cranium_set, mandible_set : int64 arrays
        Dirichlet nodes moving with the cranium and with the mandible; the flesh model's
        ``dirichlet_nodes`` are the first then the second.
    reused_last : bool
        Whether the last :meth:`equilibrium` call returned the stored solution without solving.
    """

    def __init__(self, anatomy: Any, *, muscle_strength: FloatArray | None = None,
                 material: MooneyRivlin = MooneyRivlin(), fibre: MuscleFibre = MuscleFibre(),
                 force_length_scale: float = 1.0, jaw: JawConstraints | None = None,
                 rim: Literal["bone", "free"] = "bone", backend: Literal["auto", "pardiso", "scipy"] = "auto",
                 tolerance: float = 1e-4) -> None:
        for name in ("nodes", "tets", "cranium_nodes", "mandible_nodes", "rim_nodes", "skin_tets", "skin_weights"):
            if not hasattr(anatomy, name):
                raise InputError(f"anatomy: expected a FaceAnatomy, missing {name!r}")
        if rim not in ("bone", "free"):
            raise InputError(f"rim: expected 'bone' or 'free', got {rim!r}")
        self.anatomy = anatomy
        cranium = np.asarray(anatomy.cranium_nodes, dtype=np.int64)
        mandible = np.asarray(anatomy.mandible_nodes, dtype=np.int64)
        if mandible.size < 3:
            raise InputError("anatomy: the mandible has fewer than 3 bone nodes")
        if rim == "bone" and anatomy.rim_nodes.size:
            bone = np.concatenate([cranium, mandible])
            _, nearest = cKDTree(anatomy.nodes[bone]).query(anatomy.nodes[anatomy.rim_nodes])
            on_jaw = nearest >= cranium.size
            cranium = np.union1d(cranium, anatomy.rim_nodes[~on_jaw])
            mandible = np.union1d(mandible, anatomy.rim_nodes[on_jaw])
        self.cranium_set: IntArray = cranium
        self.mandible_set: IntArray = mandible
        self.flesh = FleshModel(anatomy.nodes, anatomy.tets, anatomy.muscle_fractions, anatomy.muscle_fibres,
                                np.concatenate([cranium, mandible]), material=material, fibre=fibre,
                                muscle_strength=muscle_strength, force_length_scale=force_length_scale)
        self.solver = QuasistaticSolver(self.flesh, backend=backend, tolerance=tolerance)
        self.jaw = jaw if jaw is not None else JawConstraints.from_anatomy(anatomy)
        self.rest_positions: FloatArray = self.flesh.rest_positions
        self._mandible_rest = self.rest_positions[mandible]
        weights = np.asarray(anatomy.skin_weights)
        self.skin_follows: np.ndarray = np.abs(weights).max(axis=1) <= FOLLOWER_WEIGHT_LIMIT
        self._rest_skin = np.asarray(anatomy.skin_positions(), dtype=np.float64)
        self._last: tuple[FloatArray, FloatArray, QuasistaticResult] | None = None
        self.reused_last = False

    @property
    def n_muscles(self) -> int:
        """k."""
        return self.flesh.n_muscles

    def bone_positions(self, mandible: FloatArray) -> FloatArray:
        """The Dirichlet positions ``(d, 3)`` mm in the cranium's frame for a mandible transform ``(3, 4)``."""
        return np.concatenate([self.rest_positions[self.cranium_set], apply_affine(mandible, self._mandible_rest)])

    def equilibrium(self, activations: FloatArray, mandible: FloatArray,
                    x0: FloatArray | None = None) -> QuasistaticResult:
        """Quasistatic node positions in the cranium's frame (eq. 2); the solver keeps its factor.

        A call with the controls of the last solve and ``x0`` within 1e-9 mm of its solution
        returns that solution again (0 iterations) without solving, so its factor (and the
        Jacobians) stay valid: a Gauss-Newton step that starts where the last one ended
        does not repeat the assembly.
        """
        a = np.asarray(activations, dtype=np.float64).reshape(-1)
        b = np.asarray(mandible, dtype=np.float64)
        last = self._last
        if (last is not None and x0 is not None and np.array_equal(last[0], a) and np.array_equal(last[1], b)
                and np.shape(x0) == last[2].positions.shape
                and float(np.abs(np.asarray(x0) - last[2].positions).max()) <= 1e-9):
            self.reused_last = True
            return last[2]._replace(iterations=0, projected_steps=0, inverted_tets_initial=last[2].inverted_tets,
                                    timings={key: 0.0 for key in last[2].timings})
        result = self.solver.solve(a, self.bone_positions(b), x0=x0)
        self._last = (a.copy(), b.copy(), result)
        self.reused_last = False
        return result

    def mandible_velocities(self) -> FloatArray:
        """``dX_C / db`` for the 12 mandible coefficients ``[vec(M_m), t_m]``: (12, d, 3) mm per unit."""
        d = self.cranium_set.size + self.mandible_set.size
        out = np.zeros((12, d, 3))
        rows = slice(self.cranium_set.size, d)
        for i in range(3):
            for j in range(3):
                out[3 * i + j, rows, i] = self._mandible_rest[:, j]
            out[9 + i, rows, i] = 1.0
        return out

    def jacobians(self, *, jaw: bool = True) -> tuple[FloatArray, FloatArray | None]:
        """At the last equilibrium: ``dX/da`` (k, n, 3) by eq. 5 and ``dX/db_m`` (12, n, 3) by eq. 6.

        Both in the cranium's frame, mm per unit control; one factorisation for all.
        The second is None when ``jaw`` is False.
        """
        dXa = self.solver.activation_jacobian()
        if not jaw:
            return dXa, None
        return dXa, self.solver.boundary_jacobian(self.mandible_velocities())

    def skin(self, x: FloatArray) -> FloatArray:
        """Scan vertices ``(n_scan, 3)`` mm in the cranium's frame from nodes ``x`` in that frame.

        Vertices whose embedding weights exceed :data:`FOLLOWER_WEIGHT_LIMIT` (far outside the
        meshed region) stay at rest in the cranium's frame.
        """
        out = self._rest_skin.copy()
        follows = self.skin_follows
        corners = np.asarray(x)[self.anatomy.tets[self.anatomy.skin_tets[follows]]]
        out[follows] = np.einsum("ij,ijk->ik", self.anatomy.skin_weights[follows], corners)
        return out
