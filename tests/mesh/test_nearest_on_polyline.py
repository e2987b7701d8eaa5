"""Tests for facecap.mesh.nearest_on_polyline."""

from __future__ import annotations

import numpy as np

from facecap.mesh.nearest_on_polyline import nearest_on_polyline


def test_an_l_shaped_line_by_hand():
    line = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]])
    points = np.array([
        [4.0, 3.0, 0.0],    # beside the first segment
        [12.0, 6.0, 0.0],   # beside the second
        [-3.0, 4.0, 0.0],   # before the start: its foot is the first vertex
        [10.0, 13.0, 0.0],  # past the end
        [11.0, -1.0, 2.0],  # off the corner
    ])
    distance, position = nearest_on_polyline(points, line)
    np.testing.assert_allclose(distance, [3.0, 2.0, 5.0, 3.0, np.sqrt(6.0)], rtol=1e-15)
    np.testing.assert_allclose(position, [4.0, 16.0, 0.0, 20.0, 10.0], rtol=1e-15)
    # the values given at the vertices are interpolated at the feet instead of the arc length
    _, fraction = nearest_on_polyline(points, line, np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(fraction, [0.2, 0.8, 0.0, 1.0, 0.5], rtol=1e-15)


def test_against_a_dense_sampling_of_the_line():
    rng = np.random.default_rng(4)
    line = np.cumsum(rng.normal(size=(12, 3)), axis=0)
    points = rng.normal(size=(60, 3)) * 3 + line.mean(axis=0)
    distance, position = nearest_on_polyline(points, line)
    # the line sampled every 2e-4 of a segment: the nearest sample is as near, to that spacing
    u = np.linspace(0.0, 1.0, 5001)
    samples = np.concatenate([a + u[:, None] * (b - a) for a, b in zip(line[:-1], line[1:])])
    seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
    arc = np.concatenate([np.concatenate([[0.0], np.cumsum(seg)])[k] + u * seg[k] for k in range(seg.size)])
    d = np.linalg.norm(points[:, None] - samples[None], axis=2)
    nearest = np.argmin(d, axis=1)
    np.testing.assert_allclose(distance, d.min(axis=1), atol=5e-4)
    assert np.all(distance <= d.min(axis=1) + 1e-12)
    np.testing.assert_allclose(position, arc[nearest], atol=1e-2)
