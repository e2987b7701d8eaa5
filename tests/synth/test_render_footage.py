"""The footage renderer: self-shadowed valleys, paint where the truth curve projects (OpenCV), the sensor's noise."""

from functools import lru_cache

import cv2
import numpy as np
import pytest

from facecap.cameras import Camera, ray_cast
from facecap.errors import InputError
from facecap.mesh.vertex_normals import vertex_normals
from facecap.synth.render_footage import FootageRenderer, ambient_occlusion, quantize, sensor_noise
from facecap.synth.wrinkles import WrinkleCurves, add_wrinkles

DEPTH, WIDTH = 0.8, 1.5  # mm


@lru_cache(maxsize=1)
def _plane_with_a_wrinkle():
    """A 60 x 30 mm grid (0.25 mm spacing) in z = 0 with one wrinkle along y = 0 from x = -25 to 25 (mm)."""
    xs, ys = np.arange(-30.0, 30.0001, 0.25), np.arange(-15.0, 15.0001, 0.25)
    X, Y = np.meshgrid(xs, ys)
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    nx = xs.size
    i, j = np.meshgrid(np.arange(ys.size - 1), np.arange(nx - 1), indexing="ij")
    a = (i * nx + j).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    k = 48
    line = np.column_stack([np.linspace(-25.0, 25.0, k), np.zeros(k), np.zeros(k)])
    hits = ray_cast(V, F, line + [0.0, 0.0, 10.0], np.tile([0.0, 0.0, -1.0], (k, 1)))
    curves = WrinkleCurves(names=("line",), kinds=("forehead",), points=hits.points[None], faces=hits.triangle[None],
                           barycentric=hits.barycentric[None], arc_fraction=np.linspace(0, 1, k)[None],
                           gains=np.ones((1, 1)), max_depth=np.array([DEPTH]), max_width=np.array([WIDTH]),
                           min_width=np.array([WIDTH]))
    out = add_wrinkles(V[None], F, curves, np.ones((1, 1)), rest=V)
    return V, F, out


def _camera(distortion):
    """Looking down at the plane from 150 mm, tilted 20 degrees about x, off-centre; 240 x 180 px."""
    tilt = np.deg2rad(20.0)
    R = np.array([[1.0, 0, 0], [0, -np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), -np.cos(tilt)]])
    centre = np.array([4.0, -20.0 - 150.0 * np.sin(tilt), 150.0 * np.cos(tilt)])  # the stripe near the top edge: distortion bends it
    K = np.array([[520.0, 0, 131.0], [0, 520.0, 84.0], [0, 0, 1]])
    return Camera("test", K=K, distortion=np.asarray(distortion, dtype=float), width=240, height=180,
                  R=R, T=-R @ centre)


def _project(cam, P):
    rvec = cv2.Rodrigues(cam.R)[0]
    return cv2.projectPoints(P.reshape(-1, 1, 3), rvec, cam.T, cam.K, cam.distortion)[0].reshape(-1, 2)


def _bilinear(image, uv):
    return np.stack([cv2.remap(image[..., c], uv[:, 0].astype(np.float32)[None], uv[:, 1].astype(np.float32)[None],
                               cv2.INTER_LINEAR)[0] for c in range(image.shape[2])], axis=1)


def test_ambient_occlusion_flat_is_one_and_valley_is_shadowed():
    V, F, out = _plane_with_a_wrinkle()
    flat = ambient_occlusion(V, F, rays=32)
    interior = (np.abs(V[:, 0]) < 29) & (np.abs(V[:, 1]) < 14)
    np.testing.assert_array_equal(flat[interior], 1.0)  # nothing above a plane
    ao = ambient_occlusion(out.vertices[0].astype(np.float64), F, rays=64)
    valley = (np.abs(V[:, 1]) < 0.01) & (np.abs(V[:, 0]) < 5)
    bulge = (np.abs(np.abs(V[:, 1]) - np.sqrt(2) * WIDTH) < 0.13) & (np.abs(V[:, 0]) < 5)
    far = (np.abs(np.abs(V[:, 1]) - 6.0) < 0.01) & (np.abs(V[:, 0]) < 5)
    # 2.5D check of the valley bottom: the walls' horizon from the profile itself bounds its sky
    assert ao[valley].mean() < 0.92
    assert ao[far].min() > 0.995 and ao[bulge].mean() > ao[valley].mean() + 0.05


