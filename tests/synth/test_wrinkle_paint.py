"""Wrinkle paint: a stripe of one colour over each valley and its bulges, neighbours in different colours."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.synth import skin_albedo
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkle_paint import PAINT_COLORS, PAINT_HALF_WIDTH, paint_wrinkles
from facecap.synth.wrinkle_scan import subdivide_scan
from facecap.synth.wrinkles import place_wrinkles


def test_stripes_cover_the_valleys_and_neighbours_differ():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=1)
    V = fine.mesh.vertices
    curves = place_wrinkles(fine.mesh, sample, seed=7)
    skin = skin_albedo(V, seed=7)
    painted = paint_wrinkles(curves, V, skin)
    bare = painted.stripe < 0
    np.testing.assert_array_equal(painted.albedo[bare], skin[bare])
    palette = np.asarray(PAINT_COLORS)
    for i in range(curves.n_curves):
        mine = np.flatnonzero(painted.stripe == i)
        assert mine.size > 0
        np.testing.assert_array_equal(painted.albedo[mine], np.broadcast_to(palette[painted.color_index[i]], (mine.size, 3)))
        # every painted vertex is within the stripe's half-width of its valley line (brute force on a dense line)
        P = curves.points[i]
        line = np.concatenate([np.linspace(a, b, 30) for a, b in zip(P[:-1], P[1:])])
        d = np.min(np.linalg.norm(V[mine, None] - line[None], axis=2), axis=1)
        assert d.max() <= PAINT_HALF_WIDTH * curves.max_width[i] + 0.02
        # and the valley line itself is painted: the vertices nearest its middle points
        mid = P[8:-8]
        nearest = np.argmin(np.linalg.norm(V[None] - mid[:, None], axis=2), axis=1)
        assert np.all(painted.stripe[nearest] == i)
    # neighbouring wrinkles (stripes within 10 mm) never share a paint
    for i in range(curves.n_curves):
        for j in range(i):
            gap = np.linalg.norm(curves.points[i][:, None] - curves.points[j][None], axis=2).min()
            if gap < PAINT_HALF_WIDTH * (curves.max_width[i] + curves.max_width[j]) + 10.0:
                assert painted.color_index[i] != painted.color_index[j], (curves.names[i], curves.names[j])
    # the paints stand out from skin: far from every skin colour in RGB
    assert np.min(np.linalg.norm(skin[:, None] - palette[None], axis=2)) > 0.25


def test_bad_shapes():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=1)
    curves = place_wrinkles(fine.mesh, sample, kinds=("forehead",))
    with pytest.raises(InputError, match="rest, skin"):
        paint_wrinkles(curves, fine.mesh.vertices, np.zeros((3, 3)))
