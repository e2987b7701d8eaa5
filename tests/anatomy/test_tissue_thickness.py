"""tissue_thickness: landmark depths interpolated harmonically over a flat grid (maximum principle, constants)."""

from __future__ import annotations

import numpy as np
import pytest

from anatomy_meshes import grid_mesh as _grid_mesh
from facecap.anatomy import tissue_thickness
from facecap.errors import InputError


def test_thickness_keeps_landmark_values_and_stays_within_their_range() -> None:
    V, F = _grid_mesh()
    rng = np.random.default_rng(3)
    idx = rng.choice(V.shape[0], size=8, replace=False)
    depths = rng.uniform(4.0, 22.0, size=8)
    t = tissue_thickness(V, F, idx, depths)
    assert np.allclose(t[idx], depths, atol=1e-12)
    # discrete maximum principle on a mesh of right triangles (cotangent weights >= 0)
    assert t.min() >= depths.min() - 1e-9 and t.max() <= depths.max() + 1e-9
    # a constant is harmonic: equal landmark values give that value everywhere
    assert np.allclose(tissue_thickness(V, F, idx, np.full(8, 7.25)), 7.25, atol=1e-9)


def test_thickness_refuses_bad_depths() -> None:
    V, F = _grid_mesh(5)
    with pytest.raises(InputError, match="depths"):
        tissue_thickness(V, F, [0, 3], [5.0, -1.0])
    with pytest.raises(InputError, match="vertices"):
        tissue_thickness(V, F, [0, 0], [5.0, 6.0])
