"""Marker conditioning: gap filling, denoising, head stabilisation and rigid fits.

The usual order for a raw take is :func:`fill_gaps`, :func:`stabilize_head`,
then :func:`bilateral_filter` on the stabilised positions; :func:`condition_take`
runs them in that order.
"""

from __future__ import annotations

from .bilateral_filter import bilateral_filter
from .condition_take import ConditionedTake, auto_stabilize, condition_take
from .fill_gaps import FilledMarkers, fill_gaps
from .rigid_fit import RigidTransform, rigid_fit
from .stabilize_head import Stabilization, stabilize_head

__all__ = [
    "ConditionedTake",
    "FilledMarkers",
    "RigidTransform",
    "Stabilization",
    "auto_stabilize",
    "bilateral_filter",
    "condition_take",
    "fill_gaps",
    "rigid_fit",
    "stabilize_head",
]
