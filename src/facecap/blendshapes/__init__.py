"""Blendshapes from mocap (Huang et al. 2011): which frames to scan, and non-negative weights.

:func:`select_scan_frames` picks the fewest frames of a conditioned take whose
non-negative blends rebuild every frame (sec. 4, Algorithm 1);
:func:`nnls_weights` solves the non-negative weights of many frames at once
(eqs. 3 and 12).
"""

from __future__ import annotations

from .nnls_weights import NnlsWeights, nnls_weights
from .select_scan_frames import ScanPlan, select_scan_frames

__all__ = ["NnlsWeights", "ScanPlan", "nnls_weights", "select_scan_frames"]
