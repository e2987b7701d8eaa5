"""A performance from bases and weights written as a result folder: the frames, the job's files, the method."""

import json

import numpy as np

from facecap.pipelines.write_blended_performance import write_blended_performance
from facecap.io.ict_sample import load_ict_sample


def test_known_combinations_are_written_in_the_output_frame(tmp_path):
    s = load_ict_sample()
    rng = np.random.default_rng(1)
    K, T = 6, 40
    bases = np.stack([s.mesh.vertices + s.expression_deltas[k] for k in (26, 45, 46, 10, 2, 39)])
    w = rng.uniform(0, 1, size=(T, K))
    w /= w.sum(axis=1, keepdims=True)
    frames = np.einsum("tk,knc->tnc", w, bases)
    pose = np.eye(4)
    pose[:3, 3] = [10.0, -5.0, 2.0]
    out = write_blended_performance(tmp_path / "out", s.mesh, bases, w, rate=60.0, output_from_bases=pose,
                                    progress=False, extra_files={"weights.npy": w, "note.txt": "x"})
    V = np.load(out / "vertices.npy", mmap_mode="r")
    np.testing.assert_allclose(V, frames + [10.0, -5.0, 2.0], atol=1e-3)
    assert json.loads((out / "performance.json").read_text())["method"] == "huang2011-blendshapes"
    np.testing.assert_array_equal(np.load(out / "weights.npy"), w)
    assert (out / "note.txt").read_text() == "x"
