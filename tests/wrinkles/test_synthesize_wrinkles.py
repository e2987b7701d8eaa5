"""Valleys, regions and the shell on analytic cases (5.3)."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.wrinkles import cross_section, synthesize_wrinkles, wrinkle_depth_scale
from wrinkle_lines import straight_wrinkle as _line


def _sheet(half: float = 15.0, spacing: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A flat square sheet in the z = 0 plane, triangles counter-clockwise seen from +z (normals +z)."""
    xs = np.arange(-half, half + 1e-9, spacing)
    n = len(xs)
    X, Y = np.meshgrid(xs, xs)
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(n * n)])
    F = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            F += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return V, np.array(F)


def test_valleys_alone_are_the_cross_section_along_the_normal() -> None:
    V, F = _sheet()
    found = synthesize_wrinkles(V, F, [_line("a:0", -8.0, 8.0)], shell=False)
    along = np.abs(V[:, 0]) <= 8.0  # beside the line, not round its ends
    p = np.abs(V[:, 1])
    inside = along & (p < 2.0)
    expected = cross_section(p[inside], 2.0, 0.5, rounding=2.0)
    assert np.allclose(found.vertices[inside, 2], expected, atol=1e-12)
    assert np.array_equal(found.vertices[:, :2], V[:, :2])  # offsets along the normal only
    # the valley is every vertex within a half-width of the line (round past its ends), and nothing else
    to_line = np.hypot(np.clip(np.abs(V[:, 0]) - 8.0, 0.0, None), V[:, 1])
    assert np.array_equal(found.valley, to_line < 2.0)
    assert found.vertices[inside, 2].min() == pytest.approx(-0.5, abs=1e-12)  # the vertex on the line
    assert np.array_equal(found.vertices[~found.valley], V[~found.valley])


def test_the_shell_raises_bulges_beside_the_valley_and_moves_nothing_beyond_its_region() -> None:
    V, F = _sheet()
    found = synthesize_wrinkles(V, F, [_line("a:0", -8.0, 8.0)])
    free = (found.region >= 0) & ~found.valley
    # keeping the curvature of the flat sheet, the skin beside the imposed valley rises (the bulges of 5.3)
    beside = free & (np.abs(V[:, 0]) < 4.0)
    assert found.vertices[beside, 2].max() > 0.01
    assert found.n_regions == 1 and (found.shell_energy < found.initial_energy).all()
    outside = found.region < 0
    assert np.array_equal(found.vertices[outside], V[outside])
    assert np.abs(V[found.region >= 0, 1]).max() <= 2 * 2.0 + 0.5  # the influence is two widths


def test_two_distant_wrinkles_are_two_regions_and_no_wrinkle_changes_nothing() -> None:
    V, F = _sheet()
    found = synthesize_wrinkles(V, F, [_line("a:0", -8.0, 8.0, y=-8.0), _line("a:1", -8.0, 8.0, y=8.0)])
    assert found.n_regions == 2
    none = synthesize_wrinkles(V, F, [_line("a:0", -8.0, 8.0, depth=0.0)])
    assert np.array_equal(none.vertices, V) and none.n_regions == 0


def test_depth_scale_names_a_merged_wrinkle_by_any_cameras_part() -> None:
    V, F = _sheet()
    base = synthesize_wrinkles(V, F, [_line("a:1+b:2", -8.0, 8.0)], shell=False)
    doubled = synthesize_wrinkles(V, F, [_line("a:1+b:2", -8.0, 8.0)], shell=False, depth_scale={"b:2": 2.0})
    assert np.allclose(doubled.vertices[:, 2], 2.0 * base.vertices[:, 2], atol=1e-12)


def test_bad_input_is_refused() -> None:
    V, F = _sheet(half=2.0)
    with pytest.raises(InputError, match="influence_widths"):
        synthesize_wrinkles(V, F, [], influence_widths=0.5)
    with pytest.raises(InputError, match="motion"):
        synthesize_wrinkles(V, F, [], motion="sideways")
    with pytest.raises(InputError, match="faces"):
        synthesize_wrinkles(V, F + len(V), [])


def test_depth_scale_by_number_by_identity_and_by_the_cameras_parts() -> None:
    merged = _line("cam_left:2+cam_right:1", 0.0, 10.0)
    alone = _line("cam_left:4", 0.0, 10.0)
    assert wrinkle_depth_scale(merged, 0.7) == 0.7
    assert wrinkle_depth_scale(merged, {"cam_left:2": 0.5, "cam_right:1": 3.0}) == 1.5  # parts multiply
    assert wrinkle_depth_scale(merged, {"cam_left:2+cam_right:1": 2.0, "cam_left:2": 0.5}) == 2.0  # full name wins
    assert wrinkle_depth_scale(alone, {"cam_left:2": 0.5}) == 1.0  # not named: kept
    # synthesize_wrinkles imposes the valley of the wrinkle made that much deeper
    V, F = _sheet()
    scaled = synthesize_wrinkles(V, F, [merged], shell=False, depth_scale={"cam_left:2": 0.5, "cam_right:1": 3.0})
    deeper = synthesize_wrinkles(V, F, [_line("other:0", 0.0, 10.0, depth=0.5 * 1.5)], shell=False)
    np.testing.assert_allclose(scaled.vertices, deeper.vertices, atol=1e-12)
