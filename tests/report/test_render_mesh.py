"""Tests for facecap.report.render_mesh."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib import colormaps
from matplotlib.image import imread

from facecap.errors import InputError, MeshError
from facecap.report.render_mesh import MeshPanel, render_mesh, render_side_by_side

# A square [-1, 1]^2 in the z = 0 plane, counter-clockwise seen from +z (facing the front camera).
SQUARE_V = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def _covered(img: np.ndarray) -> np.ndarray:
    """Pixels that differ from the white background."""
    return np.any(img[..., :3] < 0.98, axis=-1)


def _saturated(img: np.ndarray) -> np.ndarray:
    rgb = img[..., :3]
    return rgb.max(axis=-1) - rgb.min(axis=-1) > 0.2


def _bump_grid(n: int = 40):
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    V = np.stack([60 * u.ravel(), 80 * v.ravel(), 30 * np.exp(-2 * (u.ravel() ** 2 + v.ravel() ** 2))], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return V, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_png_has_requested_size_and_is_shaded(tmp_path):
    V, F = _bump_grid()
    out = tmp_path / "grey.png"
    render_mesh(V, F, out, size_px=(320, 240), title="bump")
    img = imread(out)
    assert img.shape[:2] == (240, 320)
    cov = _covered(img)
    assert 0.2 < cov.mean() < 0.9
    # Lambert shading: the grey varies across the mesh, and it is grey (not coloured).
    grey = img[cov][:, :3]
    assert grey[:, 0].std() > 0.02
    assert not _saturated(img).any()
    assert not list(tmp_path.glob(".*")), "no temporary file left behind"


def test_flat_square_covers_its_projected_area(tmp_path):
    out = tmp_path / "square.png"
    render_mesh(SQUARE_V, SQUARE_F, out, size_px=(200, 200), bounds=(-2, 2, -2, 2))
    cov = _covered(imread(out))
    # The square is a quarter of the 4 x 4 window: the central 100 x 100 pixels.
    assert cov.mean() == pytest.approx(0.25, abs=0.01)
    assert cov[60:140, 60:140].all() and not cov[:45].any() and not cov[:, 155:].any()
    # Half of it (one triangle) covers half as much.
    render_mesh(SQUARE_V, SQUARE_F[:1], out, size_px=(200, 200), bounds=(-2, 2, -2, 2))
    assert _covered(imread(out)).mean() == pytest.approx(0.125, abs=0.01)


def test_values_colour_the_mesh_and_leave_background(tmp_path):
    out = tmp_path / "heat.png"
    W, H = 350, 200
    render_mesh(
        SQUARE_V, SQUARE_F, out, values=np.full(4, 0.5), vmin=0.0, vmax=1.0,
        value_label="error (mm)", size_px=(W, H), bounds=(-2, 2, -2, 2),
    )
    img = imread(out)
    assert img.shape[:2] == (H, W)
    panel_w = W - round(0.14 * W)  # documented: the right 14 % holds the colour bar
    sat = _saturated(img[:, :panel_w])
    cov = _covered(img[:, :panel_w])
    # Equal scale: the 4-unit window spans the 200 px height, so the square is 100 x 100 px.
    assert sat.sum() == pytest.approx(100 * 100, rel=0.04)
    np.testing.assert_array_equal(sat, cov)  # coloured where the mesh is, background elsewhere
    expected = np.array(colormaps["inferno"](0.5)[:3])
    np.testing.assert_allclose(img[H // 2, panel_w // 2, :3], expected, atol=0.01)
    assert _saturated(img[:, panel_w:]).any()  # the colour bar


def test_back_faces_are_culled(tmp_path):
    out = tmp_path / "back.png"
    flipped = SQUARE_F[:, ::-1]
    render_mesh(SQUARE_V, flipped, out, size_px=(100, 100), bounds=(-2, 2, -2, 2))
    assert not _covered(imread(out)).any()
    # Seen from behind (azimuth 180 degrees) the flipped square faces the camera.
    render_mesh(SQUARE_V, flipped, out, size_px=(100, 100), bounds=(-2, 2, -2, 2), view=(180.0, 0.0))
    assert _covered(imread(out)).mean() == pytest.approx(0.25, abs=0.02)


@pytest.mark.parametrize("near_first", [True, False])
def test_nearer_triangles_are_drawn_over_farther_ones(tmp_path, near_first):
    far = SQUARE_V + [-0.5, 0.0, 0.0]
    near = SQUARE_V + [0.5, 0.0, 1.0]
    blocks = [(near, 1.0), (far, 0.0)] if near_first else [(far, 0.0), (near, 1.0)]
    V = np.concatenate([b[0] for b in blocks])
    F = np.concatenate([SQUARE_F, SQUARE_F + 4])
    vals = np.repeat([b[1] for b in blocks], 4)
    out = tmp_path / "order.png"
    render_mesh(V, F, out, values=vals, vmin=0, vmax=1, cmap="viridis", size_px=(400, 200),
                bounds=(-2, 2, -1.5, 1.5))
    img = imread(out)
    # The overlap x in [-0.5, 0.5] is at the centre of the panel; it shows the near (value 1) colour.
    panel_w = 400 - round(0.14 * 400)
    np.testing.assert_allclose(img[100, panel_w // 2, :3], colormaps["viridis"](1.0)[:3], atol=0.01)


def test_side_by_side_layout(tmp_path):
    V, F = _bump_grid(20)
    err = np.linalg.norm(V, axis=1)
    out = tmp_path / "sbs.png"
    render_side_by_side(
        [MeshPanel(V, F, None, "truth"), (V + [0, 0, 1.0], F, None, "result"), (V, F, err, "error")],
        out, value_label="error (mm)", title="frame 0", panel_size_px=(120, 150),
    )
    img = imread(out)
    cbar = round(0.14 * 120 / 0.86)
    assert img.shape[:2] == (150 + 2 * round(0.07 * 150), 3 * 120 + cbar)
    # Same framing in every panel: the silhouettes of the first two coincide.
    body = img[-150:]
    np.testing.assert_array_equal(_covered(body[:, :120]), _covered(body[:, 120:240]))
    assert _saturated(body[:, 240:360]).mean() > 0.2 and not _saturated(body[:, :240]).any()


def test_side_view_shows_depth_profile(tmp_path):
    # A thin slab 2 wide (x), 2 tall (y), facing +x: invisible from the front, a square from the side.
    V = np.array([[0, -1, 1], [0, -1, -1], [0, 1, -1], [0, 1, 1]], float)
    out = tmp_path / "side.png"
    render_mesh(V, SQUARE_F, out, size_px=(100, 100), bounds=(-2, 2, -2, 2), view="side")
    assert _covered(imread(out)).mean() == pytest.approx(0.25, abs=0.02)
    render_mesh(V, SQUARE_F, out, size_px=(100, 100), bounds=(-2, 2, -2, 2), view="front")
    assert not _covered(imread(out)).any()


def test_bad_input_raises(tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match="view"):
        render_mesh(SQUARE_V, SQUARE_F, out, view="top")
    with pytest.raises(InputError, match="values"):
        render_mesh(SQUARE_V, SQUARE_F, out, values=np.ones(3))
    with pytest.raises(MeshError, match="F"):
        render_mesh(SQUARE_V, SQUARE_F + 2, out)
    with pytest.raises(InputError, match="size_px"):
        render_mesh(SQUARE_V, SQUARE_F, out, size_px=(0, 10))
    with pytest.raises(InputError, match="vmin"):
        render_mesh(SQUARE_V, SQUARE_F, out, values=np.ones(4), vmin=2, vmax=1)
    with pytest.raises(InputError, match="panels"):
        render_side_by_side([], out)
    assert not out.exists()
