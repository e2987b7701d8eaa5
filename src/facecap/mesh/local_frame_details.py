"""Detail displacements stored in each vertex's local frame of a base surface (Kobbelt et al. 1999)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import igl
import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_vertices

__all__ = ["LocalFrameDetails", "local_frames"]


def local_frames(V: Any, F: Any, reference_neighbour: Any) -> FloatArray:
    """Orthonormal frame ``(t1, t2, n)`` at every vertex of a surface.

    ``n`` is the area-weighted vertex normal, ``t1`` the edge to the vertex's
    reference neighbour projected onto the tangent plane and normalised,
    ``t2 = n x t1``. The frame rotates with the surface around the vertex, so
    a displacement written in it follows the surface when the surface bends.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions of the surface.
    F : (m, 3) int64 array
        Triangles, consistently oriented (the normal is on the side of
        counter-clockwise corners).
    reference_neighbour : (n,) int64 array
        For each vertex, the neighbour whose edge gives ``t1``
        (:attr:`LocalFrameDetails.reference_neighbour`); ``-1`` for a
        vertex in no triangle, whose frame is then the identity.

    Returns
    -------
    frames : (n, 3, 3) float64 array
        ``frames[i]`` has rows ``t1, t2, n`` of vertex ``i``: ``frames[i] @ d``
        are the coordinates of a vector ``d`` in that frame.

    Raises
    ------
    MeshError
        If ``V`` or ``F`` is malformed.
    InputError
        If ``reference_neighbour`` has the wrong shape or indices.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> frames = local_frames(V, np.array([[0, 1, 2]]), np.array([1, 2, 0]))
    >>> frames[0].round(6).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    V = as_vertices(V)
    F = as_faces(F, V.shape[0])
    ref = _as_reference(reference_neighbour, V.shape[0])
    normal = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    has = ref >= 0
    frames = np.broadcast_to(np.eye(3), (V.shape[0], 3, 3)).copy()
    n = normal[has]
    edge = V[ref[has]] - V[has]
    t1 = edge - np.einsum("kd,kd->k", edge, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    frames[has] = np.stack([t1, np.cross(n, t1), n], axis=1)
    return frames


def _as_reference(reference_neighbour: Any, n: int) -> IntArray:
    ref = np.asarray(reference_neighbour)
    if ref.shape != (n,) or not np.issubdtype(ref.dtype, np.integer):
        raise InputError(f"reference_neighbour: expected an ({n},) integer array, got {ref.shape} {ref.dtype}")
    if ref.size and (ref.min() < -1 or ref.max() >= n):
        raise InputError(f"reference_neighbour: indices must be -1 or in 0..{n - 1}, got {ref.min()}..{ref.max()}")
    return ref.astype(np.int64)


def _reference_neighbours(V: FloatArray, F: IntArray) -> IntArray:
    """Per vertex, the neighbour whose edge lies most nearly in the tangent plane (-1 if none)."""
    normal = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    E = igl.edges(F)
    i = np.concatenate([E[:, 0], E[:, 1]])
    j = np.concatenate([E[:, 1], E[:, 0]])
    edge = V[j] - V[i]
    length = np.linalg.norm(edge, axis=1)
    # sine of the edge's angle to the normal: 1 for an edge in the tangent plane; the
    # frame's t1 is then well defined however the surface bends afterwards
    along_normal = np.abs(np.einsum("kd,kd->k", edge, normal[i])) / np.maximum(length, 1e-300)
    order = np.lexsort((along_normal, i))
    first_of_vertex, at = np.unique(i[order], return_index=True)
    ref = np.full(V.shape[0], -1, dtype=np.int64)
    ref[first_of_vertex] = j[order[at]]
    return ref


@dataclass(frozen=True, eq=False)
class LocalFrameDetails:
    """Displacements of a detailed surface from a base surface, in the base's local frames.

    Multiresolution editing after Kobbelt et al. [1]_: with ``D = detailed -
    base`` and ``R_i`` the frame of :func:`local_frames` at vertex ``i`` of the
    base, the coefficients ``c_i = R_i D_i`` are stored; on a changed base
    ``B'`` the details come back as ``B'_i + R'_i^T c_i``, turned with the
    surface (section 5.4 of Bickel et al. 2007 adds fine-scale details back
    this way after removing the wrinkles underneath them).

    Attributes
    ----------
    coefficients : (n, 3) float64 array, mm
        ``(along t1, along t2, along n)`` of each vertex's displacement.
    reference_neighbour : (n,) int64 array
        The neighbour that fixes ``t1`` at each vertex (chosen on the base
        the details were encoded on; -1 for a vertex in no triangle).
    faces : (m, 3) int64 array
        The triangles the frames are built from.

    References
    ----------
    .. [1] L. Kobbelt, J. Vorsatz, H.-P. Seidel, "Multiresolution hierarchies
       on unstructured triangle meshes", Computational Geometry 14, 1999.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> F = np.array([[0, 1, 2]])
    >>> details = LocalFrameDetails.encode(V + [0, 0, 0.1], V, F)
    >>> details.coefficients[:, 2].round(6).tolist()
    [0.1, 0.1, 0.1]
    >>> turned = V @ np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # x to z, z to -x
    >>> details.add_to(turned)[0].round(6).tolist()  # the offset along the normal turned with it
    [-0.1, 0.0, 0.0]
    """

    coefficients: FloatArray
    reference_neighbour: IntArray
    faces: IntArray

    @classmethod
    def encode(cls, detailed: Any, base: Any, F: Any) -> LocalFrameDetails:
        """Store ``detailed - base`` in the local frames of ``base``.

        Parameters
        ----------
        detailed : (n, 3) float64 array, mm
            The surface with its details.
        base : (n, 3) float64 array, mm
            The same mesh without them (a smoothed copy).
        F : (m, 3) int64 array
            Triangles shared by both.

        Returns
        -------
        LocalFrameDetails

        Raises
        ------
        MeshError
            If an array is malformed or the two vertex arrays differ in shape.
        """
        base = as_vertices(base, name="base")
        detailed = as_vertices(detailed, name="detailed")
        if detailed.shape != base.shape:
            raise InputError(f"detailed: expected shape {base.shape} (the base's), got {detailed.shape}")
        F = as_faces(F, base.shape[0])
        ref = _reference_neighbours(base, F)
        frames = local_frames(base, F, ref)
        coefficients = np.einsum("nij,nj->ni", frames, detailed - base)
        return cls(coefficients=coefficients, reference_neighbour=ref, faces=F)

    def add_to(self, base: Any) -> FloatArray:
        """The details added back on another base surface, in its own local frames.

        Parameters
        ----------
        base : (n, 3) float64 array, mm
            New base positions of the same mesh.

        Returns
        -------
        (n, 3) float64 array, mm
            ``base_i + R_i^T c_i`` with ``R_i`` the frame of the new base.
        """
        base = as_vertices(base, name="base")
        if base.shape != self.coefficients.shape:
            raise InputError(f"base: expected shape {self.coefficients.shape}, got {base.shape}")
        frames = local_frames(base, self.faces, self.reference_neighbour)
        return base + np.einsum("nij,ni->nj", frames, self.coefficients)
