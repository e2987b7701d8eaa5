"""Tests for facecap.mesh.facing_outward against analytic values on spheres, caps and a plane."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from facecap.errors import MeshError
from facecap.mesh import facing_outward


def _sphere(radius: float, n: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """A fine triangulated sphere (the convex hull of a Fibonacci point set), wound outward."""
    from scipy.spatial import ConvexHull

    k = np.arange(n * n) + 0.5
    z = 1.0 - 2.0 * k / (n * n)
    phi = np.pi * (1.0 + 5.0 ** 0.5) * k
    P = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1) * radius
    F = ConvexHull(P).simplices
    N = igl.per_face_normals(P, F, np.zeros(3))
    inward = np.einsum("fd,fd->f", N, P[F].mean(axis=1)) < 0
    F[inward] = F[inward][:, ::-1]
    return P, F


def test_a_closed_sphere_gives_its_radius_and_its_sign_follows_the_winding() -> None:
    V, F = _sphere(40.0)
    assert facing_outward(V, F) == pytest.approx(40.0, rel=2e-3)  # 3 V / A = r
    assert facing_outward(V, F[:, ::-1]) == pytest.approx(-40.0, rel=2e-3)


def test_a_hemispherical_cap_gives_three_quarters_of_its_radius() -> None:
    # open, like a face scan: its area centroid sits r / 2 above the centre, so the mean of
    # n . (x - c) = r - z / 2 over the cap is r - r / 4
    V, F = _sphere(40.0)
    cap = F[V[F].mean(axis=1)[:, 2] > 0]
    assert facing_outward(V, cap) == pytest.approx(30.0, rel=1e-2)
    assert facing_outward(V, cap[:, ::-1]) == pytest.approx(-30.0, rel=1e-2)


def test_a_flat_patch_cannot_tell() -> None:
    x, y = np.meshgrid(np.linspace(0, 100, 11), np.linspace(0, 100, 11))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    i = np.arange(10)[:, None] * 11 + np.arange(10)[None]
    F = np.concatenate([np.stack([i, i + 1, i + 12], -1).reshape(-1, 3), np.stack([i, i + 12, i + 11], -1).reshape(-1, 3)])
    assert abs(facing_outward(V, F)) < 1e-9


def test_bad_input() -> None:
    with pytest.raises(MeshError, match="no area"):
        facing_outward(np.zeros((3, 3)), np.array([[0, 1, 2]]))
    with pytest.raises(MeshError, match="expected"):
        facing_outward(np.zeros((3, 2)), np.array([[0, 1, 2]]))
    with pytest.raises(MeshError, match="out of range"):
        facing_outward(np.eye(3), np.array([[0, 1, -1]]))
    with pytest.raises(MeshError):
        facing_outward(np.array([[0.0, 0, 0], [1, 0, 0], [0, np.nan, 0]]), np.array([[0, 1, 2]]))
