"""The skin baked into the rest surface's atlas, and the colour textures of generated scans."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.cameras import srgb_to_linear
from facecap.io.ict_sample import load_ict_sample
from facecap.io.write_gltf import triangle_corners
from facecap.mesh import surface_colors, texel_size_mm
from facecap.synth import SkinTexture, bake_skin_albedo, scan_expression, skin_albedo, textured_neutral


@pytest.fixture(scope="module")
def face():
    return load_ict_sample().mesh


def test_the_baked_albedo_is_the_skin_at_each_material_point(face):
    skin = bake_skin_albedo(face, seed=4, size=384, pores=False)
    # at each vertex (a triangle corner), the lookup against the solid texture evaluated there
    tri = np.repeat(np.arange(face.n_faces), 3)
    bary = np.tile(np.eye(3), (face.n_faces, 1))
    looked_up = skin.albedo_at(tri, bary)
    truth = skin_albedo(face.vertices, seed=4)[face.faces.ravel()]
    error = np.abs(looked_up - truth).max(axis=1)
    # 0.77 mm texels: the smooth skin within a few per cent of its value, freckle edges aside
    assert np.median(error) < 0.005 and np.percentile(error, 90) < 0.02, (np.median(error), np.percentile(error, 90))


def _analytic_skin(face) -> SkinTexture:
    """An albedo that is a known function of UV (:func:`_albedo_of_uv`), not the package's skin."""
    size = 256
    rows, cols = np.mgrid[0:size, 0:size]
    u = (cols + 0.5) / size
    v = 1.0 - (rows + 0.5) / size
    image = np.stack([_albedo_of_uv(np.stack([u, v], -1).reshape(-1, 2)).reshape(size, size)] * 3, axis=2)
    return SkinTexture(image.astype(np.float32), face.uvs, np.asarray(face.uv_indices)[triangle_corners(face)])


def _albedo_of_uv(uv):
    """Stripes across u and a ramp along v: a v flip or a u/v swap shows."""
    return 0.3 + 0.15 * np.sin(2 * np.pi * 6 * uv[:, 0]) + 0.2 * uv[:, 1]



def test_a_scans_texture_shows_the_skin_at_each_vertex_in_its_own_atlas(face):
    skin = _analytic_skin(face)
    scanned = scan_expression(face.vertices, face.faces, target_vertices=10000, seed=3, skin_texture=skin,
                              noise_mm=0.0)
    mesh = scanned.mesh
    assert mesh.texture is not None and mesh.vertex_colors is None
    assert 0.18 < texel_size_mm(mesh) < 0.4
    # the colour at each scan vertex (its own UVs, its own atlas) against the albedo at its material point
    material_uv = np.einsum("kc,kcd->kd", scanned.barycentric,
                            face.uvs[np.asarray(face.uv_indices)[triangle_corners(face)][scanned.source_faces]])
    albedo = _albedo_of_uv(material_uv)
    corner = np.zeros(mesh.n_vertices, dtype=np.int64)
    corner[mesh.faces.ravel()] = np.arange(mesh.faces.size)
    tri, k = np.divmod(corner, 3)
    recorded = srgb_to_linear(surface_colors(mesh, tri, np.eye(3)[k]))[:, 1]
    # exposure and smooth shading scale it (within 0.85-1.15 and 8 %), sensor noise adds 0.01
    ratio = recorded / albedo
    assert 0.7 < np.median(ratio) < 1.3
    assert np.corrcoef(recorded, albedo)[0, 1] > 0.97


def test_the_textured_neutral_carries_the_skin_in_the_rest_surfaces_own_atlas(face):
    skin = _analytic_skin(face)
    neutral = textured_neutral(face, skin, seed=1, noise=0.0)
    assert neutral.texture.shape == (256, 256, 3) and np.array_equal(neutral.vertices, face.vertices)
    tri = np.arange(face.n_faces)
    centre = np.full((face.n_faces, 3), 1.0 / 3.0)
    uv = np.einsum("kc,kcd->kd", centre, face.uvs[np.asarray(face.uv_indices)[triangle_corners(face)]])
    albedo = _albedo_of_uv(uv)
    recorded = srgb_to_linear(surface_colors(neutral, tri, centre))[:, 0]
    assert np.corrcoef(recorded, albedo)[0, 1] > 0.97
