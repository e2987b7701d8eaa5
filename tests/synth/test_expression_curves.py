"""Tests for facecap.synth.expression_curves: performance-like blendshape weights."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.synth.expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from facecap.synth.ict_sample import load_ict_sample


@pytest.fixture(scope="module")
def names():
    return load_ict_sample().expression_names


def test_curves_start_neutral_stay_in_range_and_are_smooth(names):
    W = smooth_expression_curves(1200, names, rate=60.0, seed=3)
    assert W.shape == (1200, 53)
    assert W.min() >= 0 and W.max() <= 1
    # the lead-in (0.25 s = 15 frames) is exactly neutral: frame 0 is the scan's expression
    assert np.all(W[:15] == 0)
    assert W.max() > 0.8  # reaches the real expression range
    assert (W > 0.05).sum(axis=1).max() >= 3  # several blendshapes at once
    # smooth: second differences are small (eased ramps, no jumps);
    # blinks close in under 0.1 s, so they are allowed to be sharper
    blink = [names.index("eyeBlink_L"), names.index("eyeBlink_R")]
    slow = np.delete(W, blink, axis=1)
    assert np.abs(np.diff(slow, 2, axis=0)).max() < 0.05
    assert np.abs(np.diff(W[:, blink], 2, axis=0)).max() < 0.5


def test_blinks_are_short_pulses_on_both_eyes(names):
    W = smooth_expression_curves(1800, names, rate=60.0, seed=5)
    a, b = W[:, names.index("eyeBlink_L")], W[:, names.index("eyeBlink_R")]
    np.testing.assert_array_equal(a, b)
    closed = a > 0.5
    starts = np.flatnonzero(closed[1:] & ~closed[:-1])
    ends = np.flatnonzero(~closed[1:] & closed[:-1])
    assert 3 <= starts.size <= 30  # about 0.3 blinks/s over 30 s
    durations = (ends - starts[: ends.size]) / 60.0
    assert durations.max() < 0.4  # seconds


def test_timing_is_in_seconds_so_a_faster_rate_samples_the_same_curves(names):
    W60 = smooth_expression_curves(300, names, rate=60.0, seed=2)
    W120 = smooth_expression_curves(600, names, rate=120.0, seed=2)
    np.testing.assert_allclose(W120[::2], W60, atol=1e-12)


def test_curves_are_reproducible_and_seed_dependent():
    names = ["jawOpen", "mouthSmile_L", "eyeBlink_L", "eyeBlink_R", "notABlendshape"]
    a = smooth_expression_curves(300, names, seed=1)
    np.testing.assert_array_equal(a, smooth_expression_curves(300, names, seed=1))
    assert not np.array_equal(a, smooth_expression_curves(300, names, seed=2))
    assert np.all(a[:, 4] == 0)  # names no preset uses stay neutral


def test_presets_name_real_blendshapes(names):
    for preset in EXPRESSION_PRESETS.values():
        assert set(preset) <= set(names)
        assert 0 < max(preset.values()) <= 1


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_frames": 0}, "n_frames"),
        ({"n_frames": 2.5}, "n_frames"),
        ({"names": "jawOpen"}, "names"),
        ({"rate": 0.0}, "rate"),
        ({"intensity": (0.9, 0.2)}, "intensity"),
        ({"expressions_per_second": -1.0}, "expressions_per_second"),
    ],
)
def test_bad_arguments_are_clear_errors(kwargs, match):
    args = {"n_frames": 10, "names": ["jawOpen"]}
    args.update(kwargs)
    n, nm = args.pop("n_frames"), args.pop("names")
    with pytest.raises(InputError, match=match):
        smooth_expression_curves(n, nm, **args)
