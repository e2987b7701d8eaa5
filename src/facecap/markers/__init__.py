"""Marker conditioning: gap filling, denoising, head stabilisation and rigid fits.

The usual order for a raw take is :func:`fill_gaps` (``fill_gaps.py``),
:func:`stabilize_head` (``stabilize_head.py``), then :func:`bilateral_filter`
(``bilateral_filter.py``) on the stabilised positions, its temporal sigma chosen
for the take by :func:`choose_temporal_sigma` (``choose_temporal_sigma.py``:
leave-self-out cross-validation); :func:`condition_take`
(``condition_take.py``) runs them in that order, and :func:`auto_stabilize`
uses a head band when it is rigid, else :func:`consensus_stabilize`
(``consensus_stabilize.py``: per frame, the rigid motion most skin markers
agree on; :func:`estimate_marker_noise` measures the noise it scales by). :func:`rigid_fit` (``rigid_fit.py``) is the
batched, NaN-aware Kabsch fit they share, returning a :class:`RigidTransform`.
"""

from __future__ import annotations

from .bilateral_filter import bilateral_filter
from .choose_temporal_sigma import DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S, TemporalSigmaChoice, choose_temporal_sigma
from .condition_take import (
    DEFAULT_HEAD_MOTION_SIGMA_S,
    SKIN_HEAD_POSES,
    STILL_HEAD_RATIO,
    ConditionedTake,
    auto_stabilize,
    condition_take,
)
from .consensus_stabilize import consensus_stabilize, estimate_marker_noise
from .fill_gaps import FilledMarkers, fill_gaps
from .rigid_fit import RigidTransform, rigid_fit
from .stabilize_head import Stabilization, stabilize_head

__all__ = [
    "fill_gaps",
    "FilledMarkers",
    "stabilize_head",
    "Stabilization",
    "bilateral_filter",
    "choose_temporal_sigma",
    "TemporalSigmaChoice",
    "DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S",
    "condition_take",
    "ConditionedTake",
    "auto_stabilize",
    "consensus_stabilize",
    "estimate_marker_noise",
    "DEFAULT_HEAD_MOTION_SIGMA_S",
    "SKIN_HEAD_POSES",
    "STILL_HEAD_RATIO",
    "rigid_fit",
    "RigidTransform",
]
