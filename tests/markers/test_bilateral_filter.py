"""Tests for facecap.markers.bilateral_filter: a slow reference, scipy's Gaussian, noise and steps."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest
from scipy.ndimage import correlate1d, gaussian_filter1d

from facecap.errors import FacecapWarning, InputError, MarkerError
from facecap.markers import bilateral_filter, bilateral_setup, bilateral_weighted_sums, marker_rest_configuration

RATE = 120.0


def _slow_reference(
    P: np.ndarray,
    *,
    sigma_t: float,
    sigma_s: float,
    sigma_r: float | None,
    cut: float,
    rest: int,
    rest_average: float,
) -> np.ndarray:
    """The docstring's formula, written out with loops."""
    T, M, _ = P.shape
    valid = ~np.isnan(P).any(axis=2)
    sigma_rest = rest_average * sigma_t
    w_rest = int(cut * sigma_rest + 0.5)
    ref = np.full((M, 3), np.nan)
    in_space = np.zeros(M, dtype=bool)
    for i in range(M):
        frames = [t for t in range(max(0, rest - w_rest), min(T, rest + w_rest + 1)) if valid[t, i]]
        if frames:
            a = min(frames, key=lambda t: (abs(t - rest), t))
            g = [math.exp(-0.5 * ((t - rest) / sigma_rest) ** 2) if sigma_rest > 0 else float(t == rest) for t in frames]
            dev = sum(gk * (P[t, i] - P[a, i]) for gk, t in zip(g, frames))
            ref[i] = P[a, i] + dev / sum(g)
            in_space[i] = True
        elif valid[:, i].any():
            ref[i] = P[np.flatnonzero(valid[:, i])[0], i]
    W = int(cut * sigma_t + 0.5)
    out = np.full_like(P, np.nan)
    for t in range(T):
        for i in range(M):
            if not valid[t, i]:
                continue
            ui = P[t, i] - ref[i]
            num = np.zeros(3)
            den = 0.0
            for j in range(M):
                if j == i:
                    ws = 1.0
                else:
                    if sigma_s == 0 or not (in_space[i] and in_space[j]):
                        continue
                    d = np.linalg.norm(ref[j] - ref[i])
                    if d > cut * sigma_s:
                        continue
                    ws = math.exp(-0.5 * (d / sigma_s) ** 2)
                for tp in range(max(0, t - W), min(T, t + W + 1)):
                    if not valid[tp, j]:
                        continue
                    uj = P[tp, j] - ref[j]
                    wt = math.exp(-0.5 * ((tp - t) / sigma_t) ** 2) if sigma_t > 0 else 1.0
                    wr = 1.0 if sigma_r is None else math.exp(-0.5 * np.sum((uj - ui) ** 2) / sigma_r**2)
                    num += ws * wt * wr * uj
                    den += ws * wt * wr
            out[t, i] = ref[i] + num / den
    return out


@pytest.mark.parametrize(
    "sigma_t, sigma_s, sigma_r, rest, rest_average",
    [(1.5, 8.0, 1.0, 0, 5.0), (2.0, 12.0, None, 7, 2.0), (1.0, 0.0, 0.5, 3, 0.0), (0.0, 10.0, 1.0, 2, 5.0)],
)
def test_matches_slow_reference(sigma_t, sigma_s, sigma_r, rest, rest_average) -> None:
    rng = np.random.default_rng(0)
    T, M = 40, 7
    base = rng.uniform(0.0, 20.0, (M, 3)) + 100.0
    P = base[None] + np.cumsum(rng.normal(0.0, 0.4, (T, M, 3)), axis=0)
    P[rng.random((T, M)) < 0.15] = np.nan
    P[rest, 1] = np.nan  # a marker missing at the rest frame itself
    # with no rest window, marker 1 is lost at the rest frame and filtered in time only
    lost = rest_average * sigma_t == 0
    with pytest.warns(FacecapWarning) if lost else contextlib.nullcontext():
        got = bilateral_filter(
            P,
            temporal_sigma_frames=sigma_t,
            spatial_sigma_mm=sigma_s,
            range_sigma_mm=sigma_r,
            rest_frame=rest,
            rest_average=rest_average,
        )
    want = _slow_reference(
        P, sigma_t=sigma_t, sigma_s=sigma_s, sigma_r=sigma_r, cut=2.5, rest=rest, rest_average=rest_average
    )
    assert np.array_equal(np.isnan(got), np.isnan(P))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)


