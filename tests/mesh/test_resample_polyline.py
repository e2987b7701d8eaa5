"""Tests for facecap.mesh.resample_polyline: even spacing in arc length, against curves with known lengths."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.mesh.resample_polyline import resample_polyline


def test_points_lie_evenly_in_arc_length_on_a_finely_sampled_helix():
    t = np.linspace(0.0, 4 * np.pi, 2001)
    helix = np.column_stack([np.cos(t), np.sin(t), 0.5 * t])  # arc length 4 pi sqrt(1.25)
    line = resample_polyline(helix, 50, [t])
    np.testing.assert_allclose(line.arc[-1], 4 * np.pi * np.sqrt(1.25), rtol=1e-5)
    np.testing.assert_allclose(np.diff(line.arc), line.arc[-1] / 49, rtol=1e-12)
    # on a helix the parameter grows with arc length: the carried values are the parameter at each point
    np.testing.assert_allclose(line.values[0], np.linspace(0.0, 4 * np.pi, 50), atol=1e-9)
    np.testing.assert_allclose(line.points, np.column_stack([np.cos(line.values[0]), np.sin(line.values[0]),
                                                             0.5 * line.values[0]]), atol=1e-5)
    np.testing.assert_array_equal(line.points[[0, -1]], helix[[0, -1]])


def test_uneven_vertices_do_not_bunch_the_points():
    P = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [10.0, 0.0]])  # three vertices in the first 2 %
    line = resample_polyline(P, 11)
    np.testing.assert_allclose(line.points[:, 0], np.linspace(0.0, 10.0, 11), atol=1e-12)


def test_bad_input_is_refused():
    with pytest.raises(InputError, match="points"):
        resample_polyline(np.zeros((1, 3)), 5)
    with pytest.raises(InputError, match="count"):
        resample_polyline(np.zeros((3, 3)), 1)
    with pytest.raises(InputError, match="values"):
        resample_polyline(np.zeros((3, 3)), 5, [np.zeros(2)])
