import numpy as np

from facecap.synth.expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from facecap.synth.ict_sample import load_ict_sample


def test_curves_start_neutral_stay_in_range_and_are_smooth():
    names = load_ict_sample().expression_names
    W = smooth_expression_curves(1200, names, rate=60.0, seed=3)
    assert W.shape == (1200, 53)
    assert np.all(W[0] == 0) and W.min() >= 0 and W.max() <= 1
    assert W.max() > 0.8  # reaches the real expression range
    active = (W > 0.05).sum(axis=1)
    assert active.max() >= 3  # several blendshapes at once
    # smooth: second differences are small compared with the range (eased ramps, no jumps);
    # blinks close in under 0.1 s, so they are allowed to be sharper
    blink = [names.index("eyeBlink_L"), names.index("eyeBlink_R")]
    slow = np.delete(W, blink, axis=1)
    assert np.abs(np.diff(slow, 2, axis=0)).max() < 0.05
    assert np.abs(np.diff(W[:, blink], 2, axis=0)).max() < 0.5


def test_curves_are_reproducible_and_seed_dependent():
    names = ["jawOpen", "mouthSmile_L", "eyeBlink_L", "eyeBlink_R"]
    a = smooth_expression_curves(300, names, seed=1)
    np.testing.assert_array_equal(a, smooth_expression_curves(300, names, seed=1))
    assert not np.array_equal(a, smooth_expression_curves(300, names, seed=2))
    # blinks are short and the same on both eyes
    np.testing.assert_array_equal(a[:, 2], a[:, 3])


def test_presets_name_real_blendshapes():
    names = set(load_ict_sample().expression_names)
    for preset in EXPRESSION_PRESETS.values():
        assert set(preset) <= names
