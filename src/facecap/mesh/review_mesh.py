"""A lighter mesh for reviewing a take in a viewer, made of a subset of the scan's own vertices.

A review file (glTF morph targets, :func:`facecap.io.write_gltf`) costs a
viewer 16 bytes per vertex per target, so a 700k-vertex scan is decimated
first. Every vertex the review mesh keeps is one of the scan's vertices, at
its exact position, so any frame of the take restricts to the review mesh by
indexing: ``frame[vertex_subset]``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..structures import Mesh

__all__ = ["review_mesh", "ReviewMesh"]

_SLIVER_HEIGHT = 0.01  # a triangle lower than 1 % of its longest edge is dropped: edge-on, it covers nothing


class ReviewMesh(NamedTuple):
    """The decimated mesh and the scan vertex behind each of its vertices."""

    mesh: Mesh
    """Triangles over the kept vertices (mm), UVs and colours carried."""
    vertex_subset: np.ndarray
    """(n_kept,) int64, increasing: ``mesh.vertices == scan.vertices[vertex_subset]``."""


def review_mesh(mesh: Mesh, max_vertices: int = 100_000) -> ReviewMesh:
    """Decimate ``mesh`` to at most ``max_vertices`` of its own vertices, by vertex clustering.

    Parameters
    ----------
    mesh : Mesh
        The scan (mm).
    max_vertices : int, optional
        Most vertices to keep; default 100,000 (a 64-target review file is
        then about 100 MB of GPU memory in three.js).

    Returns
    -------
    ReviewMesh
        ``(mesh, vertex_subset)``. When ``mesh`` already has at most
        ``max_vertices`` vertices it is returned unchanged with
        ``vertex_subset = arange(n)``.

    Raises
    ------
    InputError
        If ``max_vertices`` is below 3, or the mesh has no faces.

    Notes
    -----
    Vertex clustering (Rossignac and Borrel 1993): space is cut into cubes of
    side ``h``; the vertices in one cube merge into one, and triangles whose
    corners fall in fewer than three cubes vanish. Unlike their method (and
    unlike quadric simplifiers such as Fast-Quadric-Mesh-Simplification,
    which move vertices to optimal positions), the merged vertex is not a new
    point: it is the cube's original vertex nearest to the mean of the cube's
    vertices, so the review mesh's vertices are a subset of the scan's. ``h``
    is found by bisection so that the kept vertices are as many as possible
    but at most ``max_vertices``. Triangles are re-indexed, keep their
    orientation, and are dropped when degenerate (two corners in one cube, or
    slivers lower than 1 % of their longest edge, which clustering leaves
    where three corners fall along one row of cubes: edge-on, they cover
    nothing) or duplicated (the same three vertices in any order).

    Face-varying UVs are carried by UV chart (a connected set of triangles
    sharing UV indices): a kept triangle's corner takes the UV its new vertex
    has in that triangle's chart, or, when the vertex lies in another chart
    (a cube straddling a seam), the vertex's first UV. Per-vertex UVs and
    vertex colours are indexed by ``vertex_subset``. The result has
    triangles only (no polygons) and may be non-manifold where a cube
    bridged two sheets; it is meant for looking at, not for solving on.

    References
    ----------
    J. Rossignac and P. Borrel, "Multi-resolution 3D approximations for
    rendering complex scenes", Modeling in Computer Graphics, 1993.

    Examples
    --------
    >>> import numpy as np
    >>> from facecap.structures import Mesh
    >>> u, v = np.meshgrid(np.arange(50.0), np.arange(50.0))
    >>> V = np.stack([u.ravel(), v.ravel(), np.zeros(2500)], 1)
    >>> a = (np.arange(49)[:, None] * 50 + np.arange(49)).ravel()
    >>> F = np.concatenate([np.stack([a, a + 1, a + 50], 1), np.stack([a + 1, a + 51, a + 50], 1)])
    >>> small, kept = review_mesh(Mesh(V, F), max_vertices=500)
    >>> small.n_vertices <= 500 and np.array_equal(small.vertices, V[kept])
    True
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
    if not isinstance(max_vertices, (int, np.integer)) or int(max_vertices) < 3:
        raise InputError(f"max_vertices: expected an integer of at least 3, got {max_vertices!r}")
    n = mesh.n_vertices
    if n <= max_vertices:
        return ReviewMesh(mesh, np.arange(n, dtype=np.int64))
    if mesh.n_faces == 0:
        raise InputError("mesh: has no faces to decimate")
    V = mesh.vertices
    F = mesh.faces
    used = np.unique(F)
    cell_of = _cluster(V, F, used, int(max_vertices))
    representative = _representatives(V, used, cell_of)
    new_faces = representative[F]
    keep = _proper_triangles(V, new_faces)
    new_faces = new_faces[keep]
    vertex_subset, local = np.unique(new_faces, return_inverse=True)
    triangles = local.reshape(-1, 3).astype(np.int64)

    uvs = uv_indices = None
    if mesh.uvs is not None:
        if mesh.uv_indices is None:
            uvs = np.asarray(mesh.uvs)[vertex_subset]
        else:
            uvs, uv_indices = _carry_face_varying_uvs(mesh, np.flatnonzero(keep), new_faces)
    colors = None if mesh.vertex_colors is None else mesh.vertex_colors[vertex_subset]
    small = Mesh(
        V[vertex_subset], triangles, uvs=uvs, uv_indices=uv_indices, source_unit=mesh.source_unit,
        source_path=mesh.source_path, vertex_colors=colors,
        texture=mesh.texture if uv_indices is not None else None,  # the same UVs, so the same image
    )
    return ReviewMesh(small, vertex_subset.astype(np.int64))


