"""Tests for facecap.report.plot_series."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from facecap.errors import InputError
from facecap.report.plot_series import _nan_stats, draw_series, plot_series


def test_writes_png_of_requested_size_with_gappy_marker_residuals(tmp_path):
    rng = np.random.default_rng(0)
    T, M = 240, 12
    t = np.arange(T) / 120.0
    res = np.abs(rng.normal(size=(T, M)))
    res[rng.random((T, M)) < 0.1] = np.nan
    res[5] = np.nan  # a frame with every marker occluded must not warn or fail
    out = tmp_path / "residuals.png"
    plot_series(
        t, {"markers": res, "dense error": np.nan_to_num(res).mean(axis=1)}, out,
        ylabel="residual (mm)", title="take", bands={"tolerance": (np.zeros(T), np.full(T, 0.5))},
        size_px=(640, 320),
    )
    img = imread(out)
    assert img.shape[:2] == (320, 640)
    assert img[..., :3].std() > 0.05  # not blank
    assert not list(tmp_path.glob(".*"))


def test_matrix_summary_matches_numpy_ignoring_gaps():
    rng = np.random.default_rng(1)
    A = rng.random((30, 9))
    A[rng.random(A.shape) < 0.3] = np.nan
    A[3] = np.nan
    A[4, 1:] = np.nan  # one value
    A[5, 2:] = np.nan  # two: the quantiles interpolate between them
    med, p95, mx = _nan_stats(A)
    for i in range(30):
        row = A[i][~np.isnan(A[i])]
        if row.size == 0:
            assert np.isnan(med[i]) and np.isnan(p95[i]) and np.isnan(mx[i])
        else:
            assert med[i] == pytest.approx(np.median(row))
            assert p95[i] == pytest.approx(np.percentile(row, 95))
            assert mx[i] == row.max()


@pytest.mark.parametrize(
    "series, bands, match",
    [
        ({"a": np.zeros(9)}, None, "series\\['a'\\]"),
        ({"a": np.zeros((11, 2))}, None, "series\\['a'\\]"),
        ({}, None, "series"),
        ({"a": np.zeros(10)}, {"b": (np.zeros(10), np.zeros(8))}, "bands\\['b'\\] upper"),
    ],
)
def test_mismatched_lengths_raise(tmp_path, series, bands, match):
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match=match):
        plot_series(np.arange(10) / 60.0, series, out, ylabel="mm", bands=bands)
    assert not out.exists()


def test_bad_times_raise(tmp_path):
    with pytest.raises(InputError, match="times"):
        plot_series(np.array([0.0, np.nan]), {"a": np.zeros(2)}, tmp_path / "x.png", ylabel="mm")


def test_draw_series_draws_lines_median_band_maximum_and_bands():
    from matplotlib.figure import Figure

    rng = np.random.default_rng(3)
    T, M = 50, 7
    t = np.arange(T) / 10.0
    A = rng.normal(size=(T, M))
    A[rng.random((T, M)) < 0.2] = np.nan
    A[:, 0] = 0.0  # every row has a sample: NumPy's references warn on an all-NaN row
    line = np.sin(t)
    lo, hi = -np.ones(T), np.ones(T)
    ax = Figure().add_subplot()
    draw_series(ax, t, {"a": line, "b": A}, {"tol": (lo, hi)})
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert set(lines) == {"a", "b (median)", "b (max)"}
    np.testing.assert_array_equal(lines["a"].get_ydata(), line)
    np.testing.assert_allclose(lines["b (median)"].get_ydata(), np.nanmedian(A, axis=1), rtol=1e-12)
    np.testing.assert_array_equal(lines["b (max)"].get_ydata(), np.nanmax(A, axis=1))
    assert lines["a"].get_color() == "C0" and lines["b (median)"].get_color() == "C1"
    assert [c.get_label() for c in ax.collections] == ["b (to p95)", "tol"]
