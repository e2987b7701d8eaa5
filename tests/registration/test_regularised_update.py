"""Tests for facecap.registration.regularised_update: eq. 11 solved, put back on the scan, no flips."""

from __future__ import annotations

import igl
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.registration.regularised_update import regularised_update
from facecap.structures import Mesh


def _grid(n, spacing):
    x, y = np.meshgrid((np.arange(n) - (n - 1) / 2) * spacing, (np.arange(n) - (n - 1) / 2) * spacing)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1), F


def _flipped(V0, V1, F):
    n0 = np.cross(V0[F[:, 1]] - V0[F[:, 0]], V0[F[:, 2]] - V0[F[:, 0]])
    n1 = np.cross(V1[F[:, 1]] - V1[F[:, 0]], V1[F[:, 2]] - V1[F[:, 0]])
    return int(np.sum(np.einsum("ij,ij->i", n0, n1) < 0))


def test_a_slide_along_a_tilted_plane_is_followed_exactly():
    V, F = _grid(15, 1.0)
    S, FS = _grid(41, 1.0)
    R = Rotation.from_rotvec([0.4, -0.7, 0.2]).as_matrix()
    t = np.array([3.0, -1.0, 20.0])
    slide = R @ np.array([0.35, -0.2, 0.0])  # along the plane
    n = len(V)
    W = regularised_update(V @ R.T + t, F, np.tile(slide, (n, 1)), np.full(n, 0.3), Mesh(S @ R.T + t, FS),
                           np.ones(n, dtype=bool), alpha=2.0, backend="scipy")
    np.testing.assert_allclose(W, V @ R.T + t + slide, atol=1e-9)  # the Laplacian does not see a translation


def test_solves_eq_11_with_confidences_and_a_constraint():
    # on a plane the solution stays in the plane, so the snap changes nothing: compare with a dense solve
    V, F = _grid(11, 1.0)
    S, FS = _grid(31, 1.0)
    n = len(V)
    rng = np.random.default_rng(4)
    dv = np.c_[0.15 * rng.standard_normal((n, 2)), np.zeros(n)]
    confidence = rng.uniform(0.0, 1.0, n)
    confidence[rng.random(n) < 0.3] = 0.0  # some vertices left to the Laplacian
    alpha, weight, j = 0.7, 50.0, 17
    p = V[j] + [0.3, -0.25, 0.0]  # a pull along the plane
    W = regularised_update(V, F, dv, confidence, Mesh(S, FS), np.ones(n, dtype=bool), alpha=alpha,
                           constraints=[(j, p)], constraint_weight=weight, backend="scipy")
    L = igl.cotmatrix(V, F).toarray()  # cotangent weights of a regular grid: none near the clip at 10
    LtL = L.T @ L
    A = np.diag(confidence) + alpha * LtL
    b = confidence[:, None] * (V + dv) + alpha * LtL @ V
    A[j, j] += weight
    b[j] += weight * p
    np.testing.assert_allclose(W, np.linalg.solve(A, b), atol=1e-9)
    assert _flipped(V, W, F) == 0


def test_vertices_on_the_scan_are_put_back_on_it_and_the_others_are_not():
    V, F = _grid(13, 1.0)
    S, FS = _grid(41, 0.5)
    bump = lambda P: 1.5 * np.exp(-(P[:, 0] ** 2 + P[:, 1] ** 2) / 18.0)  # noqa: E731
    S[:, 2] = bump(S)
    V[:, 2] = bump(V) + 0.05  # a little above the scan
    n = len(V)
    on_scan = np.arange(n) % 3 != 0
    W = regularised_update(V, F, np.zeros((n, 3)), np.ones(n), Mesh(S, FS), on_scan, backend="scipy")
    sq, _, closest = igl.point_mesh_squared_distance(W, S, FS)
    assert np.sqrt(sq[on_scan]).max() < 1e-9
    np.testing.assert_allclose(W[~on_scan], V[~on_scan], atol=1e-12)  # nothing to move them: the solve keeps V
    _, _, expected = igl.point_mesh_squared_distance(V[on_scan], S, FS)
    np.testing.assert_allclose(W[on_scan], expected, atol=1e-9)


def test_a_displacement_that_would_fold_the_mesh_is_dropped_around_the_fold():
    V, F = _grid(15, 1.0)
    S, FS = _grid(41, 1.0)
    n = len(V)
    dv = np.tile([0.1, 0.0, 0.0], (n, 1))
    centre = n // 2
    dv[centre] = [4.0, 0.0, 0.0]  # across four neighbours: would turn its triangles over
    W = regularised_update(V, F, dv, np.ones(n), Mesh(S, FS), np.ones(n, dtype=bool), alpha=0.01, backend="scipy")
    assert _flipped(V, W, F) == 0
    far = np.linalg.norm(V - V[centre], axis=1) > 5.0
    np.testing.assert_allclose(W[far], V[far] + [0.1, 0.0, 0.0], atol=0.02)  # the rest followed its slide


@pytest.mark.parametrize("change, match", [
    ({"dv": np.zeros((5, 3))}, "dv"),
    ({"confidence": -np.ones(25)}, "confidence"),
    ({"on_scan": np.ones(25)}, "on_scan"),
    ({"constraints": [(25, np.zeros(3))]}, "constraints"),
    ({"constraints": [(3, np.zeros(2))]}, "constraints"),
    ({"alpha": -1.0}, "alpha"),
    ({"scan": "plane"}, "scan"),
])
def test_refuses_bad_input(change, match):
    V, F = _grid(5, 1.0)
    args = {"dv": np.zeros((25, 3)), "confidence": np.ones(25), "scan": Mesh(V, F), "on_scan": np.ones(25, dtype=bool)}
    options = {"alpha": 1.0, "constraints": (), "backend": "scipy"}
    for key, value in change.items():
        (args if key in args else options)[key] = value
    with pytest.raises(InputError, match=match):
        regularised_update(V, F, args["dv"], args["confidence"], args["scan"], args["on_scan"], **options)
