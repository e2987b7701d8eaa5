"""Ground-truth wrinkles: the profile's analytic shape, placement, growth with expression, displacement only in the mask."""

from functools import lru_cache

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.mesh.vertex_normals import vertex_normals
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkle_scan import subdivide_scan
from facecap.synth.wrinkles import (INFLUENCE_WIDTHS, WRINKLE_KINDS, add_wrinkles, place_wrinkles,
                                    wrinkle_activation, wrinkle_expression_curves, wrinkle_profile)


@lru_cache(maxsize=1)
def _fine():
    return subdivide_scan(load_ict_sample().mesh, levels=1)


def test_profile_is_a_valley_with_bulges_and_not_the_solvers_function():
    d, w = 0.7, 1.8
    p = np.linspace(0.0, 4 * w, 4001)
    h = wrinkle_profile(p, d, w)
    assert h[0] == pytest.approx(-d)
    assert wrinkle_profile(w, d, w) == pytest.approx(0.0, abs=1e-15)
    peak = np.argmax(h)
    assert p[peak] == pytest.approx(np.sqrt(2) * w, abs=2e-3)
    assert h[peak] == pytest.approx(d * np.exp(-2.0), rel=1e-5)
    assert np.all(h[p >= INFLUENCE_WIDTHS * w] == 0.0)
    # round at the bottom (zero slope) where the solver's S = d (p/w - 1) exp(-p/w) has slope 2 d / w
    slope = (wrinkle_profile(1e-5, d, w) - wrinkle_profile(0.0, d, w)) / 1e-5
    assert abs(slope) < 1e-3 * d / w
    S = d * (p / w - 1.0) * np.exp(-p / w)
    assert np.max(np.abs(h + S)) > 0.2 * d  # a different shape (S is a height of -d at 0 with the sign flipped)


def test_curves_lie_on_the_surface_and_cover_every_family():
    sample = load_ict_sample()
    fine = _fine()
    curves = place_wrinkles(fine.mesh, sample, seed=4)
    assert set(curves.kinds) == set(WRINKLE_KINDS)
    V, F = fine.mesh.vertices, fine.mesh.faces
    on_surface = np.einsum("ckj,ckjd->ckd", curves.barycentric, V[F[curves.faces]])
    np.testing.assert_allclose(on_surface, curves.points, atol=1e-3)
    assert np.all(np.diff(curves.arc_fraction, axis=1) > 0)
    # forehead lines above the brows, nasolabial folds below the nose
    brow_top = V[sample.landmarks[17:27], 1].max()
    nose_base = V[sample.landmarks[33], 1]
    for name, P in zip(curves.names, curves.points):
        if name.startswith("forehead"):
            assert P[:, 1].min() > brow_top and P[:, 1].max() > brow_top + 10.0
            region = np.array(sample.region_names)[sample.region_labels[
                np.argmin(np.linalg.norm(V[: sample.n_vertices, None] - P[None, ::6], axis=2), axis=0)]]
            assert set(region) <= {"forehead", "brows"}
        if name.startswith("nasolabial"):
            assert P[:, 1].max() < nose_base + 5.0


