"""Synchronisation: video <-> mocap frames by rate ratio and offset, and the footage must cover the take."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.cameras import synchronize
from facecap.errors import InputError


def test_quarter_rate_footage_maps_every_fourth_mocap_frame() -> None:
    # Bickel et al. 2007: 12.5 Hz video, exactly a quarter of 50 Hz mocap
    sync = synchronize(50.0, 100, 12.5, 25)
    assert sync.ratio == 4.0
    np.testing.assert_array_equal(sync.mocap_frame(np.arange(25)), np.arange(0, 100, 4))
    np.testing.assert_array_equal(sync.video_position([0, 2, 4, 97]), [0.0, 0.5, 1.0, 24.25])
    np.testing.assert_array_equal(sync.nearest_video_frame([0, 1, 2, 3, 99]), [0, 0, 0, 1, 24])


def test_bracket_interpolates_between_video_frames_and_holds_the_last() -> None:
    sync = synchronize(50.0, 100, 12.5, 25)
    bracket = sync.bracket([0, 1, 6, 96, 99])
    np.testing.assert_array_equal(bracket.before, [0, 0, 1, 24, 24])
    np.testing.assert_array_equal(bracket.after, [0, 1, 2, 24, 24])
    np.testing.assert_allclose(bracket.weight, [0.0, 0.25, 0.5, 0.0, 0.0])
    # interpolating a per-video-frame quantity linear in time gives it back at the mocap frames
    value = 3.0 * sync.mocap_frame(np.arange(25)) + 1.0
    j = np.arange(0, 97)
    b = sync.bracket(j)
    np.testing.assert_allclose((1 - b.weight) * value[b.before] + b.weight * value[b.after], 3.0 * j + 1.0)
    np.testing.assert_array_equal(sync.video_frames_for(10, 14), [2, 3, 4])  # 13 is at 3.25


def test_offset_video_started_before_the_take() -> None:
    sync = synchronize(120.0, 240, 30.0, 62, first_mocap_frame=-6)
    assert sync.mocap_frame(0) == -6.0 and sync.video_position(0) == 1.5
    np.testing.assert_array_equal(sync.nearest_video_frame([0]), [2])  # rint(1.5) = 2 (round half to even)


def test_footage_shorter_than_the_take_is_an_error_naming_the_shortfall() -> None:
    synchronize(50.0, 100, 12.5, 25)  # 25 frames x 4 cover 0..99
    with pytest.raises(InputError, match=r"cam1: footage shorter than the take.*at least 25 video frames"):
        synchronize(50.0, 100, 12.5, 24, footage_name="cam1")
    with pytest.raises(InputError, match="at least 26 video frames"):
        synchronize(50.0, 100, 12.5, 25, first_mocap_frame=-4)  # starts a video frame early: one more needed
    with pytest.raises(InputError, match="after the take's first frame"):
        synchronize(50.0, 100, 12.5, 40, first_mocap_frame=3)


def test_rate_that_does_not_divide_the_mocap_rate() -> None:
    with pytest.raises(InputError, match="does not divide"):
        synchronize(120.0, 120, 29.97, 40)
    with pytest.raises(InputError, match="does not divide"):
        synchronize(50.0, 100, 100.0, 200)  # faster than the mocap
    sync = synchronize(120.0, 120, 29.97, 40, allow_fractional_ratio=True)
    assert sync.ratio == pytest.approx(120 / 29.97)


@pytest.mark.parametrize(
    ("args", "message"),
    [((0.0, 10, 12.5, 10), "mocap_rate_hz"), ((50.0, 10, -1.0, 10), "video rate"),
     ((50.0, 0, 12.5, 10), "n_mocap_frames"), ((50.0, 10, 12.5, 2.5), "frame count")],
)
def test_bad_arguments(args: tuple, message: str) -> None:
    with pytest.raises(InputError, match=message):
        synchronize(*args)
