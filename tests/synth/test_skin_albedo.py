"""Tests for facecap.synth.skin_albedo: a solid skin texture of the material point."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.skin_albedo import BASE_SKIN_TONE, SkinRegions, skin_albedo

LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB


@pytest.fixture(scope="module")
def sample():
    return load_ict_sample()


def test_deterministic_per_seed_and_different_across_seeds(sample) -> None:
    V = sample.mesh.vertices
    a = skin_albedo(V, seed=4)
    np.testing.assert_array_equal(a, skin_albedo(V, seed=4))
    assert np.abs(a - skin_albedo(V, seed=5)).mean() > 0.01
    assert a.shape == V.shape and a.dtype == np.float64


def test_a_point_colour_does_not_depend_on_the_other_points(sample) -> None:
    V = sample.mesh.vertices
    a = skin_albedo(V, seed=2)
    pick = np.random.default_rng(0).choice(V.shape[0], 300, replace=False)
    np.testing.assert_allclose(skin_albedo(V[pick], seed=2), a[pick], rtol=0, atol=1e-12)


def test_tone_range_and_contrast_are_plausible(sample) -> None:
    V = sample.mesh.vertices
    for seed in range(3):
        a = skin_albedo(V, seed=seed)
        assert np.all((a > 0) & (a < 1))
        mean = a.mean(axis=0)
        assert np.all(np.abs(mean / np.array(BASE_SKIN_TONE) - 1) < 0.25)
        assert mean[0] > mean[1] > mean[2]  # skin is red > green > blue
        L = a @ LUMA
        assert 0.03 < L.std() / L.mean() < 0.15


def test_mottling_gives_contrast_at_the_millimetre_scale(sample) -> None:
    # neighbouring points 3 mm apart differ (mottling), points 0.1 mm apart hardly
    rng = np.random.default_rng(1)
    P = rng.uniform(-60, 60, (4000, 3))
    step = rng.normal(size=(4000, 3))
    step /= np.linalg.norm(step, axis=1, keepdims=True)
    L0 = skin_albedo(P, seed=0) @ LUMA
    far = np.abs(skin_albedo(P + 3.0 * step, seed=0) @ LUMA - L0).mean() / L0.mean()
    near = np.abs(skin_albedo(P + 0.1 * step, seed=0) @ LUMA - L0).mean() / L0.mean()
    assert far > 0.015 and near < far / 4


def test_freckles_are_sparse_dark_spots() -> None:
    # a flat 120 x 120 mm patch sampled at 0.4 mm: spots darker than 8 % below the local skin
    x = np.arange(0, 120, 0.4)
    X, Y = np.meshgrid(x, x)
    P = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    L = (skin_albedo(P, seed=3) @ LUMA).reshape(X.shape)
    from scipy import ndimage

    smooth = ndimage.uniform_filter(L, size=25)
    spots, n = ndimage.label(L < 0.92 * smooth)
    per_cm2 = n / 144.0
    assert 0.1 < per_cm2 < 1.5
    dark_fraction = float(np.mean(L < 0.92 * smooth))
    assert dark_fraction < 0.05


def test_regions_darken_brows_and_redden_lips(sample) -> None:
    V = sample.mesh.vertices
    region = SkinRegions(sample.region_labels, sample.region_names, V[sample.landmarks[48:60]])
    plain = skin_albedo(V, seed=0)
    a = skin_albedo(V, seed=0, region=region)
    names = list(sample.region_names)
    brow = sample.region_labels == names.index("brows")
    ratio = (a[brow] @ LUMA) / (plain[brow] @ LUMA)
    assert 0.5 < ratio.mean() < 0.8
    mouth = sample.region_labels == names.index("mouth")
    lips = mouth & (np.abs(a - plain).max(axis=1) > 0)
    assert lips.sum() > 50
    red_ratio = (a[lips, 0] / a[lips, 1]) / (plain[lips, 0] / plain[lips, 1])
    assert red_ratio.mean() > 1.15
    others = ~(brow | mouth)
    np.testing.assert_array_equal(a[others], plain[others])


def test_bad_input_is_refused() -> None:
    with pytest.raises(InputError):
        skin_albedo(np.zeros((4, 2)))
    with pytest.raises(InputError):
        skin_albedo(np.zeros((4, 3)), region=SkinRegions(np.zeros(3, int), ("brows",)))
