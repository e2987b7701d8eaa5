"""The skin's albedo baked into a face's own UV atlas, and the textured neutral scan a studio holds.

:func:`~facecap.synth.skin_albedo.skin_albedo` gives the colour of a material point; evaluating it
(with pores) at every texel of every generated scan would take 10-20 s a scan. The albedo is baked
once per identity into the rest surface's UV atlas at about 0.15 mm a texel (2048 x 2048 on the
bundled ICT face), and every texture made of that skin reads it there: the scans' textures
(:func:`~facecap.synth.scan_expression.scan_expression`) and the neutral's
(:func:`textured_neutral`). A point of skin keeps its colour in every scan, to within the
bilinear lookup.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..io.write_gltf import triangle_corners
from ..mesh.surface_colors import sample_image
from ..mesh.uv_raster import UVRaster
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from .capture_colors import capture_colors
from .skin_albedo import SkinRegions, skin_albedo_layers

__all__ = ["SkinTexture", "bake_skin_albedo", "textured_neutral", "DEFAULT_ALBEDO_TEXELS"]

DEFAULT_ALBEDO_TEXELS = 2048
"""Width and height of the baked albedo (0.145 mm a texel, median, on the bundled ICT face)."""


class SkinTexture:
    """A linear-light albedo over a rest surface's UV atlas (:func:`bake_skin_albedo`).

    Attributes
    ----------
    image : (size, size, 3) float32 array
        Linear RGB reflectance, row 0 the atlas's top (``v = 1``), padded past the islands' edges.
    uv_triangles : (m, 3) int64 array
        Each triangle's corners as indices into ``uvs``.
    uvs : (u, 2) float64 array
        The rest surface's texture coordinates (OBJ convention).
    """

    def __init__(self, image: FloatArray, uvs: FloatArray, uv_triangles: IntArray) -> None:
        self.image = image
        self.uvs = uvs
        self.uv_triangles = uv_triangles

    def albedo_at(self, triangles: IntArray, barycentric: FloatArray) -> FloatArray:
        """(k, 3) albedo at points of the rest surface given by triangle and barycentric coordinates."""
        uv = np.einsum("kc,kcd->kd", barycentric, self.uvs[self.uv_triangles[triangles]])
        return sample_image(self.image, uv)


def bake_skin_albedo(
    rest: Mesh,
    *,
    seed: int,
    region: SkinRegions | None = None,
    size: int = DEFAULT_ALBEDO_TEXELS,
    pores: bool = True,
) -> SkinTexture:
    """Bake :func:`~facecap.synth.skin_albedo.skin_albedo_layers` into the rest surface's UV atlas.

    Parameters
    ----------
    rest : Mesh
        The identity's rest (neutral) surface, with UVs: its points are the material points.
    seed : int
        The skin's seed (as :func:`~facecap.synth.skin_albedo.skin_albedo`).
    region : SkinRegions or None, optional
        Brows and lips, ``labels`` per vertex of ``rest`` (a texel takes the label of its
        triangle's nearest corner).
    size : int, default 2048
        The texture's width and height in texels.
    pores : bool, default True
        Pores and fine texture (``skin_albedo_layers(pores=True)``): what a scan's texture resolves.

    Returns
    -------
    SkinTexture

    Raises
    ------
    InputError
        If ``rest`` has no UVs.
    """
    if rest.uvs is None or rest.uv_indices is None:
        raise InputError("rest: the rest surface needs UVs to bake a texture into", path=rest.source_path)
    uv_triangles = np.asarray(rest.uv_indices, dtype=np.int64)[triangle_corners(rest)]
    raster = UVRaster(rest.uvs, uv_triangles, int(size), padding=4)
    tri = raster.triangle[raster.covered]
    w = raster.weights[raster.covered]
    points = np.einsum("kc,kcd->kd", w, rest.vertices[rest.faces[tri]])
    texel_region = None
    if region is not None:
        labels = np.asarray(region.labels, dtype=np.int64).reshape(-1)
        if labels.shape[0] != rest.n_vertices:
            raise InputError(f"region.labels: expected one label per vertex ({rest.n_vertices}), got {labels.shape[0]}")
        corner = rest.faces[tri, np.argmax(w, axis=1)]
        texel_region = SkinRegions(labels[corner], tuple(region.names), region.lip_outline)
    albedo = skin_albedo_layers(points, seed=seed, region=texel_region, pores=pores).albedo
    flat = np.zeros((raster.size * raster.size, 3), dtype=np.float32)
    flat[raster.covered] = albedo
    flat[raster.pad_target] = flat[raster.pad_source]
    return SkinTexture(flat.reshape(raster.size, raster.size, 3), np.asarray(rest.uvs, dtype=np.float64),
                       uv_triangles)


def textured_neutral(rest: Mesh, skin: SkinTexture, *, seed: int, noise: float = 0.01) -> Mesh:
    """The rest surface with the texture a scanner's camera records of ``skin`` in its own atlas.

    The albedo (linear) times one capture's exposure and smooth shading, plus sensor noise
    (:func:`~facecap.synth.capture_colors.capture_colors`), sRGB-encoded to 8 bits.
    """
    size = skin.image.shape[0]
    raster = UVRaster(skin.uvs, skin.uv_triangles, size, padding=4)
    inside = raster.covered
    albedo = skin.image.reshape(-1, 3)[inside].astype(np.float64)
    points = np.einsum("kc,kcd->kd", raster.weights[inside], rest.vertices[rest.faces[raster.triangle[inside]]])
    flat = np.zeros((size * size, 3))
    flat[inside] = capture_colors(albedo, points, seed=seed, noise=noise)
    flat[raster.pad_target] = flat[raster.pad_source]
    image = np.round(flat.reshape(size, size, 3) * 255.0).astype(np.uint8)
    return replace(rest, texture=image, vertex_colors=None)

