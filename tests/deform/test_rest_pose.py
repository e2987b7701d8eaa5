"""Where the warp puts the rest markers: the scan's expression, the actor's own, or a neutral reference."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.deform import choose_rest_pose, neutral_from_frames, neutral_from_take, parse_frame_range
from facecap.errors import InputError, MarkerError
from facecap.markers import rigid_fit
from facecap.structures import MarkerSequence


def _take(seed: int, *, expression_mm: float, frames: int = 300, K: int = 50):
    """A take of a face-sized cap whose motion spans two smooth modes; the rest frame holds ``expression_mm``."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(K, 3)) * [40.0, 50.0, 15.0]
    modes = np.array([np.exp(-np.sum((X - X[i]) ** 2, axis=1) / 800.0)[:, None] * rng.normal(size=3)
                      for i in (0, 1)])
    expression = expression_mm * modes[0] / np.sqrt(np.mean(np.sum(modes[0] ** 2, axis=1)))
    w = np.cumsum(rng.normal(scale=0.2, size=(frames, 2)), axis=0)
    w -= w[0]  # the rest frame holds the expression alone
    motion = X[None] + expression[None] + 3.0 * np.einsum("tk,kmc->tmc", w, modes)
    motion += rng.normal(scale=0.03, size=motion.shape)
    return X, motion, expression


def test_auto_keeps_a_resting_expression_and_says_so():
    X, motion, expression = _take(0, expression_mm=0.8)
    chosen = choose_rest_pose(motion[0], X, noise_mm=0.03)
    assert (chosen.mode, chosen.chosen_by, chosen.warn) == ("expression", "auto", True)
    assert "expression of its own" in chosen.reason
    # the warp's targets hold the expression: the rest markers land on the scan plus it
    np.testing.assert_allclose(chosen.targets, X + expression, atol=0.15)
    report = chosen.to_dict([f"M{i}" for i in range(len(X))])
    assert report["mode"] == "expression" and report["mismatch_rms_mm"] == pytest.approx(0.8, abs=0.15)


def test_auto_maps_a_neutral_rest_frame_onto_the_scan_and_options_are_obeyed():
    X, motion, _ = _take(1, expression_mm=0.0)
    chosen = choose_rest_pose(motion[0], X, noise_mm=0.03)
    assert (chosen.mode, chosen.warn) == ("scan", False)
    np.testing.assert_array_equal(chosen.targets, X)
    X, motion, expression = _take(2, expression_mm=0.8)
    forced = choose_rest_pose(motion[0], X, noise_mm=0.03, rest_pose="scan")
    assert (forced.mode, forced.chosen_by) == ("scan", "option")
    np.testing.assert_array_equal(forced.targets, X)
    neutral = choose_rest_pose(motion[0], X, noise_mm=0.03, neutral_markers=X + 1.0)
    assert neutral.mode == "neutral_reference"
    np.testing.assert_array_equal(neutral.sources, X + 1.0)
    with pytest.raises(InputError, match="rest_pose"):
        choose_rest_pose(motion[0], X, noise_mm=0.03, rest_pose="neutral")


def test_neutral_frames_average_out_noise_and_head_motion():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(30, 3)) * 40.0
    R = Rotation.from_rotvec(np.linspace(0, 0.1, 40)[:, None] * [0.0, 1.0, 0.2]).as_matrix()
    frames = np.einsum("tij,kj->tki", R, X) + rng.normal(scale=0.2, size=(40, 30, 3))
    mean = neutral_from_frames(frames, 0, 40)
    # up to the first frame's pose (a rigid motion the warp's own rigid part takes), the shape is the
    # truth: the noise averaged down (0.2 mm per coordinate, 40 frames) and the head's 5.7 degrees taken out
    assert rigid_fit(mean, X).rms < 2.0 * 0.2 * np.sqrt(3 / 40)


def test_a_separate_neutral_take_is_carried_into_the_takes_frame():
    rng = np.random.default_rng(4)
    X = rng.normal(size=(20, 3)) * 40.0
    R = Rotation.from_rotvec([0.0, 2.0, 0.5]).as_matrix()
    other = X @ R.T + [500.0, 0.0, 1500.0] + rng.normal(scale=0.05, size=(50, 20, 3))  # another session's frame
    labels = [f"M{i}" for i in range(20)]
    take = MarkerSequence(other[:, 1:], tuple(labels[1:]), rate=100.0)  # M0 was not worn that day
    rest = X + 0.3  # the main take's rest frame, its own frame
    out, notes = neutral_from_take(take, labels, rest)
    np.testing.assert_allclose(out[1:], X[1:] + 0.3, atol=0.05)
    np.testing.assert_array_equal(out[0], rest[0])
    assert "M0" in notes[0]
    with pytest.raises(MarkerError, match="at least 4"):
        neutral_from_take(MarkerSequence(other[:, :3], tuple(labels[:3]), rate=100.0), labels, rest)


def test_neutral_frames_leave_out_a_frame_the_fit_cannot_place():
    rng = np.random.default_rng(5)
    X = rng.normal(size=(20, 3)) * 40.0
    frames = X[None] + rng.normal(scale=0.1, size=(10, 20, 3))
    frames[3, 2:] = np.nan  # a frame that sees two markers: no rigid fit, left out of the mean
    mean = neutral_from_frames(frames, 0, 10)
    assert np.isfinite(mean).all() and rigid_fit(mean, X).rms < 2.0 * 0.1 * np.sqrt(3 / 9)


def test_a_neutral_take_label_never_seen_keeps_the_rest_place():
    rng = np.random.default_rng(6)
    X = rng.normal(size=(20, 3)) * 40.0
    labels = [f"M{i}" for i in range(20)]
    other = X[None] + rng.normal(scale=0.05, size=(30, 20, 3))
    other[:, 0] = np.nan  # labelled in the neutral take, never captured
    rest = X + 0.3
    out, notes = neutral_from_take(MarkerSequence(other, tuple(labels), rate=100.0), labels, rest)
    np.testing.assert_array_equal(out[0], rest[0])
    np.testing.assert_allclose(out[1:], X[1:] + 0.3, atol=0.05)
    assert "M0" in notes[0]


@pytest.mark.parametrize("text, expected", [("0:10", (0, 10)), ("5:6", (5, 6))])
def test_frame_ranges(text, expected):
    assert parse_frame_range(text, 10) == expected


@pytest.mark.parametrize("text", ["3", "a:b", "4:4", "0:11", "-1:3"])
def test_bad_frame_ranges(text):
    with pytest.raises(InputError, match="--neutral"):
        parse_frame_range(text, 10)
