"""Tests for facecap.report.plot_scan_selection."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from facecap.blendshapes.select_scan_frames import ScanPlan, select_scan_frames
from facecap.errors import InputError
from facecap.report.plot_scan_selection import plot_scan_selection


def _plan(frames=(7, 2, 11), T=20) -> ScanPlan:
    K = len(frames)
    residual = np.linspace(0.1, 0.5, T)
    residual[list(frames)] = 0.0
    return ScanPlan(frames=np.array(frames), times=np.array(frames) / 10.0,
                    error_after_each=np.linspace(1.0, 0.2, K), worst_frame_after_each=np.linspace(2.0, 0.4, K),
                    per_frame_residual=residual, tolerance_mm=0.5, diagonal_mm=100.0, weights=np.zeros((K, T)),
                    converged=True, tolerance=0.005, rate=10.0)


def _visible_ticks(axis) -> np.ndarray:
    lo, hi = sorted(axis.get_xlim())
    ticks = axis.get_xticks()
    return ticks[(ticks >= lo) & (ticks <= hi)]


def test_whole_scan_counts_and_the_chosen_frames_marked(tmp_path):
    plan = _plan()
    out = tmp_path / "plan.png"
    fig = plot_scan_selection(plan, out)
    top, bottom = fig.axes[:2]
    # one tick per whole number of scans, never 1.5 scans
    ticks = _visible_ticks(top)
    np.testing.assert_array_equal(ticks, np.round(ticks))
    assert set(ticks.astype(int)) == {1, 2, 3}
    # the curves are the plan's numbers at 1..K scans
    lines = {line.get_label(): line for line in top.get_lines()}
    every = next(v for k, v in lines.items() if k.startswith("all frames"))
    np.testing.assert_array_equal(every.get_xdata(), [1, 2, 3])
    np.testing.assert_allclose(every.get_ydata(), plan.error_after_each)
    # each point says which frame it adds, in the order chosen
    assert [a.get_text() for a in top.texts] == ["+ frame 7", "+ frame 2", "+ frame 11"]
    # the take panel marks exactly the chosen frames, with their order
    chosen = next(c for c in bottom.collections if c.get_gid() == "chosen_frames")
    marked = sorted(float(seg[0][0]) for seg in chosen.get_segments())
    assert marked == [2.0, 7.0, 11.0]
    assert sorted(a.get_text() for a in bottom.texts) == ["#1: 7", "#2: 2", "#3: 11"]
    np.testing.assert_array_equal(_visible_ticks(bottom), np.round(_visible_ticks(bottom)))
    assert "frames 7, 2, 11" in fig.get_suptitle()
    image = imread(out)
    assert image.shape[:2] == (820, 1400) and image[..., :3].std() > 0.05
    assert not list(tmp_path.glob(".*"))


def test_a_real_plan_is_drawn_with_its_frames(tmp_path):
    # three expressions mixed over a take: the plan picks frames, the picture marks those
    rng = np.random.default_rng(3)
    T, M = 90, 12
    shapes = rng.normal(size=(3, M, 3))
    weights = np.clip(np.sin(np.linspace(0, 3 * np.pi, T)[:, None] + np.arange(3) * 2.0), 0, None)
    P = rng.normal(size=(M, 3)) * 40 + np.einsum("tk,kmc->tmc", weights, shapes)
    plan = select_scan_frames(P, tolerance=0.001, rate=30.0, progress=False)
    fig = plot_scan_selection(plan, tmp_path / "plan.png")
    chosen = next(c for c in fig.axes[1].collections if c.get_gid() == "chosen_frames")
    assert sorted(float(s[0][0]) for s in chosen.get_segments()) == sorted(plan.frames.astype(float).tolist())
    assert set(_visible_ticks(fig.axes[0]).astype(int)) == set(range(1, plan.n_frames + 1))


def test_inconsistent_plan_is_refused(tmp_path):
    plan = _plan()
    bad = ScanPlan(**{**plan.__dict__, "error_after_each": plan.error_after_each[:2]})
    with pytest.raises(InputError, match="errors"):
        plot_scan_selection(bad, tmp_path / "x.png")
    outside = ScanPlan(**{**plan.__dict__, "frames": np.array([7, 2, 25])})
    with pytest.raises(InputError, match="within the take"):
        plot_scan_selection(outside, tmp_path / "x.png")
    assert not list(tmp_path.iterdir())
