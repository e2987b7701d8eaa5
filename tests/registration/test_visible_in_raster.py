"""Tests for facecap.registration.visible_in_raster: a layer hidden under another is not seen."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.registration.cylindrical_map import cylindrical_map
from facecap.registration.visible_in_raster import visible_in_raster


def _sheet(n, half_width, radius):
    """A patch of the cylinder of the given radius around the y axis, facing +z, (n, n) vertices."""
    theta, h = np.meshgrid(np.linspace(-half_width, half_width, n) / radius, np.linspace(-half_width, half_width, n))
    V = np.stack([radius * np.sin(theta.ravel()), h.ravel(), radius * np.cos(theta.ravel())], 1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def _brute_force(raster):
    """Per vertex: look at the 3 x 3 pixels around its rounded position, one by one."""
    h, w = raster.face.shape
    seen = np.zeros(raster.pixels.shape[0], dtype=bool)
    for j, (u, v) in enumerate(raster.pixels):
        c, r = min(max(int(np.rint(u)), 0), w - 1), min(max(int(np.rint(v)), 0), h - 1)
        for rr in range(r - 1, r + 2):
            for cc in range(c - 1, c + 2):
                t = raster.face[min(max(rr, 0), h - 1), min(max(cc, 0), w - 1)]
                seen[j] |= bool(t >= 0 and j in raster.F[t])
    return seen


def test_a_sheet_facing_the_image_is_seen_everywhere():
    V, F = _sheet(11, 20.0, 80.0)
    raster = cylindrical_map(V, centre=(0, 0, 0), size_px=96).rasterise(F)
    assert visible_in_raster(raster).all()


def test_a_layer_under_another_is_hidden_and_its_rim_beyond_it_is_seen():
    # the outer sheet's triangles come first, so they win the pixels the two layers share
    outer, F_outer = _sheet(11, 20.0, 80.0)
    inner, F_inner = _sheet(15, 28.0, 70.0)  # wider: its rim shows beyond the outer sheet
    V = np.concatenate([outer, inner])
    F = np.concatenate([F_outer, F_inner + len(outer)])
    cmap = cylindrical_map(V, centre=(0, 0, 0), size_px=128)
    raster = cmap.rasterise(F)
    seen = visible_in_raster(raster)
    np.testing.assert_array_equal(seen, _brute_force(raster))
    assert seen[: len(outer)].all()
    inner_seen = seen[len(outer):]
    # image extent of the outer sheet in the inner sheet's arc and height, with a pixel and a half to spare
    arc_outer = 20.0 / 80.0 * 70.0
    slack = 1.5 / cmap.px_per_mm
    under = (np.abs(70.0 * np.arctan2(inner[:, 0], inner[:, 2])) < arc_outer - slack) & (np.abs(inner[:, 1]) < 20.0 - slack)
    beyond = (np.abs(70.0 * np.arctan2(inner[:, 0], inner[:, 2])) > arc_outer + slack) | (np.abs(inner[:, 1]) > 20.0 + slack)
    assert under.sum() > 20 and beyond.sum() > 20
    assert not inner_seen[under].any()
    assert inner_seen[beyond].all()


def test_a_mesh_moved_off_the_image_is_not_seen():
    V, F = _sheet(9, 15.0, 80.0)
    cmap = cylindrical_map(V, centre=(0, 0, 0), size_px=64)
    half = cmap.pixels + [0.5 * cmap.shape[1], 0.0]  # half of it beyond the right edge
    raster = cmap.rasterise(F, pixels=half)
    seen = visible_in_raster(raster)
    np.testing.assert_array_equal(seen, _brute_force(raster))
    assert seen[half[:, 0] < cmap.shape[1] - 3].all() and not seen[half[:, 0] > cmap.shape[1] + 1].any()
    with pytest.raises(InputError, match="TriangleRaster"):
        visible_in_raster(cmap)  # type: ignore[arg-type]
