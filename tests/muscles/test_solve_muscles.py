"""solve_muscles: a short take, each frame warm-started from the one before."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.muscles import MuscleControls, forward_markers, marker_embedding, solve_muscles


def test_a_take_is_tracked_frame_by_frame(anatomy, model, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    rng = np.random.default_rng(9)
    k = model.n_muscles
    start = rng.uniform(0, 0.7, k) * (rng.uniform(size=k) < 0.5)
    end = rng.uniform(0, 0.7, k) * (rng.uniform(size=k) < 0.5)
    truth, markers = [], []
    for s in np.linspace(0, 1, 4):  # activations change by up to 0.23 between frames, the jaw by 1.3 degrees
        jaw = model.jaw.transform(np.radians(3 + 4 * s), s, 2 * s)
        c = MuscleControls((1 - s) * start + s * end, np.eye(3, 4), jaw)
        truth.append(c)
        markers.append(forward_markers(model, e, c).markers)
    take = solve_muscles(anatomy, layout.marker_vertices, layout.rest_markers, np.stack(markers), model=model,
                         max_warm_steps=4)
    assert take.activations.shape == (4, k) and take.skin.shape == (4,) + anatomy.scan_vertices.shape
    assert take.cranium.shape == (4, 3, 4) and take.marker_residuals.shape == (4, layout.marker_vertices.size)
    assert all(f.steps <= 4 for f in take.frames[1:])  # warm frames: at most max_warm_steps
    assert all(flags == () for flags in take.flags)
    # noise-free markers: every frame, warm ones included, comes back exactly
    error = np.abs(take.activations - np.stack([c.activations for c in truth]))
    assert error.max() < 1e-2, error.max(axis=1)
    poses = np.array([model.jaw.pose(c.mandible) for c in truth])
    assert np.abs(take.jaw_pose - poses).max() < 1e-3
    assert (take.rms_mm < 0.01).all()


def test_bad_take(anatomy, layout) -> None:
    with pytest.raises(InputError, match=r"\(T, M, 3\)"):
        solve_muscles(anatomy, layout.marker_vertices, layout.rest_markers, np.zeros((3, 3)))
