"""Smooth blendshape-weight curves that look like a facial performance."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from ..validate import as_positive, as_positive_range
from .blink_curve import blink_curve
from .smoothstep import smoothstep

__all__ = ["EXPRESSION_PRESETS", "smooth_expression_curves"]

EXPRESSION_PRESETS: dict[str, dict[str, float]] = {
    "smile": {"mouthSmile_L": 0.9, "mouthSmile_R": 0.9, "cheekSquint_L": 0.5, "cheekSquint_R": 0.5,
              "eyeSquint_L": 0.3, "eyeSquint_R": 0.3},
    "surprise": {"browInnerUp_L": 0.9, "browInnerUp_R": 0.9, "browOuterUp_L": 0.8, "browOuterUp_R": 0.8,
                 "eyeWide_L": 0.7, "eyeWide_R": 0.7, "jawOpen": 0.5},
    "anger": {"browDown_L": 0.9, "browDown_R": 0.9, "noseSneer_L": 0.6, "noseSneer_R": 0.6,
              "mouthPress_L": 0.5, "mouthPress_R": 0.5, "eyeSquint_L": 0.4, "eyeSquint_R": 0.4},
    "jaw_open": {"jawOpen": 1.0, "mouthLowerDown_L": 0.4, "mouthLowerDown_R": 0.4},
    "pucker": {"mouthPucker": 1.0, "mouthFunnel": 0.4},
    "disgust": {"noseSneer_L": 0.9, "noseSneer_R": 0.9, "mouthUpperUp_L": 0.7, "mouthUpperUp_R": 0.7,
                "browDown_L": 0.4, "browDown_R": 0.4},
    "sad": {"mouthFrown_L": 0.9, "mouthFrown_R": 0.9, "browInnerUp_L": 0.7, "browInnerUp_R": 0.7,
            "mouthShrugLower": 0.5},
    "cheek_puff": {"cheekPuff_L": 1.0, "cheekPuff_R": 1.0, "mouthClose": 0.3},
    "wide_mouth": {"mouthStretch_L": 0.9, "mouthStretch_R": 0.9, "jawOpen": 0.3},
    "side_smirk": {"mouthSmile_L": 1.0, "mouthLeft": 0.6, "cheekSquint_L": 0.6},
    "jaw_shift": {"jawLeft": 0.8, "mouthLeft": 0.4},
    "lip_roll": {"mouthRollLower": 0.8, "mouthRollUpper": 0.8},
}
"""Named expressions as blendshape weights; a performance eases in and out of these."""


def smooth_expression_curves(
    n_frames: int,
    names: Sequence[str],
    *,
    rate: float = 60.0,
    seed: int = 0,
    expressions_per_second: float = 0.6,
    intensity: tuple[float, float] = (0.6, 1.0),
    blinks_per_second: float = 0.3,
    lead_in_s: float = 0.25,
    ramp_in_s: tuple[float, float] = (0.25, 0.6),
    ramp_out_s: tuple[float, float] = (0.3, 0.7),
    asymmetry: float = 0.0,
    max_timing_offset_s: float = 0.0,
) -> FloatArray:
    """Blendshape weights over time for a plausible facial performance.

    A sequence of expressions from :data:`EXPRESSION_PRESETS` (smile,
    surprise, jaw open, pucker, anger, ...: a few blendshapes active at once)
    each eases in, holds and eases out with C2 ramps, overlapping its
    neighbours, at a random intensity; blinks (``eyeBlink_L/R`` pulses of
    about 0.2 s, both eyes together) are laid on top. Overlapping
    expressions add, and the sum is clipped to [0, 1]. Frame 0 is neutral
    (all weights exactly 0), matching the scan.

    Parameters
    ----------
    n_frames : int
        Number of frames T, at least 1.
    names : sequence of str
        Blendshape names, in the order of the returned columns. Names the
        presets do not use stay 0; preset names missing here are skipped.
    rate : float, default 60.0
        Frame rate in Hz; the timing below is in seconds.
    seed : int, default 0
        Seed of the local random generator: same seed, same curves.
    expressions_per_second : float, default 0.6
        Mean rate at which a new expression starts.
    intensity : (float, float), default (0.6, 1.0)
        Range of the random scale applied to each expression's preset weights
        (the presets peak at 0.8-1.0).
    blinks_per_second : float, default 0.3
        Mean blink rate (the gap between blinks is at least 0.4 s).
    lead_in_s : float, default 0.25
        Neutral time at the start, s.
    ramp_in_s, ramp_out_s : (float, float), default (0.25, 0.6) and (0.3, 0.7)
        Range of the ease-in and ease-out durations, s. (0.06, 0.15) gives
        the rapid onsets of a real actor (60-150 ms ramps).
    asymmetry : float, default 0.0
        In [0, 1): each expression's ``_L`` and ``_R`` shapes get intensities
        ``scale (1 + a u)`` and ``scale (1 - a u)`` with ``|u|`` uniform in
        [0.25, 1] and a random sign, ``a = asymmetry``; unpaired shapes keep
        ``scale``. 0 keeps the presets symmetric.
    max_timing_offset_s : float, default 0.0
        Each expression's ``_R`` shapes start up to this much earlier or
        later than its ``_L`` shapes (uniform), s.

    Returns
    -------
    (n_frames, len(names)) float64 array in [0, 1]

    Raises
    ------
    InputError
        If ``n_frames`` is not a positive integer, ``names`` is not a sequence
        of strings, a rate, duration or intensity is not positive/finite, a
        range is not (low, high) with low <= high, or ``asymmetry`` is not in [0, 1).

    Notes
    -----
    The ramps use the quintic smoothstep ``s(x) = 6x^5 - 15x^4 + 10x^3``,
    whose first and second derivatives vanish at both ends; an expression
    with ramp-in ``a``, hold ``h`` and ramp-out ``r`` starting at ``t0`` has
    envelope ``s((t - t0)/a) (1 - s((t - t0 - a - h)/r))``. The asymmetry
    and timing offsets draw from a second generator seeded with
    ``(seed, 1)``, so with their defaults the curves are those of earlier
    versions, draw for draw.

    Examples
    --------
    >>> W = smooth_expression_curves(120, ["jawOpen", "eyeBlink_L"], seed=1)
    >>> W.shape, float(W[0].max())
    ((120, 2), 0.0)
    """
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
    if isinstance(names, str) or not all(isinstance(s, str) for s in names):
        raise InputError("names: expected a sequence of blendshape names (str)")
    rate = as_positive(rate, name="rate")
    expressions_per_second = as_positive(expressions_per_second, name="expressions_per_second")
    blinks_per_second = as_positive(blinks_per_second, name="blinks_per_second")
    lead_in_s = as_positive(lead_in_s, name="lead_in_s", allow_zero=True)
    lo, hi = (as_positive(x, name="intensity", allow_zero=True) for x in intensity)
    if lo > hi:
        raise InputError(f"intensity: expected (low, high) with low <= high, got {intensity!r}")
    intensity = (lo, hi)
    ramp_in_s = as_positive_range(ramp_in_s, name="ramp_in_s")
    ramp_out_s = as_positive_range(ramp_out_s, name="ramp_out_s")
    asymmetry = as_positive(asymmetry, name="asymmetry", allow_zero=True)
    if asymmetry >= 1.0:
        raise InputError(f"asymmetry: expected a value in [0, 1), got {asymmetry}")
    max_timing_offset_s = as_positive(max_timing_offset_s, name="max_timing_offset_s", allow_zero=True)
    rng = np.random.default_rng(seed)
    rng_side = np.random.default_rng((seed, 1))
    index = {s: i for i, s in enumerate(names)}
    t = np.arange(n_frames) / float(rate)
    W = np.zeros((n_frames, len(names)))
    duration = n_frames / float(rate)
    start = lead_in_s
    presets = list(EXPRESSION_PRESETS)
    while start < duration:
        preset = EXPRESSION_PRESETS[presets[rng.integers(len(presets))]]
        ramp_in, hold, ramp_out = rng.uniform(*ramp_in_s), rng.uniform(0.2, 1.0), rng.uniform(*ramp_out_s)
        envelope = smoothstep((t - start) / ramp_in) * (1.0 - smoothstep((t - start - ramp_in - hold) / ramp_out))
        scale = rng.uniform(*intensity)
        side_gain, envelope_r = {"_L": 1.0, "_R": 1.0}, envelope
        if asymmetry > 0 or max_timing_offset_s > 0:
            u = rng_side.uniform(0.25, 1.0) * rng_side.choice((-1.0, 1.0))
            side_gain = {"_L": 1.0 + asymmetry * u, "_R": 1.0 - asymmetry * u}
            lag = rng_side.uniform(-max_timing_offset_s, max_timing_offset_s)
            envelope_r = (smoothstep((t - start - lag) / ramp_in)
                          * (1.0 - smoothstep((t - start - lag - ramp_in - hold) / ramp_out)))
        for name, weight in preset.items():
            if name in index:
                gain = side_gain.get(name[-2:], 1.0)
                W[:, index[name]] += gain * scale * weight * (envelope_r if name.endswith("_R") else envelope)
        start += rng.exponential(1.0 / expressions_per_second) + 0.5 * ramp_in
    blink = blink_curve(rng, t, duration, lead_in_s, blinks_per_second)
    for name in ("eyeBlink_L", "eyeBlink_R"):
        if name in index:
            W[:, index[name]] = np.maximum(W[:, index[name]], blink)
    np.clip(W, 0.0, 1.0, out=W)
    W[0] = 0.0
    return W
