import json

import numpy as np

from facecap.blendshapes.reconstruct_performance import blend_weights, write_blended_performance
from facecap.synth import load_ict_sample


def test_weights_and_dense_frames_of_known_combinations(tmp_path):
    s = load_ict_sample()
    rng = np.random.default_rng(1)
    K, T = 6, 40
    bases = np.stack([s.mesh.vertices + s.expression_deltas[k] for k in (26, 45, 46, 10, 2, 39)])
    true_w = rng.uniform(0, 1, size=(T, K))
    true_w /= true_w.sum(axis=1, keepdims=True)
    frames = np.einsum("tk,knc->tnc", true_w, bases)
    mv = rng.choice(9409, 80, replace=False)
    w, residual = blend_weights(bases[:, mv], frames[:, mv])
    np.testing.assert_allclose(w, true_w, atol=1e-6)
    assert residual.max() < 1e-6
    pose = np.eye(4)
    pose[:3, 3] = [10.0, -5.0, 2.0]
    out = write_blended_performance(tmp_path / "out", s.mesh, bases, w, rate=60.0, output_from_bases=pose,
                                    progress=False, extra_files={"weights.npy": w, "note.txt": "x"})
    V = np.load(out / "vertices.npy", mmap_mode="r")
    np.testing.assert_allclose(V, frames + [10.0, -5.0, 2.0], atol=1e-3)
    assert json.loads((out / "performance.json").read_text())["method"] == "huang2011-blendshapes"
    np.testing.assert_array_equal(np.load(out / "weights.npy"), w)
