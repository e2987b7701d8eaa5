"""Lights: the direction and irradiance each kind sends, against closed forms."""

import numpy as np
import pytest

from facecap.cameras import Light
from facecap.errors import InputError


def test_point_light_falls_off_with_the_inverse_square_of_the_distance():
    light = Light("point", intensity=2.0, position=[100.0, -50.0, 900.0])
    rng = np.random.default_rng(0)
    X = rng.normal(scale=80.0, size=(50, 3))
    to_light, irradiance = light.arriving(X)
    offset = light.position - X
    d = np.linalg.norm(offset, axis=1)
    np.testing.assert_allclose(to_light, offset / d[:, None], atol=1e-15)
    np.testing.assert_allclose(irradiance, 2.0 * (1000.0 / d) ** 2, rtol=1e-14)


def test_directional_light_is_the_same_everywhere():
    light = Light("directional", intensity=0.3, direction=[0.0, 0.0, -2.0])
    to_light, irradiance = light.arriving(np.zeros((4, 3)) + [[0, 0, 0], [1e4, 0, 0], [0, -5, 3], [7, 7, 7]])
    np.testing.assert_array_equal(to_light, np.tile([0.0, 0.0, 1.0], (4, 1)))
    np.testing.assert_array_equal(irradiance, 0.3)
    assert np.all(np.isinf(light.distance_to(np.zeros((2, 3)))))


def test_spot_profile_is_full_inside_the_cone_smooth_across_the_penumbra_and_zero_outside():
    light = Light("spot", position=[0.0, 0.0, 1000.0], direction=[0.0, 0.0, -1.0], cone_deg=20.0, penumbra_deg=6.0)
    angles = np.radians([0.0, 10.0, 13.99, 17.0, 20.0, 25.0])
    outgoing = np.stack([np.zeros_like(angles), np.sin(angles), -np.cos(angles)], axis=1)
    profile = light.cone_profile(outgoing)
    s = (20.0 - 17.0) / 6.0
    np.testing.assert_allclose(profile, [1.0, 1.0, 1.0, s * s * (3 - 2 * s), 0.0, 0.0], atol=1e-9)
    # on the axis the spot is the point light
    _, on_axis = light.arriving([[0.0, 0.0, 500.0]])
    np.testing.assert_allclose(on_axis, [4.0])


@pytest.mark.parametrize("kwargs, message", [
    (dict(kind="lamp"), "type"),
    (dict(kind="point"), "position"),
    (dict(kind="point", position=[0, 0, np.nan]), "position"),
    (dict(kind="spot", position=[0, 0, 0], direction=[0, 0, 1]), "cone_deg"),
    (dict(kind="spot", position=[0, 0, 0], direction=[0, 0, 1], cone_deg=120), "cone_deg"),
    (dict(kind="directional", direction=[0, 0, 0]), "non-zero"),
    (dict(kind="point", position=[0, 0, 0], intensity=-1), "intensity"),
])
def test_malformed_lights_are_refused(kwargs, message):
    with pytest.raises(InputError, match=message):
        Light(**kwargs)


def test_a_moved_light_is_displaced_and_rescaled():
    light = Light("point", intensity=1.0, position=[0.0, 0.0, 1000.0])
    off = light.moved(offset_mm=[30.0, 0.0, 0.0], intensity_scale=1.2)
    np.testing.assert_array_equal(off.position, [30.0, 0.0, 1000.0])
    assert off.intensity == pytest.approx(1.2)
