"""Head stabilisation when no marker is rigid: the rigid motion most markers agree on, frame by frame."""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError, MarkerError
from ..typing import FloatArray
from ..validate import as_marker_positions
from .rigid_fit import RigidTransform, rigid_fit
from .stabilize_head import Stabilization, stabilize_head

__all__ = ["consensus_stabilize", "estimate_marker_noise"]

CONSENSUS_SCALE_PER_NOISE = 4.0
"""Welsch scale of the per-frame agreement, in units of the markers' noise standard deviation."""

MIN_CONSENSUS_SCALE_MM = 0.5
"""Floor of that scale: noise estimates of nearly exact data must not make every marker an outlier."""


def estimate_marker_noise(positions: FloatArray) -> float:
    """Standard deviation of the markers' measurement noise per coordinate (mm), from the data alone.

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        Raw marker positions, NaN for gaps.

    Returns
    -------
    float
        ``sigma``, mm; NaN when fewer than three consecutive frames exist.

    Notes
    -----
    For white noise of standard deviation ``sigma`` the second difference
    ``x(t+1) - 2 x(t) + x(t-1)`` has standard deviation ``sqrt(6) sigma``.
    Facial motion sampled at 60 Hz or more changes far less than that between
    three frames for most samples, so the median absolute second difference
    (over every marker, frame and axis, scaled by 1/0.6745 for a Gaussian)
    measures the noise and is robust to the fast minority (speech, blinks).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> P = np.cumsum(rng.normal(scale=0.01, size=(600, 20, 3)), axis=0) + rng.normal(scale=0.2, size=(600, 20, 3))
    >>> round(estimate_marker_noise(P), 2)
    0.2
    """
    P = as_marker_positions(positions, name="positions")
    if P.shape[0] < 3:
        return float("nan")
    d2 = P[2:] - 2.0 * P[1:-1] + P[:-2]
    d2 = np.abs(d2[np.isfinite(d2)])
    if d2.size == 0:
        return float("nan")
    return float(np.median(d2) / 0.6745 / np.sqrt(6.0))


