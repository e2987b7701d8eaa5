"""Tests for facecap.synth.expression_curves: performance-like blendshape weights."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.synth.expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from facecap.io.ict_sample import load_ict_sample


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


def test_rapid_asymmetric_curves_have_short_onsets_and_different_sides():
    names = load_ict_sample().expression_names
    rate = 240.0
    kw = dict(rate=rate, seed=8, ramp_in_s=(0.06, 0.15), ramp_out_s=(0.06, 0.15))
    sym = smooth_expression_curves(2400, names, **kw)
    asym = smooth_expression_curves(2400, names, **kw, asymmetry=0.4, max_timing_offset_s=0.08)
    # onsets: a rise from 10 % to 90 % of a smile peak takes at most 150 ms
    smile = sym[:, names.index("mouthSmile_L")]
    d = np.diff(smile)
    peaks = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0) & (smile[1:-1] > 0.3)) + 1
    assert peaks.size >= 1
    for p in peaks:
        lo = np.flatnonzero(smile[:p] < 0.1 * smile[p])[-1]
        assert (p - lo) / rate <= 0.15 + 1 / rate
    assert np.abs(d).max() * rate > 5.0  # weight per second: far faster than the default ramps
    # symmetric without the option; L and R differ in size and timing with it
    # (pairs the presets drive symmetrically: side_smirk moves mouthSmile_L and cheekSquint_L alone)
    pairs = [(n, n[:-2] + "_R") for n in ("browDown_L", "browInnerUp_L", "browOuterUp_L", "eyeWide_L",
                                           "eyeSquint_L", "noseSneer_L", "mouthFrown_L", "mouthPress_L",
                                           "mouthStretch_L", "mouthUpperUp_L", "cheekPuff_L")]
    assert max(np.abs(sym[:, names.index(l)] - sym[:, names.index(r)]).max() for l, r in pairs) < 1e-12
    gaps = [np.abs(asym[:, names.index(l)] - asym[:, names.index(r)]).max() for l, r in pairs]
    assert max(gaps) > 0.2
    np.testing.assert_array_equal(asym[:, names.index("eyeBlink_L")], asym[:, names.index("eyeBlink_R")])
    # the defaults are the old curves, draw for draw: the side options draw from their own stream
    np.testing.assert_array_equal(smooth_expression_curves(300, names, seed=8),
                                  smooth_expression_curves(300, names, seed=8, asymmetry=0.0))
    assert asym.min() >= 0 and asym.max() <= 1 and np.all(asym[0] == 0)
    with pytest.raises(InputError, match="asymmetry"):
        smooth_expression_curves(10, names, asymmetry=1.0)
    with pytest.raises(InputError, match="ramp_in_s"):
        smooth_expression_curves(10, names, ramp_in_s=(0.2, 0.1))
