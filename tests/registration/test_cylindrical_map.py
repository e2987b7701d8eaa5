import numpy as np
import pytest

from facecap.errors import InputError
from facecap.registration.cylindrical_map import cylindrical_map


def _cylinder_patch(radius=80.0, n_theta=41, n_h=31, theta_max=1.0, h_max=60.0, centre=(5.0, -3.0, 2.0)):
    """A face-like patch of a cylinder around the y axis, looking along +z; its (theta, h) grid."""
    th, h = np.meshgrid(np.linspace(-theta_max, theta_max, n_theta), np.linspace(-h_max, h_max, n_h))
    th, h = th.ravel(), h.ravel()
    V = np.stack([radius * np.sin(th), h, radius * np.cos(th)], 1) + np.asarray(centre)
    a = (np.arange(n_h - 1)[:, None] * n_theta + np.arange(n_theta - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n_theta], 1), np.stack([a + 1, a + n_theta + 1, a + n_theta], 1)])
    return V, F, th, h


def test_pixels_are_arc_length_and_height_at_one_scale():
    V, F, th, h = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=200, margin_px=3)
    s = cmap.px_per_mm
    np.testing.assert_allclose(cmap.pixels[:, 0], cmap.origin[0] + 80.0 * th * s, atol=1e-9)
    np.testing.assert_allclose(cmap.pixels[:, 1], cmap.origin[1] - h * s, atol=1e-9)
    # the longer side (arc 160 mm vs height 120 mm) spans the image minus its margins
    assert cmap.shape[1] == 200
    np.testing.assert_allclose(cmap.pixels[:, 0].min(), 3.0)
    np.testing.assert_allclose(cmap.pixels[:, 0].max(), 196.0)
    np.testing.assert_allclose(cmap.project(V), cmap.pixels)


def test_fitted_axis_recovers_the_cylinder():
    V, _, _, _ = _cylinder_patch(radius=90.0, centre=(4.0, 10.0, -7.0))
    cmap = cylindrical_map(V, size_px=128)
    np.testing.assert_allclose(cmap.centre[[0, 2]], [4.0, -7.0], atol=1e-6)
    np.testing.assert_allclose(cmap.radius_mm, 90.0, rtol=1e-9)


def test_a_value_linear_in_angle_and_height_round_trips_through_the_raster():
    V, F, th, h = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=160)
    raster = cmap.rasterise(F)
    value = 3.0 * th - 0.02 * h + 1.0
    image = raster.interpolate(value, fill=np.nan)
    # the (theta, h) grid is a regular grid in the image: the image is exactly the linear field
    rows, cols = np.nonzero(raster.covered)
    theta_px = (cols - cmap.origin[0]) / (80.0 * cmap.px_per_mm)
    h_px = (cmap.origin[1] - rows) / cmap.px_per_mm
    np.testing.assert_allclose(image[rows, cols], 3.0 * theta_px - 0.02 * h_px + 1.0, atol=1e-9)
    # and bilinear look-ups at the vertices (away from the image border) give the values back
    lo, hi = cmap.pixels.min(0) + 1, cmap.pixels.max(0) - 1
    inner = np.all((cmap.pixels > lo) & (cmap.pixels < hi), axis=1)
    np.testing.assert_allclose(cmap.sample(image, cmap.pixels[inner]), value[inner], atol=1e-9)


def test_raster_covers_exactly_the_pixel_centres_inside_the_mesh():
    V, F, _, _ = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=120)
    raster = cmap.rasterise(F)
    (u0, v0), (u1, v1) = cmap.pixels.min(0), cmap.pixels.max(0)
    rows, cols = np.mgrid[0 : cmap.shape[0], 0 : cmap.shape[1]]
    inside = (cols >= u0 - 1e-9) & (cols <= u1 + 1e-9) & (rows >= v0 - 1e-9) & (rows <= v1 + 1e-9)
    np.testing.assert_array_equal(raster.covered, inside)


def test_raster_against_a_brute_force_point_in_triangle_reference():
    rng = np.random.default_rng(3)
    # a small irregular mesh: jittered grid on a flat sheet facing +z, far from the axis
    x, y = np.meshgrid(np.linspace(-20, 20, 7), np.linspace(-15, 15, 6))
    P = np.stack([x.ravel(), y.ravel()], 1) + rng.uniform(-2, 2, (42, 2))
    V = np.stack([P[:, 0], P[:, 1], 100.0 + rng.uniform(-1, 1, 42)], 1)
    a = (np.arange(5)[:, None] * 7 + np.arange(6)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + 7], 1), np.stack([a + 1, a + 8, a + 7], 1)])
    cmap = cylindrical_map(V, centre=(0.0, 0.0, 0.0), size_px=60)
    raster = cmap.rasterise(F)
    rows, cols = np.mgrid[0 : cmap.shape[0], 0 : cmap.shape[1]]
    q = np.stack([cols.ravel(), rows.ravel()], 1).astype(float)
    T = cmap.pixels[F]
    hit = np.full(q.shape[0], -1)
    for f in range(F.shape[0]):  # slow reference: every pixel against every triangle
        a0, a1, a2 = T[f]
        M = np.array([a1 - a0, a2 - a0]).T
        lam = np.linalg.solve(M, (q - a0).T).T
        inside = (lam[:, 0] >= -1e-9) & (lam[:, 1] >= -1e-9) & (lam.sum(1) <= 1 + 1e-9)
        hit[inside & (hit < 0)] = f
    np.testing.assert_array_equal(raster.covered.ravel(), hit >= 0)
    # each covered pixel's barycentric coordinates reproduce its centre in its triangle
    cov = raster.covered
    centres = np.einsum("pk,pkj->pj", raster.barycentric[cov], T[raster.face[cov]])
    np.testing.assert_allclose(centres, np.stack([cols[cov], rows[cov]], 1), atol=1e-9)
    assert raster.barycentric[cov].min() >= -1e-9


