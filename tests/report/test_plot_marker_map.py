"""Tests for facecap.report.plot_marker_map: the picture ``facecap map`` writes."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from facecap.errors import InputError
from facecap.report import plot_marker_map
from facecap.report.plot_marker_map import MARKER_MAP_COLORS


def _cap(n: int = 30):
    """A dome facing +z (out of the face), 120 x 160 mm."""
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    V = np.stack([60 * u.ravel(), 80 * v.ravel(), 30 * (1 - u.ravel() ** 2) * (1 - v.ravel() ** 2)], 1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return V, F


def test_each_marker_is_drawn_where_it_is_with_its_label_and_kind(tmp_path):
    V, F = _cap()
    points = np.array([[0.0, 0.0, 30.0], [30.0, 40.0, 10.0], [-30.0, -40.0, 10.0], [np.nan, np.nan, np.nan]])
    labels = ["Nose", "BrowL", "ChinR", "Lost"]
    kinds = ["placed", "check", "not placed", "not placed"]
    # the scan turned so that the face looks along -x with +z up: the picture must undo it
    turn = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # a rotation: face +z -> -x, up +y -> +z
    fig = plot_marker_map(V @ turn.T, F, points @ turn.T, labels, kinds, tmp_path / "map.png",
                          forward=[-1.0, 0.0, 0.0], up=[0.0, 0.0, 1.0], title="map.json", size_px=(400, 500))
    ax = fig.axes[0]
    drawn = {c.get_gid(): c.get_offsets() for c in ax.collections if c.get_gid()}
    assert set(drawn) == set(MARKER_MAP_COLORS)
    np.testing.assert_allclose(drawn["placed"], [[0.0, 0.0]], atol=1e-9)
    np.testing.assert_allclose(drawn["check"], [[30.0, 40.0]], atol=1e-9)  # right and up, as on the face
    np.testing.assert_allclose(drawn["not placed"], [[-30.0, -40.0]], atol=1e-9)
    assert [t.get_text() for t in ax.texts] == ["Nose", "BrowL", "ChinR"]  # nothing for the point not drawn
    assert imread(tmp_path / "map.png").shape[:2] == (500, 400)


def test_bad_input_is_refused(tmp_path):
    V, F = _cap(5)
    out = tmp_path / "map.png"
    with pytest.raises(InputError, match="kinds"):
        plot_marker_map(V, F, V[:2], ["a", "b"], ["placed", "lost"], out, forward=[0, 0, 1], up=[0, 1, 0])
    with pytest.raises(InputError, match="labels"):
        plot_marker_map(V, F, V[:2], ["a"], ["placed"], out, forward=[0, 0, 1], up=[0, 1, 0])
    with pytest.raises(InputError, match="up"):
        plot_marker_map(V, F, V[:1], ["a"], ["placed"], out, forward=[0, 0, 1], up=[0, 0, 2])
    assert not out.exists()