def test_plain_temporal_gaussian_matches_scipy() -> None:
    rng = np.random.default_rng(1)
    P = 100.0 + np.cumsum(rng.normal(0.0, 0.5, (300, 5, 3)), axis=0)
    sigma = 3.3
    got = bilateral_filter(P, temporal_sigma_frames=sigma, spatial_sigma_mm=0.0, range_sigma_mm=None)
    want = gaussian_filter1d(P, sigma, axis=0, truncate=2.5)
    W = int(2.5 * sigma + 0.5)
    np.testing.assert_allclose(got[W:-W], want[W:-W], rtol=0, atol=1e-10)


def _grid_take(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """36 markers 6 mm apart (a dense layout) with a slow, spatially smooth 4 mm motion, 5 s."""
    g = np.arange(6) * 6.0
    X, Y = np.meshgrid(g, g)
    rest = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)] + np.array([0.0, 0.0, 100.0])
    t = np.arange(600) / RATE
    shape = np.cos(rest[:, 0] / 40.0)[None, :, None] * np.array([1.0, 0.5, 0.2])
    truth = rest[None] + 4.0 * np.sin(2 * np.pi * 0.3 * t)[:, None, None] * shape
    noisy = truth + np.random.default_rng(seed).normal(0.0, 0.2, truth.shape)
    return truth, noisy


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_white_noise_is_reduced_by_a_large_factor() -> None:
    truth, noisy = _grid_take(seed=2)
    before = _rms(noisy, truth)
    after = _rms(bilateral_filter(noisy, rate=RATE), truth)
    assert before == pytest.approx(0.2, rel=0.02)
    assert after < before / 3.5
    # the spatial term helps on a dense layout
    time_only = _rms(bilateral_filter(noisy, rate=RATE, spatial_sigma_mm=0.0), truth)
    assert after < 0.85 * time_only
    # a wider temporal kernel on this slow motion reduces it further
    wide = _rms(bilateral_filter(noisy, rate=RATE, temporal_sigma_s=0.06), truth)
    assert wide < before / 4.2


def test_step_is_preserved_much_better_than_by_a_plain_gaussian() -> None:
    rng = np.random.default_rng(3)
    T = 400
    truth = np.zeros((T, 4, 3))
    truth[:, :, 0] = np.arange(4) * 30.0
    truth[200:, :, 2] += 5.0  # a 5 mm jump between two frames
    noisy = truth + rng.normal(0.0, 0.2, truth.shape)
    options = dict(rate=RATE, temporal_sigma_s=0.04, spatial_sigma_mm=0.0)
    bilateral = bilateral_filter(noisy, **options)
    gaussian = bilateral_filter(noisy, **options, range_sigma_mm=None)
    near = slice(185, 215)
    assert _rms(bilateral[near], truth[near]) < 0.2 * _rms(gaussian[near], truth[near])
    assert _rms(bilateral[near], truth[near]) < 0.6 * _rms(noisy[near], truth[near])
    # the jump itself stays a jump
    jump = bilateral[200, :, 2] - bilateral[199, :, 2]
    assert np.all(jump > 4.5)


def test_constant_take_is_unchanged_exactly() -> None:
    rng = np.random.default_rng(4)
    P = np.broadcast_to(rng.uniform(-200.0, 200.0, (30, 3)), (200, 30, 3)).copy()
    P[rng.random((200, 30)) < 0.1] = np.nan
    out = bilateral_filter(P, rate=RATE, spatial_sigma_mm=40.0)
    assert np.array_equal(out, P, equal_nan=True)


def test_rigid_translation_is_preserved() -> None:
    truth, noisy = _grid_take(seed=5)
    offset = np.array([123.4, -56.7, 890.1])
    a = bilateral_filter(noisy, rate=RATE)
    b = bilateral_filter(noisy + offset, rate=RATE)
    np.testing.assert_allclose(b, a + offset, rtol=0, atol=1e-9)
    # every marker carried along one straight line at constant speed: unchanged away from the ends
    t = np.arange(600)[:, None, None] / RATE
    moving = truth[:1] + t * np.array([30.0, -10.0, 5.0])
    out = bilateral_filter(moving, rate=RATE)
    W = int(2.5 * 0.02 * RATE + 0.5)
    np.testing.assert_allclose(out[W:-W], moving[W:-W], rtol=0, atol=1e-9)


def test_sigma_in_seconds_equals_sigma_in_frames() -> None:
    _, noisy = _grid_take(seed=6)
    a = bilateral_filter(noisy, rate=100.0, temporal_sigma_s=0.03)
    b = bilateral_filter(noisy, temporal_sigma_frames=3.0)
    np.testing.assert_array_equal(a, b)


