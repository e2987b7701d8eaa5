"""Tests for facecap.registration.rigid_icp: known rigid motions of points on known surfaces."""

from __future__ import annotations

import numpy as np
import pytest
from igl import per_vertex_normals
from scipy.spatial.transform import Rotation

from facecap.errors import InputError, MeshError
from facecap.markers import rigid_fit
from facecap.registration import IcpResult, check_surface_units, rigid_icp, trimmed_inliers
from facecap.io.ict_sample import load_ict_sample


def _bumpy_sheet(n: int = 60, size: float = 120.0) -> tuple[np.ndarray, np.ndarray]:
    """A face-sized sheet (mm) curved unevenly in both directions, so that no rigid motion slides along it."""
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, n) * size, np.linspace(-0.5, 0.5, n) * size)
    x, y = u.ravel(), v.ravel()
    z = -0.008 * x**2 - 0.004 * y**2 + 12.0 * np.exp(-(x**2 + (y - 10) ** 2) / 300.0) + 0.05 * x * y / 10
    V = np.stack([x, y, z], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return V, F


def _motion(seed: int, angle_deg: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    if angle_deg is None:
        R = Rotation.random(rng=rng).as_matrix()
    else:
        axis = rng.normal(size=3)
        R = Rotation.from_rotvec(np.deg2rad(angle_deg) * axis / np.linalg.norm(axis)).as_matrix()
    return R, rng.uniform(-300.0, 300.0, 3)


def _angle_deg(R: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(R @ R_true.T).magnitude()))


def _on_surface(V: np.ndarray, F: np.ndarray, count: int, seed: int) -> np.ndarray:
    """Random points spread uniformly over the surface (not at vertices)."""
    rng = np.random.default_rng(seed)
    area = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    faces = rng.choice(F.shape[0], size=count, p=area / area.sum())
    b = rng.dirichlet(np.ones(3), size=count)
    return np.einsum("kc,kcd->kd", b, V[F[faces]])


@pytest.mark.parametrize(
    ("method", "iterations", "atol"),
    # point-to-plane converges quadratically; point-to-point linearly (about 800 iterations to 1e-5 mm here)
    [("point_to_plane", 20, 1e-8), ("point_to_point", 300, 0.05)],
)
def test_points_on_the_surface_are_moved_back(method: str, iterations: int, atol: float) -> None:
    V, F = _bumpy_sheet()
    truth = _on_surface(V, F, 150, seed=1)
    R, t = _motion(2, angle_deg=6.0)
    source = (truth - t) @ R  # the inverse motion: rigid_icp must find (R, t)
    init = np.eye(4)
    init[:3, 3] = truth.mean(axis=0) - source.mean(axis=0)  # centroids only
    fit = rigid_icp(source, V, F, init=init, method=method, max_iterations=iterations, trim=1.0, tolerance_mm=1e-7)
    assert isinstance(fit, IcpResult) and fit.converged == (method == "point_to_plane")
    np.testing.assert_allclose(fit.apply(source), truth, atol=atol)
    assert fit.rms < atol and np.all(fit.distances < atol)
    np.testing.assert_allclose(fit.matrix[:3, :3], fit.rotation)
    np.testing.assert_allclose(fit.matrix[:3, 3], fit.translation)
    # with the pairs known, the answer is the closed-form fit
    ref = rigid_fit(source, truth)
    assert np.deg2rad(_angle_deg(fit.rotation, ref.rotation)) * 60.0 < atol  # at a 60 mm lever arm
    assert np.abs(fit.apply(truth.mean(axis=0)) - ref.apply(truth.mean(axis=0))).max() < atol


def test_global_start_finds_an_arbitrary_rotation_of_face_points() -> None:
    face = load_ict_sample().mesh
    truth = _on_surface(face.vertices, face.faces, 120, seed=3)
    for seed in (4, 5):
        R, t = _motion(seed)
        source = (truth - t) @ R
        fit = rigid_icp(source, face.vertices, face.faces)
        assert _angle_deg(fit.rotation, R) < 0.01
        assert np.abs(fit.apply(source) - truth).max() < 0.02


def test_offset_points_come_to_rest_at_the_offset() -> None:
    V, F = _bumpy_sheet()
    rng = np.random.default_rng(6)
    idx = rng.choice(np.flatnonzero((np.abs(V[:, :2]) < 45).all(axis=1)), 80, replace=False)
    truth = V[idx] + 1.5 * per_vertex_normals(V, F)[idx]
    R, t = _motion(7, angle_deg=4.0)
    source = (truth - t) @ R
    init = np.eye(4)
    init[:3, 3] = truth.mean(axis=0) - source.mean(axis=0)
    # the points cover the middle of the sheet only: their size differs from the sheet's, on purpose
    fit = rigid_icp(source, V, F, init=init, offset_mm=1.5, trim=1.0, size_tolerance=None)
    assert _angle_deg(fit.rotation, R) < 0.01
    np.testing.assert_allclose(fit.distances, 1.5, atol=0.01)
    # the offset on the other side of the sheet is a different, worse fit
    other = rigid_icp(source, V, F, init=init, offset_mm=-1.5, trim=1.0, size_tolerance=None)
    assert other.rms > 5 * fit.rms


def test_outliers_are_trimmed_and_holes_are_not_matched() -> None:
    V, F = _bumpy_sheet()
    truth = _on_surface(V, F, 200, seed=8)
    rng = np.random.default_rng(9)
    wild = rng.random(200) < 0.08
    truth_seen = truth.copy()
    truth_seen[wild] += rng.normal(0.0, 1.0, (wild.sum(), 3)) * 10.0  # 8% outliers, ~10 mm off
    # a hole: drop the triangles around one spot of the target
    centre = np.array([20.0, -15.0])
    keep = np.linalg.norm(V[F].mean(axis=1)[:, :2] - centre, axis=1) > 12.0
    over_hole = np.linalg.norm(truth[:, :2] - centre, axis=1) < 12.0
    assert over_hole.sum() >= 5
    R, t = _motion(10, angle_deg=5.0)
    source = (truth_seen - t) @ R
    init = np.eye(4)
    init[:3, 3] = truth.mean(axis=0) - source.mean(axis=0)
    fit = rigid_icp(source, V, F[keep], init=init, trim=0.85)
    assert _angle_deg(fit.rotation, R) < 0.01
    np.testing.assert_allclose(fit.apply(source)[~wild & ~over_hole], truth[~wild & ~over_hole], atol=0.01)
    assert not fit.inliers[wild].any() and not fit.inliers[over_hole].any()
    # without trimming or boundary rejection the outliers and the hole's rim pull the fit away
    naive = rigid_icp(source, V, F[keep], init=init, trim=1.0, reject_boundary=False)
    assert _angle_deg(naive.rotation, R) > 10 * _angle_deg(fit.rotation, R)


def test_nan_rows_are_ignored() -> None:
    V, F = _bumpy_sheet()
    truth = _on_surface(V, F, 60, seed=11)
    R, t = _motion(12, angle_deg=3.0)
    source = (truth - t) @ R
    source[[3, 17]] = np.nan
    init = np.eye(4)
    init[:3, 3] = np.nanmean(truth - source, axis=0)
    fit = rigid_icp(source, V, F, init=init, trim=1.0)
    assert _angle_deg(fit.rotation, R) < 0.01
    assert np.isnan(fit.distances[[3, 17]]).all() and not fit.inliers[[3, 17]].any()


def test_a_target_in_other_units_is_refused() -> None:
    face = load_ict_sample().mesh
    points = _on_surface(face.vertices, face.faces, 80, seed=13)
    with pytest.raises(MeshError, match="other units"):
        rigid_icp(points, face.vertices * 0.1, face.faces)  # a file in cm read as mm
    with pytest.raises(MeshError, match="other units"):
        rigid_icp(points * 0.001, face.vertices, face.faces)
    fit = rigid_icp(points, face.vertices * 1.1, face.faces, init=np.eye(4))  # 10% is within tolerance
    assert np.isfinite(fit.rms)
    rigid_icp(points, face.vertices * 0.1, face.faces, init=np.eye(4), size_tolerance=None, max_iterations=2)


def test_bad_input_is_named() -> None:
    V, F = _bumpy_sheet(10)
    P = V[:20]
    with pytest.raises(InputError, match="source_points"):
        rigid_icp(np.ones((5, 2)), V, F)
    with pytest.raises(InputError, match="source_points"):
        rigid_icp(np.full((5, 3), np.nan), V, F)
    with pytest.raises(MeshError, match="target_F"):
        rigid_icp(P, V, F + 1000)
    with pytest.raises(InputError, match="trim"):
        rigid_icp(P, V, F, trim=0.0)
    with pytest.raises(InputError, match="method"):
        rigid_icp(P, V, F, method="magic")
    with pytest.raises(InputError, match="init"):
        rigid_icp(P, V, F, init=np.eye(3))
    with pytest.raises(InputError, match="max_iterations"):
        rigid_icp(P, V, F, max_iterations=0)


def test_one_surface_serves_many_fits() -> None:
    from facecap.registration import ClosestPointSurface, rigid_icp_to_surface

    V, F = _bumpy_sheet()
    surface = ClosestPointSurface(V, F, reject_boundary=True)
    for seed in (3, 4):
        truth = _on_surface(V, F, 120, seed=seed)
        R, t = _motion(seed, angle_deg=5.0)
        source = (truth - t) @ R
        init = np.eye(4)
        init[:3, 3] = truth.mean(axis=0) - source.mean(axis=0)
        shared = rigid_icp_to_surface(source, surface, init)
        alone = rigid_icp(source, V, F, init=init)
        assert _angle_deg(shared.rotation, R) < 1e-6 and np.allclose(shared.apply(source), truth, atol=1e-6)
        np.testing.assert_allclose(shared.matrix, alone.matrix, atol=1e-12)
    with pytest.raises(MeshError, match="F"):
        ClosestPointSurface(V, F + V.shape[0], reject_boundary=True)


def test_trimmed_inliers_keep_the_smallest_usable_residuals():
    rng = np.random.default_rng(8)
    residual = rng.normal(size=200)
    usable = rng.random(200) < 0.7
    for trim in (0.01, 0.3, 0.8, 1.0):
        mask = trimmed_inliers(residual, usable, trim)
        u = int(usable.sum())
        assert mask.sum() == min(u, max(3, int(np.ceil(trim * u))))
        assert not np.any(mask & ~usable)
        # every inlier's |residual| is at most every usable outlier's
        assert np.abs(residual[mask]).max() <= np.abs(residual[usable & ~mask]).min(initial=np.inf)
    assert not trimmed_inliers(residual, np.zeros(200, bool), 0.5).any()
    np.testing.assert_array_equal(trimmed_inliers(np.array([1.0, -1.0, 1.0, 2.0]), np.ones(4, bool), 0.5),
                                  [True, True, True, False])  # three at least; a tie keeps the earlier


def test_check_surface_units_refuses_a_surface_in_cm_and_passes_mm():
    # a flat 20 mm square of even triangles: its RMS radius is sqrt(2 * 20^2 / 12) = 8.16 mm (its
    # triangles' centroids' to 1e-3), its vertices' 8.56 mm
    u = np.linspace(-10.0, 10.0, 21)
    x, y = np.meshgrid(u, u, indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    quads = (np.arange(20)[:, None] * 21 + np.arange(20)[None]).ravel()
    F = np.concatenate([np.column_stack([quads, quads + 21, quads + 22]), np.column_stack([quads, quads + 22, quads + 1])])
    points = V + [0.0, 0.0, 50.0]  # where they are does not matter, only their size
    check_surface_units(points, V, F, 0.1)
    check_surface_units(points, 1.4 * V, F, 0.5)
    with pytest.raises(MeshError, match=r"x1\.33"):  # 1.4 * 8.16 / 8.56
        check_surface_units(points, 1.4 * V, F, 0.3)
    with pytest.raises(MeshError, match=r"target_V: the scan appears to be in other units than source_points.*x0\.1"):
        check_surface_units(points, 0.1 * V, F, 0.5)
    with pytest.raises(MeshError, match="scan_V: .* than markers"):
        check_surface_units(points, 1000.0 * V, F, 0.5, points="markers", surface="scan_V")
