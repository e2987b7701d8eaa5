"""Tests for facecap.synth.blink_curve."""

from __future__ import annotations

import numpy as np

from facecap.synth.blink_curve import blink_curve


def test_blinks_are_short_separate_and_start_after_the_lead_in():
    rate = 240.0
    t = np.arange(int(60 * rate)) / rate
    lead_in = 0.5
    blink = blink_curve(np.random.default_rng(7), t, 60.0, lead_in, 0.5)
    assert blink.min() == 0.0 and blink.max() == 1.0
    assert np.all(blink[t < lead_in + 0.3] == 0.0)
    closed = blink > 0.0
    starts = np.flatnonzero(closed[1:] & ~closed[:-1]) + 1
    stops = np.flatnonzero(~closed[1:] & closed[:-1]) + 1
    assert starts.size == stops.size and starts.size > 10  # about one every 2.4 s
    length = (stops - starts) / rate
    assert np.all((length > 0.06 + 0.04) & (length <= 0.1 + 0.04 + 0.15 + 1.5 / rate))
    assert np.all(np.diff(starts) / rate >= 0.4 - 1.0 / rate)  # each starts >= 0.4 s after the last
    # each blink reaches 1 (shut) once closed: a smoothstep up, a hold of 0.04 s, a smoothstep down
    assert all(blink[a:b].max() == 1.0 for a, b in zip(starts, stops))


def test_the_callers_generator_makes_it_reproducible():
    t = np.arange(600) / 60.0
    a = blink_curve(np.random.default_rng(3), t, 10.0, 0.25, 0.3)
    b = blink_curve(np.random.default_rng(3), t, 10.0, 0.25, 0.3)
    np.testing.assert_array_equal(a, b)