def consensus_stabilize(
    positions: FloatArray,
    *,
    rest_frame: int = 0,
    noise_mm: float | None = None,
    iterations: int = 10,
    rounds: int = 1,
    start: Stabilization | None = None,
    motion_scale_mm: float | None = None,
) -> Stabilization:
    """Remove head motion from skin markers alone: per frame, the rigid motion most markers agree on.

    Without a head band, every marker on a face moves with some expression,
    so a fixed "stable" set carries expression into the head pose (a brow
    raise read as a nod). Here each frame gets its own robust rigid fit to
    the rest frame: markers that land within a few noise deviations of
    their rest positions carry the fit, markers the expression moved are
    weighted down, and markers that move a lot over the whole take (lips,
    jaw) count less in every frame, so a jaw opening as one piece cannot
    capture the fit.

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        Gap-filled marker positions (NaN where still missing).
    rest_frame : int, default 0
        The frame every other frame is moved onto.
    noise_mm : float, optional
        Noise standard deviation of the markers; default
        :func:`estimate_marker_noise` of ``positions``.
    iterations : int, default 10
        Reweighting steps per round.
    rounds : int, default 1
        Times the per-marker motion prior is estimated: the first time from
        ``start``, then from the current consensus. More than one lets the
        consensus confirm itself: where most markers move together for a
        while (a broad expression on a 60-marker take) the fit absorbs part
        of that motion, the markers then look still and gain weight (worst
        5 % of frames 1.3-1.4 degrees off with 3 rounds, 0.9 with 1).
    start : Stabilization, optional
        Where to start: :func:`~facecap.markers.stabilize_head.stabilize_head`
        of ``positions`` with the same ``rest_frame`` (computed when not given;
        pass it when you have it).
    motion_scale_mm : float, optional
        Scale of the per-marker motion prior (see Notes); default the
        per-frame Welsch scale. Larger values trust the per-frame agreement
        more than the take-long stillness of a marker.

    Returns
    -------
    Stabilization
        As :func:`~facecap.markers.stabilize_head.stabilize_head`;
        ``stable_markers`` are the markers whose mean weight over the take is
        at least half the largest (those that carried the fit), and
        ``residual_rms`` the weighted RMS misfit.

    Raises
    ------
    MarkerError
        If fewer than 3 markers are visible at the rest frame.
    InputError
        If an option is out of range.

    Notes
    -----
    Iteratively reweighted least squares on
    ``sum_k p_k rho(|R_t m_k(t) + c_t - m_k(rest)|)`` per frame ``t``, with
    Welsch's ``rho`` (weights ``exp(-(r / s)^2)``, ``s`` =
    :data:`CONSENSUS_SCALE_PER_NOISE` noise deviations, at least
    :data:`MIN_CONSENSUS_SCALE_MM`) and a per-marker prior
    ``p_k = 1 / (1 + (q_k / s_p)^2)`` (``s_p`` = ``motion_scale_mm``, default
    ``s``), ``q_k`` the 90th percentile of the
    marker's distance from its rest position after ``start``'s
    stabilisation (in later rounds, the current consensus's): a marker the
    expressions move by more than the noise scale counts little in every
    frame, so that the markers that carry a frame are those that stay still
    over the take. (Until 2026-12-04 the prior's scale was 2 mm and it was
    re-estimated in 3 rounds: on four tuned takes without a head band, three
    turning about the neck, the median rotation error went from 0.09-0.18
    to 0.10-0.15 degrees and the worst 5 % from 0.24-1.42 to 0.21-0.95;
    ``benchmarks/RESULTS.md``. ``--stabilize consensus`` and plans that
    recorded it use the new defaults.) Each step is a weighted Kabsch fit
    (:func:`~facecap.markers.rigid_fit.rigid_fit`), batched over frames. It
    starts from :func:`~facecap.markers.stabilize_head.stabilize_head`'s most
    rigid set, which is within a degree or so of the truth, so the
    redescending weights converge to the consensus rather than to a moving
    patch.
    """
    P = as_marker_positions(positions, name="positions")
    T, M, _ = P.shape
    if not (isinstance(rest_frame, (int, np.integer)) and 0 <= rest_frame < T):
        raise InputError(f"rest_frame: expected an integer frame index in [0, {T}), got {rest_frame!r}")
    for name, value in (("iterations", iterations), ("rounds", rounds)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name}: expected an integer >= 1, got {value!r}")
    target = P[rest_frame]
    if np.count_nonzero(np.isfinite(target).all(axis=1)) < 3:
        raise MarkerError(f"positions: fewer than 3 markers visible at rest_frame {rest_frame}")
    sigma = estimate_marker_noise(P) if noise_mm is None else float(noise_mm)
    if not np.isfinite(sigma) or sigma < 0:
        sigma = 0.0
    scale = max(CONSENSUS_SCALE_PER_NOISE * sigma, MIN_CONSENSUS_SCALE_MM)

    motion_scale = scale if motion_scale_mm is None else float(motion_scale_mm)
    if not np.isfinite(motion_scale) or motion_scale <= 0:
        raise InputError(f"motion_scale_mm: expected a positive number of mm, got {motion_scale_mm!r}")
    if start is None:
        start = stabilize_head(P, rest_frame=rest_frame)
    elif start.positions.shape != P.shape:
        raise InputError(f"start: a stabilisation of {start.positions.shape[:2]} frames x markers, expected {P.shape[:2]}")
    moved = start.positions
    seen = np.isfinite(P).all(axis=2) & np.isfinite(target).all(axis=1)[None]
    fit = RigidTransform(start.rotations, start.translations, start.residual_rms)
    W = np.zeros((T, M))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns and frames
        for _ in range(rounds):
            distance = np.linalg.norm(moved - target[None], axis=2)
            q90 = np.nanpercentile(np.where(seen, distance, np.nan), 90, axis=0)
            prior = 1.0 / (1.0 + (np.nan_to_num(q90, nan=np.inf) / motion_scale) ** 2)
            for _ in range(iterations):
                W = np.where(seen, prior[None] * np.exp(-(np.nan_to_num(distance, nan=np.inf) / scale) ** 2), 0.0)
                # a frame whose markers all moved keeps the start's weights rather than none
                weak = np.count_nonzero(W > 1e-6 * prior.max(), axis=1) < 3
                if weak.any():
                    W[weak] = np.where(seen[weak], prior[None], 0.0)
                fit = rigid_fit(P, target, weights=W)
                moved = fit.apply(P)
                distance = np.linalg.norm(moved - target[None], axis=2)
    mean_weight = W.sum(axis=0) / max(T, 1)
    carried = np.flatnonzero(mean_weight >= 0.5 * mean_weight.max())
    return Stabilization(
        positions=np.ascontiguousarray(moved),
        rotations=fit.rotation,
        translations=fit.translation,
        stable_markers=carried.astype(np.int64),
        residual_rms=fit.rms,
    )
