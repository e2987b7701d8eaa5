"""place_fine_lines and skin_texture_heights: lines of the right families and scales, made by the right
expressions, the same on a refinement; the static texture's amplitude; the independent profile."""

import numpy as np

from facecap.io.ict_sample import load_ict_sample
from facecap.synth.fine_lines import (FINE_LINE_KINDS, double_crease_profile, place_fine_lines,
                                      skin_texture_heights)
from facecap.synth.wrinkle_scan import refine_near, subdivide_scan
from facecap.synth.wrinkles import INFLUENCE_WIDTHS, WRINKLE_EXPRESSIONS, wrinkle_activation, wrinkle_heights


def test_fine_lines_families_scales_and_drivers():
    sample = load_ict_sample()
    mesh = subdivide_scan(sample.mesh, levels=1).mesh
    lines = place_fine_lines(mesh, sample, seed=3)
    assert set(lines.kinds) == set(FINE_LINE_KINDS)
    assert np.all((lines.max_depth >= 0.02) & (lines.max_depth <= 0.3))
    assert np.all((2 * lines.min_width >= 0.2) & (2 * lines.max_width <= 1.5))  # valleys 0.3-1.5 mm across
    index = {s: i for i, s in enumerate(sample.expression_names)}
    kinds = np.array(lines.kinds)

    def active(expression):
        w = np.zeros((1, len(index)))
        for name, g in WRINKLE_EXPRESSIONS[expression].items():
            w[0, index[name]] = g
        return wrinkle_activation(lines, w)[0] > 0.05

    assert set(kinds[active("brow_raise")]) == {"forehead"}
    assert "glabella" in set(kinds[active("frown")]) and "forehead" not in set(kinds[active("frown")])
    assert {"crows_feet", "under_eye"} <= set(kinds[active("smile")])
    assert not wrinkle_activation(lines, np.zeros((1, len(index)))).any()
    # forehead lines above the brows, under-eye lines below the eyes
    L = mesh.vertices[sample.landmarks]
    assert lines.points[kinds == "forehead", :, 1].min() > L[17:27, 1].max()
    assert lines.points[kinds == "under_eye", :, 1].max() < L[36:48, 1].max()
    # the same lines on a refinement of the same surface
    near = np.zeros(mesh.n_vertices, dtype=bool)
    near[sample.landmarks[17:27]] = True
    again = place_fine_lines(refine_near(mesh, near, max_edge_mm=0.8).mesh, sample, seed=3)
    np.testing.assert_allclose(again.points, lines.points, atol=1e-9)


def test_heights_reach_the_depth_at_full_activation_and_vanish_beyond_the_reach():
    sample = load_ict_sample()
    mesh = subdivide_scan(sample.mesh, levels=1).mesh
    lines = place_fine_lines(mesh, sample, seed=0)
    rest = lines.points[0]  # points on the first forehead line
    mask, moving, h = wrinkle_heights(lines, rest, np.eye(lines.n_curves)[:1])
    mid = np.argmin(np.abs(lines.arc_fraction[0] - 0.5))
    taper = np.sqrt(np.sin(np.pi * lines.arc_fraction[0, mid]))  # the depth's taper along the line
    np.testing.assert_allclose(h[0, mid], -lines.max_depth[0] * taper, rtol=1e-9)
    # exactly 0 beyond the reach of every line: the scan's vertices far from all of them
    d = np.min([np.linalg.norm(mesh.vertices[:, None] - P[None], axis=2).min(axis=1) for P in lines.points], axis=0)
    mask, _, _ = wrinkle_heights(lines, mesh.vertices, np.ones((1, lines.n_curves)))
    assert not mask[d > INFLUENCE_WIDTHS * lines.max_width.max() + 1.0].any()


def test_double_crease_and_texture():
    q = np.linspace(0.0, 2.0, 201)
    h = double_crease_profile(q, 0.2, 1.0)
    assert h.min() == -0.2 and np.all(h <= 0) and np.all(h[q >= 1.05] == 0)
    np.testing.assert_allclose(h[[0, 45]], [-0.1, -0.2])
    P = np.random.default_rng(0).uniform(-60, 60, (30000, 3))
    t = skin_texture_heights(P, seed=2)
    assert 0.009 < t.std() < 0.011 and np.percentile(np.abs(t), 90) < 0.03
    np.testing.assert_array_equal(skin_texture_heights(P[:5], seed=2), t[:5])  # a solid texture