def test_depth_and_width_grow_with_the_expression_and_vanish_at_rest():
    sample = load_ict_sample()
    fine = _fine()
    curves = place_wrinkles(fine.mesh, sample, kinds=("forehead",), seed=1)
    names = sample.expression_names
    levels = np.linspace(0.0, 1.0, 6)
    W = np.zeros((levels.size, len(names)))
    for s in ("browInnerUp_L", "browInnerUp_R"):
        W[:, names.index(s)] = levels
    V = fine.mesh.vertices
    large = np.broadcast_to(V, (levels.size, *V.shape)).astype(np.float32)
    out = add_wrinkles(large, fine.mesh.faces, curves, W, rest=V)
    mid = out.depths[:, :, curves.points.shape[1] // 2]
    assert np.all(np.diff(mid, axis=0) > 0)
    assert np.all(np.diff(out.widths[:, :, 10], axis=0) > 0)
    np.testing.assert_array_equal(out.depths[0], 0.0)
    np.testing.assert_array_equal(out.vertices[0], large[0])
    # the deepest vertex near each line follows the truth depth (the mesh samples the profile every ~1.9 mm)
    assert out.heights[-1].min() < -0.8 * curves.max_depth.min()
    # a wrinkle of an expression that is not played stays flat
    frown = place_wrinkles(fine.mesh, sample, kinds=("glabella",), seed=1)
    assert np.all(wrinkle_activation(frown, W) == 0.0)


def test_displacement_along_the_normals_and_zero_outside_the_mask():
    sample = load_ict_sample()
    fine = _fine()
    curves = place_wrinkles(fine.mesh, sample, seed=2)
    names = sample.expression_names
    W = np.zeros((2, len(names)))
    W[1] = 0.8
    deltas = np.stack([fine.upsample @ sample.expression_deltas[k] for k in range(len(names))])
    large = (fine.mesh.vertices[None] + np.tensordot(W, deltas, axes=1)).astype(np.float32)
    out = add_wrinkles(large, fine.mesh.faces, curves, W, rest=fine.mesh.vertices)
    moved = out.vertices.astype(np.float64) - large
    np.testing.assert_array_equal(moved[:, ~out.mask], 0.0)
    assert np.all(out.heights[:, ~out.mask] == 0.0)
    inside = np.flatnonzero(out.mask)
    N = vertex_normals(large[1].astype(np.float64), fine.mesh.faces, inside)
    np.testing.assert_allclose(moved[1, inside], out.heights[1, inside, None] * N, atol=2e-5)  # float32 storage at ~100 mm
    # every vertex farther than INFLUENCE_WIDTHS widths from all valley lines is outside the mask
    from scipy.spatial import cKDTree
    dist = np.full(fine.mesh.n_vertices, np.inf)
    for P, w in zip(curves.points, curves.max_width):
        fine_line = np.concatenate([np.linspace(a, b, 20) for a, b in zip(P[:-1], P[1:])])
        dist = np.minimum(dist, cKDTree(fine_line).query(fine.mesh.vertices)[0] / w)
    assert not np.any(out.mask & (dist > INFLUENCE_WIDTHS + 0.01))
    assert np.all(out.mask[dist < INFLUENCE_WIDTHS - 0.01])
    # the truth valley line sits the truth depth below the large-scale surface
    mid = curves.points.shape[1] // 2
    assert np.all(out.depths[1, :, mid] > 0)


def test_bad_input():
    sample = load_ict_sample()
    fine = _fine()
    with pytest.raises(InputError, match="kinds"):
        place_wrinkles(fine.mesh, sample, kinds=("dimples",))
    curves = place_wrinkles(fine.mesh, sample, kinds=("forehead",))
    with pytest.raises(InputError, match="weights"):
        wrinkle_activation(curves, np.zeros((3, 5)))
    with pytest.raises(InputError, match="large_scale"):
        add_wrinkles(np.zeros((4, 3)), fine.mesh.faces, curves, np.zeros((4, 53)))


def test_wrinkle_expression_curves_form_every_wrinkle_in_a_four_second_take():
    sample = load_ict_sample()
    curves = place_wrinkles(_fine().mesh, sample, seed=3)
    W = wrinkle_expression_curves(200, sample.expression_names, rate=50.0, seed=3)
    assert W.shape == (200, 53) and np.all(W[0] == 0.0) and W.min() >= 0.0 and W.max() <= 1.0
    a = wrinkle_activation(curves, W)
    assert np.all(a.max(axis=0) > 0.5), dict(zip(curves.names, a.max(axis=0)))
    assert np.max(np.abs(np.diff(W, axis=0))) < 0.2  # eased, not switched (50 Hz, ramps >= 0.3 s)
    np.testing.assert_array_equal(W, wrinkle_expression_curves(200, sample.expression_names, rate=50.0, seed=3))
