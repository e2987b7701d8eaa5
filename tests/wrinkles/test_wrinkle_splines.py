"""fit_wrinkle_spline (eq. 5): exact on a parabola, weighted as stated, a drawn stripe's centre from its pixels."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.wrinkles import control_points_for_length, darkness_weights, fit_wrinkle_spline

from wrinkle_stripe_images import centre_curve, polyline_distance, render_stripes


def test_a_polynomial_curve_is_reproduced_exactly() -> None:
    """Pixels on a parabola, sampled symmetrically about its vertex along a tilted axis: the PCA axis is the
    parabola's own, x is exact, and a uniform cubic B-spline spans quadratics, so the fit is exact."""
    rng = np.random.default_rng(0)
    half = rng.uniform(0.0, 80.0, 200)
    x = np.concatenate([half, -half])
    y = 3.0 + 2e-3 * x**2
    angle = 0.4
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    P = np.stack([x, y], axis=1) @ R.T + [300.0, 200.0]
    spline = fit_wrinkle_spline(P, smoothing=0.0)
    q = (spline.sample(300) - [300.0, 200.0]) @ R  # back in the parabola's frame
    assert np.max(np.abs(q[:, 1] - (3.0 + 2e-3 * q[:, 0] ** 2))) < 1e-8
    assert q[:, 0].min() == pytest.approx(-half.max()) and q[:, 0].max() == pytest.approx(half.max())
    assert spline.half_width < 1e-6


def test_weights_pull_the_curve_as_a_weighted_mean() -> None:
    """Two parallel rows of pixels at v = 0 and v = 2, weighted 3 : 1: the least-squares curve is v = 0.5."""
    u = np.arange(0.0, 120.0)
    P = np.concatenate([np.stack([u, np.zeros_like(u)], 1), np.stack([u, np.full_like(u, 2.0)], 1)])
    w = np.concatenate([np.full(u.size, 3.0), np.ones(u.size)])
    Q = fit_wrinkle_spline(P, w).sample(50)
    np.testing.assert_allclose(Q[:, 1], 0.5, atol=1e-9)
    Q = fit_wrinkle_spline(P).sample(50)
    np.testing.assert_allclose(Q[:, 1], 1.0, atol=1e-9)


@pytest.mark.parametrize(("slope", "bend"), [(0.2, 0.001), (-0.4, 0.0015), (0.8, -0.002)])
def test_a_drawn_stripe_gives_its_centre_curve(slope: float, bend: float) -> None:
    """An anti-aliased stripe 12 px wide around a known parabola: the fitted valley lies within 0.3 px of it."""
    centre = centre_curve(40.0, 250.0, 60.0 if slope >= 0 else 180.0, slope, bend)
    _, mask = render_stripes((320, 240), [(centre, 6.0, np.array([0.1, 0.2, 0.6]))])
    rows, cols = np.nonzero(mask == 1)
    spline = fit_wrinkle_spline(np.stack([cols, rows], axis=1).astype(float))
    assert spline.half_width == pytest.approx(6.0, abs=0.5)  # the stripe's half-width from the pixels' spread
    length = np.sum(np.linalg.norm(np.diff(centre, axis=0), axis=1))
    assert spline.elongation == pytest.approx((length + 12.0) / 12.0, rel=0.12)  # its round caps included
    tracked = spline.sample(200, trim=spline.half_width)  # the round caps left out
    d, interior = polyline_distance(tracked, centre)
    assert interior.all()  # trimmed by the half-width, the curve ends inside the true one
    assert d.mean() < 0.3 and np.percentile(d, 95) < 0.6
    back, inside = polyline_distance(centre[::10], spline.sample(400))
    assert back[inside].mean() < 0.3


def test_control_points_grow_with_length_within_5_to_12() -> None:
    counts = [control_points_for_length(length) for length in np.linspace(0.0, 1000.0, 201)]
    assert min(counts) == 5 and max(counts) == 12
    assert all(b >= a for a, b in zip(counts, counts[1:]))
    u = np.arange(0.0, 400.0)
    P = np.stack([np.repeat(u, 3), np.tile([-1.0, 0.0, 1.0], u.size)], axis=1)
    assert fit_wrinkle_spline(P[: 3 * 60]).n_control == 5
    assert fit_wrinkle_spline(P).n_control == 12


def test_darkness_weights_follow_the_paper() -> None:
    """w = (g_max - g_min) / (g - g_min), regularised at g_min by the floor."""
    g = np.linspace(0.2, 0.8, 1001)
    w = darkness_weights(g, floor=0.05)
    lo, hi = np.percentile(g, [1.0, 99.0])
    inner = (g > lo) & (g < hi)
    np.testing.assert_allclose(w[inner], 1.0 / ((g[inner] - lo) / (hi - lo) + 0.05))
    assert w.max() == pytest.approx(20.0) and w.min() == pytest.approx(1.0 / 1.05)


def test_bad_input_is_refused() -> None:
    with pytest.raises(InputError, match="too few"):
        fit_wrinkle_spline(np.zeros((3, 2)))
    with pytest.raises(InputError, match="weights"):
        fit_wrinkle_spline(np.random.default_rng(0).normal(size=(50, 2)), np.ones(49))
    with pytest.raises(InputError, match="n_control"):
        fit_wrinkle_spline(np.random.default_rng(0).normal(size=(50, 2)), n_control=13)
