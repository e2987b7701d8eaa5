"""Random frames of odd sizes for the footage tests (odd on purpose: some video writers silently pad to a
multiple of 16)."""

from __future__ import annotations

import numpy as np

RNG = np.random.default_rng(11)
FRAMES_8 = RNG.integers(0, 256, (40, 37, 61, 3), dtype=np.uint8)
FRAMES_16 = RNG.integers(0, 65536, (12, 37, 61, 3), dtype=np.uint16)
