"""Tests for facecap.markers.rigid_fit: known motions, scipy's align_vectors, NaN handling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.errors import InputError
from facecap.markers import RigidTransform, rigid_fit


def _random_motion(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    R = Rotation.random(n, rng=rng).as_matrix()
    t = rng.uniform(-500.0, 500.0, (n, 3))
    return R, t


def test_recovers_known_motion_batched_with_nan_rows() -> None:
    rng = np.random.default_rng(1)
    R, t = _random_motion(50, seed=2)
    src = rng.normal(0.0, 60.0, (50, 12, 3))
    dst = np.einsum("bij,bkj->bki", R, src) + t[:, None, :]
    # knock out rows in either set; every item keeps at least 3 rows
    src[rng.random((50, 12)) < 0.2] = np.nan
    holes = rng.random((50, 12)) < 0.2
    holes[:, :3] = False
    dst[holes] = np.nan
    fit = rigid_fit(src, dst)
    assert isinstance(fit, RigidTransform)
    assert fit.rotation.shape == (50, 3, 3) and fit.translation.shape == (50, 3) and fit.rms.shape == (50,)
    ok = (~np.isnan(src).any(-1) & ~np.isnan(dst).any(-1)).sum(-1) >= 3
    np.testing.assert_allclose(fit.rotation[ok], R[ok], atol=1e-10)
    np.testing.assert_allclose(fit.translation[ok], t[ok], atol=1e-10)
    assert np.all(fit.rms[ok] < 1e-10)
    assert np.all(np.isnan(fit.rms[~ok]))


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_matches_scipy_align_vectors_with_weights_and_noise(seed: int) -> None:
    rng = np.random.default_rng(seed)
    R, t = _random_motion(1, seed=seed + 10)
    src = rng.normal(0.0, 50.0, (20, 3))
    dst = src @ R[0].T + t[0] + rng.normal(0.0, 2.0, (20, 3))
    w = rng.uniform(0.1, 3.0, 20)
    fit = rigid_fit(src, dst, weights=w)

    s0 = (w[:, None] * src).sum(0) / w.sum()
    y0 = (w[:, None] * dst).sum(0) / w.sum()
    ref, rssd = Rotation.align_vectors(dst - y0, src - s0, weights=w)
    np.testing.assert_allclose(fit.rotation, ref.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(fit.translation, y0 - ref.as_matrix() @ s0, atol=1e-9)
    np.testing.assert_allclose(fit.rms, rssd / np.sqrt(w.sum()), rtol=1e-10)
    resid = src @ fit.rotation.T + fit.translation - dst
    np.testing.assert_allclose(fit.rms, np.sqrt((w * (resid**2).sum(1)).sum() / w.sum()), rtol=1e-12)


def test_mirror_image_still_gives_a_proper_rotation() -> None:
    rng = np.random.default_rng(6)
    src = rng.normal(0.0, 40.0, (15, 3))
    dst = src * np.array([-1.0, 1.0, 1.0])  # a reflection: no rotation maps src onto dst
    fit = rigid_fit(src, dst)
    np.testing.assert_allclose(np.linalg.det(fit.rotation), 1.0, atol=1e-12)
    np.testing.assert_allclose(fit.rotation @ fit.rotation.T, np.eye(3), atol=1e-12)
    ref, _ = Rotation.align_vectors(dst - dst.mean(0), src - src.mean(0))
    np.testing.assert_allclose(fit.rotation, ref.as_matrix(), atol=1e-9)
    assert fit.rms > 1.0


def test_single_source_broadcasts_against_a_sequence() -> None:
    rng = np.random.default_rng(7)
    R, t = _random_motion(8, seed=8)
    src = rng.normal(0.0, 50.0, (10, 3))
    dst = np.einsum("bij,kj->bki", R, src) + t[:, None, :] + rng.normal(0.0, 0.5, (8, 10, 3))
    fit = rigid_fit(src, dst)
    for b in range(8):
        one = rigid_fit(src, dst[b])
        np.testing.assert_allclose(fit.rotation[b], one.rotation, atol=1e-13)
        np.testing.assert_allclose(fit.translation[b], one.translation, atol=1e-11)
        np.testing.assert_allclose(fit.rms[b], one.rms, rtol=1e-12)


def test_nan_row_is_the_same_as_zero_weight_and_as_dropping_it() -> None:
    rng = np.random.default_rng(9)
    src = rng.normal(0.0, 50.0, (9, 3))
    dst = src[:, ::-1] + rng.normal(0.0, 3.0, (9, 3))
    with_nan = dst.copy()
    with_nan[4] = np.nan
    w = np.ones(9)
    w[4] = 0.0
    a = rigid_fit(src, with_nan)
    b = rigid_fit(src, dst, weights=w)
    c = rigid_fit(np.delete(src, 4, 0), np.delete(dst, 4, 0))
    for x in (a, b):
        np.testing.assert_allclose(x.rotation, c.rotation, atol=1e-12)
        np.testing.assert_allclose(x.translation, c.translation, atol=1e-10)
        np.testing.assert_allclose(x.rms, c.rms, rtol=1e-12)


def test_fewer_than_three_points_is_undetermined() -> None:
    src = np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 0, 0], [0, 1, 0]])
    fit = rigid_fit(src, src, weights=np.array([1.0, 1.0, 1.0, 0.0]))
    assert np.all(np.isnan(fit.rotation)) and np.all(np.isnan(fit.translation)) and np.isnan(fit.rms)


def test_apply_moves_source_onto_target() -> None:
    R, t = _random_motion(4, seed=11)
    src = np.random.default_rng(12).normal(0.0, 30.0, (4, 6, 3))
    dst = np.einsum("bij,bkj->bki", R, src) + t[:, None, :]
    fit = rigid_fit(src, dst)
    np.testing.assert_allclose(fit.apply(src), dst, atol=1e-10)


def test_rejects_bad_input() -> None:
    pts = np.zeros((5, 3))
    with pytest.raises(InputError, match="target"):
        rigid_fit(pts, np.zeros((4, 3)))
    with pytest.raises(InputError, match="source"):
        rigid_fit(np.zeros((5, 2)), pts)
    with pytest.raises(InputError, match="weights"):
        rigid_fit(pts, pts, weights=-np.ones(5))
    with pytest.raises(InputError, match="weights"):
        rigid_fit(pts, pts, weights=np.ones(4))
    with pytest.raises(InputError, match="batch"):
        rigid_fit(np.zeros((2, 5, 3)), np.zeros((3, 5, 3)))
    with pytest.raises(InputError, match="infinite"):
        rigid_fit(np.full((5, 3), np.inf), pts)
