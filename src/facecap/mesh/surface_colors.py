"""The colour of a mesh at points on its surface: from its texture where it has one, else its vertices."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..io.write_gltf import triangle_corners
from ..structures import Mesh
from ..typing import FloatArray

__all__ = ["surface_colors", "texel_size_mm", "has_colors", "sample_image"]


def has_colors(mesh: Mesh) -> bool:
    """Whether :func:`surface_colors` can colour ``mesh``: a texture with UVs, or vertex colours."""
    return mesh.texture is not None or mesh.vertex_colors is not None


def surface_colors(mesh: Mesh, triangles: Any, barycentric: Any) -> FloatArray:
    """sRGB-encoded colours in [0, 1] at points given by triangle and barycentric coordinates.

    Parameters
    ----------
    mesh : Mesh
        With a ``texture`` (sampled bilinearly at the points' UVs, wrapping as OBJ and glTF do)
        or ``vertex_colors`` (interpolated).
    triangles : (k,) int array
        Index into ``mesh.faces`` of the triangle holding each point.
    barycentric : (k, 3) float array
        The points' barycentric coordinates in their triangles.

    Returns
    -------
    (k, 3) float32 array
        RGB as stored (sRGB-encoded), 8- and 16-bit textures scaled to [0, 1].

    Raises
    ------
    InputError
        If the mesh has no colour, or the arrays do not match.

    Examples
    --------
    >>> import numpy as np
    >>> from facecap.structures import Mesh
    >>> image = np.zeros((1, 2, 3), dtype=np.uint8); image[0, 1] = 255  # black left, white right
    >>> square = Mesh(np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 3]]),
    ...               uvs=np.array([[0., 0], [1, 0], [1, 1], [0, 1]]), uv_indices=np.array([0, 1, 2, 0, 2, 3]),
    ...               texture=image)
    >>> surface_colors(square, [0, 0], [[1.0, 0, 0], [0.5, 0.5, 0]])[:, 0].round(3)  # u = 0 (wraps) and 0.5
    array([0.5, 0.5], dtype=float32)
    """
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1)
    w = np.asarray(barycentric, dtype=np.float64)
    if w.shape != (tri.size, 3):
        raise InputError(f"barycentric: expected shape ({tri.size}, 3), got {w.shape}")
    if tri.size and (tri.min() < 0 or tri.max() >= mesh.n_faces):
        raise InputError(f"triangles: expected indices in [0, {mesh.n_faces}), got {tri.min()}..{tri.max()}")
    if mesh.texture is not None:
        uv_of_corner = np.asarray(mesh.uv_indices, dtype=np.int64)[triangle_corners(mesh)]
        uv = np.einsum("kc,kcd->kd", w, np.asarray(mesh.uvs)[uv_of_corner[tri]])
        return sample_image(mesh.texture, uv).astype(np.float32)
    if mesh.vertex_colors is not None:
        return np.einsum("kc,kcd->kd", w, mesh.vertex_colors[mesh.faces[tri]]).astype(np.float32)
    raise InputError("the mesh has no colour (no texture and no vertex colours)", path=mesh.source_path)


def sample_image(image: np.ndarray, uv: FloatArray) -> FloatArray:
    """Bilinear lookup of an (h, w, c) image at UVs (OBJ convention: ``v = 0`` at the bottom; wrapping).

    Texel centres are at ``((j + 0.5) / w, 1 - (i + 0.5) / h)``. Integer images are scaled to [0, 1] by
    their type's maximum, float images are returned as they are. Returns (k, c) float64.
    """
    h, w = image.shape[:2]
    scale = 1.0 / np.iinfo(image.dtype).max if np.issubdtype(image.dtype, np.integer) else 1.0
    x = uv[:, 0] * w - 0.5
    y = (1.0 - uv[:, 1]) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    x0 = x0.astype(np.int64) % w
    y0 = y0.astype(np.int64) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    top = image[y0, x0] * (1.0 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1.0 - fx) + image[y1, x1] * fx
    return (top * (1.0 - fy) + bottom * fy) * scale


def texel_size_mm(mesh: Mesh) -> float:
    """The median length on the surface of one texel of ``mesh.texture`` (mm): how fine its colour is.

    Per triangle, the square root of its area over its area in texels; the median over triangles
    whose UV area is not zero. Raises :class:`~facecap.errors.InputError` without a texture.
    """
    if mesh.texture is None:
        raise InputError("the mesh has no texture", path=mesh.source_path)
    h, w = mesh.texture.shape[:2]
    corners = np.asarray(mesh.uvs)[np.asarray(mesh.uv_indices, dtype=np.int64)[triangle_corners(mesh)]]
    d1, d2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    texels = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) * w * h
    P = mesh.vertices[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    ok = texels > 0
    if not ok.any():
        raise InputError("the mesh's UVs cover no texels", path=mesh.source_path)
    return float(np.median(np.sqrt(area[ok] / texels[ok])))