def _cells(P: np.ndarray, h: float) -> np.ndarray:
    """Cube index of each point for cubes of side ``h`` (a dense int64 key)."""
    q = np.floor((P - P.min(axis=0)) / h).astype(np.int64)
    dims = q.max(axis=0) + 1
    return (q[:, 0] * dims[1] + q[:, 1]) * dims[2] + q[:, 2]


def _cluster(V: np.ndarray, F: np.ndarray, used: np.ndarray, max_vertices: int) -> np.ndarray:
    """Cube label (0..c-1) of each used vertex, with the most cubes c <= max_vertices found by bisection."""
    P = V[used]
    extent = float(np.max(P.max(axis=0) - P.min(axis=0)))
    if extent <= 0:
        return np.zeros(P.shape[0], dtype=np.int64)
    low, high = 0.0, extent * 1.001  # one cube holds everything at `high`
    best = np.zeros(P.shape[0], dtype=np.int64)
    # a surface of area A meets about A / h^2 cubes of side h: bracket around that guess
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    guess = np.sqrt(max(float(area), 1e-30) / max_vertices)
    for trial in (0.5 * guess, 2.0 * guess, 8.0 * guess):
        if low < trial < high:
            count = np.unique(_cells(P, trial)).size
            if count <= max_vertices:
                high = trial
                break
            low = trial
    for _ in range(40):
        h = 0.5 * (low + high)
        labels = np.unique(_cells(P, h), return_inverse=True)[1]
        count = int(labels.max()) + 1
        if count <= max_vertices:
            high, best = h, labels
            if count > 0.99 * max_vertices:
                break
        else:
            low = h
    return best.astype(np.int64)


def _representatives(V: np.ndarray, used: np.ndarray, cell_of: np.ndarray) -> np.ndarray:
    """For every vertex, the original vertex its cube merges into (unused vertices map to themselves)."""
    n_cells = int(cell_of.max()) + 1
    P = V[used]
    counts = np.bincount(cell_of, minlength=n_cells)[:, None]
    mean = np.stack([np.bincount(cell_of, P[:, c], minlength=n_cells) for c in range(3)], axis=1) / counts
    distance = np.einsum("ij,ij->i", P - mean[cell_of], P - mean[cell_of])
    order = np.lexsort((used, distance, cell_of))  # ties go to the lower vertex index
    first = order[np.r_[True, cell_of[order][1:] != cell_of[order][:-1]]]
    rep_of_cell = used[first]
    representative = np.arange(V.shape[0], dtype=np.int64)
    representative[used] = rep_of_cell[cell_of]
    return representative


def _proper_triangles(V: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mask of the triangles with three distinct corners, non-zero area, first of their vertex set."""
    a, b, c = faces.T
    distinct = (a != b) & (b != c) & (a != c)
    area2 = np.linalg.norm(np.cross(V[b] - V[a], V[c] - V[a]), axis=1)  # twice the area
    longest2 = np.max([np.einsum("ij,ij->i", V[q] - V[p], V[q] - V[p]) for p, q in ((a, b), (b, c), (c, a))], axis=0)
    # slivers: height under SLIVER_HEIGHT of the longest edge (three corners along one row of cubes)
    proper = distinct & (area2 > _SLIVER_HEIGHT * longest2)
    candidates = np.flatnonzero(proper)
    _, first = np.unique(np.sort(faces[candidates], axis=1), axis=0, return_index=True)
    keep = np.zeros(faces.shape[0], dtype=bool)
    keep[candidates[first]] = True
    return keep


def _carry_face_varying_uvs(mesh: Mesh, kept_faces: np.ndarray, new_faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """UVs and per-corner UV indices for the kept triangles (see the Notes of :func:`review_mesh`)."""
    from ..io.write_gltf import triangle_corners  # the one home of polygon corner -> triangle corner

    uvs = np.asarray(mesh.uvs, dtype=np.float64)
    n_uv = uvs.shape[0]
    corner_uv = np.asarray(mesh.uv_indices, dtype=np.int64)[triangle_corners(mesh)]  # (m, 3)
    m = corner_uv.shape[0]
    # charts: connected components of the triangle -- UV index graph
    graph = coo_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), m + corner_uv.ravel())), shape=(m + n_uv,) * 2)
    chart = connected_components(graph, directed=False)[1][:m]
    n_chart = int(chart.max()) + 1
    # (vertex, chart) -> a UV index of that vertex in that chart
    key = mesh.faces * n_chart + chart[:, None]
    table_keys, first = np.unique(key.ravel(), return_index=True)
    table_uv = corner_uv.ravel()[first]
    any_keys, any_first = np.unique(mesh.faces.ravel(), return_index=True)
    any_uv = corner_uv.ravel()[any_first]

    wanted = new_faces * n_chart + chart[kept_faces][:, None]
    at = np.clip(np.searchsorted(table_keys, wanted), 0, table_keys.size - 1)
    found = table_keys[at] == wanted
    chosen = np.where(found, table_uv[at], any_uv[np.searchsorted(any_keys, new_faces)])
    used_uv, uv_index = np.unique(chosen.ravel(), return_inverse=True)
    return uvs[used_uv], uv_index.astype(np.int64)
