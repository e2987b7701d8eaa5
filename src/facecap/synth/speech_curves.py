"""Fast, speech-like blendshape-weight curves: syllable-rate jaw cycles and visemes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from ..validate import as_positive, as_positive_range
from .blink_curve import blink_curve
from .smoothstep import smoothstep

__all__ = ["CONSONANT_VISEMES", "VOWEL_VISEMES", "speech_expression_curves"]

VOWEL_VISEMES: dict[str, dict[str, float]] = {
    "a": {"jawOpen": 0.7, "mouthLowerDown_L": 0.3, "mouthLowerDown_R": 0.3},
    "e": {"jawOpen": 0.35, "mouthStretch_L": 0.4, "mouthStretch_R": 0.4, "mouthSmile_L": 0.2, "mouthSmile_R": 0.2},
    "i": {"jawOpen": 0.2, "mouthStretch_L": 0.5, "mouthStretch_R": 0.5, "mouthSmile_L": 0.4, "mouthSmile_R": 0.4},
    "o": {"jawOpen": 0.45, "mouthFunnel": 0.6, "mouthPucker": 0.3},
    "u": {"jawOpen": 0.2, "mouthPucker": 0.8, "mouthFunnel": 0.4},
}
"""The vowel nucleus of a syllable (ARKit shapes at full stress): the jaw opens most for 'a'."""

CONSONANT_VISEMES: dict[str, dict[str, float]] = {
    "mbp": {"mouthClose": 0.4, "mouthPress_L": 0.4, "mouthPress_R": 0.4},
    "fv": {"mouthRollLower": 0.6, "mouthUpperUp_L": 0.2, "mouthUpperUp_R": 0.2, "jawOpen": 0.05},
    "tdnl": {"jawOpen": 0.1, "mouthStretch_L": 0.1, "mouthStretch_R": 0.1},
    "sz": {"jawOpen": 0.04, "mouthStretch_L": 0.25, "mouthStretch_R": 0.25},
    "kg": {"jawOpen": 0.15},
}
"""The consonant onset of a syllable: the lips close (m, b, p), the lower lip rolls under the teeth (f, v), or the jaw nearly closes."""

_VOWEL_ODDS = np.array([0.3, 0.25, 0.2, 0.15, 0.1])  # a e i o u
_CONSONANT_ODDS = np.array([0.25, 0.12, 0.33, 0.15, 0.15])  # mbp fv tdnl sz kg
_BROWS = ("browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R")


def _keyframe_curve(t: FloatArray, key_times: FloatArray, key_values: FloatArray) -> FloatArray:
    """(T, k) curve through the keys, eased from each key to the next with the quintic smoothstep (held outside)."""
    out = np.empty((t.size, key_values.shape[1]))
    seg = np.clip(np.searchsorted(key_times, t, side="right") - 1, 0, key_times.size - 2)
    span = key_times[seg + 1] - key_times[seg]
    s = smoothstep((t - key_times[seg]) / span)[:, None]
    out[:] = key_values[seg] + s * (key_values[seg + 1] - key_values[seg])
    return out


def speech_expression_curves(
    n_frames: int,
    names: Sequence[str],
    *,
    rate: float = 60.0,
    seed: int = 0,
    syllables_per_second: tuple[float, float] = (4.0, 6.0),
    phrase_s: tuple[float, float] = (1.0, 3.0),
    pause_s: tuple[float, float] = (0.25, 0.8),
    brow_accents: float = 0.15,
    blinks_per_second: float = 0.3,
    lead_in_s: float = 0.25,
) -> FloatArray:
    """Blendshape weights over time for an actor talking: fast jaw and lip motion.

    Phrases of syllables alternate with pauses. Each syllable is a consonant
    key (:data:`CONSONANT_VISEMES`: lips closed and pressed for m/b/p,
    ``mouthRollLower`` for f/v, a nearly closed jaw otherwise) followed,
    40-60 % of a syllable later, by a vowel key (:data:`VOWEL_VISEMES`:
    ``jawOpen`` for 'a', funnel and pucker for 'o'/'u', stretch and smile
    for 'i'/'e'), scaled by a random stress of 0.5-1.0. Between keys the
    weights ease with the quintic smoothstep, so at 4-6 syllables a second
    the jaw opens and closes within 70-150 ms. A phrase ends by easing back
    to neutral 120-200 ms after its last vowel. Stressed syllables (stress > 0.9) raise the
    brows with probability ``brow_accents``; blinks as in
    :func:`smooth_expression_curves`. Frame 0 and the lead-in are neutral.

    Parameters
    ----------
    n_frames : int
        Number of frames T, at least 1.
    names : sequence of str
        Blendshape names (ARKit, as ``load_ict_sample().expression_names``),
        in the order of the returned columns; names the visemes do not use stay 0.
    rate : float, default 60.0
        Frame rate, Hz; the timing below is in seconds.
    seed : int, default 0
        Seed of the local random generator.
    syllables_per_second : (float, float), default (4.0, 6.0)
        Range of each phrase's syllable rate, Hz (each syllable also varies
        by +-15 %).
    phrase_s : (float, float), default (1.0, 3.0)
        Range of the phrase durations, s.
    pause_s : (float, float), default (0.25, 0.8)
        Range of the neutral pauses between phrases, s.
    brow_accents : float, default 0.15
        Probability that a stressed syllable carries a brow raise (0.15-0.3 s
        pulse of 0.3-0.6), in [0, 1].
    blinks_per_second : float, default 0.3
        Mean blink rate.
    lead_in_s : float, default 0.25
        Neutral time at the start, s.

    Returns
    -------
    (n_frames, len(names)) float64 array in [0, 1]

    Raises
    ------
    InputError
        If ``n_frames`` is not a positive integer, ``names`` is not a
        sequence of strings, a rate or duration is not positive, a range is
        not (low, high) with low <= high, or ``brow_accents`` is outside [0, 1].

    Notes
    -----
    With keys ``(t_k, w_k)`` the weights are
    ``w(t) = w_k + s((t - t_k) / (t_{k+1} - t_k)) (w_{k+1} - w_k)``,
    ``s(x) = 6x^5 - 15x^4 + 10x^3``: C1 at the keys, zero velocity there.

    Examples
    --------
    >>> W = speech_expression_curves(120, ["jawOpen", "mouthClose"], seed=1)
    >>> W.shape, float(W[0].max()), bool(W.max() <= 1.0)
    ((120, 2), 0.0, True)
    """
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
    if isinstance(names, str) or not all(isinstance(s, str) for s in names):
        raise InputError("names: expected a sequence of blendshape names (str)")
    rate = as_positive(rate, name="rate")
    syllable_rate = as_positive_range(syllables_per_second, name="syllables_per_second")
    phrase_s = as_positive_range(phrase_s, name="phrase_s")
    pause_s = as_positive_range(pause_s, name="pause_s")
    brow_accents = as_positive(brow_accents, name="brow_accents", allow_zero=True)
    if brow_accents > 1:
        raise InputError(f"brow_accents: expected a probability in [0, 1], got {brow_accents}")
    blinks_per_second = as_positive(blinks_per_second, name="blinks_per_second")
    lead_in_s = as_positive(lead_in_s, name="lead_in_s", allow_zero=True)

    rng = np.random.default_rng(seed)
    shapes = sorted({s for v in (*VOWEL_VISEMES.values(), *CONSONANT_VISEMES.values()) for s in v})
    column = {s: j for j, s in enumerate(shapes)}
    vowels, consonants = list(VOWEL_VISEMES.values()), list(CONSONANT_VISEMES.values())
    duration = n_frames / rate
    t = np.arange(n_frames) / rate

    key_times, key_values = [0.0, lead_in_s], [np.zeros(len(shapes)), np.zeros(len(shapes))]
    accents: list[float] = []
    at = lead_in_s + rng.uniform(0.0, 0.3)
    while at < duration + 0.5:
        phrase_end = at + rng.uniform(*phrase_s)
        period_mean = 1.0 / rng.uniform(*syllable_rate)
        while at < phrase_end:
            period = period_mean * rng.uniform(0.85, 1.15)
            stress = rng.uniform(0.5, 1.0)
            consonant = consonants[rng.choice(len(consonants), p=_CONSONANT_ODDS)]
            vowel = vowels[rng.choice(len(vowels), p=_VOWEL_ODDS)]
            for when, viseme, gain in ((at, consonant, 1.0), (at + period * rng.uniform(0.4, 0.6), vowel, stress)):
                value = np.zeros(len(shapes))
                for s, w in viseme.items():
                    value[column[s]] = gain * w
                key_times.append(when)
                key_values.append(value)
            if stress > 0.9 and rng.uniform() < brow_accents:
                accents.append(at)
            at += period
        at = key_times[-1] + rng.uniform(0.12, 0.2)  # back to rest 120-200 ms after the phrase's last vowel
        key_times.append(at)
        key_values.append(np.zeros(len(shapes)))
        at += rng.uniform(*pause_s)
        key_times.append(at)
        key_values.append(np.zeros(len(shapes)))
    K = _keyframe_curve(t, np.asarray(key_times), np.asarray(key_values))

    brow = np.zeros(n_frames)
    for start in accents:
        ramp, hold, height = rng.uniform(0.08, 0.12), rng.uniform(0.15, 0.3), rng.uniform(0.3, 0.6)
        brow = np.maximum(brow, height * smoothstep((t - start) / ramp)
                          * (1.0 - smoothstep((t - start - ramp - hold) / (1.5 * ramp))))
    blink = blink_curve(rng, t, duration, lead_in_s, blinks_per_second)

    W = np.zeros((n_frames, len(names)))
    for j, s in enumerate(names):
        if s in column:
            W[:, j] = K[:, column[s]]
        if s in _BROWS:
            W[:, j] = np.maximum(W[:, j], brow)
        if s in ("eyeBlink_L", "eyeBlink_R"):
            W[:, j] = np.maximum(W[:, j], blink)
    np.clip(W, 0.0, 1.0, out=W)
    W[t < lead_in_s] = 0.0
    W[0] = 0.0
    return W


