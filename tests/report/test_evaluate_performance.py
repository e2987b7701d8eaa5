"""Tests for facecap.report.evaluate_performance."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.report.evaluate_performance import evaluate_performance


def _brute(R, G):
    return np.linalg.norm(np.asarray(R, dtype=np.float64) - np.asarray(G, dtype=np.float64), axis=2)


def test_constant_offset_every_statistic_equals_offset():
    rng = np.random.default_rng(0)
    G = rng.normal(size=(7, 50, 3)) * 40.0
    d = np.array([0.3, -1.2, 2.0])
    res = evaluate_performance(G + d, G, region_labels=np.arange(50) % 3, chunk_frames=2)
    norm = float(np.linalg.norm(d))
    for v in (res.mean_mm, res.median_mm, res.p95_mm, res.max_mm):
        assert v == pytest.approx(norm, rel=1e-12)
    np.testing.assert_allclose(res.per_frame_mean_mm, norm, rtol=1e-12)
    np.testing.assert_allclose(res.per_frame_max_mm, norm, rtol=1e-12)
    np.testing.assert_allclose(res.per_vertex_mean_mm, norm, rtol=1e-12)
    assert set(res.regions) == {"region_0", "region_1", "region_2"}
    for r in res.regions.values():
        assert r.mean_mm == pytest.approx(norm) and r.p95_mm == pytest.approx(norm)
        assert r.max_mm == pytest.approx(norm)
    diag = np.linalg.norm(G[0].max(0) - G[0].min(0))
    assert res.diagonal_mm == pytest.approx(diag)
    assert res.mean_pct == pytest.approx(100 * norm / diag)


def test_matches_brute_force_on_random_memmap(tmp_path):
    rng = np.random.default_rng(1)
    T, n = 23, 400
    G = rng.normal(size=(T, n, 3)) * 30.0
    R = (G + rng.gamma(2.0, 0.5, size=(T, n, 1)) * rng.normal(size=(T, n, 3))).astype(np.float32)
    np.save(tmp_path / "r.npy", R)
    Rm = np.load(tmp_path / "r.npy", mmap_mode="r")
    labels = rng.integers(-1, 4, size=n)
    mask = rng.random(n) > 0.2
    names = ["brow", "eye", "cheek", "mouth"]
    res = evaluate_performance(
        Rm, G, region_labels=labels, region_names=names, vertex_mask=mask, chunk_frames=5
    )
    e_all = _brute(R, G)
    e = e_all[:, mask]
    assert res.n_frames == T and res.n_vertices == int(mask.sum())
    assert res.mean_mm == pytest.approx(e.mean(), rel=1e-12)
    assert res.max_mm == pytest.approx(e.max(), rel=1e-12)
    # Histogram quantiles: documented to be within one bin (2**-13 relative) of numpy's.
    assert res.median_mm == pytest.approx(np.median(e), rel=2**-13)
    assert res.p95_mm == pytest.approx(np.percentile(e, 95), rel=2**-13)
    t, i = np.unravel_index(np.argmax(np.where(mask, e_all, -1)), e_all.shape)
    assert (res.max_frame, res.max_vertex) == (t, i)
    np.testing.assert_allclose(res.per_frame_mean_mm, e.mean(axis=1), rtol=1e-12)
    np.testing.assert_allclose(res.per_frame_max_mm, e.max(axis=1), rtol=1e-12)
    np.testing.assert_allclose(res.per_vertex_mean_mm, e_all.mean(axis=0), rtol=1e-12)
    for k, name in enumerate(names):
        sel = mask & (labels == k)
        r = res.regions[name]
        assert r.n_vertices == int(sel.sum())
        assert r.mean_mm == pytest.approx(e_all[:, sel].mean(), rel=1e-12)
        assert r.max_mm == pytest.approx(e_all[:, sel].max(), rel=1e-12)
        assert r.p95_mm == pytest.approx(np.percentile(e_all[:, sel], 95), rel=2**-10)
    # The chunk size does not change the answer.
    res1 = evaluate_performance(Rm, G, vertex_mask=mask, chunk_frames=1000)
    assert res1.mean_mm == pytest.approx(res.mean_mm, rel=1e-12)
    assert res1.p95_mm == res.p95_mm


def test_float32_inputs_match_float64_brute_force():
    rng = np.random.default_rng(3)
    G = (rng.normal(size=(6, 300, 3)) * 80.0).astype(np.float32)
    R = (G + rng.normal(size=G.shape) * 0.3).astype(np.float32)
    e = _brute(R, G)
    res = evaluate_performance(R, G, chunk_frames=4)
    assert res.mean_mm == pytest.approx(e.mean(), rel=1e-6)
    assert res.max_mm == pytest.approx(e.max(), rel=1e-6)
    assert res.p95_mm == pytest.approx(np.percentile(e, 95), rel=2**-13)
    np.testing.assert_allclose(res.per_vertex_mean_mm, e.mean(axis=0), rtol=1e-5)


def test_to_dict_is_json_ready():
    rng = np.random.default_rng(2)
    G = rng.normal(size=(3, 10, 3))
    res = evaluate_performance(G + 1.0, G, region_labels=np.zeros(10, dtype=np.int64))
    d = json.loads(json.dumps(res.to_dict(per_vertex=True)))
    assert d["mean_mm"] == pytest.approx(np.sqrt(3.0))
    assert len(d["per_frame_max_mm"]) == 3 and len(d["per_vertex_mean_mm"]) == 10
    assert d["regions"]["region_0"]["n_vertices"] == 10


def test_single_frame_is_accepted():
    V = np.zeros((5, 3))
    res = evaluate_performance(V + [0.0, 0.0, 2.0], V)
    assert res.n_frames == 1 and res.max_mm == 2.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"truth_vertices": np.zeros((4, 6, 3))}, "same shape"),
        ({"vertex_mask": np.zeros(5, dtype=bool)}, "vertex_mask"),
        ({"vertex_mask": np.ones(4, dtype=bool)}, "vertex_mask"),
        ({"region_labels": np.zeros(4, dtype=np.int64)}, "region_labels"),
        ({"region_labels": np.array([0, 1, 2, 2, 2]), "region_names": ["a", "b"]}, "region_names"),
        ({"region_names": ["a"]}, "region_names"),
        ({"chunk_frames": 0}, "chunk_frames"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {"result_vertices": np.zeros((4, 5, 3)), "truth_vertices": np.zeros((4, 5, 3))}
    args.update(kwargs)
    R = args.pop("result_vertices")
    G = args.pop("truth_vertices")
    with pytest.raises(InputError, match=match):
        evaluate_performance(R, G, **args)


def test_nan_names_the_array_and_frame():
    G = np.zeros((4, 5, 3))
    R = G.copy()
    R[2, 3, 1] = np.nan
    with pytest.raises(InputError, match="result_vertices.*frame 2, vertex 3"):
        evaluate_performance(R, G)


def test_errors_split_across_and_along_the_skin():
    # a flat sheet (normals +z): an error of 0.3 mm in x and 0.4 mm in z is 0.4 across and 0.3 along
    xs, ys = np.meshgrid(np.arange(5.0), np.arange(4.0))
    V = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    idx = np.arange(xs.size).reshape(xs.shape)
    F = np.concatenate([np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()], 1),
                        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], 1)])
    truth = np.stack([V, V + [0.0, 0.0, 0.0]])
    result = truth + np.array([0.3, 0.0, 0.4])
    out = evaluate_performance(result, truth, faces=F)
    assert out.mean_mm == pytest.approx(0.5)
    assert out.across_mean_mm == pytest.approx(0.4) and out.along_mean_mm == pytest.approx(0.3)
    varied = truth + np.arange(V.shape[0])[None, :, None] * np.array([0.0, 0.0, 0.1])  # vertex i: 0.1 i across
    masked = evaluate_performance(varied, truth, faces=F, vertex_mask=np.arange(V.shape[0]) < 5)
    assert masked.across_mean_mm == pytest.approx(0.2) and masked.along_mean_mm == pytest.approx(0.0, abs=1e-6)
    assert masked.n_vertices == 5
    assert evaluate_performance(result, truth).across_mean_mm is None