def test_ambient_occlusion_equals_the_2d_visible_wedge_integral_across_a_long_valley():
    """Bickel et al.'s eq. 6 in 2.5D: a wedge from -a to b about the normal receives (sin b + sin a) / 2 of the sky."""
    V, F, out = _plane_with_a_wrinkle()
    W = out.vertices[0].astype(np.float64)
    ao = ambient_occlusion(W, F, rays=64)
    row = np.flatnonzero(V[:, 0] == 0.0)
    row = row[np.argsort(V[row, 1])]
    y, h = V[row, 1], W[row, 2]
    N = vertex_normals(W, F, row)
    errors = []
    for j in np.flatnonzero(np.abs(y) <= 6.0):
        dy, dh = y - y[j], h - h[j]
        tilt = np.arctan2(N[j, 1], N[j, 2])  # the normal's angle from +z towards +y
        rise_plus = np.max(np.arctan2(dh[dy > 0], dy[dy > 0]))  # horizon elevations either side
        rise_minus = np.max(np.arctan2(dh[dy < 0], -dy[dy < 0]))
        low = max(-(np.pi / 2 - rise_minus), tilt - np.pi / 2) - tilt
        high = min(np.pi / 2 - rise_plus, tilt + np.pi / 2) - tilt
        expected = (np.sin(high) - np.sin(low)) / 2.0
        # the valley is straight and steady mid-way: average the vertices of this row across |x| <= 4 mm
        same = (np.abs(V[:, 1] - y[j]) < 1e-9) & (np.abs(V[:, 0]) <= 4.0)
        errors.append(ao[same].mean() - expected)
        if abs(y[j]) < 1e-9:
            assert expected < 0.9  # the valley bottom does lose sky
    assert np.max(np.abs(errors)) < 0.012 and np.mean(np.abs(errors)) < 0.003


def test_rendered_valley_is_darker_than_the_skin_beside_it():
    V, F, out = _plane_with_a_wrinkle()
    W = out.vertices[0].astype(np.float64)
    ao = ambient_occlusion(W, F, rays=64)
    cam = _camera([-0.15, 0.05, 0.001, -0.001, 0.0])
    renderer = FootageRenderer(F, [cam])
    image = renderer.render(W, np.full((V.shape[0], 3), 0.6) * ao[:, None])[0]
    renderer.close()
    x = np.linspace(-15.0, 15.0, 31)
    on_line = _project(cam, np.column_stack([x, np.zeros_like(x), np.full_like(x, -DEPTH)]))
    beside = _project(cam, np.column_stack([x, np.full_like(x, 6.0), np.zeros_like(x)]))
    valley_level = _bilinear(image, on_line)[:, 1]
    skin_level = _bilinear(image, beside)[:, 1]
    np.testing.assert_allclose(skin_level, 0.6, rtol=0.01)
    assert np.all(valley_level < 0.93 * skin_level)


