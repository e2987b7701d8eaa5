"""forward_markers: the rest pose gives the rest markers; the cranium carries markers and offsets rigidly; noise."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.muscles import MuscleControls, forward_markers, marker_embedding


def test_rest_controls_give_the_rest_markers(anatomy, model, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    out = forward_markers(model, e, MuscleControls.rest(model.n_muscles))
    assert out.result.converged and out.result.inverted_tets == 0
    assert np.abs(out.markers - layout.rest_markers).max() < 1e-9
    assert np.abs(out.skin - anatomy.scan_vertices).max() < 1e-9


def test_the_cranium_moves_markers_and_offsets_rigidly(anatomy, model, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    rng = np.random.default_rng(4)
    a = rng.uniform(0, 0.5, model.n_muscles)
    jaw = model.jaw.transform(0.1)
    head = np.hstack([Rotation.from_rotvec([0.1, 0.3, -0.2]).as_matrix(), [[1.0], [2.0], [3.0]]])
    still = forward_markers(model, e, MuscleControls(a, np.eye(3, 4), jaw))
    moved = forward_markers(model, e, MuscleControls(a, head, jaw), x0=still.result.positions)
    assert np.abs(moved.markers - (still.markers @ head[:, :3].T + head[:, 3])).max() < 1e-6
    assert np.abs(moved.skin - (still.skin @ head[:, :3].T + head[:, 3])).max() < 1e-6
    # the muscles and the jaw moved the markers
    assert np.linalg.norm(still.markers - layout.rest_markers, axis=1).max() > 3.0


def test_noise(anatomy, model, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    c = MuscleControls.rest(model.n_muscles)
    noisy = forward_markers(model, e, c, noise_mm=0.2, seed=1)
    assert 0.15 < np.std(noisy.markers - layout.rest_markers) < 0.25
    assert np.array_equal(noisy.markers, forward_markers(model, e, c, noise_mm=0.2, seed=1).markers)
    with pytest.raises(InputError, match="noise_mm"):
        forward_markers(model, e, c, noise_mm=-1.0)
    with pytest.raises(InputError, match="controls"):
        forward_markers(model, e, MuscleControls.rest(2))
