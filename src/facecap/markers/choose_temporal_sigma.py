"""The bilateral filter's temporal sigma, chosen from the take itself by leave-self-out cross-validation."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import InputError
from ..structures import TemporalSigmaChoice
from ..typing import FloatArray
from ..validate import as_frame_index, as_marker_positions, as_positive
from .bilateral_filter import bilateral_setup, bilateral_weighted_sums, marker_rest_configuration

__all__ = ["choose_temporal_sigma", "DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S"]

DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S = (0.005, 0.01, 0.02, 0.03, 0.045, 0.06, 0.08, 0.1)
"""Temporal sigmas tried (s). At 0.1 s the window reaches 0.25 s either side, a syllable: no further."""

_MAX_SCORED_FRAMES = 600
_SCORED_BLOCKS = 4


def choose_temporal_sigma(
    positions: FloatArray,
    *,
    rate: float,
    rest_frame: int = 0,
    candidates_s: Sequence[float] = DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S,
    spatial_sigma_mm: float = 5.0,
    range_sigma_mm: float | None = 1.0,
    truncate: float = 2.5,
    rest_average: float = 5.0,
) -> TemporalSigmaChoice:
    """Choose :func:`~facecap.markers.bilateral_filter`'s temporal sigma for a take by cross-validation.

    For each candidate the filter predicts every sample from the others (its
    own weight left out of the normalised sum: the weight of a valid sample on
    itself is exactly 1) and the candidate that predicts best is chosen. A
    noisy take of smooth motion favours a wide window; a clean take, or one
    whose markers move fast, a narrow one. The other filter parameters are
    those :func:`bilateral_filter` takes, with the same defaults.

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        Marker positions, NaN for gaps (as :func:`bilateral_filter` takes them:
        stabilised first, where the head moves).
    rate : float
        Frame rate, Hz.
    rest_frame : int, optional
        The filter's rest frame; default 0.
    candidates_s : sequence of float, optional
        Temporal sigmas to try, s; default
        :data:`DEFAULT_TEMPORAL_SIGMA_CANDIDATES_S`.
    spatial_sigma_mm, range_sigma_mm, truncate, rest_average
        As :func:`bilateral_filter`.

    Returns
    -------
    TemporalSigmaChoice

    Raises
    ------
    MarkerError
        If ``positions`` is not a (T, M, 3) array or holds infinite values.
    InputError
        If ``candidates_s`` is empty or holds a negative or non-finite value,
        or another parameter is invalid as for :func:`bilateral_filter`.

    Notes
    -----
    The scores are averaged over up to 600 frames in four blocks spread
    evenly over the take (all frames of a shorter take): 160k samples for 90
    markers, and the cost of filtering those frames once per candidate (0.3 s
    for 90 markers at 120 Hz). Leave-self-out is cross-validation in the sense of Wahba (1990,
    ch. 4) for the filter's normalised weighted mean; the range weights still
    compare the other samples with the left-out one, which biases the score
    towards narrow windows (on generated takes with 0.2-0.3 mm noise the
    choice lies at or below the sigma that is best against the truth, measured
    in ``benchmarks/RESULTS.md``).

    References
    ----------
    G. Wahba, "Spline Models for Observational Data", SIAM, 1990.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(600) / 120.0
    >>> smooth = np.sin(2 * np.pi * 0.5 * t)[:, None, None] * np.ones((1, 4, 3))
    >>> choose_temporal_sigma(smooth + rng.normal(0, 0.3, smooth.shape), rate=120.0).sigma_s
    0.1
    """
    P = as_marker_positions(positions, name="positions")
    T = P.shape[0]
    rest = as_frame_index(rest_frame, T, name="rest_frame")
    frame_rate = as_positive(rate, name="rate")
    sigmas = tuple(float(as_positive(s, name="candidates_s", allow_zero=True)) for s in candidates_s)
    if not sigmas:
        raise InputError("candidates_s: expected at least one temporal sigma in seconds")
    sigma_s = as_positive(spatial_sigma_mm, name="spatial_sigma_mm", allow_zero=True)
    sigma_r = None if range_sigma_mm is None else as_positive(range_sigma_mm, name="range_sigma_mm")
    cut = as_positive(truncate, name="truncate")
    average = as_positive(rest_average, name="rest_average", allow_zero=True)

    # the scored frames: the whole take, or blocks spread evenly over it
    block = _MAX_SCORED_FRAMES // _SCORED_BLOCKS if T > _MAX_SCORED_FRAMES else T
    starts = np.unique(np.linspace(0, T - block, _SCORED_BLOCKS if block < T else 1).round().astype(int))
    blocks = [(int(first), int(first) + block) for first in starts]

    valid = ~np.isnan(P).any(axis=2)
    scores = []
    for sigma in sigmas:
        sigma_t = sigma * frame_rate
        reach = int(cut * sigma_t + 0.5)  # the filter's window radius: context each block needs
        # the whole take's rest; silent: the filter itself warns of markers missing there, once
        rest_state = marker_rest_configuration(P, valid, rest, average * sigma_t, cut, warn=False)
        squared_sum, count = 0.0, 0
        for first, stop in blocks:
            lo, hi = max(0, first - reach), min(T, stop + reach)
            setup = bilateral_setup(P[lo:hi], sigma_t, sigma_s, sigma_r, cut, rest_state)
            inner = slice(first - lo, stop - lo)
            num, den = bilateral_weighted_sums(setup, [(inner.start, inner.stop)])
            U, own = setup.U[:, inner], setup.valid[inner]
            others = den[inner] - own  # the weight of the other samples: a valid sample's own weight is 1
            usable = own & (others > 1e-9)
            predicted = (num[:, inner] - U) / np.where(usable, others, 1.0)
            squared = np.sum((predicted - U) ** 2, axis=0)
            squared_sum += float(squared[usable].sum())
            count += int(usable.sum())
        scores.append(squared_sum / count if count else float("inf"))
    best = int(np.argmin(scores))
    return TemporalSigmaChoice(sigmas[best], sigmas, tuple(scores), len(blocks) * block)
