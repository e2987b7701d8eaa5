"""Tests for facecap.report.render_mesh."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib import colormaps
from matplotlib.image import imread

from facecap.errors import InputError, MeshError
from facecap.report.render_mesh import MeshPanel, as_size_px, draw_mesh, render_mesh, render_side_by_side

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


def test_returned_colour_range_and_values_beyond_it(tmp_path):
    V, F = _bump_grid(20)
    err = np.linalg.norm(V, axis=1)  # 0 .. ~100
    out = tmp_path / "sbs.png"
    # two compared panels on one given range: both drawn with it, the faces past vmax in the top colour
    norm = render_side_by_side([(V, F, err, "a"), (V, F, 0.5 * err, "b")], out, vmin=0.0, vmax=40.0,
                               panel_size_px=(120, 150))
    assert (norm.vmin, norm.vmax) == (0.0, 40.0)
    img = imread(out)
    top = np.array(colormaps["inferno"](1.0)[:3])
    corner = img[-150:, :120][_saturated(img[-150:, :120])][:, :3]  # panel a's coloured pixels
    assert (np.abs(corner - top).max(axis=1) < 0.02).mean() > 0.3  # most of |V| > 40 mm: clipped to the top colour
    # without a range: the finite min and max over every panel with values
    norm = render_mesh(V, F, out, values=np.where(err > 90, np.nan, err), size_px=(120, 150))
    finite = err[err <= 90]
    assert (norm.vmin, norm.vmax) == (finite.min(), finite.max())
    assert render_mesh(V, F, out, size_px=(120, 150)) is None
    assert render_side_by_side([(V, F, None, "grey")], out, panel_size_px=(120, 150)) is None


@pytest.mark.parametrize(("values", "expected"), [
    ([0.0, 1.0], "neither"), ([0.0, 1.5], "max"), ([-0.5, 1.0], "min"), ([-0.5, np.nan, 1.5], "both"),
    ([np.nan], "neither"),
])
def test_colour_bar_arrows_say_which_values_were_clipped(values, expected):
    from matplotlib.colors import Normalize

    from facecap.report.render_mesh import _colorbar_extend

    assert _colorbar_extend([np.array([0.5]), np.array(values)], Normalize(0.0, 1.0)) == expected


def test_caption_strip_under_the_panels(tmp_path):
    V, F = _bump_grid(20)
    out = tmp_path / "captioned.png"
    render_side_by_side([(V, F, None, "A: truth"), (V, F, None, "B: result")], out, panel_size_px=(120, 150),
                        caption="A: the truth\nB: the result")
    img = imread(out)
    ptitle = round(0.07 * 150)
    caption_h = 3 * 19  # two lines and one of leading
    assert img.shape[:2] == (150 + ptitle + caption_h, 240)
    assert _covered(img[-caption_h:]).any()  # the text
    # the panels moved up by the strip, not squeezed: the silhouette is that of an uncaptioned render
    render_side_by_side([(V, F, None, "A: truth"), (V, F, None, "B: result")], tmp_path / "plain.png",
                        panel_size_px=(120, 150))
    plain = imread(tmp_path / "plain.png")
    np.testing.assert_array_equal(_covered(img[ptitle:ptitle + 150]), _covered(plain[ptitle:ptitle + 150]))


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


def test_draw_mesh_draws_what_render_mesh_renders(tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    V, F = _bump_grid(20)
    render_mesh(V, F, tmp_path / "alone.png", size_px=(120, 150), bounds=(-70, 70, -90, 90))
    fig = Figure(figsize=(1.2, 1.5), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    window = draw_mesh(ax, V, F, bounds=(-70, 70, -90, 90), aspect_px=120 / 150)
    FigureCanvasAgg(fig)
    fig.savefig(tmp_path / "drawn.png", dpi=100, facecolor="white")
    assert window == (-70.0, 70.0, -90.0, 90.0)
    np.testing.assert_array_equal(_covered(imread(tmp_path / "drawn.png")), _covered(imread(tmp_path / "alone.png")))
    with pytest.raises(MeshError, match="F"):
        draw_mesh(ax, V, F + V.shape[0])



def test_as_size_px_gives_whole_pixels_and_names_the_argument():
    assert as_size_px((640.9, np.int64(480))) == (640, 480)
    assert all(type(v) is int for v in as_size_px(np.array([16.0, 16.0])))
    with pytest.raises(InputError, match=r"panel_size_px: expected at least 16 x 16"):
        as_size_px((15, 100), name="panel_size_px")
    for bad in (None, 640, (1, 2, 3), ("a", "b")):
        with pytest.raises(InputError, match=r"size_px: expected \(width, height\)"):
            as_size_px(bad)
