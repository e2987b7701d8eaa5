"""The rest frame against the scan: robust rigid fit, an expression against a misplaced map, the decision."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError, MarkerError
from facecap.markers import (
    MIN_COHERENCE,
    measure_resting_expression,
    robust_rigid_fit,
    rigid_fit,
)

K = 70


def _face_points(rng: np.random.Generator) -> np.ndarray:
    """K points on a face-sized cap (mm)."""
    theta = rng.uniform(-1.0, 1.0, K)
    phi = rng.uniform(-0.9, 0.9, K)
    return 90.0 * np.c_[np.sin(theta) * np.cos(phi), np.sin(phi), np.cos(theta) * np.cos(phi)]


def _scene(seed: int, *, expression_mm: float, placement_mm: float, noise_mm: float = 0.05):
    """A rest frame holding a smooth expression (a Gaussian bump round one marker), in a mocap frame.

    Returns the rest markers (mocap frame), the map's targets on the scan (off by ``placement_mm`` per
    coordinate), the true rigid motion (scan -> mocap) and the true expression (scan frame).
    """
    rng = np.random.default_rng(seed)
    X = _face_points(rng)
    bump = np.exp(-np.sum((X - X[rng.integers(K)]) ** 2, axis=1) / (2 * 25.0**2))[:, None] * rng.normal(size=3)
    expression = expression_mm * bump / np.sqrt(np.mean(np.sum(bump**2, axis=1)))
    local = X + expression + rng.normal(scale=noise_mm, size=X.shape)
    targets = X + rng.normal(scale=placement_mm, size=(K, 3))
    R = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
    t = rng.normal(scale=300.0, size=3)
    return local @ R.T + t, targets, (R, t), expression


def test_robust_rigid_fit_ignores_moved_points_and_matches_kabsch_on_clean_data():
    rng = np.random.default_rng(3)
    X = _face_points(rng)
    R = Rotation.from_rotvec([0.3, -0.2, 1.0]).as_matrix()
    Y = X @ R.T + [10.0, -4.0, 2.0]
    fit, w = robust_rigid_fit(X, Y)
    np.testing.assert_allclose(fit.rotation, R, atol=1e-9)
    np.testing.assert_allclose(w, 1.0, atol=1e-9)
    Y[:8] += rng.normal(scale=5.0, size=(8, 3))  # eight markers moved by an expression
    fit, w = robust_rigid_fit(X, Y)
    np.testing.assert_allclose(fit.rotation, R, atol=1e-6)
    np.testing.assert_allclose(fit.translation, [10.0, -4.0, 2.0], atol=1e-4)
    assert w[:8].max() < 1e-3 < w[8:].min()
    plain = rigid_fit(X, Y)
    assert np.abs(plain.translation - [10.0, -4.0, 2.0]).max() > 0.05  # least squares alone is pulled


def test_robust_rigid_fit_rejects_too_few_points():
    with pytest.raises(MarkerError, match="at least 3"):
        robust_rigid_fit(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(InputError, match="same shape"):
        robust_rigid_fit(np.zeros((4, 3)), np.zeros((5, 3)))


def test_an_expression_neighbours_share_is_found_and_kept():
    rest, targets, (R, t), true = _scene(1, expression_mm=0.6, placement_mm=0.0)
    m = measure_resting_expression(rest, targets, noise_mm=0.05)
    assert m.is_significant and m.is_expression and m.coherence > MIN_COHERENCE
    # the markers the expression left in place carry the fit: it is the true motion (mocap -> scan is R^T)
    np.testing.assert_allclose(m.alignment.rotation, R.T, atol=2e-3)
    assert np.sqrt(np.mean(np.sum((m.residual - true) ** 2, axis=1))) < 0.1
    # nothing misplaced, no offset or scale to absorb: the warp keeps the whole mismatch
    np.testing.assert_allclose(m.kept_targets(targets), m.alignment.apply(rest), atol=0.05)


def test_noise_alone_and_a_loose_map_are_not_called_an_expression():
    rest, targets, _, _ = _scene(2, expression_mm=0.0, placement_mm=0.0)
    m = measure_resting_expression(rest, targets, noise_mm=0.05)
    assert not m.is_significant and not m.is_expression
    # a map picked by hand, 1 mm off per coordinate: far above the noise, but marker by marker
    rest, targets, _, _ = _scene(2, expression_mm=0.6, placement_mm=1.0)
    m = measure_resting_expression(rest, targets, noise_mm=0.05)
    assert m.is_significant and not m.is_expression and m.coherence < MIN_COHERENCE
    assert m.placement_sd_mm == pytest.approx(1.0, rel=0.3)


def test_a_misplaced_marker_is_named_and_absorbed():
    rest, targets, _, true = _scene(4, expression_mm=0.6, placement_mm=0.0)
    targets = targets.copy()
    targets[5] += [0.0, 4.0, 0.0]  # one marker mapped 4 mm off
    m = measure_resting_expression(rest, targets, noise_mm=0.05)
    assert m.is_expression
    assert np.flatnonzero(m.misplaced).tolist() == [5]
    kept = m.kept_targets(targets)
    np.testing.assert_allclose(kept[5], targets[5] + m.expression[5])
    np.testing.assert_allclose(kept[6:], (targets + m.residual - m.calibration)[6:])


def test_shapes_are_checked():
    rest, targets, _, _ = _scene(5, expression_mm=0.0, placement_mm=0.0)
    with pytest.raises(InputError, match="same"):
        measure_resting_expression(rest, targets[:-1], noise_mm=0.1)
    few = np.full_like(rest, np.nan)
    few[:3] = rest[:3]
    with pytest.raises(MarkerError, match="fewer than 4"):
        measure_resting_expression(few, targets, noise_mm=0.1)


def test_a_wrong_marker_offset_and_a_scale_are_calibration_not_an_expression():
    rng = np.random.default_rng(6)
    axes = np.array([70.0, 95.0, 55.0])  # a face-like ellipsoidal cap: a normal shift is no scale of it
    u = _face_points(rng) / 90.0
    targets = u * axes
    normals = u / axes
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    R = Rotation.from_rotvec([0.4, -1.1, 0.3]).as_matrix()
    local = targets * 1.003 + 2.0 * normals + rng.normal(scale=0.05, size=targets.shape)  # 2 mm further, 0.3 % larger
    rest = local @ R.T + [100.0, 1500.0, -40.0]
    m = measure_resting_expression(rest, targets, noise_mm=0.05, normals=normals)
    assert not m.is_expression
    assert m.offset_error_mm == pytest.approx(2.0, abs=0.1) and m.scale_error == pytest.approx(0.003, abs=1e-3)
    # the markers' calibration absorbed: what is kept is the noise
    assert np.abs(m.kept_targets(targets) - targets).max() < 0.3
    without = measure_resting_expression(rest, targets, noise_mm=0.05)
    assert without.offset_error_mm == 0.0 and without.is_expression  # without normals it looks like one


def test_another_actors_markers_do_not_fit_the_scan():
    rest, targets, (R, t), _ = _scene(7, expression_mm=0.5, placement_mm=0.0)
    bigger = ((rest - t) @ R) * 1.1  # a head 10 % larger: another actor
    m = measure_resting_expression(bigger @ R.T + t, targets, noise_mm=0.05)
    assert m.scale_error == pytest.approx(0.1, abs=0.01)
    assert not m.fits_scan and not m.is_expression