def test_painted_stripe_lands_on_the_projected_truth_curve_within_a_pixel():
    V, F, out = _plane_with_a_wrinkle()
    W = out.vertices[0].astype(np.float64)
    cam = _camera([-0.45, 0.15, 0.002, -0.0015, 0.0])  # strong barrel: a wrong distortion moves the stripe pixels
    paint = np.abs(V[:, 1]) <= 2.0 * WIDTH
    radiance = np.where(paint[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    renderer = FootageRenderer(F, [cam])
    image = renderer.render(W, radiance)[0]
    renderer.close()
    x = np.linspace(-22.0, 22.0, 400)
    truth = _project(cam, out.curve_points[0, 0].astype(np.float64))  # the valley line on the wrinkled surface
    dense = truth[(np.abs(out.curve_points[0, 0, :, 0]) < 12.0)]  # mid-curve, where the depth and width are steady
    fraction = image[..., 2] / np.maximum(image[..., 0] + image[..., 2], 1e-9)
    # where the stripe's edges are: half-way between the last painted and the first bare row of vertices
    edge_y = 2.0 * WIDTH + 0.125
    edge_z = float(np.interp(edge_y, V[V[:, 0] == 0.0, 1], W[V[:, 0] == 0.0, 2]))
    edges_3d = [_project(cam, np.column_stack([x, np.full_like(x, sign * edge_y), np.full_like(x, edge_z)]))
                for sign in (-1.0, 1.0)]
    centre_errors, edge_errors = [], []
    for u in range(int(edges_3d[0][:, 0].min()) + 5, int(edges_3d[0][:, 0].max()) - 5):  # the stripe's length
        column = fraction[:, u]
        rows = np.flatnonzero(column > 0.5)
        if rows.size < 4:
            continue
        top, bottom = rows.min(), rows.max()
        # the stripe's sub-pixel edges (the 0.5 crossings) and their mid-point
        edge_top = top - 1 + (0.5 - column[top - 1]) / (column[top] - column[top - 1])
        edge_bottom = bottom + (column[bottom] - 0.5) / (column[bottom] - column[bottom + 1])
        expected = sorted(np.interp(u, e[:, 0], e[:, 1]) for e in edges_3d)
        edge_errors += [edge_top - expected[0], edge_bottom - expected[1]]
        if dense[:, 0].min() < u < dense[:, 0].max():
            centre_errors.append(0.5 * (edge_top + edge_bottom) - np.interp(u, truth[:, 0], truth[:, 1]))
    assert len(edge_errors) > 250 and len(centre_errors) > 60
    # the edges are where OpenCV's model projects them (MSAA and the remap blur them symmetrically; a renderer
    # that ignored the distortion would put them up to 1.3 px off) ...
    assert np.abs(edge_errors).max() < 0.35
    # ... and the paint's colour is what the camera sees at the projected truth curve (the valley line), with
    # the stripe's edges 6-9 px to either side (the valley bottom lies 0.8 mm below the edges, seen obliquely,
    # so the stripe's image centre is about a pixel off the projected valley line)
    seen = _bilinear(fraction[..., None], dense)[:, 0]
    assert np.all(seen > 0.99)
    assert np.abs(centre_errors).max() < 1.5
    # the truth curve is the valley bottom (on a plane: depth below z = 0)
    np.testing.assert_allclose(out.curve_points[0, 0, :, 2], -out.depths[0, 0], atol=1e-6)


def test_sensor_noise_matches_shot_plus_read_noise():
    rng = np.random.default_rng(5)
    full_well, read = 10000.0, 20.0
    for level in (0.05, 0.3, 0.7):
        x = np.full(400_000, level)
        y = sensor_noise(x, rng=rng, full_well_electrons=full_well, read_noise_electrons=read)
        var = level / full_well + (read / full_well) ** 2
        assert abs(y.mean() - level) < 5 * np.sqrt(var / x.size)
        assert y.var() == pytest.approx(var, rel=0.02)
    assert np.array_equal(sensor_noise(np.full(10, 0.5), rng=np.random.default_rng(1)),
                          sensor_noise(np.full(10, 0.5), rng=np.random.default_rng(1)))


def test_quantize_and_bad_input():
    assert quantize(np.array([0.0, 0.5, 1.0, 2.0]), bits=8).tolist() == [0, 128, 255, 255]
    assert quantize(np.array([0.5]), bits=16).dtype == np.uint16
    with pytest.raises(InputError, match="bits"):
        quantize(np.zeros(3), bits=12)
    V, F, _ = _plane_with_a_wrinkle()
    renderer = FootageRenderer(F, [_camera([])])
    with pytest.raises(InputError, match="radiance"):
        renderer.render(V, np.zeros((3, 3)))
    renderer.close()
