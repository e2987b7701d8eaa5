"""Tests for facecap.rotations.nearest_rotation, against SciPy's nearest rotation and the polar decomposition."""

import numpy as np
import pytest
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.rotations import nearest_rotation


def test_a_rotation_is_its_own_nearest():
    R = Rotation.random(20, random_state=0).as_matrix()
    np.testing.assert_allclose(nearest_rotation(R), R, atol=1e-14)


def test_drifted_matrices_go_to_scipys_nearest_rotation_and_the_polar_factor():
    rng = np.random.default_rng(1)
    R = Rotation.random(50, random_state=1).as_matrix()
    M = R + 0.05 * rng.normal(size=R.shape)  # a blend or a solve's round-off: near a rotation, not one
    ours = nearest_rotation(M)
    np.testing.assert_allclose(ours, Rotation.from_matrix(M).as_matrix(), atol=1e-10)
    for k in range(5):
        np.testing.assert_allclose(ours[k], polar(M[k])[0], atol=1e-12)  # det > 0 here: the polar factor
    np.testing.assert_allclose(ours @ np.swapaxes(ours, -1, -2), np.broadcast_to(np.eye(3), ours.shape), atol=1e-12)


def test_a_reflection_gives_a_proper_rotation_never_a_reflection():
    M = np.diag([1.0, 1.0, -1.0]) @ Rotation.random(random_state=2).as_matrix()
    R = nearest_rotation(M)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.linalg.det(polar(M)[0]) == pytest.approx(-1.0)  # what the unconstrained projection would give


def test_bad_matrices_are_refused():
    with pytest.raises(InputError, match="3, 3"):
        nearest_rotation(np.eye(4))
    with pytest.raises(InputError, match="finite"):
        nearest_rotation(np.full((3, 3), np.nan))
