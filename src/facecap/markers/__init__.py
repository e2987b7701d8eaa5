"""Marker conditioning: gap filling, denoising, head stabilisation and rigid fits.

The usual order for a raw take is :func:`fill_gaps` (``fill_gaps.py``),
:func:`stabilize_head` (``stabilize_head.py``), then :func:`bilateral_filter`
(``bilateral_filter.py``) on the stabilised positions, its temporal sigma chosen
for the take by :func:`choose_temporal_sigma` (``choose_temporal_sigma.py``:
leave-self-out cross-validation, with the filter's parts both share:
:func:`marker_rest_configuration`, :func:`bilateral_setup` as a :class:`BilateralSetup`,
:func:`bilateral_weighted_sums`); :func:`condition_take`
(``condition_take.py``) runs them in that order, and :func:`auto_stabilize`
uses a head band when it is rigid, else :func:`consensus_stabilize`
(``consensus_stabilize.py``: per frame, the rigid motion most skin markers
agree on; :func:`estimate_marker_noise` measures the noise it scales by). :func:`rigid_fit` (``rigid_fit.py``) is the
batched, NaN-aware Kabsch fit they share, returning a :class:`RigidTransform`;
:func:`moving_stable_markers` (``condition_take.py``) names the markers a head pose rests on that move
with the face; :func:`savitzky_golay` (``condition_take.py``) smooths the head poses over time.
:func:`measure_resting_expression` (``resting_expression.py``) measures a take's rest frame
against the scan (a :class:`RestingExpression`: the robust rigid fit, :func:`robust_rigid_fit`, and how much
of the mismatch is an expression the actor holds at rest, by how much of it each marker's neighbours share).
:func:`prepare_markers` (``prepare_take.py``) makes a take ready for any solver: matched to the map
(:func:`check_take_against_map`), conditioned, as :class:`PreparedMarkers`; :func:`rest_average` gives the
warp its rest markers and :func:`head_pose_in_scan` the head motion in the scan's coordinates.
:func:`check_scan_units` (``check_scan_units.py``) checks a scan's length unit against the markers' size
(and converts it on request); :func:`check_take_units` (``check_take_units.py``) does so for a scan, a take
and the map between them.
"""

from __future__ import annotations

from .bilateral_filter import (BilateralSetup, bilateral_filter, bilateral_setup, bilateral_weighted_sums,
                               marker_rest_configuration)
from .check_scan_units import check_scan_units
from .check_take_units import check_take_units
from .choose_temporal_sigma import DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S, choose_temporal_sigma
from .condition_take import (
    DEFAULT_HEAD_MOTION_SIGMA_S,
    HEAD_POSE_SOURCES,
    SKIN_HEAD_POSES,
    STABLE_MARKER_MOTION_MM,
    STILL_HEAD_RATIO,
    auto_stabilize,
    condition_take,
    moving_stable_markers,
    savitzky_golay,
)
from .consensus_stabilize import consensus_stabilize, estimate_marker_noise
from .fill_gaps import FilledMarkers, fill_gaps
from .resting_expression import (
    ABOVE_NOISE,
    MAX_RESTING_MM,
    MAX_SCALE_ERROR,
    MIN_RESTING_MM,
    MIN_COHERENCE,
    MISPLACED_MM,
    MOTION_Z_SCORE,
    PLACEMENT_LIMIT_MM,
    PLACEMENT_LIMIT_PER_NOISE,
    NEIGHBOUR_SCALE_MM,
    RestingExpression,
    measure_resting_expression,
    robust_rigid_fit,
)
from .prepare_take import (DEFAULT_REST_AVERAGE_S, MIN_DRIVING_MARKERS, PreparedMarkers, check_take_against_map,
                           head_pose_in_scan, prepare_markers, rest_average)
from .rigid_fit import RigidTransform, rigid_fit
from .stabilize_head import Stabilization, stabilize_head

__all__ = [
    "check_scan_units",
    "check_take_units",
    "prepare_markers",
    "PreparedMarkers",
    "check_take_against_map",
    "rest_average",
    "head_pose_in_scan",
    "DEFAULT_REST_AVERAGE_S",
    "MIN_DRIVING_MARKERS",
    "fill_gaps",
    "FilledMarkers",
    "stabilize_head",
    "Stabilization",
    "bilateral_filter",
    "BilateralSetup",
    "marker_rest_configuration",
    "bilateral_setup",
    "bilateral_weighted_sums",
    "choose_temporal_sigma",
    "DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S",
    "condition_take",
    "auto_stabilize",
    "consensus_stabilize",
    "estimate_marker_noise",
    "DEFAULT_HEAD_MOTION_SIGMA_S",
    "SKIN_HEAD_POSES",
    "STILL_HEAD_RATIO",
    "HEAD_POSE_SOURCES",
    "STABLE_MARKER_MOTION_MM",
    "moving_stable_markers",
    "savitzky_golay",
    "measure_resting_expression",
    "RestingExpression",
    "robust_rigid_fit",
    "MIN_COHERENCE",
    "NEIGHBOUR_SCALE_MM",
    "ABOVE_NOISE",
    "MAX_SCALE_ERROR",
    "MAX_RESTING_MM",
    "MIN_RESTING_MM",
    "MISPLACED_MM",
    "MOTION_Z_SCORE",
    "PLACEMENT_LIMIT_MM",
    "PLACEMENT_LIMIT_PER_NOISE",
    "rigid_fit",
    "RigidTransform",
]
