"""The valley model S(w, d, p) and its sky-lit intensity (eq. 6) against analytic values and brute force."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.wrinkles import cross_section, profile_sky_visibility, wedge_intensity


@pytest.mark.parametrize("rounding", [0.0, 2.0])
def test_cross_section_analytic_points(rounding: float) -> None:
    w, d = 1.7, 0.6
    assert cross_section(0.0, w, d, rounding=rounding) == pytest.approx(-d, abs=1e-15)
    assert cross_section([w, -w], w, d, rounding=rounding) == pytest.approx([0.0, 0.0], abs=1e-15)
    p = np.linspace(-12 * w, 12 * w, 240001)
    S = cross_section(p, w, d, rounding=rounding)
    np.testing.assert_allclose(S, S[::-1], rtol=1e-12, atol=1e-15)  # symmetric
    assert S.min() == pytest.approx(-d, abs=1e-12)
    assert abs(p[np.argmin(S)]) < 1e-3
    # bulge height d e^-2, at 2 w for the paper's S (at sqrt(12/5) w once rounded by 2)
    assert S.max() == pytest.approx(d * np.exp(-2.0), rel=1e-6)
    top = np.sqrt(12.0 / 5.0) * w if rounding else 2.0 * w
    assert abs(abs(p[np.argmax(S)]) - top) < 1e-3
    # valley below zero exactly inside (-w, w), bulge outside
    assert np.all(S[np.abs(p) < w * 0.999] < 0) and np.all(S[np.abs(p) > w * 1.001] > 0)


def test_paper_cross_section_formula() -> None:
    p = np.array([0.3, 1.0, 2.5, 7.0])
    w, d = 1.3, 0.45
    np.testing.assert_allclose(cross_section(p, w, d), d * (p / w - 1) * np.exp(-p / w), rtol=1e-15)
    np.testing.assert_allclose(cross_section(-p, w, d), cross_section(p, w, d), rtol=1e-15)


def _hemisphere_brute_force(p0: float, p: np.ndarray, h: np.ndarray, directions: int = 12000) -> float:
    """(1/pi) int V (n . omega) d omega over 3D directions, each ray marched against the extruded profile."""
    k = np.arange(directions) + 0.5
    z = 1.0 - 2.0 * k / directions  # uniform on the sphere (Fibonacci), equal solid angle each
    phi = np.pi * (1.0 + 5**0.5) * k
    r = np.sqrt(1.0 - z * z)
    omega = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])  # x across, y along the valley, z up
    h0 = np.interp(p0, p, h)
    slope = np.interp(p0, p, np.gradient(h, p))
    n = np.array([-slope, 0.0, 1.0]) / np.hypot(slope, 1.0)
    cosine = omega @ n
    up = cosine > 0
    omega, cosine = omega[up], cosine[up]
    # march each direction's projection onto the cross-section plane against the profile
    horizontal = omega[:, 0]
    t = np.geomspace(1e-4, 40.0, 1500)
    x = p0 + t[None, :] * horizontal[:, None]
    height = h0 + t[None, :] * omega[:, 2:3]
    ground = np.interp(x, p, h)
    visible = ~np.any(ground > height + 1e-9, axis=1)
    return float((cosine * visible).sum() * (4 * np.pi / directions) / np.pi)


@pytest.mark.parametrize("rounding", [0.0, 2.0])
@pytest.mark.parametrize("w, d", [(1.5, 0.4), (2.0, 1.1)])
def test_wedge_intensity_matches_a_brute_force_hemisphere_integral(w: float, d: float, rounding: float) -> None:
    p = np.linspace(-40.0, 40.0, 16001)
    h = cross_section(p, w, d, rounding=rounding)
    for p0 in (0.35 * w, 0.8 * w, 1.3 * w, 2.6 * w, -0.5 * w):
        brute = _hemisphere_brute_force(p0, p, h)
        assert wedge_intensity(p0, w, d, rounding=rounding) == pytest.approx(brute, abs=4e-3)


@pytest.mark.parametrize("rounding", [0.0, 2.0])
def test_wedge_intensity_table_matches_the_horizon_brute_force(rounding: float) -> None:
    p = np.linspace(-30.0, 30.0, 6001)
    for w, d in [(2.0, 0.2), (2.0, 0.6), (1.0, 1.2), (0.8, 2.0)]:
        brute = profile_sky_visibility(p, cross_section(p, w, d, rounding=rounding))
        tabulated = wedge_intensity(p, w, d, rounding=rounding)
        away_from_kink = np.abs(p) > 0.05
        np.testing.assert_allclose(tabulated[away_from_kink], brute[away_from_kink], atol=2e-4)


def test_wedge_intensity_limits() -> None:
    p = np.linspace(-10, 10, 201)
    np.testing.assert_array_equal(wedge_intensity(p, 2.0, 0.0), 1.0)  # flat: the whole sky
    assert wedge_intensity(4.0, 2.0, 0.7) == pytest.approx(1.0, abs=1e-9)  # the bulge top of S
    # deeper valleys are darker at their bottom, and it is scale-free in (p/w, d/w)
    assert wedge_intensity(0.5, 2.0, 0.4) > wedge_intensity(0.5, 2.0, 0.8) > wedge_intensity(0.5, 2.0, 1.6)
    assert wedge_intensity(0.7, 1.4, 0.5) == pytest.approx(wedge_intensity(1.4, 2.8, 1.0), rel=1e-12)
    assert np.all((wedge_intensity(p, 1.5, 0.9) > 0) & (wedge_intensity(p, 1.5, 0.9) <= 1.0 + 1e-12))


def test_profile_sky_visibility_rejects_bad_input() -> None:
    with pytest.raises(InputError, match="increasing"):
        profile_sky_visibility([0.0, 2.0, 1.0], [0.0, 0.0, 0.0])
