"""Tests for facecap/cameras/calibrate_light.py: a light recovered from a rendered chrome sphere (round trips)."""

import numpy as np
import pytest

from facecap.cameras import Light
from facecap.cameras.calibrate_light import LightCalibrationError, calibrate_light
from facecap.errors import InputError
from facecap.synth.mirror_sphere import render_mirror_sphere
from mirror_sphere_stage import SPHERE_RADIUS_MM, stage

# The rendered highlight's centroid is within 0.13 px of the mirror point of the bulb's centre on eight random
# stages (noise, saturation, 8-bit sRGB), so 0.15 px is the honest per-image error for the uncertainty here.
HIGHLIGHT_SIGMA_PX = 0.15


def _footage(st, *, n=None, light=None, seed=0):
    rng = np.random.default_rng(seed)
    frames = [[] for _ in st.cameras]
    for centre in st.positions[:n]:
        for k, image in enumerate(render_mirror_sphere(st.cameras, centre, SPHERE_RADIUS_MM, light or st.light,
                                                       rng=rng)):
            frames[k].append(image)
    return frames


def test_a_point_light_from_five_sphere_positions():
    st = stage(1)
    result = calibrate_light(_footage(st), st.cameras, SPHERE_RADIUS_MM, highlight_sigma_px=HIGHLIGHT_SIGMA_PX)
    assert result.light.kind == "point" and not result.weak
    # the sphere: a fraction of a millimetre (0.05-0.09 mm seen on eight stages: the rim's shading)
    assert np.linalg.norm(result.sphere_centres - st.positions, axis=1).max() < 0.15
    # the light: each component of the error, along the covariance's axes, within three of its sigmas; the depth
    # axis is the weak one (tens of mm at 1.1 m), the two across it a few mm
    error = result.light.position - st.light.position
    values, axes = np.linalg.eigh(result.covariance_mm2)
    assert np.all(np.abs(axes.T @ error) < 3 * np.sqrt(values))
    assert np.sqrt(values[:2]).max() < 4.0 and np.sqrt(values[2]) < 60.0
    assert np.linalg.norm(error) < 0.03 * np.linalg.norm(st.light.position)
    assert result.ray_distances_mm.shape == (10,) and result.spread_deg > 5
    np.testing.assert_allclose(result.sigma_mm, np.sqrt(values[::-1]))


def test_one_position_gives_a_direction_and_says_why():
    # rays from one sphere start millimetres apart: a light 1.1 m away has no measurable distance
    st = stage(1)
    result = calibrate_light(_footage(st, n=1), st.cameras, SPHERE_RADIUS_MM)
    assert result.light.kind == "directional" and "uncertain" in result.weak
    towards = st.light.position - st.positions[0]
    angle = np.degrees(np.arccos(-result.light.direction @ towards / np.linalg.norm(towards)))
    assert angle < 1.0  # the two mirror points' parallax to the bulb, about 0.7-1.1 deg on eight stages


def test_a_far_light_is_recovered_as_a_direction():
    st = stage(4, light_kind="directional")
    result = calibrate_light(_footage(st, n=3), st.cameras, SPHERE_RADIUS_MM, highlight_sigma_px=HIGHLIGHT_SIGMA_PX)
    assert result.light.kind == "directional" and result.weak
    angle = np.degrees(np.arccos(np.clip(result.light.direction @ st.light.direction, -1, 1)))
    assert angle < max(3 * result.direction_sigma_deg, 0.05)
    assert result.spread_deg < 1.0  # the rays differ by the highlights' errors only (the sun is 1 deg across)


def test_bad_images_name_the_camera_and_frame():
    st = stage(2, n_positions=2)
    frames = _footage(st)
    dark = [[np.zeros_like(frames[0][0])] * 2, frames[1]]
    with pytest.raises(LightCalibrationError, match="camera 'cam0', frame 0: no sphere found") as caught:
        calibrate_light(dark, st.cameras, SPHERE_RADIUS_MM)
    assert caught.value.camera == 0 and caught.value.frame == 0
    away = Light("spot", position=st.light.position, direction=st.light.position, cone_deg=20)
    with pytest.raises(LightCalibrationError, match="frame 0: no highlight on the sphere"):
        calibrate_light(_footage(st, light=away), st.cameras, SPHERE_RADIUS_MM)
    cut = [[f[:, 300:] for f in frames[0]], frames[1]]
    with pytest.raises(InputError, match="calibrated for 640x480"):
        calibrate_light(cut, st.cameras, SPHERE_RADIUS_MM)
    shifted = [[np.roll(f, 300, axis=1) for f in frames[0]], frames[1]]
    with pytest.raises(LightCalibrationError, match="(edge|no sphere)"):
        calibrate_light(shifted, st.cameras, SPHERE_RADIUS_MM)
    with pytest.raises(InputError, match="frame counts differ"):
        calibrate_light([frames[0][:1], frames[1]], st.cameras, SPHERE_RADIUS_MM)
    with pytest.raises(InputError, match="sphere_radius_mm"):
        calibrate_light(frames, st.cameras, -1.0)
