"""JawConstraints: psi1-psi6 on analytic jaw motions, the transform/pose round trip, the affine form."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.muscles import JawConstraints

U, V, M, L = np.array([1.0, 0, 0]), np.array([0.0, 0, 1]), np.array([0.0, 30.0, -50.0]), 100.0


def jaw() -> JawConstraints:
    return JawConstraints(U, V, M, L, track_length_mm=15.0, max_opening_rad=np.radians(35.0))


def test_frame_vectors() -> None:
    j = jaw()
    assert np.allclose(j.w, [0, 1, 0])  # v x u: up
    assert np.allclose(j.values(np.eye(3, 4)), 0.0) and np.all(j.violations(np.eye(3, 4)) == 0)


def test_pure_opening_is_a_rotation_about_the_condyles() -> None:
    j = jaw()
    b = j.transform(0.4)
    R, t = b[:, :3], b[:, 3]
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-14) and np.isclose(np.linalg.det(R), 1.0)
    # the condyles stay put, the chin (ahead of the condyles) goes down
    for condyle in (M - 0.5 * L * U, M + 0.5 * L * U):
        assert np.allclose(R @ condyle + t, condyle, atol=1e-12)
    chin = M + np.array([0, -40.0, 90.0])
    assert (R @ chin + t)[1] < chin[1] - 30
    psi = j.values(b)
    assert np.allclose(psi[:5], 0.0, atol=1e-12) and np.isclose(psi[5], -np.sin(0.4))


def test_transform_and_pose_round_trip() -> None:
    j = jaw()
    rng = np.random.default_rng(1)
    for _ in range(20):
        opening, left, right = rng.uniform(0, 0.6), rng.uniform(0, 15), rng.uniform(0, 15)
        b = j.transform(opening, left, right)
        psi = j.values(b)
        assert np.allclose(psi[:3], 0.0, atol=1e-12)  # psi1-psi3 hold exactly
        assert np.isclose(psi[3], right) and np.isclose(psi[4], left)  # the two slides
        assert np.isclose(psi[5], -np.sin(opening))
        assert np.allclose(j.pose(b), [opening, left, right], atol=1e-12)
        assert np.allclose(b[:, :3].T @ b[:, :3], np.eye(3), atol=1e-12)


def test_linear_terms_match_values() -> None:
    j = jaw()
    G, g0 = j.linear_terms()
    rng = np.random.default_rng(2)
    b = rng.normal(size=(3, 4))
    vec = np.concatenate([b[:, :3].ravel(), b[:, 3]])
    assert np.allclose(G @ vec + g0, j.values(b))
    # psi is affine: central differences give G exactly
    h = 1e-3
    for i in range(12):
        e = np.zeros(12)
        e[i] = h
        plus = np.hstack([(vec + e)[:9].reshape(3, 3), (vec + e)[9:, None]])
        minus = np.hstack([(vec - e)[:9].reshape(3, 3), (vec - e)[9:, None]])
        assert np.allclose((j.values(plus) - j.values(minus)) / (2 * h), G[:, i], atol=1e-9)


def test_violations_of_the_bounds() -> None:
    j = jaw()
    excess = np.sin(np.radians(45)) - np.sin(np.radians(35))
    assert np.allclose(j.violations(j.transform(np.radians(45.0))), [0, 0, 0, 0, 0, excess])
    v = j.violations(j.transform(0.1, 20.0, 16.0))
    assert np.isclose(v[4], 5.0) and np.isclose(v[3], 1.0) and v[5] == 0
    backwards = j.transform(-0.1)  # closing past the rest bite
    assert np.isclose(j.violations(backwards)[5], np.sin(0.1))


def test_from_anatomy(anatomy) -> None:
    j = JawConstraints.from_anatomy(anatomy)
    assert np.isclose(j.condyle_distance_mm, np.linalg.norm(anatomy.condyles[0] - anatomy.condyles[1]))
    assert np.allclose(j.midpoint, anatomy.condyles.mean(axis=0))
    assert abs(j.u @ j.v) < 1e-12 and np.isclose(np.linalg.norm(j.w), 1.0)
    assert j.u @ (anatomy.condyles[0] - anatomy.condyles[1]) > 0  # right to left
    # the tracks point forward and down (the chin is ahead of and below the condyles)
    chin = anatomy.landmark_points[list(anatomy.landmark_names).index("pogonion")]
    assert j.v @ (chin - j.midpoint) > 0 and j.w @ (chin - j.midpoint) < 0


def test_bad_input() -> None:
    with pytest.raises(InputError, match="parallel"):
        JawConstraints(U, U, M, L)
    with pytest.raises(InputError, match="track_length_mm"):
        JawConstraints(U, V, M, L, track_length_mm=-1.0)
    with pytest.raises(InputError, match="slides differ"):
        jaw().transform(0.1, 0.0, 200.0)
