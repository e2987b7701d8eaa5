"""Tests for facecap.synth.capture_colors: exposure, shading, sensor noise and sRGB encoding."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.cameras import srgb_to_linear
from facecap.synth.capture_colors import capture_colors


def test_undoing_srgb_and_exposure_gives_the_albedo_back_within_the_noise() -> None:
    rng = np.random.default_rng(0)
    albedo = rng.uniform(0.1, 0.7, (20000, 3))
    P = rng.uniform(-100, 100, (20000, 3))
    c = capture_colors(albedo, P, seed=5, shading_amplitude=0.0, noise=0.01)
    assert c.dtype == np.float32 and c.min() >= 0 and c.max() <= 1
    linear = srgb_to_linear(c)
    exposure = np.median(linear / albedo)
    assert 0.85 <= exposure <= 1.15
    residual = linear / exposure - albedo
    assert abs(np.std(residual) * exposure - 0.01) < 0.001  # the sensor noise, nothing else
    assert abs(np.mean(residual)) < 5e-4


def test_shading_is_smooth_bounded_and_differs_per_capture() -> None:
    rng = np.random.default_rng(1)
    albedo = np.full((5000, 3), 0.4)
    P = rng.uniform(-100, 100, (5000, 3))
    f = [srgb_to_linear(capture_colors(albedo, P, seed=s, exposure_range=(1, 1), noise=0.0))[:, 0] / 0.4
         for s in (0, 1)]
    for g in f:
        assert np.all(np.abs(g - 1) <= 0.08 + 1e-6) and g.std() > 0.005
    assert np.abs(f[0] - f[1]).max() > 0.01
    np.testing.assert_array_equal(capture_colors(albedo, P, seed=3), capture_colors(albedo, P, seed=3))


def test_bad_options_are_refused() -> None:
    with pytest.raises(InputError):
        capture_colors(np.zeros((3, 2)), seed=0)
    with pytest.raises(InputError):
        capture_colors(np.zeros((3, 3)), seed=0, shading_amplitude=1.5)
    with pytest.raises(InputError):
        capture_colors(np.zeros((3, 3)), np.zeros((2, 3)), seed=0)
