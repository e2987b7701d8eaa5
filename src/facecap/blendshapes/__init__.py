"""Blendshapes from mocap and scans (Huang et al. 2011): which frames to scan, bases, weights, the take rebuilt.

In the order a user meets them:

- :func:`select_scan_frames` (``select_scan_frames.py``): the fewest frames of
  a conditioned take whose non-negative blends rebuild every frame (sec. 4,
  Algorithm 1), as a :class:`ScanPlan`.
- :func:`nnls_weights` (``nnls_weights.py``): non-negative weights of many
  frames at once (eqs. 3 and 12), as :class:`NnlsWeights`.
- :func:`lawson_hanson` (``lawson_hanson.py``): the batched Lawson-Hanson kernel both solve
  with, on a :class:`SharedGram` or a :class:`BorderedGram` (a shared block and one basis per
  problem), continued in place; :func:`solve_on_passive` and :func:`refine_on_passive` its
  least-squares solve and refinement on the passive sets.
- :func:`blend_weights`, :func:`blend_weights_with_head_pose` (the weights and
  each frame's head pose solved together, as :class:`BlendWithPose`),
  :func:`blend_rig` (``reconstruct_performance.py``): the dense performance from
  bases and weights, as a rig about the rest shape (:class:`BlendRig`).

The scan registration itself lives in :mod:`facecap.registration`; the scan workflow file to
file, as ``facecap plan-scans``, ``register-scans`` and ``blend`` run it, in :mod:`facecap.pipelines`.
"""

from __future__ import annotations

from .lawson_hanson import BorderedGram, SharedGram, lawson_hanson, refine_on_passive, solve_on_passive
from .nnls_weights import NnlsWeights, nnls_weights
from .reconstruct_performance import (
    BlendRig,
    BlendWithPose,
    blend_rig,
    blend_weights,
    blend_weights_with_head_pose,
)
from .select_scan_frames import ScanPlan, select_scan_frames

__all__ = [
    "select_scan_frames",
    "ScanPlan",
    "nnls_weights",
    "NnlsWeights",
    "lawson_hanson",
    "SharedGram",
    "BorderedGram",
    "solve_on_passive",
    "refine_on_passive",
    "blend_weights",
    "blend_weights_with_head_pose",
    "BlendWithPose",
    "blend_rig",
    "BlendRig",
]
