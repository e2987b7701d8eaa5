"""Random eye blinks, for the generator's weight curves."""

from __future__ import annotations

import numpy as np

from .smoothstep import smoothstep

__all__ = ["blink_curve"]


def blink_curve(rng: np.random.Generator, t: np.ndarray, duration: float, lead_in_s: float,
                blinks_per_second: float) -> np.ndarray:
    """A random blink closure over a take: 0.2-0.3 s pulses, starting at least 0.4 s apart.

    Each blink closes over 0.06-0.1 s (``close``), stays shut 0.04 s and opens over ``1.5 close``,
    each ramp a :func:`smoothstep`. The first starts 0.3-1.5 s after the lead-in; each next one an
    exponential wait (mean ``1 / blinks_per_second``) plus 0.4 s after the previous.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the blinks' times and lengths (the caller's, so its curves stay reproducible).
    t : (T,) float64 array, s
        Every frame's time.
    duration : float, s
        Blinks start before this time only.
    lead_in_s : float, s
        Time before which no blink starts (plus the first one's 0.3-1.5 s).
    blinks_per_second : float, 1/s
        Mean rate of the blinks after the first (less the 0.4 s gaps).

    Returns
    -------
    (T,) float64 array
        The eyes' closure in [0, 1] at each frame (1 shut).

    Examples
    --------
    >>> t = np.arange(600) / 60.0
    >>> blink = blink_curve(np.random.default_rng(0), t, 10.0, 0.25, 0.3)
    >>> bool(blink.max() == 1.0 and blink.min() == 0.0)
    True
    """
    blink_at = lead_in_s + rng.uniform(0.3, 1.5)
    blink = np.zeros(t.size)
    while blink_at < duration:
        close = rng.uniform(0.06, 0.1)
        blink = np.maximum(blink, smoothstep((t - blink_at) / close) * (1.0 - smoothstep((t - blink_at - close - 0.04) / (close * 1.5))))
        blink_at += rng.exponential(1.0 / blinks_per_second) + 0.4
    return blink
