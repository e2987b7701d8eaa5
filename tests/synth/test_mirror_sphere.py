"""Tests for facecap/synth/mirror_sphere.py: the chrome sphere's picture against closed forms."""

import numpy as np
import pytest

from facecap.cameras import Camera, Light
from facecap.errors import InputError
from facecap.synth.mirror_sphere import render_mirror_sphere
from mirror_sphere_stage import SPHERE_RADIUS_MM, mirror_point, stage


def _highlight_centroid(image):
    """The bright spot's centroid over the sphere around it, in a 15 px window about the brightest pixel."""
    grey = image.astype(np.float64).mean(axis=2)
    row, col = np.unravel_index(np.argmax(grey), grey.shape)
    window = grey[row - 7:row + 8, col - 7:col + 8]
    ring = np.concatenate([window[0], window[-1], window[:, 0], window[:, -1]])
    base = np.median(ring)
    weights = np.clip(window - base - 0.1 * (window.max() - base), 0, None)
    v, u = np.nonzero(weights)
    centroid = np.array([(u * weights[v, u]).sum(), (v * weights[v, u]).sum()]) / weights[v, u].sum()
    return centroid + [col - 7, row - 7]


def test_the_highlight_is_where_the_mirror_law_puts_it():
    # the sun (a 0.5 degree disc) unsaturated, 16-bit linear, no noise: its reflection, blurred by the lens into a
    # compact spot, is centred on the mirror point of the sun's direction (Alhazen's problem with the light far
    # away, solved independently) to a small fraction of a pixel, lens distortion included
    st = stage(3, light_kind="directional")
    far = -st.light.direction * 1e9
    for centre in st.positions[:3]:
        images = render_mirror_sphere(st.cameras, centre, SPHERE_RADIUS_MM, st.light, bulb_radiance=12.0, bits=16,
                                      supersample=8)
        for camera, image in zip(st.cameras, images):
            assert image.max() < 65535
            expected = camera.project(mirror_point(centre, SPHERE_RADIUS_MM, camera.centre, far))
            assert np.linalg.norm(_highlight_centroid(image) - expected.pixels) < 0.05


def test_the_outline_is_the_spheres_projection():
    # one sample a pixel, no blur: a pixel shows the sphere exactly when its centre's ray meets it; on the optical
    # axis the outline is the circle of radius f tan(a), sin(a) = r / D, about the principal point
    camera = Camera.look_at("c", [0.0, 0.0, 700.0], [0.0, 0.0, 0.0], focal_px=1000, width=320, height=240)
    image, = render_mirror_sphere([camera], [0.0, 0.0, 0.0], 30.0, Light("directional", direction=[0, 0, 1]),
                                  background=0.0, bits=16, blur_px=0.0, supersample=1)
    sin_a = 30.0 / 700.0
    radius_px = 1000.0 * sin_a / np.sqrt(1 - sin_a ** 2)
    u, v = np.meshgrid(np.arange(320) - 159.5, np.arange(240) - 119.5)
    distance = np.hypot(u, v)
    clear = np.abs(distance - radius_px) > 1e-6
    assert np.array_equal((image[..., 0] > 0)[clear], (distance < radius_px)[clear])


def test_noise_bits_and_errors():
    st = stage(1, n_positions=1)
    a = render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, st.light, rng=np.random.default_rng(0))
    b = render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, st.light, rng=np.random.default_rng(0))
    assert all(x.dtype == np.uint8 and x.shape == (480, 640, 3) and np.array_equal(x, y) for x, y in zip(a, b))
    c = render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, st.light, bits=16)
    assert c[0].dtype == np.uint16 and c[0].max() == 65535  # the bulb saturates, as on a stage
    with pytest.raises(InputError, match="bits"):
        render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, st.light, bits=12)
    with pytest.raises(InputError, match="in front"):
        render_mirror_sphere(st.cameras, st.cameras[0].centre, SPHERE_RADIUS_MM, st.light)


def test_a_spot_is_seen_only_from_inside_its_cone():
    st = stage(2, n_positions=1)
    towards_face = -st.light.position / np.linalg.norm(st.light.position)
    aimed = Light("spot", position=st.light.position, direction=towards_face, cone_deg=20)
    away = Light("spot", position=st.light.position, direction=-towards_face, cone_deg=20)
    lit = render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, aimed)
    dark = render_mirror_sphere(st.cameras, st.positions[0], SPHERE_RADIUS_MM, away)
    assert all(x.max() == 255 for x in lit) and all(x.max() < 200 for x in dark)
