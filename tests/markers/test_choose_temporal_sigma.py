"""Tests for facecap.markers.choose_temporal_sigma: a written-out leave-one-out, and choices against the truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.markers import bilateral_filter, choose_temporal_sigma

RATE = 120.0


def _leave_one_out_score(P: np.ndarray, *, sigma_t: float, sigma_s: float, sigma_r: float, cut: float) -> float:
    """Mean squared distance from each sample to the filter's weighted mean of all the others (rest frame 0 alone)."""
    T, M, _ = P.shape
    ref = P[0]
    U = P - ref[None]
    W = int(cut * sigma_t + 0.5)
    total, count = 0.0, 0
    for t in range(T):
        for i in range(M):
            num, den = np.zeros(3), 0.0
            for j in range(M):
                d = np.linalg.norm(ref[j] - ref[i])
                if j != i and (sigma_s == 0 or d > cut * sigma_s):
                    continue
                ws = 1.0 if j == i else math.exp(-0.5 * (d / sigma_s) ** 2)
                for tp in range(max(0, t - W), min(T, t + W + 1)):
                    if (tp, j) == (t, i):
                        continue
                    wt = math.exp(-0.5 * ((tp - t) / sigma_t) ** 2)
                    wr = math.exp(-0.5 * np.sum((U[tp, j] - U[t, i]) ** 2) / sigma_r**2)
                    num += ws * wt * wr * U[tp, j]
                    den += ws * wt * wr
            total += float(np.sum((num / den - U[t, i]) ** 2))
            count += 1
    return total / count


def _smooth_take(T: int, M: int, *, frequency_hz: float, noise_mm: float, seed: int,
                 spacing_mm: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Markers on a line ``spacing_mm`` apart, each moving along a 3 mm sinusoid of its own phase: (truth, noisy)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / RATE
    phase = rng.uniform(0, 2 * np.pi, size=(M, 3))
    rest = np.zeros((M, 3))
    rest[:, 0] = spacing_mm * np.arange(M)
    truth = rest[None] + 3.0 * np.sin(2 * np.pi * frequency_hz * t[:, None, None] + phase[None])
    return truth, truth + rng.normal(0.0, noise_mm, truth.shape)


def test_scores_are_the_written_out_leave_one_out():
    _, P = _smooth_take(40, 5, frequency_hz=1.0, noise_mm=0.3, seed=1, spacing_mm=6.0)  # spatial neighbours too
    candidates = (0.01, 0.03)
    choice = choose_temporal_sigma(P, rate=RATE, candidates_s=candidates, spatial_sigma_mm=5.0, rest_average=0.0)
    for sigma, score in zip(candidates, choice.scores_mm2):
        expected = _leave_one_out_score(P, sigma_t=sigma * RATE, sigma_s=5.0, sigma_r=1.0, cut=2.5)
        assert score == pytest.approx(expected, rel=1e-9)
    assert choice.sigma_s == candidates[int(np.argmin(choice.scores_mm2))]
    assert choice.scored_frames == 40


def test_noisy_slow_motion_gets_a_wide_window_and_clean_motion_a_narrow_one():
    truth, noisy = _smooth_take(1500, 12, frequency_hz=0.4, noise_mm=0.3, seed=2)
    wide = choose_temporal_sigma(noisy, rate=RATE)
    narrow = choose_temporal_sigma(truth + np.random.default_rng(3).normal(0, 0.005, truth.shape), rate=RATE)
    assert wide.sigma_s >= 0.06 and narrow.sigma_s <= 0.01
    assert wide.scored_frames == 600  # four blocks of 150 frames out of 1500


def test_the_chosen_sigma_is_close_to_the_best_against_the_truth():
    # fast motion (3 Hz, a syllable rate) with noise: the choice must not blur it, nor leave the noise
    truth, noisy = _smooth_take(900, 10, frequency_hz=3.0, noise_mm=0.25, seed=4)
    choice = choose_temporal_sigma(noisy, rate=RATE, spatial_sigma_mm=0.0)

    def error(sigma: float) -> float:
        out = bilateral_filter(noisy, rate=RATE, temporal_sigma_s=sigma, spatial_sigma_mm=0.0)
        return float(np.sqrt(np.mean((out - truth) ** 2)))

    errors = {s: error(s) for s in choice.candidates_s}
    best = min(errors.values())
    assert errors[choice.sigma_s] <= 1.15 * best
    assert errors[choice.sigma_s] < 0.75 * float(np.sqrt(np.mean((noisy - truth) ** 2)))  # and it does denoise


def test_rejects_bad_candidates():
    _, P = _smooth_take(50, 4, frequency_hz=1.0, noise_mm=0.1, seed=5)
    with pytest.raises(InputError, match="candidates_s"):
        choose_temporal_sigma(P, rate=RATE, candidates_s=())
    with pytest.raises(InputError, match="candidates_s"):
        choose_temporal_sigma(P, rate=RATE, candidates_s=(0.02, -0.01))
    with pytest.raises(InputError, match="rate"):
        choose_temporal_sigma(P, rate=0.0)


def test_a_marker_missing_at_rest_is_left_to_the_filter_to_warn_about():
    _, P = _smooth_take(300, 5, frequency_hz=1.0, noise_mm=0.2, seed=6)
    P[:200, 2] = np.nan  # not seen within the rest window (at most 150 frames at 0.1 s)
    choice = choose_temporal_sigma(P, rate=RATE)  # the suite turns warnings into errors: none here
    assert np.isfinite(choice.scores_mm2).all()
    with pytest.warns(Warning, match="not visible within"):
        bilateral_filter(P, rate=RATE, temporal_sigma_s=choice.sigma_s)  # once, from the filter itself
