"""Marker conditioning: gap filling, denoising, head stabilisation and rigid fits.

The usual order for a raw take is :func:`fill_gaps` (``fill_gaps.py``),
:func:`stabilize_head` (``stabilize_head.py``), then :func:`bilateral_filter`
(``bilateral_filter.py``) on the stabilised positions; :func:`condition_take`
(``condition_take.py``) runs them in that order, and :func:`auto_stabilize`
finds the markers that stay rigid. :func:`rigid_fit` (``rigid_fit.py``) is the
batched, NaN-aware Kabsch fit they share, returning a :class:`RigidTransform`.
"""

from __future__ import annotations

from .bilateral_filter import bilateral_filter
from .condition_take import ConditionedTake, auto_stabilize, condition_take
from .fill_gaps import FilledMarkers, fill_gaps
from .rigid_fit import RigidTransform, rigid_fit
from .stabilize_head import Stabilization, stabilize_head

__all__ = [
    "fill_gaps",
    "FilledMarkers",
    "stabilize_head",
    "Stabilization",
    "bilateral_filter",
    "condition_take",
    "ConditionedTake",
    "auto_stabilize",
    "rigid_fit",
    "RigidTransform",
]
