"""Tests for facecap.report.plot_activations."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from facecap.errors import InputError
from facecap.report.plot_activations import plot_activations


def _take(T=40, k=12):
    t = np.arange(T) / 20.0
    ramp = np.linspace(0.0, 1.0, T)
    # muscle i holds i / k of the ramp, muscle 0 sits at the bound: the named ones are the 8 highest means
    A = np.clip(np.outer(ramp, np.arange(k)[::-1] + 1) / k * 1.5, 0.0, 1.0)
    names = [f"m{i}" for i in range(k)]
    return t, A, names


def test_the_bound_the_named_muscles_and_the_rest_summarised(tmp_path):
    t, A, names = _take()
    out = tmp_path / "act.png"
    fig = plot_activations(t, A, names, out, title="frown")
    ax = fig.axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels[:8] == [f"m{i}" for i in range(8)]  # highest mean first
    assert "the other 4 muscles (median)" in labels
    bound = next(line for line in ax.get_lines() if line.get_gid() == "activation_bound")
    assert set(bound.get_ydata()) == {1.0} and "full activation" in bound.get_label()
    assert len(fig.axes) == 1  # no residual given, no residual panel
    assert fig.get_suptitle() == "frown"
    image = imread(out)
    assert image.shape[:2] == (720, 1200) and image[..., :3].std() > 0.05


def test_flagged_frames_shaded_and_the_residual_against_its_threshold(tmp_path):
    t, A, names = _take()
    flagged = np.zeros(t.size, bool)
    flagged[10:20] = True
    flagged[30:] = True
    residual = np.where(flagged, 7.0, 2.0)
    caption = "line one\nline two"
    fig = plot_activations(t, A, names, tmp_path / "act.png", flagged=flagged, max_residual_mm=residual,
                           flag_residual_mm=5.0, caption=caption)
    top, low = fig.axes[:2]
    dt = t[1] - t[0]
    for axis in (top, low):
        spans = sorted((p.get_x(), p.get_x() + p.get_width()) for p in axis.patches if p.get_alpha() == 0.15)
        np.testing.assert_allclose(spans, [(t[10] - dt / 2, t[19] + dt / 2), (t[30] - dt / 2, t[39] + dt / 2)])
    assert "flagged (20 of 40 frames)" in [text.get_text() for text in top.get_legend().get_texts()]
    threshold = [line for line in low.get_lines() if "flagged large_residual" in line.get_label()]
    assert len(threshold) == 1 and set(threshold[0].get_ydata()) == {5.0}
    np.testing.assert_array_equal(low.get_lines()[0].get_ydata(), residual)
    assert any(text.get_text() == caption for text in fig.texts)
    assert imread(tmp_path / "act.png").shape[:2] == (720 + 2 * 20, 1200)  # 20 px per caption line


def test_bad_shapes_are_refused(tmp_path):
    t, A, names = _take()
    with pytest.raises(InputError, match="activations"):
        plot_activations(t[:-1], A, names, tmp_path / "x.png")
    with pytest.raises(InputError, match="flagged"):
        plot_activations(t, A, names, tmp_path / "x.png", flagged=np.zeros(3, bool))
    with pytest.raises(InputError, match="finite"):
        plot_activations(t, np.where(A > 0.5, np.nan, A), names, tmp_path / "x.png")
    assert not list(tmp_path.iterdir())
