"""The markers' smooth disagreement with a basis, told from their noise by likelihood."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample
from facecap.registration.smooth_marker_changes import smooth_marker_changes


@pytest.fixture(scope="module")
def marker_places():
    face = load_ict_sample().mesh
    rng = np.random.default_rng(3)
    return face.vertices[rng.choice(face.n_vertices, 90, replace=False)]


def _smooth_field(P, rng, length):
    """A smooth random change over the face: a few Gaussian bumps of the given width (mm)."""
    centres = P[rng.choice(P.shape[0], 6, replace=False)]
    amplitude = rng.normal(scale=0.5, size=(6, 3))
    w = np.exp(-0.5 * np.sum((P[:, None] - centres[None]) ** 2, axis=2) / length**2)
    return w @ amplitude


def test_noise_is_removed_and_the_smooth_change_kept(marker_places):
    rng = np.random.default_rng(0)
    smooth = np.stack([_smooth_field(marker_places, rng, 20.0) for _ in range(20)])
    noisy = smooth + rng.normal(scale=0.15, size=smooth.shape)
    out = smooth_marker_changes(noisy, marker_places)
    # markers 14 mm apart on average sample a 20 mm field coarsely: measured 0.060 against 0.120 mm
    assert np.abs(out.changes - smooth).mean() < 0.6 * np.abs(noisy - smooth).mean()
    assert out.noise_mm == pytest.approx(0.15, rel=0.25)


def test_pure_noise_moves_nothing(marker_places):
    noise = np.random.default_rng(1).normal(scale=0.2, size=(20, 90, 3))
    out = smooth_marker_changes(noise, marker_places)
    assert np.abs(out.changes).mean() < 0.15 * np.abs(noise).mean()
    assert out.noise_mm == pytest.approx(0.2, rel=0.15)


def test_a_noiseless_smooth_change_is_kept_whole(marker_places):
    rng = np.random.default_rng(2)
    smooth = np.stack([_smooth_field(marker_places, rng, 25.0) for _ in range(10)])
    out = smooth_marker_changes(smooth, marker_places)
    assert np.abs(out.changes - smooth).max() < 0.05 * np.abs(smooth).max()


def test_markers_left_out_are_predicted_from_the_others(marker_places):
    rng = np.random.default_rng(4)
    smooth = np.stack([_smooth_field(marker_places, rng, 30.0) for _ in range(10)])
    corrupted = smooth.copy()
    weights = np.ones(smooth.shape[:2])
    weights[0, :5] = 0
    corrupted[0, :5] += 10.0  # guesses off the scan: must not count
    out = smooth_marker_changes(corrupted, marker_places, weights=weights)
    assert np.abs(out.changes[0, :5] - smooth[0, :5]).max() < 0.2 * np.abs(smooth[0]).max()


def test_shapes_are_checked(marker_places):
    with pytest.raises(InputError, match="positions"):
        smooth_marker_changes(np.zeros((2, 90, 3)), marker_places[:10])


def test_markers_every_scan_misses_do_not_spoil_the_fit(marker_places):
    # a single-view scan misses a few side-of-face markers in every basis; their guesses are 3 mm off
    rng = np.random.default_rng(5)
    smooth = np.stack([_smooth_field(marker_places, rng, 20.0) for _ in range(10)])
    noisy = smooth + rng.normal(scale=0.15, size=smooth.shape)
    weights = np.ones(smooth.shape[:2])
    for k in range(10):
        missed = rng.choice(90, 3, replace=False)
        weights[k, missed] = 0
        noisy[k, missed] += 3.0
    out = smooth_marker_changes(noisy, marker_places, weights=weights)
    counted = weights > 0
    clean = smooth_marker_changes(smooth + rng.normal(scale=0.15, size=smooth.shape), marker_places)
    assert np.abs(out.changes - smooth)[counted].mean() < 0.09  # measured 0.071; noise alone 0.12, the old pooling 0.105
    assert out.noise_mm == pytest.approx(clean.noise_mm, rel=0.3)
