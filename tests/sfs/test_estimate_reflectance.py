"""Reflectance from the rest frame: a known albedo map and Phong lobe recovered from two views."""

import numpy as np

from facecap.sfs.estimate_reflectance import estimate_reflectance

from sfs_patch import dome_patch, lined_frames


def test_albedo_per_sample_and_the_specular_lobe_round_trip():
    V, F = dome_patch(60, 50)
    rng = np.random.default_rng(2)
    albedo = 0.55 + 0.1 * np.sin(V[:, 0]) - 0.25 * (np.linalg.norm(V[:, :2] - [7.0, 6.0], axis=1) < 1.0)  # a freckle
    frames = lined_frames(V, F, np.zeros((1, V.shape[0])), albedo=albedo, k_s=0.08, alpha=16.0, noise=0.002,
                          light=None, cameras=((250.0, 50.0, 600.0), (-250.0, -50.0, 600.0)))
    out = estimate_reflectance(frames, ambient=0.05)
    assert out.alpha == 16.0
    assert abs(out.k_s - 0.08) < 0.01
    np.testing.assert_allclose(out.albedo, albedo, rtol=0.02)
    uniform = estimate_reflectance(frames, ambient=0.05, per_sample=False)
    assert uniform.residual > 5 * out.residual  # one albedo cannot explain the freckle and the waves
    del rng


def test_the_diffuse_stage_alone_has_no_lobe():
    V, F = dome_patch(30, 30)
    frames = lined_frames(V, F, np.zeros((1, V.shape[0])), albedo=0.5, k_s=0.0, noise=0.0)
    out = estimate_reflectance(frames, ambient=0.05, specular=False)
    assert out.k_s == 0.0
    np.testing.assert_allclose(out.albedo, 0.5, rtol=1e-9)


def test_a_lobe_per_patch_round_trips_and_a_patch_without_highlight_takes_the_pooled_one():
    V, F = dome_patch(60, 50)
    left = V[:, 0] < 7.5
    k_s = np.where(left, 0.2, 0.05)
    alpha = np.where(left, 32.0, 8.0)
    from sfs_patch import lined_frames as frames_of

    frames = frames_of(V, F, np.zeros((1, V.shape[0])), albedo=0.5, k_s=k_s, alpha=alpha, noise=0.001,
                       cameras=((250.0, 50.0, 600.0), (-250.0, -50.0, 600.0)))
    out = estimate_reflectance(frames, ambient=0.05, patches=left.astype(int))
    assert np.all(out.alpha[left] == 32.0) and np.all(out.alpha[~left] == 8.0)
    np.testing.assert_allclose(out.k_s[left], 0.2, rtol=0.1)
    np.testing.assert_allclose(out.k_s[~left], 0.05, rtol=0.1)
    np.testing.assert_allclose(out.albedo, 0.5, rtol=0.03)
