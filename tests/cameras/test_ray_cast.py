"""Ray casting: analytic plane and sphere, the ICT face's vertices seen back through their pixels, brute-force occlusion."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.cameras import Camera, RayCaster, ray_cast
from facecap.errors import InputError, MeshError
from facecap.io.ict_sample import load_ict_sample

DISTORTION = [-0.1, 0.05, 1e-3, -5e-4, 0.01]


def _grid(n: int = 41, half: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat square z = 0, [-half, half]^2, split into 2 (n-1)^2 triangles."""
    x = np.linspace(-half, half, n)
    xx, yy = np.meshgrid(x, x)
    V = np.stack([xx.ravel(), yy.ravel(), np.zeros(n * n)], axis=1)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return V, F


def _icosphere(level: int = 4, radius: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=level, radius=radius)
    return np.asarray(sphere.vertices, dtype=np.float64), np.asarray(sphere.faces, dtype=np.int64)


def test_plane_hits_are_the_analytic_ray_plane_intersections() -> None:
    V, F = _grid()
    cam = Camera.look_at("oblique", [60.0, -80.0, 300.0], [10.0, 5.0, 0.0], focal_px=250.0, width=320, height=240,
                         distortion=DISTORTION)
    pixels = cam.pixel_grid(step=3)
    rays = cam.pixel_rays(pixels)
    hits = RayCaster(V, F).cast_pixels(cam, pixels)
    t = -rays.origins[..., 2] / rays.directions[..., 2]  # ray meets z = 0
    expected = rays.origins + t[..., None] * rays.directions
    inside = np.all(np.abs(expected[..., :2]) < 100.0 - 1e-6, axis=-1) & (t > 0)
    outside = np.any(np.abs(expected[..., :2]) > 100.0 + 1e-6, axis=-1) | (t < 0)
    assert inside.sum() > 1000 and outside.sum() > 100
    np.testing.assert_array_equal(hits.hit[inside], True)
    np.testing.assert_array_equal(hits.hit[outside], False)
    np.testing.assert_allclose(hits.points[inside], expected[inside], rtol=0, atol=1e-9)
    np.testing.assert_allclose(hits.distance[inside], t[inside], rtol=0, atol=1e-9)
    np.testing.assert_allclose(hits.normals[inside], np.broadcast_to([0, 0, 1.0], expected[inside].shape), atol=1e-12)
    corners = V[F[hits.triangle[inside]]]
    np.testing.assert_allclose(np.einsum("ki,kij->kj", hits.barycentric[inside], corners), expected[inside], atol=1e-9)
    assert (hits.barycentric[inside] >= 0).all()
    assert np.isnan(hits.points[outside]).all() and np.isinf(hits.distance[outside]).all()


def test_sphere_hits_lie_between_inscribed_and_circumscribed_spheres_and_visibility_is_the_near_cap() -> None:
    V, F = _icosphere(4, 50.0)  # 2562 vertices, edge ~ 3.9 mm: the facets sag at most ~0.1 mm
    caster = RayCaster(V, F)
    cam = Camera.look_at("c", [0.0, 40.0, 400.0], [0.0, 0.0, 0.0], focal_px=1500.0, width=400, height=400)
    hits = caster.cast_pixels(cam, cam.pixel_grid(step=4))
    radius = np.linalg.norm(hits.points[hits.hit], axis=1)
    assert hits.hit.sum() > 1000
    assert radius.max() <= 50.0 + 1e-9 and radius.min() > 49.8
    # a rays that hits must pass within 50 mm of the centre; one that misses the inscribed sphere must not hit
    rays = cam.pixel_rays(cam.pixel_grid(step=4))
    along = -np.einsum("...j,...j->...", rays.origins, rays.directions)
    closest = np.linalg.norm(rays.origins + along[..., None] * rays.directions, axis=-1)
    assert (closest[hits.hit] <= 50.0 + 1e-9).all()
    assert hits.hit[closest < 49.8].all()
    # a convex surface: a vertex is seen iff it faces the camera (away from the silhouette band)
    facing = np.einsum("ij,ij->i", V / 50.0, (cam.centre - V) / np.linalg.norm(cam.centre - V, axis=1)[:, None])
    visible = caster.visible_vertices(cam)
    clear = np.abs(facing) > 0.05
    np.testing.assert_array_equal(visible[clear], facing[clear] > 0)


def _grazing(V: np.ndarray, F: np.ndarray, cam: Camera) -> np.ndarray:
    """Vertices seen at grazing incidence (|cos| < 0.05): there float32 rounding decides, so they are left out."""
    import igl

    normals = igl.per_vertex_normals(V, F)
    view = (V - cam.centre) / np.linalg.norm(V - cam.centre, axis=1)[:, None]
    return np.abs(np.einsum("ij,ij->i", normals, view)) < 0.05


def _ict_camera() -> Camera:
    return Camera.look_at("front", [150.0, 40.0, 700.0], [0.0, 0.0, 60.0], focal_px=2400.0, width=1384,
                          height=1038, distortion=DISTORTION)


