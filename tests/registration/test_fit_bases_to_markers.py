import numpy as np

from facecap.registration.fit_bases_to_markers import fit_bases_to_markers
from facecap.io.ict_sample import load_ict_sample


def test_fitted_bases_hit_their_markers_and_change_little_elsewhere():
    s = load_ict_sample()
    V, F = s.mesh.vertices, s.mesh.faces
    rng = np.random.default_rng(0)
    mv = rng.choice(np.arange(0, 9000, 7), 60, replace=False)
    registered = np.stack([V + 5 * s.expression_deltas[k].astype(np.float64) * 0.2 for k in (26, 45, 10)])
    # the scanned expressions differ a little from the mocap frames: markers 0.5 mm away
    offsets = rng.normal(scale=0.5, size=(3, 60, 3))
    targets = registered[:, mv] + offsets
    idx = np.stack([mv, mv, mv], 1)
    w = np.tile([1.0, 0.0, 0.0], (60, 1))
    bases, change = fit_bases_to_markers(registered, F, idx, w, targets)
    np.testing.assert_allclose(bases[:, mv], targets, atol=1e-4)
    np.testing.assert_allclose(change, np.linalg.norm(offsets, axis=2), atol=1e-9)
    # a smooth correction: nowhere moves much more than the marker offsets
    assert np.linalg.norm(bases - registered, axis=2).max() < 3 * np.abs(offsets).max()
