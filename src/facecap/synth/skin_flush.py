"""An expression-driven flush: the cheeks redden (and darken) as the subject smiles, lagging the smile.

A trap for a shape-from-shading solver that reads "darker" as "deeper": the colour changes over time
where the shape does not.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["FLUSH_TINT", "SkinFlush", "skin_flush"]

FLUSH_TINT = (0.0, 0.22, 0.18)
"""Fraction of the albedo's (red, green, blue) a full flush takes away at the middle of a cheek."""
_SIGMA_MM = 13.0
_TIME_CONSTANT_S = 0.6


class SkinFlush(NamedTuple):
    """Where and when the cheeks flush: ``albedo_t = albedo (1 - level[t] weight[:, None] FLUSH_TINT)``.

    Attributes
    ----------
    level : (T,) float64 array in [0, 1]
    weight : (n,) float64 array in [0, 1]
    tint : (3,) float64 array
    """

    level: FloatArray
    weight: FloatArray
    tint: FloatArray

    def albedo(self, albedo: FloatArray, t: int) -> FloatArray:
        """(n, 3) the albedo at frame ``t``."""
        return np.asarray(albedo) * (1.0 - self.level[t] * self.weight[:, None] * self.tint)


def skin_flush(points: FloatArray, landmark_points: FloatArray, weights: FloatArray, names: Sequence[str], *,
               rate: float) -> SkinFlush:
    """The flush of a take: a level per frame from the smile, and a weight per point on the cheeks.

    Parameters
    ----------
    points : (n, 3) float array, mm
        Material points (the rest face).
    landmark_points : (68, 3) float array, mm
        The rest face's landmarks (dlib-68 order).
    weights : (T, e) float array
        The take's expression weights.
    names : sequence of str, length e
        Their names (``mouthSmile_L`` ... as the ICT sample's).
    rate : float
        Frames per second.

    Returns
    -------
    SkinFlush

    Notes
    -----
    The drive is ``clip(0.6 (smile_L + smile_R) + 0.2 (cheekSquint_L + cheekSquint_R), 0, 1)``; the
    level follows it with a first-order lag of 0.6 s (blood takes time to come and go). The weight is
    a Gaussian (sigma 13 mm) about each cheek's centre: the mean of the lower lid, the nose wing, the
    mouth corner and the jaw below them.

    Examples
    --------
    >>> W = np.zeros((100, 2)); W[10:, 0] = W[10:, 1] = 1.0
    >>> L = np.zeros((68, 3))
    >>> f = skin_flush(np.zeros((1, 3)), L, W, ["mouthSmile_L", "mouthSmile_R"], rate=50.0)
    >>> float(f.level[9]), bool(0.5 < f.level[50] < 1.0), bool(f.level[99] > 0.95)
    (0.0, True, True)
    """
    W = np.asarray(weights, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != len(names):
        raise InputError(f"weights: expected (T, {len(names)}), got {W.shape}")
    index = {s: i for i, s in enumerate(names)}
    gains = {"mouthSmile_L": 0.6, "mouthSmile_R": 0.6, "cheekSquint_L": 0.2, "cheekSquint_R": 0.2}
    drive = np.zeros(W.shape[0])
    for name, gain in gains.items():
        if name in index:
            drive += gain * W[:, index[name]]
    drive = np.clip(drive, 0.0, 1.0)
    step = 1.0 - np.exp(-1.0 / (float(rate) * _TIME_CONSTANT_S))
    level = np.empty_like(drive)
    current = drive[0] if drive.size else 0.0
    for t, x in enumerate(drive):
        current += step * (x - current) if t else 0.0
        level[t] = current
    L = np.asarray(landmark_points, dtype=np.float64)
    P = np.asarray(points, dtype=np.float64)
    weight = np.zeros(P.shape[0])
    for lid, wing, mouth, jaw in ((46, 35, 54, 13), (41, 31, 48, 3)):  # the subject's left, then right
        centre = L[[lid, wing, mouth, jaw]].mean(axis=0)
        weight = np.maximum(weight, np.exp(-np.sum((P - centre) ** 2, axis=1) / (2 * _SIGMA_MM**2)))
    return SkinFlush(level, weight, np.array(FLUSH_TINT))
