"""A straight wrinkle line on the z = 0 plane, of constant width, depth and quality, for the wrinkle tests."""

from __future__ import annotations

import numpy as np

from facecap.wrinkles import SurfaceWrinkle


def straight_wrinkle(name: str, x0: float, x1: float, y: float = 0.0, *, width: float = 2.0, depth: float = 0.5,
                     quality: float = 1.0, color: int = 0) -> SurfaceWrinkle:
    x = np.linspace(x0, x1, 41)
    k = len(x)
    return SurfaceWrinkle(name, color, np.column_stack([x, np.full(k, y), np.zeros(k)]), np.full(k, width),
                          np.full(k, depth), np.full(k, quality))
