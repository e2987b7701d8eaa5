"""solve_muscles: a short take, each frame warm-started from the one before."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.muscles import forward_markers, marker_embedding, solve_muscles

from muscle_cases import ramping_controls


def test_a_take_is_tracked_frame_by_frame(anatomy, model, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    k = model.n_muscles
    # activations change by up to 0.23 between frames, the jaw by 1.3 degrees
    truth = ramping_controls(k, 4, seed=9, peak=0.7, jaw=lambda s: model.jaw.transform(np.radians(3 + 4 * s), s, 2 * s))
    markers = [forward_markers(model, e, c).markers for c in truth]
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
