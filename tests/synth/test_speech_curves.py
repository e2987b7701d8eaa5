"""Tests for facecap.synth.speech_curves: fast, syllable-rate jaw and lip motion."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.speech_curves import speech_expression_curves

RATE = 120.0  # fine sampling, so that 100-200 ms are 12-24 frames


@pytest.fixture(scope="module")
def curves():
    names = load_ict_sample().expression_names
    return names, speech_expression_curves(1200, names, rate=RATE, seed=3)  # 10 s


def _extrema(x):
    d = np.diff(x)
    peaks = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0)) + 1
    troughs = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0)) + 1
    return peaks, troughs


def test_range_lead_in_and_reproducibility(curves):
    names, W = curves
    assert W.shape == (1200, 53) and W.min() >= 0 and W.max() <= 1
    assert np.all(W[: int(0.25 * RATE)] == 0)  # neutral lead-in, frame 0 = the scan
    np.testing.assert_array_equal(W, speech_expression_curves(1200, names, rate=RATE, seed=3))
    assert not np.array_equal(W, speech_expression_curves(1200, names, rate=RATE, seed=4))


def test_jaw_opens_and_closes_at_syllable_rate_within_200_ms(curves):
    names, W = curves
    jaw = W[:, names.index("jawOpen")]
    peaks, troughs = _extrema(jaw)
    big = peaks[jaw[peaks] > 0.3]
    assert big.size >= 8  # many wide openings in 10 s
    # every wide opening closes (and opened) through half its height within 200 ms, not instantly
    for p in big:
        below = jaw < 0.5 * jaw[p]
        after = np.flatnonzero(below[p:])
        before = np.flatnonzero(below[:p])
        assert after.size and after[0] / RATE <= 0.2
        assert before.size and (p - before[-1]) / RATE <= 0.2
        assert after[0] / RATE >= 0.025  # eased, not a jump
    # the syllable rate: 4-6 jaw cycles per second of speech (pauses excluded: cycles closer than 0.4 s)
    cycles = np.diff(peaks[jaw[peaks] > 0.05]) / RATE
    speaking = cycles[cycles < 0.4]
    assert 1 / 6.5 < np.median(speaking) < 1 / 3.5
    # fast: the jaw moves faster than the smooth generator ever does (its ramps last >= 0.25 s)
    assert np.abs(np.diff(jaw)).max() * RATE > 5.0


def test_visemes_pauses_brows_and_blinks(curves):
    names, W = curves
    col = {s: W[:, names.index(s)] for s in names}
    for s in ("mouthClose", "mouthPress_L", "mouthFunnel", "mouthPucker", "mouthStretch_L", "mouthSmile_L",
              "mouthRollLower", "eyeBlink_L"):
        assert col[s].max() > 0.2, s
    # bilabials close the jaw: where the lips press, the jaw is nearly shut
    pressed = col["mouthPress_L"] > 0.3
    assert pressed.any() and col["jawOpen"][pressed].max() < 0.3
    # pauses: stretches of >= 0.2 s with the mouth at rest, after the lead-in
    mouth = np.max([col[s] for s in names if s.startswith(("mouth", "jaw"))], axis=0)
    rest = mouth[int(0.25 * RATE):] < 1e-9
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], rest.astype(int), [0]]))))[::2]
    assert (runs >= 0.2 * RATE).sum() >= 2
    np.testing.assert_array_equal(col["eyeBlink_L"], col["eyeBlink_R"])
    busy = speech_expression_curves(1200, names, rate=RATE, seed=3, brow_accents=1.0)
    assert busy[:, names.index("browInnerUp_L")].max() > 0.25


def test_bad_options_are_refused():
    names = load_ict_sample().expression_names
    with pytest.raises(InputError, match="syllables_per_second"):
        speech_expression_curves(10, names, syllables_per_second=(6.0, 4.0))
    with pytest.raises(InputError, match="brow_accents"):
        speech_expression_curves(10, names, brow_accents=1.5)
    with pytest.raises(InputError, match="n_frames"):
        speech_expression_curves(0, names)
