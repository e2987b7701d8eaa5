"""shade_skin: Phong against its closed form on a lit plate (rendered), cast shadows leave only the ambient, the
independent microfacet skin is another model."""

import numpy as np
import pytest

from facecap.cameras import Camera, Light, LightSetup, RayCaster
from facecap.errors import InputError
from facecap.synth.render_footage import FootageRenderer
from facecap.synth.shade_skin import Shading, region_reflectance, shade_skin, skin_radiance, subsurface_blur


def _plate(half=60.0, n=31, z=0.0):
    x, y = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n))
    V = np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([q, q + 1, q + n + 1], 1), np.stack([q, q + n + 1, q + n], 1)])
    return V, F  # normals +z


def test_a_rendered_pixel_of_a_flat_lit_plate_is_the_closed_form_phong_value():
    V, F = _plate()
    light = Light("directional", intensity=0.7, direction=[-0.3, 0.2, -1.0])
    lights = LightSetup([light], ambient=0.05)
    eye = np.array([10.0, -20.0, 500.0])
    # a camera at ``eye`` looking down -z at the plate's centre (OpenCV: x right, y down, z forward)
    R = np.diag([1.0, -1.0, -1.0])
    cam = Camera("top", K=np.array([[400.0, 0, 31.5], [0, 400.0, 31.5], [0, 0, 1]]), distortion=np.zeros(5),
                 width=64, height=64, R=R, T=-R @ eye)
    albedo = np.tile([0.5, 0.4, 0.3], (len(V), 1))
    refl = np.tile([1.0, 0.3, 20.0], (len(V), 1))
    N = np.tile([0.0, 0.0, 1.0], (len(V), 1))
    shading = shade_skin(V, N, refl, lights, eye[None], appearance="phong")
    radiance = skin_radiance(shading, albedo, refl)[0]
    # closed form at the point the centre pixel sees, (10, -20, 0) on the ray through the principal point
    P = cam.pixel_rays(np.array([[31.5, 31.5]])).origins[0] + 500.0 * cam.pixel_rays(np.array([[31.5, 31.5]])).directions[0]
    l = -light.direction
    n = np.array([0.0, 0.0, 1.0])
    r = 2 * (n @ l) * n - l
    e = (eye - P) / np.linalg.norm(eye - P)
    expected = albedo[0] * (0.05 + 0.7 * (n @ l)) + 0.3 * 0.7 * max(r @ e, 0.0) ** 20
    renderer = FootageRenderer(F, [cam])
    try:
        image = renderer.render(V, radiance[None])[0]
    finally:
        renderer.close()
    # the radiance is interpolated linearly over triangles 4 mm wide; the specular lobe is smooth at that scale
    np.testing.assert_allclose(image[31:33, 31:33].reshape(-1, 3).mean(axis=0), expected, rtol=2e-3)


def test_a_vertex_in_a_cast_shadow_gets_only_the_ambient():
    V, F = _plate()
    W, G = _plate(half=15.0, n=4, z=30.0)  # an occluder above the middle
    V_all = np.concatenate([V, W])
    F_all = np.concatenate([F, G + len(V)])
    light = Light("point", intensity=1.0, position=[0.0, 0.0, 400.0])
    lights = LightSetup([light], ambient=0.07)
    N = np.tile([0.0, 0.0, 1.0], (len(V_all), 1))
    lit = RayCaster(V_all, F_all).lit(V_all, light, normals=N)[None]
    occlusion = np.linspace(0.5, 1.0, len(V_all))
    refl = np.tile([1.0, 0.4, 10.0], (len(V_all), 1))
    shading = shade_skin(V_all, N, refl, lights, np.array([[0.0, 0.0, 400.0]]), lit=lit, occlusion=occlusion)
    centre = np.argmin(np.linalg.norm(V[:, :2], axis=1))
    assert not lit[0, centre] and lit[0, 0]
    np.testing.assert_allclose(shading.irradiance[centre], 0.07 * occlusion[centre])
    assert shading.specular[0, centre] == 0.0
    # a lit corner gets the ambient plus the light's cosine-weighted irradiance
    to_light, E = light.arriving(V[:1])
    np.testing.assert_allclose(shading.irradiance[0], 0.07 * occlusion[0] + E[0] * to_light[0, 2])


def test_the_specular_follows_the_eye_and_the_independent_skin_is_another_model():
    P = np.zeros((1, 3))
    N = np.array([[0.0, 0.0, 1.0]])
    lights = LightSetup([Light("directional", intensity=1.0, direction=[-1.0, 0.0, -1.0])], ambient=0.0)
    mirror, off = np.array([[-1000.0, 0.0, 1000.0]]), np.array([[1000.0, 0.0, 1000.0]])  # the light is at +x
    for appearance in ("phong", "independent"):
        refl = region_reflectance(np.array([0]), ("forehead",), appearance=appearance)
        s = shade_skin(P, N, refl, lights, np.concatenate([mirror, off]), appearance=appearance)
        assert s.specular[0, 0] > 20 * s.specular[1, 0]
    phong = shade_skin(P, N, region_reflectance([0], ("forehead",)), lights, mirror)
    ggx = shade_skin(P, N, region_reflectance([0], ("forehead",), appearance="independent"), lights, mirror,
                     appearance="independent")
    # the wrapped diffuse lights a surface past the terminator, red furthest; Phong's does not
    behind = LightSetup([Light("directional", intensity=1.0, direction=[-1.0, 0.0, 0.1])], ambient=0.0)
    s = shade_skin(P, N, region_reflectance([0], ("forehead",), appearance="independent"), behind, mirror,
                   appearance="independent")
    assert s.irradiance[0, 0] > s.irradiance[0, 1] > s.irradiance[0, 2] > 0.0
    assert shade_skin(P, N, region_reflectance([0], ("forehead",)), behind, mirror).irradiance[0, 0] == 0.0
    assert not np.isclose(phong.specular[0, 0], ggx.specular[0, 0])


def test_region_reflectance_is_oilier_on_the_t_zone_and_the_blur_keeps_a_constant():
    names = ("forehead", "brows", "eyes", "nose", "cheeks", "mouth", "chin_jaw", "other")
    R = region_reflectance(np.arange(8), names)
    assert R[0, 1] > R[4, 1] and R[3, 1] > R[4, 1] and R[0, 2] > R[4, 2] and R[3, 2] > R[4, 2]
    with pytest.raises(InputError, match="appearance"):
        region_reflectance([0], names, appearance="lambert")
    V, F = _plate(n=6)
    flat = np.full((len(V), 3), 0.4)
    np.testing.assert_allclose(subsurface_blur(flat, F), flat)
    spike = np.zeros((len(V), 3))
    spike[14] = 1.0
    blurred = subsurface_blur(spike, F)
    spread = ((V[:, :2] - V[14, :2]) ** 2).sum(axis=1) @ (blurred / blurred.sum(axis=0))  # red spreads furthest
    assert spread[0] > spread[1] > spread[2] > 0.0
    assert isinstance(Shading(flat, np.zeros((1, len(V)))), tuple)
