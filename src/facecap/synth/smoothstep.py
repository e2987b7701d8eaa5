"""The quintic smoothstep every generated curve eases with."""

from __future__ import annotations

import numpy as np

__all__ = ["smoothstep"]


def smoothstep(x: np.ndarray) -> np.ndarray:
    """The quintic smoothstep ``s(x) = 6x^5 - 15x^4 + 10x^3`` of ``x`` clipped to [0, 1].

    A C2 ease from 0 to 1: zero velocity and acceleration at both ends, so curves built of it
    (the generator's expression, speech, wrinkle and head-motion curves) start and stop smoothly.

    Parameters
    ----------
    x : float array, any shape
        Where to evaluate it (a fraction of a ramp: ``(t - start) / duration``); values below 0
        give 0, above 1 give 1.

    Returns
    -------
    float64 array, the shape of ``x``
        ``s(x)`` in [0, 1].

    Examples
    --------
    >>> smoothstep(np.array([-1.0, 0.0, 0.5, 1.0, 2.0])).tolist()
    [0.0, 0.0, 0.5, 1.0, 1.0]
    """
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)  # C2 ease: zero velocity and acceleration at both ends
