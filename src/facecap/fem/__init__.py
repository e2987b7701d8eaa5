"""The flesh finite element model of Sifakis, Neverov and Fedkiw 2005 (section 4).

Arrays in, arrays out: rest nodes ``X (n, 3)`` mm, tetrahedra ``T (m, 4)`` positively
oriented, per-tetrahedron muscle volume fractions ``(m, k)`` and fibre directions
``(m, k, 3)``, Dirichlet nodes with their prescribed positions, activations ``(k,)``.
Stresses in kPa, energies in uJ, forces in mN (see ``docs/fem.md``).

- :class:`MooneyRivlin`, :func:`mooney_rivlin_response`, :class:`StressResponse`
  (``mooney_rivlin.py``): the isotropic flesh, Mooney-Rivlin on the isochoric invariants
  plus a volumetric term, defined for inverted tetrahedra.
- :class:`MuscleFibre`, :func:`active_force_length`, :func:`passive_force_length`,
  :func:`fibre_response` (``muscle_fibre.py``): the along-fibre muscle term with
  Blemker et al. 2005's force-length curves.
- :class:`FleshModel`, :class:`ElementResponse` (``flesh_model.py``): the assembled model,
  energy, forces ``f(x, a) = f0(x) + sum_k a_k f_k(x)`` (eq. 1), the force basis
  ``f_k``, the stiffness matrix in a reused sparsity pattern.
- :class:`QuasistaticSolver`, :func:`solve_quasistatic`, :class:`QuasistaticResult`
  (``solve_quasistatic.py``): the equilibrium of eq. 2 by projected Newton with an energy
  line search, and the reused factorisation for the Jacobians of eq. 5 and 6; an optional
  external energy (:class:`ExternalEnergy`, :class:`ExternalResponse`) joins the solve.
- :class:`SphereContact` (``sphere_contact.py``): a kinematic sphere's penalty contact on
  nodes or embedded points, an external energy of the solve (sec. 9).
"""

from __future__ import annotations

from .mooney_rivlin import MooneyRivlin, StressResponse, mooney_rivlin_response
from .muscle_fibre import MuscleFibre, active_force_length, fibre_response, passive_force_length
from .flesh_model import ElementResponse, FleshModel
from .solve_quasistatic import ExternalEnergy, ExternalResponse, QuasistaticResult, QuasistaticSolver, solve_quasistatic
from .sphere_contact import SphereContact

__all__ = [
    "MooneyRivlin",
    "StressResponse",
    "mooney_rivlin_response",
    "MuscleFibre",
    "active_force_length",
    "passive_force_length",
    "fibre_response",
    "FleshModel",
    "ElementResponse",
    "QuasistaticSolver",
    "QuasistaticResult",
    "solve_quasistatic",
    "ExternalEnergy",
    "ExternalResponse",
    "SphereContact",
]
