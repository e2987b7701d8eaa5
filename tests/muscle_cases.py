"""Known muscle controls for the round trips of the muscle tests (markers then come from the forward model)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from facecap.muscles import MuscleControls


def ramping_controls(n_muscles: int, n_frames: int, *, seed: int, peak: float,
                     jaw: Callable[[float], np.ndarray],
                     cranium: Callable[[float], np.ndarray] = lambda s: np.eye(3, 4)) -> list[MuscleControls]:
    """Known controls over a short take: about half the muscles ramping between two random activations
    up to ``peak``, the jaw and the cranium as functions of the take's progress ``s`` in [0, 1]."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(0, peak, n_muscles) * (rng.uniform(size=n_muscles) < 0.5)
    end = rng.uniform(0, peak, n_muscles) * (rng.uniform(size=n_muscles) < 0.5)
    return [MuscleControls((1 - s) * start + s * end, cranium(s), jaw(s)) for s in np.linspace(0, 1, n_frames)]
