"""Tests for facecap.markers.fill_gaps: remove known samples from synthetic takes, fill, compare."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError, MarkerError
from facecap.markers import FilledMarkers, fill_gaps


def _punch(P: np.ndarray) -> tuple[np.ndarray, dict[str, tuple[int, slice]]]:
    """Remove a short, a long, a leading and a trailing gap and a never-seen marker."""
    Q = P.copy()
    gaps = {
        "short": (3, slice(100, 110)),
        "short2": (11, slice(300, 306)),
        "long": (5, slice(200, 350)),
        "start": (7, slice(0, 60)),
        "end": (8, slice(520, None)),
    }
    for i, sl in gaps.values():
        Q[sl, i] = np.nan
    Q[:, 9] = np.nan
    return Q, gaps


def _error(filled: np.ndarray, truth: np.ndarray, i: int, sl: slice) -> float:
    return float(np.linalg.norm(filled[sl, i] - truth[sl, i], axis=-1).max())


def test_masks_and_untouched_samples(synthetic_take) -> None:
    take = synthetic_take(n_frames=600, n_markers=30)
    Q, _ = _punch(take.positions)
    out = fill_gaps(Q, rate=take.rate)
    assert isinstance(out, FilledMarkers)
    missing = np.isnan(Q).any(-1)
    # present samples come back bit for bit
    assert np.array_equal(out.positions[~missing], Q[~missing])
    # everything missing is filled except the marker never seen
    expected_unfilled = np.zeros_like(missing)
    expected_unfilled[:, 9] = True
    assert np.array_equal(out.unfilled_mask, expected_unfilled)
    assert np.array_equal(out.filled_mask, missing & ~expected_unfilled)
    assert np.all(np.isnan(out.positions[:, 9]))
    assert not np.isnan(np.delete(out.positions, 9, axis=1)).any()


def test_short_gaps_follow_smooth_curves(synthetic_take) -> None:
    # 20 deg head rotation, 30 mm head travel and 3 mm skin motion: the curves are smooth
    take = synthetic_take(n_frames=600, n_markers=30, deformation_mm=3.0)
    Q, gaps = _punch(take.positions)
    out = fill_gaps(Q, rate=take.rate)  # 0.1 s = 12 frames at 120 Hz
    for key in ("short", "short2"):
        assert _error(out.positions, take.positions, *gaps[key]) < 0.02, key
    # PCHIP is shape-preserving: within a gap each coordinate stays between its two end values
    out = fill_gaps(Q, rate=take.rate, interpolation="pchip")
    for key in ("short", "short2"):
        i, sl = gaps[key]
        ends = take.positions[[sl.start - 1, sl.stop], i]
        inside = out.positions[sl, i]
        assert np.all(inside >= ends.min(0) - 1e-9) and np.all(inside <= ends.max(0) + 1e-9)
        assert _error(out.positions, take.positions, i, sl) < 1.0

def test_long_and_edge_gaps_are_exact_under_rigid_motion(synthetic_take) -> None:
    take = synthetic_take(n_frames=600, n_markers=30, deformation_mm=0.0, rotation_deg=30.0)
    Q, gaps = _punch(take.positions)
    out = fill_gaps(Q, rate=take.rate)
    for key in ("long", "start", "end"):
        assert _error(out.positions, take.positions, *gaps[key]) < 1e-6, key
    # with every gap sent to the neighbour method, the short ones are exact too
    out0 = fill_gaps(Q, max_interp_gap=0)
    for key in ("short", "short2"):
        assert _error(out0.positions, take.positions, *gaps[key]) < 1e-6, key


def test_long_gap_with_local_deformation_is_close_and_seamless(synthetic_take) -> None:
    take = synthetic_take(n_frames=600, n_markers=30, deformation_mm=3.0)
    Q, gaps = _punch(take.positions)
    out = fill_gaps(Q, rate=take.rate).positions
    i, sl = gaps["long"]
    err = _error(out, take.positions, i, sl)
    # linear interpolation across the same gap, for scale: the head moves tens of mm
    frames = np.arange(600)
    seen = ~np.isnan(Q[:, i, 0])
    linear = np.stack([np.interp(frames, frames[seen], Q[seen, i, d]) for d in range(3)], axis=-1)
    err_linear = float(np.linalg.norm(linear[sl] - take.positions[sl, i], axis=-1).max())
    assert err < 2.0  # of the order of the 3 mm skin motion, never more
    assert err < err_linear / 20
    # no jump at the seams: the first/last filled steps match the true steps
    a, b = sl.start, sl.stop
    for inside, outside in [(a, a - 1), (b - 1, b)]:
        step = out[inside, i] - out[outside, i]
        true_step = take.positions[inside, i] - take.positions[outside, i]
        assert np.linalg.norm(step - true_step) < 0.05


def test_gap_length_threshold_follows_rate() -> None:
    # three markers: too few neighbours for the rigid method, so only splines can fill
    t = np.arange(400) / 100.0
    P = np.stack([np.c_[np.sin(t + k), np.cos(2 * t), t * k] for k in range(3)], axis=1) * 10
    Q = P.copy()
    Q[100:110, 0] = np.nan  # 10 frames = 0.1 s at 100 Hz
    Q[200:211, 0] = np.nan  # 11 frames
    out = fill_gaps(Q, rate=100.0)
    assert out.filled_mask[100:110, 0].all() and out.unfilled_mask[200:211, 0].all()
    assert np.abs(out.positions[100:110, 0] - P[100:110, 0]).max() < 1e-3
    out = fill_gaps(Q, rate=50.0)  # 0.1 s = 5 frames
    assert out.unfilled_mask[100:110, 0].all()
    out = fill_gaps(Q, max_interp_gap=11)
    assert not out.unfilled_mask.any()
    assert np.abs(out.positions[200:211, 0] - P[200:211, 0]).max() < 1e-3


def test_frames_without_enough_neighbours_stay_unfilled(synthetic_take) -> None:
    take = synthetic_take(n_frames=300, n_markers=8)
    Q = take.positions.copy()
    Q[100:200, 0] = np.nan
    Q[140:160, 1:6] = np.nan  # only 2 other markers left there
    out = fill_gaps(Q, max_interp_gap=0)
    assert out.unfilled_mask[140:160, 0].all()
    assert out.filled_mask[100:140, 0].all() and out.filled_mask[160:200, 0].all()
    err = np.linalg.norm(out.positions[100:140, 0] - take.positions[100:140, 0], axis=-1)
    assert err.max() < 1e-6


def test_partial_nan_row_is_a_missing_sample(synthetic_take) -> None:
    take = synthetic_take(n_frames=200, n_markers=10)
    Q = take.positions.copy()
    Q[50, 2, 1] = np.nan
    out = fill_gaps(Q)
    assert out.filled_mask[50, 2] and out.filled_mask.sum() == 1
    assert np.linalg.norm(out.positions[50, 2] - take.positions[50, 2]) < 0.01


def test_rejects_bad_input() -> None:
    P = np.zeros((20, 4, 3))
    with pytest.raises(MarkerError, match="positions"):
        fill_gaps(np.zeros((20, 4)))
    with pytest.raises(InputError, match="max_interp_gap"):
        fill_gaps(P, max_interp_gap=-1)
    with pytest.raises(InputError, match="max_interp_gap"):
        fill_gaps(P, max_interp_gap=2.5)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="n_neighbours"):
        fill_gaps(P, n_neighbours=2)
    with pytest.raises(InputError, match="interpolation"):
        fill_gaps(P, interpolation="linear")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="rate"):
        fill_gaps(P, rate=0.0)