def test_pixels_of_visible_ict_vertices_see_those_vertices() -> None:
    mesh = load_ict_sample().mesh
    cam = _ict_camera()
    caster = RayCaster(mesh.vertices, mesh.faces)
    visible = caster.visible_vertices(cam)
    assert 4000 < visible.sum() < mesh.n_vertices  # the face is seen, the back of the head is not
    pixels = cam.project(mesh.vertices[visible]).pixels
    hits = caster.cast_pixels(cam, pixels, robust=True)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.points, mesh.vertices[visible], rtol=0, atol=1e-6)
    # the triangle hit has the vertex as a corner, with (almost) all the weight
    corner = mesh.faces[hits.triangle] == np.flatnonzero(visible)[:, None]
    assert corner.any(axis=1).all()
    assert (hits.barycentric[corner] > 1 - 1e-6).all()
    # hidden vertices inside the image: the pixel sees a surface in front of them
    hidden = ~visible & cam.project(mesh.vertices).in_image & ~_grazing(mesh.vertices, mesh.faces, cam)
    seen = caster.cast_pixels(cam, cam.project(mesh.vertices[hidden]).pixels, robust=True)
    distance = np.linalg.norm(mesh.vertices[hidden] - cam.centre, axis=1)
    assert (seen.distance < distance - 0.01).all()


def _occluded_brute_force(V: np.ndarray, F: np.ndarray, origin: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Nearest triangle crossing along each origin->target segment, by testing every triangle (float64)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = b - a, c - a
    s = origin - a
    nearest = np.empty(len(targets))
    for i, target in enumerate(targets):
        d = target - origin
        length = np.linalg.norm(d)
        d = d / length
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("ij,ij->i", s, p) / det
            q = np.cross(s, e1)
            v = (q @ d) / det
            t = np.einsum("ij,ij->i", e2, q) / det
        ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        nearest[i] = length - (t[ok].min() if ok.any() else np.inf)
    return nearest  # > 0: a surface this far in front of the target


def test_visible_vertices_match_brute_force_occlusion() -> None:
    mesh = load_ict_sample().mesh
    cam = _ict_camera()
    rng = np.random.default_rng(5)
    inside = np.flatnonzero(cam.project(mesh.vertices).in_image & ~_grazing(mesh.vertices, mesh.faces, cam))
    sample = rng.choice(inside, 400, replace=False)
    gap = _occluded_brute_force(mesh.vertices, mesh.faces, cam.centre, mesh.vertices[sample])
    visible = RayCaster(mesh.vertices, mesh.faces).visible(mesh.vertices[sample], cam)
    clear = (gap < 0.005) | (gap > 0.05)  # away from the 0.01 mm tolerance
    assert clear.sum() > 380 and (gap > 0.05).sum() > 50
    np.testing.assert_array_equal(visible[clear], gap[clear] < 0.005)


def test_ray_cast_one_shot_shapes_and_validation() -> None:
    V, F = _grid(3, 1.0)
    hits = ray_cast(V, F, [0.2, 0.3, 1.0], np.tile([0.0, 0.0, -2.0], (2, 4, 1)))
    assert hits.triangle.shape == (2, 4) and hits.points.shape == (2, 4, 3)
    np.testing.assert_allclose(hits.points, np.broadcast_to([0.2, 0.3, 0.0], (2, 4, 3)), atol=1e-12)
    np.testing.assert_allclose(hits.distance, 1.0)
    with pytest.raises(InputError, match="zero length"):
        ray_cast(V, F, [0, 0, 1.0], [[0.0, 0.0, 0.0]])
    with pytest.raises(InputError, match="does not broadcast"):
        ray_cast(V, F, np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(MeshError, match="out of range"):
        RayCaster(V, F + 100)


def test_lit_finds_the_shadow_a_plate_casts_from_each_kind_of_light():
    from facecap.cameras import Light

    # a 20 x 20 mm plate at z = 50 over points on the plane z = 0; brute force: the segment to the light
    # crosses the plate's square
    plate_V = np.array([[-10.0, -10.0, 50.0], [10.0, -10.0, 50.0], [10.0, 10.0, 50.0], [-10.0, 10.0, 50.0]])
    plate_F = np.array([[0, 1, 2], [0, 2, 3]])
    caster = RayCaster(plate_V, plate_F)
    g = np.linspace(-40.0, 40.0, 33)
    P = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    P = np.hstack([P, np.zeros((P.shape[0], 1))])
    for light in (Light("point", position=[5.0, 0.0, 200.0]), Light("directional", direction=[-0.2, 0.1, -1.0]),
                  Light("spot", position=[0.0, 5.0, 300.0], direction=[0.0, 0.0, -1.0], cone_deg=40.0)):
        to_light, _ = light.arriving(P)
        s = (50.0 - P[:, 2]) / to_light[:, 2]
        crossing = P + s[:, None] * to_light
        expected = ~((np.abs(crossing[:, 0]) < 10.0) & (np.abs(crossing[:, 1]) < 10.0))
        lit = caster.lit(P, light, normals=np.tile([0.0, 0.0, 1.0], (P.shape[0], 1)))
        near_edge = (np.abs(np.abs(crossing[:, 0]) - 10.0) < 1e-3) | (np.abs(np.abs(crossing[:, 1]) - 10.0) < 1e-3)
        np.testing.assert_array_equal(lit[~near_edge], expected[~near_edge])
        assert (~expected).sum() > 10  # the test sees a shadow
    # a light between the point and the plate is not shadowed by the plate
    assert caster.lit([[0.0, 0.0, 0.0]], Light("point", position=[0.0, 0.0, 20.0]))[0]
