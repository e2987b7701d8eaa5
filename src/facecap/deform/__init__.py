"""Large-scale deformation of a scan by mocap markers (Bickel et al. 2007, section 4).

The solvers; the job that strings them together for ``facecap animate`` is
:func:`facecap.pipelines.animate_scan`. In the order a user meets them:

- :func:`choose_rest_pose` (``rest_pose.py``): where the warp puts the rest
  markers (the scan's expression, an expression the actor holds at rest, or a
  neutral reference: :func:`neutral_from_frames`, :func:`neutral_from_take`),
  as a :class:`RestPose`; :data:`REST_POSES`, :func:`parse_frame_range`.
- :class:`TriharmonicWarp` (``triharmonic_warp.py``): the mocap-to-scan space
  warp of section 4.1, ``TriharmonicWarp(m0, f0)(m_t)``.
- :class:`ThinShellSolver` (``thin_shell.py``): the linear thin shell of
  section 4.2, factored once, ``ThinShellSolver(V, F, marker_vertices).displacements(d)``;
  :func:`thin_shell_deform` is the one-shot form.
- :class:`BasisProduct` (``basis_product.py``): the per-frame dense product
  (the hot path) in float32 or int16 fixed point.
- :class:`MarkerOffsets` (``marker_offsets.py``): marker displacements to skin
  displacements, the markers' height above the skin carried with the surface;
  :func:`marker_ring` its mesh side (the triangles round the markers, the scan's
  normals there), which needs no shell.
- :func:`rbf_deformation_basis` (``rbf_deform.py``): the warp alone, the
  baseline the shell must beat.
- :func:`principal_targets_from_rig`, :func:`principal_targets`
  (``principal_targets.py``): a take as a few principal morph targets and
  their weights (for glTF review files), as :class:`PrincipalTargets`.

Some functions share their modules' names, so ``facecap.deform.principal_targets``
is the function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .basis_product import BasisProduct, Precision
from .marker_offsets import DEFAULT_MARKER_OFFSET_MM, DEFAULT_OFFSET_ITERATIONS, MarkerOffsets, MarkerRing, marker_ring
from .principal_targets import PrincipalTargets, principal_targets, principal_targets_from_rig
from .rbf_deform import rbf_deformation_basis
from .rest_pose import REST_POSES, RestPose, choose_rest_pose, neutral_from_frames, neutral_from_take, parse_frame_range
from .thin_shell import DEFAULT_KB_MM2, DEFAULT_KS, PieceReport, ThinShellSolver, thin_shell_deform
from .triharmonic_warp import TriharmonicWarp, check_warp_sources

__all__ = [
    "choose_rest_pose",
    "RestPose",
    "REST_POSES",
    "neutral_from_frames",
    "neutral_from_take",
    "parse_frame_range",
    "TriharmonicWarp",
    "check_warp_sources",
    "ThinShellSolver",
    "thin_shell_deform",
    "PieceReport",
    "DEFAULT_KS",
    "DEFAULT_KB_MM2",
    "BasisProduct",
    "Precision",
    "MarkerOffsets",
    "MarkerRing",
    "marker_ring",
    "DEFAULT_MARKER_OFFSET_MM",
    "DEFAULT_OFFSET_ITERATIONS",
    "rbf_deformation_basis",
    "principal_targets_from_rig",
    "principal_targets",
    "PrincipalTargets",
]
