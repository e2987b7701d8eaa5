"""merge_camera_wrinkles: two cameras' lines of one wrinkle are snapped and blended; other paints' stay apart; names_wrinkle
matches a merged wrinkle's parts whole (5.3)."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.wrinkles import merge_camera_wrinkles
from facecap.wrinkles.surface_wrinkles import names_wrinkle
from wrinkle_lines import straight_wrinkle as _line


def test_two_cameras_lines_of_one_wrinkle_are_snapped_and_blended() -> None:
    # camera a sees x in [0, 20], camera b x in [10, 30], 0.5 mm apart in y; b three times as squarely
    a = _line("a:0", 0.0, 20.0, y=0.0, depth=0.4, quality=1.0)
    b = _line("b:3", 10.0, 30.0, y=0.5, depth=0.8, quality=3.0)
    merged = merge_camera_wrinkles([[a], [b]])
    assert len(merged) == 1
    line = merged[0]
    assert line.wrinkle == "a:0+b:3"
    assert line.points[:, 0].min() == pytest.approx(0.0) and line.points[:, 0].max() == pytest.approx(30.0)
    overlap = (line.points[:, 0] > 11.0) & (line.points[:, 0] < 17.0)  # a's weight eases out 2.5 mm from its end
    # the base (b, seen more squarely) blended with a by their qualities: y = 0.5 - 0.25 * 0.5
    assert np.allclose(line.points[overlap, 1], 0.5 - 0.25 * 0.5, atol=1e-9)
    assert np.allclose(line.depth[overlap], 0.8 - 0.25 * 0.4, atol=1e-9)
    # the overhang of a (x < 10), snapped onto b's end: continuous, no jump at the junction
    steps = np.diff(line.points[:, 0])
    assert steps.min() > 0 and steps.max() < 0.6 and np.abs(np.diff(line.points[:, 1])).max() < 0.06


def test_lines_of_other_paints_or_of_one_camera_stay_apart() -> None:
    a = _line("a:0", 0.0, 20.0)
    other_paint = _line("b:0", 0.0, 20.0, y=0.3, color=1)
    same_camera = _line("a:1", 0.0, 20.0, y=0.3)
    assert len(merge_camera_wrinkles([[a, same_camera], [other_paint]])) == 3
    # a camera whose name is the start of another's still merges with it
    assert len(merge_camera_wrinkles([[_line("cam:0", 0.0, 20.0)], [_line("cam_b:0", 0.0, 20.0, y=0.3)]])) == 1


def test_a_merged_wrinkle_is_named_by_any_cameras_part_whole() -> None:
    assert names_wrinkle("a:1+b:2", {"a:1"}) and not names_wrinkle("a:1+b:2", {"a:10"})