def test_marker_missing_near_rest_is_filtered_in_time_only() -> None:
    _, noisy = _grid_take(seed=7)
    noisy[:100, 14] = np.nan
    with pytest.warns(FacecapWarning, match="time only"):
        out = bilateral_filter(noisy, rate=RATE)
    with pytest.warns(FacecapWarning):
        alone = bilateral_filter(noisy[:, [14]], rate=RATE)
    np.testing.assert_allclose(out[:, 14], alone[:, 0], rtol=0, atol=1e-12)
    # and it is no spatial neighbour of the others
    rest_of = np.delete(noisy, 14, axis=1)
    np.testing.assert_allclose(np.delete(out, 14, axis=1), bilateral_filter(rest_of, rate=RATE), atol=1e-12)


def test_rejects_bad_input() -> None:
    P = np.zeros((20, 3, 3))
    with pytest.raises(InputError, match="rate"):
        bilateral_filter(P)
    with pytest.raises(InputError, match="rest_frame"):
        bilateral_filter(P, rate=RATE, rest_frame=20)
    with pytest.raises(InputError, match="spatial_sigma_mm"):
        bilateral_filter(P, rate=RATE, spatial_sigma_mm=-1.0)
    with pytest.raises(InputError, match="range_sigma_mm"):
        bilateral_filter(P, rate=RATE, range_sigma_mm=0.0)
    with pytest.raises(MarkerError, match="positions"):
        bilateral_filter(np.zeros((20, 3)), rate=RATE)


def test_weighted_sums_in_time_alone_are_the_gaussian_correlation_with_gaps_weighing_nothing():
    rng = np.random.default_rng(11)
    T, M, sigma_t, cut = 80, 5, 3.0, 2.5
    P = rng.normal(size=(T, M, 3))
    P[rng.random((T, M)) < 0.2] = np.nan
    valid = ~np.isnan(P).any(axis=2)
    rest = marker_rest_configuration(P, valid, 10, 0.0, cut, warn=False)
    setup = bilateral_setup(P, sigma_t, 0.0, None, cut, rest)
    num, den = bilateral_weighted_sums(setup, [(0, T)])
    taps = np.exp(-0.5 * (np.arange(-8, 9) / sigma_t) ** 2)  # radius int(2.5 * 3 + 0.5) = 8 frames
    U = np.where(valid[..., None], P - rest[0][None], 0.0)
    np.testing.assert_allclose(den, correlate1d(valid * 1.0, taps, axis=0, mode="constant"), rtol=1e-12)
    np.testing.assert_allclose(num, correlate1d(U, taps, axis=0, mode="constant").transpose(2, 0, 1),
                               rtol=1e-12, atol=1e-12)
    # only the frames asked for are filled
    part_num, part_den = bilateral_weighted_sums(setup, [(20, 30)])
    np.testing.assert_array_equal(part_den[20:30], den[20:30])
    assert not part_den[:20].any() and not part_num[:, 30:].any()


def test_rest_configuration_is_the_rest_frame_or_its_nearest_sample():
    T, M = 30, 3
    P = np.full((T, M, 3), np.nan)
    P[:, 0] = np.arange(T, dtype=float)[:, None]  # moving linearly
    P[:, 1] = 100.0  # still near the rest frame, elsewhere before it, and unseen at it
    P[:5, 1] = -50.0
    P[9:12, 1] = np.nan
    P[25, 2] = 7.0  # seen only far from the rest frame
    valid = ~np.isnan(P).any(axis=2)
    ref, has_rest = marker_rest_configuration(P, valid, 10, 0.0, 2.5, warn=False)
    np.testing.assert_array_equal(ref[0], [10.0] * 3)  # sigma 0: the rest frame's sample itself
    # a window of int(2.5 * 2 + 0.5) = 5 frames: the Gaussian mean of a linear motion is its rest
    # frame's position; a marker unseen at the rest frame is anchored at its nearest sample there;
    # one never seen in the window at its first sample
    ref, has_rest = marker_rest_configuration(P, valid, 10, 2.0, 2.5, warn=False)
    np.testing.assert_allclose(ref, [[10.0] * 3, [100.0] * 3, [7.0] * 3], rtol=1e-15)
    np.testing.assert_array_equal(has_rest, [True, True, False])
    with pytest.warns(FacecapWarning, match="not visible within"):
        marker_rest_configuration(P, valid, 10, 2.0, 2.5)