def test_overlapping_triangles_go_to_the_consistent_one_then_the_lowest_index():
    V, _, _, _ = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=64)
    # pixel positions given directly: three counter-clockwise squares' halves side by side (the majority's
    # orientation), and over the first a folded (clockwise) copy with a lower index than the ones it covers
    uv = np.array([[10.0, 10], [30, 10], [30, 30], [10, 30], [50, 10], [50, 30]])
    F = np.array([[0, 2, 1],      # 0: folded (the other orientation than the five below)
                  [0, 1, 2],      # 1: consistent, the same pixels as 0
                  [0, 1, 2],      # 2: consistent, the same again: 1 is lower and wins
                  [0, 2, 3],      # 3: consistent
                  [1, 4, 5],      # 4: consistent
                  [1, 5, 2]])     # 5: consistent
    raster = cmap.rasterise(F, pixels=uv)
    rows, cols = np.mgrid[0 : cmap.shape[0], 0 : cmap.shape[1]]
    below_diagonal = (cols >= 10) & (cols <= 30) & (rows >= 10) & (rows <= cols)  # triangle (0, 1, 2)
    assert set(np.unique(raster.face[below_diagonal])) == {1}
    # a folded triangle that nothing else covers keeps its pixels
    alone = cmap.rasterise(F[:1], pixels=uv)
    assert set(np.unique(alone.face[below_diagonal])) == {0}
    centres = np.einsum("pk,pkj->pj", raster.barycentric[raster.covered], uv[F[raster.face[raster.covered]]])
    np.testing.assert_allclose(centres, np.stack([cols[raster.covered], rows[raster.covered]], 1), atol=1e-9)


def test_pixel_to_surface_is_the_barycentric_inverse_of_surface_to_pixel():
    V, F, _, _ = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=150)
    raster = cmap.rasterise(F)
    # vertices map back to themselves
    points, found = raster.surface_points(cmap.pixels, V)
    assert found.all()
    np.testing.assert_allclose(points, V, atol=1e-9)
    # an image point with barycentric coordinates b in a triangle is the surface point b . V
    rng = np.random.default_rng(0)
    f = rng.integers(0, F.shape[0], 500)
    b = rng.dirichlet([2.0, 2.0, 2.0], 500)
    uv = np.einsum("kc,kcj->kj", b, cmap.pixels[F[f]])
    points, found = raster.surface_points(uv, V)
    assert found.all()
    np.testing.assert_allclose(points, np.einsum("kc,kcj->kj", b, V[F[f]]), atol=1e-9)
    # and those surface points project back to the same pixels up to the map's curvature over a triangle
    np.testing.assert_allclose(cmap.project(points), uv, atol=0.05)


def test_points_off_the_mesh_are_clamped_onto_it():
    V, F, _, _ = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=100)
    raster = cmap.rasterise(F)
    corner = cmap.pixels[np.argmin(cmap.pixels.sum(1))]
    face, bary, inside = raster.locate(corner[None] - 0.7)
    assert face[0] >= 0 and not inside[0]
    assert bary.min() >= 0 and np.isclose(bary.sum(), 1.0)
    far, found = raster.surface_points(np.array([[-50.0, -50.0]]), V)
    assert not found[0] and np.isnan(far).all()


def test_sample_is_bilinear_and_fills_outside():
    V, _, _, _ = _cylinder_patch()
    cmap = cylindrical_map(V, centre=(5.0, -3.0, 2.0), size_px=64)
    rows, cols = np.mgrid[0 : cmap.shape[0], 0 : cmap.shape[1]]
    image = np.stack([2.0 * cols - rows, cols * 0.5 + 7], axis=2)
    uv = np.array([[3.25, 4.5], [10.0, 20.75], [-1.0, 3.0]])
    out = cmap.sample(image, uv, fill=-9.0)
    np.testing.assert_allclose(out[:2], np.stack([2 * uv[:2, 0] - uv[:2, 1], uv[:2, 0] * 0.5 + 7], 1))
    np.testing.assert_array_equal(out[2], [-9.0, -9.0])


def test_rejects_bad_frames_and_sizes():
    V, _, _, _ = _cylinder_patch()
    with pytest.raises(InputError):
        cylindrical_map(V, axis=(0, 0, 1), forward=(0, 0, 2))
    with pytest.raises(InputError):
        cylindrical_map(V, axis=(0, 0, 0))
    with pytest.raises(InputError):
        cylindrical_map(V, size_px=4)
