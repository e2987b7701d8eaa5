"""Footage synchronised to a mocap take: video frames <-> mocap frames by rate ratio and offset.

Every stage that reads footage asks a :class:`FootageSync` which video frame
belongs to a mocap frame, so none converts frame numbers by hand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_positive

__all__ = ["FootageSync", "VideoBracket", "synchronize"]

_RATIO_TOLERANCE = 1e-6  # relative: 120 / 29.97 is 4.004, far outside; 50 / 12.5 is exact


class VideoBracket(NamedTuple):
    """The two video frames around each mocap frame, for linear interpolation.

    Attributes
    ----------
    before, after : (k,) int64 arrays
        Video frames; ``after == before`` where the mocap frame falls on a
        video frame or beyond the last one.
    weight : (k,) float64 array in [0, 1)
        Weight of ``after``: the value at the mocap frame is
        ``(1 - weight) * value[before] + weight * value[after]``.
    """

    before: IntArray
    after: IntArray
    weight: FloatArray


@dataclass(frozen=True)
class FootageSync:
    """How one camera's footage lines up with a take.

    Video frame ``k`` was exposed at mocap frame ``first_mocap_frame + k * ratio``
    with ``ratio = mocap_rate_hz / video_rate_hz`` (mocap frames per video frame).
    Build it with :func:`synchronize`, which checks the footage covers the take.

    Attributes
    ----------
    mocap_rate_hz, video_rate_hz : float
    first_mocap_frame : float
        The mocap frame at which video frame 0 was exposed (0 when the cameras
        start on the take's first trigger; may be negative when the video starts first).
    n_mocap_frames, n_video_frames : int
    """

    mocap_rate_hz: float
    video_rate_hz: float
    first_mocap_frame: float
    n_mocap_frames: int
    n_video_frames: int

    @property
    def ratio(self) -> float:
        """Mocap frames per video frame (4 for 50 Hz mocap and 12.5 Hz video)."""
        return self.mocap_rate_hz / self.video_rate_hz

    def mocap_frame(self, video_frames: Any) -> FloatArray:
        """The mocap frame (fractional in general) at which each video frame was exposed."""
        return self.first_mocap_frame + np.asarray(video_frames, dtype=np.float64) * self.ratio

    def video_position(self, mocap_frames: Any) -> FloatArray:
        """Fractional video frame of each mocap frame, ``(j - first_mocap_frame) / ratio``, unclipped."""
        return (np.asarray(mocap_frames, dtype=np.float64) - self.first_mocap_frame) / self.ratio

    def nearest_video_frame(self, mocap_frames: Any) -> IntArray:
        """The video frame nearest in time to each mocap frame, clipped to the footage."""
        position = np.rint(self.video_position(mocap_frames))
        return np.clip(position, 0, self.n_video_frames - 1).astype(np.int64)

    def bracket(self, mocap_frames: Any) -> VideoBracket:
        """The video frames before and after each mocap frame and the interpolation weight.

        Mocap frames after the last video frame (less than one video interval,
        which :func:`synchronize` allows) hold the last video frame.
        """
        position = np.clip(self.video_position(mocap_frames), 0, self.n_video_frames - 1)
        before = np.floor(position).astype(np.int64)
        after = np.where(position > before, np.minimum(before + 1, self.n_video_frames - 1), before)
        weight = position - before  # 0 where after == before
        return VideoBracket(before, after, weight)

    def video_frames_for(self, start: int, stop: int) -> IntArray:
        """The video frames needed to interpolate mocap frames ``start <= j < stop`` (sorted, unique)."""
        bracket = self.bracket(np.arange(start, stop))
        return np.unique(np.concatenate([bracket.before, bracket.after]))


def synchronize(mocap_rate_hz: float, n_mocap_frames: int, video_rate_hz: float, n_video_frames: int, *,
                first_mocap_frame: float = 0, allow_fractional_ratio: bool = False,
                footage_name: str = "footage") -> FootageSync:
    """Line footage up with a take and check that it covers it.

    Parameters
    ----------
    mocap_rate_hz : float
        The take's frame rate.
    n_mocap_frames : int
        Frames in the take.
    video_rate_hz : float
        The footage's frame rate (12.5 Hz in Bickel et al. 2007, a quarter of 50 Hz mocap).
    n_video_frames : int
        Frames in the footage.
    first_mocap_frame : float, default 0
        The mocap frame at which video frame 0 was exposed.
    allow_fractional_ratio : bool, default False
        Accept a video rate that does not divide the mocap rate (the video
        frames then fall between mocap frames; :meth:`FootageSync.bracket`
        still interpolates). By default that is an error: synchronised
        capture triggers the video on every n-th mocap frame.
    footage_name : str, default 'footage'
        Named in the error messages (the camera or the file).

    Returns
    -------
    FootageSync

    Raises
    ------
    InputError
        If a rate is not positive, the video rate does not divide the mocap
        rate (unless allowed), the footage starts after the take's first frame,
        or it ends before the take does: the footage must cover mocap frames
        ``0 .. n_mocap_frames - 1``, the last video frame covering the
        ``ratio`` mocap frames from its own, i.e.
        ``first_mocap_frame + n_video_frames * ratio >= n_mocap_frames``.

    Notes
    -----
    Video frame ``k`` <-> mocap frame ``j = first_mocap_frame + k * mocap_rate_hz / video_rate_hz``.

    Examples
    --------
    >>> sync = synchronize(50.0, 100, 12.5, 25)
    >>> sync.ratio, sync.mocap_frame([0, 1, 24]).tolist()
    (4.0, [0.0, 4.0, 96.0])
    """
    mocap_rate = as_positive(mocap_rate_hz, name="mocap_rate_hz")
    video_rate = as_positive(video_rate_hz, name=f"{footage_name}: video rate")
    for value, what in ((n_mocap_frames, "n_mocap_frames"), (n_video_frames, f"{footage_name}: frame count")):
        if isinstance(value, bool) or not float(value).is_integer() or value < 1:
            raise InputError(f"{what}: expected a positive integer, got {value!r}")
    try:
        first = float(first_mocap_frame)
    except (TypeError, ValueError):
        raise InputError(f"first_mocap_frame: expected a number, got {first_mocap_frame!r}") from None
    if not math.isfinite(first):
        raise InputError(f"first_mocap_frame: expected a finite number, got {first_mocap_frame!r}")
    ratio = mocap_rate / video_rate
    fractional = round(ratio) < 1 or abs(ratio - round(ratio)) > _RATIO_TOLERANCE * ratio
    if fractional and not allow_fractional_ratio:
        raise InputError(
            f"{footage_name}: the video rate {video_rate:g} Hz does not divide the mocap rate {mocap_rate:g} Hz "
            f"(ratio {ratio:.6g}); synchronised cameras run at the mocap rate divided by a whole number "
            "(check the rate; footage that really runs free of the mocap trigger needs allow_fractional_ratio=True)"
        )
    if first > 0:
        raise InputError(
            f"{footage_name}: video frame 0 is at mocap frame {first:g}, after the take's first frame: "
            f"the footage does not cover mocap frames 0..{math.ceil(first) - 1}"
        )
    covered = first + int(n_video_frames) * ratio
    if covered < int(n_mocap_frames) - 1e-9:
        needed = math.ceil((int(n_mocap_frames) - first) / ratio - 1e-9)
        raise InputError(
            f"{footage_name}: footage shorter than the take: {int(n_video_frames)} video frames at {video_rate:g} Hz "
            f"cover mocap frames up to {covered - 1:g}, the take has {int(n_mocap_frames)} frames at "
            f"{mocap_rate:g} Hz (at least {needed} video frames are needed)"
        )
    return FootageSync(mocap_rate, video_rate, first, int(n_mocap_frames), int(n_video_frames))
