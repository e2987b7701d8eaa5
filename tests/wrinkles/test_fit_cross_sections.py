"""The fit of eq. 7: profiles of known (w, d) recovered, flat ones give d = 0, and an imaged plane end to end."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.cameras import Camera, RayCaster
from facecap.errors import InputError
from facecap.synth.render_footage import sensor_noise
from facecap.wrinkles import fit_cross_sections, fit_profiles, sample_cross_sections, wedge_intensity
from facecap.wrinkles.fit_cross_sections import DEFAULT_ROUNDING

P = np.arange(-7.0, 7.0 + 1e-9, 0.1)


def _known_profiles(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.8, 3.0, n), rng.uniform(0.3, 1.2, n)


@pytest.mark.parametrize("rounding", [0.0, 2.0])
def test_noise_free_profiles_of_the_model_are_recovered_exactly(rounding: float) -> None:
    w, d = _known_profiles(150, seed=1)
    level = 0.37  # I_ambient: unknown to the fit, only the ratios matter
    Y = level * wedge_intensity(P[None, :], w[:, None], d[:, None], rounding=rounding)
    fit = fit_profiles(P, Y, rounding=rounding)
    np.testing.assert_allclose(fit.width, w, rtol=1e-6)
    np.testing.assert_allclose(fit.depth, d, rtol=1e-6)
    np.testing.assert_allclose(fit.ambient, level, rtol=1e-6)
    assert fit.has_wrinkle.all()


def _with_sensor_noise(expected: np.ndarray, *, seed: int, band: int = 9) -> np.ndarray:
    """The generator's sensor (shot + read noise at its full well), averaged over ``band`` pixels as sampled."""
    rng = np.random.default_rng(seed)
    shots = np.stack([sensor_noise(expected, rng=rng) for _ in range(band)])
    return shots.mean(axis=0)


def test_profiles_with_the_generators_sensor_noise_are_recovered_within_15_percent() -> None:
    w, d = _known_profiles(300, seed=2)
    expected = 0.3 * wedge_intensity(P[None, :], w[:, None], d[:, None], rounding=DEFAULT_ROUNDING)  # skin-like level, 0.3 of full scale
    fit = fit_profiles(P, _with_sensor_noise(expected, seed=3))
    depth_error = np.abs(fit.depth / d - 1)
    width_error = np.abs(fit.width / w - 1)
    assert np.median(depth_error) < 0.15 and np.median(width_error) < 0.15
    assert np.percentile(depth_error, 90) < 0.15  # not only the median: nearly every one
    assert fit.has_wrinkle.mean() > 0.97


def test_flat_profiles_give_no_wrinkle() -> None:
    rng = np.random.default_rng(4)
    level = rng.uniform(0.1, 0.6, 400)[:, None] * (1.0 + 0.004 * P[None, :])  # uneven large-scale shading
    fit = fit_profiles(P, _with_sensor_noise(np.broadcast_to(level, (400, P.size)).copy(), seed=5))
    assert np.all(fit.depth < 0.05)
    assert fit.has_wrinkle.mean() < 0.02


def test_fit_profiles_rejects_bad_shapes() -> None:
    with pytest.raises(InputError, match="intensity"):
        fit_profiles(P, np.ones(P.size))
    with pytest.raises(InputError, match="p:"):
        fit_profiles(P[:-1], np.ones((2, P.size)))
    with pytest.raises(InputError, match="width_range_mm"):
        fit_profiles(P, np.ones((2, P.size)), width_range_mm=(2.0, 1.0))


def _imaged_plane(w: float, d: float) -> tuple[Camera, RayCaster, np.ndarray, list[np.ndarray]]:
    """A painted straight valley along x on the plane z = 0, seen 35 degrees off its normal across the valley.

    Every pixel's intensity is computed analytically: its ray meets the plane at
    ``y`` (the distance across the valley) and the paint's albedo times eq. 6 is recorded.
    """
    eye = np.array([0.0, -500.0, 700.0])
    camera = Camera.look_at("plane", eye, [0.0, 0.0, 0.0], focal_px=6000.0, width=480, height=360)
    V = np.array([[-500.0, -500.0, 0.0], [500.0, -500.0, 0.0], [500.0, 500.0, 0.0], [-500.0, 500.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    grid = camera.pixel_grid()
    rays = camera.pixel_rays(grid.reshape(-1, 2))
    t = -rays.origins[:, 2] / rays.directions[:, 2]
    hit = rays.origins + t[:, None] * rays.directions
    y = hit[:, 1]
    paint = np.array([0.1, 0.25, 0.7])
    skin = np.array([0.7, 0.5, 0.4])
    albedo = np.where((np.abs(y) < 2.2 * w)[:, None], paint, skin)
    image = albedo * wedge_intensity(y, w, d, rounding=DEFAULT_ROUNDING)[:, None] * 0.8
    image = image.reshape(grid.shape[:2] + (3,))
    xs = np.linspace(-12.0, 12.0, 25)
    valley_px = camera.project(np.column_stack([xs, np.zeros_like(xs), np.zeros_like(xs)])).pixels
    return camera, RayCaster(V, F), image, [valley_px]


def test_an_imaged_plane_gives_the_mm_across_the_valley_and_its_shape() -> None:
    w, d = 1.6, 0.6
    camera, caster, image, splines = _imaged_plane(w, d)
    samples = sample_cross_sections(image, splines, camera, caster, spacing_px=20.0)
    assert samples.centres_px.shape[0] >= 5
    # each sample's pixel, cast back onto the plane, lies |p| from the valley line (y = 0), to the
    # linearised projection's accuracy (the scale is the Jacobian at the centre: 0.5 % off 7 mm away here)
    offsets_px = samples.p[None, :] / samples.mm_per_px[:, None]
    pixels = samples.centres_px[:, None, :] + offsets_px[..., None] * samples.normals_px[:, None, :]
    hits = caster.cast_pixels(camera, pixels.reshape(-1, 2))
    across = np.abs(hits.points[:, 1]).reshape(pixels.shape[:2])
    np.testing.assert_allclose(across, np.abs(samples.p)[None, :].repeat(len(across), 0), rtol=0.01, atol=0.01)
    # the paint ends 2.2 w from the valley: samples beyond are left out
    inside = np.abs(samples.p) < 2.2 * w - 0.3
    assert samples.valid[:, inside].all() and not samples.valid[:, np.abs(samples.p) > 2.2 * w + 0.3].any()
    result = fit_cross_sections(image, splines, camera, caster, spacing_px=20.0)
    np.testing.assert_allclose(result.width, w, rtol=0.03)
    np.testing.assert_allclose(result.depth, d, rtol=0.03)


def test_fit_cross_sections_rejects_bad_input() -> None:
    camera, caster, image, splines = _imaged_plane(1.6, 0.6)
    with pytest.raises(InputError, match="splines_px"):
        fit_cross_sections(image, [np.zeros((1, 2))], camera, caster)
    with pytest.raises(InputError, match="image"):
        fit_cross_sections(image[..., :2], splines, camera, caster)
    with pytest.raises(InputError, match="camera"):
        fit_cross_sections(image, splines, "cam", caster)
