"""Find the defects of a mesh that make solvers fail on real scans."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import MeshError
from ..typing import FloatArray, IntArray
from ..validate import as_points, as_positive
from .connected_pieces import connected_pieces
from .duplicate_representatives import duplicate_representatives

__all__ = ["check_mesh", "MeshCheck"]


@dataclass(frozen=True, eq=False)
class MeshCheck:
    """What :func:`check_mesh` found. Index arrays are 0-based and sorted.

    Attributes
    ----------
    n_vertices, n_faces : int
        Sizes of the mesh as given.
    nonfinite_vertices : (k,) int64 array
        Vertices with a NaN or infinite coordinate.
    out_of_range_faces : (k,) int64 array
        Faces with a vertex index below 0 or at least ``n_vertices``.
    degenerate_faces : (k,) int64 array
        In-range faces that repeat a vertex, touch a non-finite vertex, or
        whose height is below ``degenerate_tolerance`` times their longest
        edge (zero or sliver area).
    unreferenced_vertices : (k,) int64 array
        Vertices no in-range face uses.
    duplicate_of : (n,) int64 array
        For each finite vertex, the lowest-numbered vertex within the
        duplicate tolerance of it (transitively); the vertex itself when it
        has no duplicate, and for non-finite vertices.
    duplicate_tolerance_mm : float
        The distance used for duplicates: ``duplicate_tolerance`` times
        the mean edge length (in the units of ``V``, normally mm).
    non_manifold_edges : (k, 2) int64 array
        Edges ``(a, b)``, ``a < b``, shared by more than two faces.
    n_boundary_edges : int
        Edges used by exactly one face.
    n_boundary_loops : int
        Connected chains of boundary edges (two holes touching at a vertex
        count as one).
    n_pieces : int
        Connected pieces (see :func:`~facecap.mesh.connected_pieces`).
    piece_labels : (n,) int64 array
        Piece of each vertex, -1 for unreferenced ones.
    bounding_box : (2, 3) float64 array
        Minimum and maximum corner of the finite vertices (NaN if none).
    mean_edge_length : float
        Mean length of the unique edges of the usable faces (NaN if none).
    """

    n_vertices: int
    n_faces: int
    nonfinite_vertices: IntArray
    out_of_range_faces: IntArray
    degenerate_faces: IntArray
    unreferenced_vertices: IntArray
    duplicate_of: IntArray
    duplicate_tolerance_mm: float
    non_manifold_edges: IntArray
    n_boundary_edges: int
    n_boundary_loops: int
    n_pieces: int
    piece_labels: IntArray
    bounding_box: FloatArray
    mean_edge_length: float

    @property
    def duplicate_vertices(self) -> IntArray:
        """(k,) int64: vertices that duplicate a lower-numbered one."""
        return np.flatnonzero(self.duplicate_of != np.arange(self.n_vertices))

    @property
    def duplicate_groups(self) -> list[IntArray]:
        """Each group of duplicate vertices (two or more), sorted, by lowest vertex."""
        dup = self.duplicate_vertices
        if dup.size == 0:
            return []
        members = np.unique(np.concatenate([dup, self.duplicate_of[dup]]))
        rep = self.duplicate_of[members]
        order = np.lexsort((members, rep))
        bounds = np.flatnonzero(np.diff(rep[order])) + 1
        return np.split(members[order], bounds)

    @property
    def piece_sizes(self) -> IntArray:
        """(n_pieces,) int64: vertex count of each piece."""
        used = self.piece_labels[self.piece_labels >= 0]
        return np.bincount(used, minlength=self.n_pieces).astype(np.int64)

    @property
    def problems(self) -> list[str]:
        """One line per kind of defect found; empty when the mesh is clean."""
        out: list[str] = []
        if self.n_faces == 0:
            out.append("the mesh has no faces")
        if self.nonfinite_vertices.size:
            out.append(
                f"{_n(self.nonfinite_vertices.size, 'vertex', 'vertices')} with NaN or infinite "
                f"coordinates (first: {_first(self.nonfinite_vertices)})"
            )
        if self.out_of_range_faces.size:
            out.append(
                f"{_n(self.out_of_range_faces.size, 'face', 'faces')} referring to vertices that do "
                f"not exist (the mesh has {self.n_vertices}; first: face {_first(self.out_of_range_faces)})"
            )
        if self.degenerate_faces.size:
            out.append(
                f"{_n(self.degenerate_faces.size, 'degenerate face', 'degenerate faces')}: repeated "
                f"vertex or (near) zero area (first: face {_first(self.degenerate_faces)})"
            )
        if self.unreferenced_vertices.size:
            out.append(
                f"{_n(self.unreferenced_vertices.size, 'vertex', 'vertices')} used by no face "
                f"(first: {_first(self.unreferenced_vertices)})"
            )
        dup = self.duplicate_vertices
        if dup.size:
            groups = self.duplicate_groups
            out.append(
                f"{_n(dup.size, 'vertex duplicates', 'vertices duplicate')} another within "
                f"{self.duplicate_tolerance_mm:.3g} mm ({_n(len(groups), 'group', 'groups')}, e.g. "
                f"UV-seam splits; first group: {groups[0].tolist()})"
            )
        if self.non_manifold_edges.size:
            a, b = self.non_manifold_edges[0].tolist()
            out.append(
                f"{_n(self.non_manifold_edges.shape[0], 'edge', 'edges')} shared by more than two "
                f"faces (first: vertices {a}-{b})"
            )
        if self.n_pieces > 1:
            sizes = sorted(self.piece_sizes.tolist(), reverse=True)
            shown = ", ".join(map(str, sizes[:5])) + (", ..." if len(sizes) > 5 else "")
            out.append(f"the mesh has {self.n_pieces} separate pieces (vertices: {shown})")
        return out

    def summary(self) -> dict[str, Any]:
        """Counts, bounding box and problems as a JSON-ready dict of plain Python values."""
        finite_box = bool(np.all(np.isfinite(self.bounding_box)))
        return {
            "n_vertices": self.n_vertices,
            "n_faces": self.n_faces,
            "n_nonfinite_vertices": int(self.nonfinite_vertices.size),
            "n_out_of_range_faces": int(self.out_of_range_faces.size),
            "n_degenerate_faces": int(self.degenerate_faces.size),
            "n_unreferenced_vertices": int(self.unreferenced_vertices.size),
            "n_duplicate_vertices": int(self.duplicate_vertices.size),
            "n_duplicate_groups": len(self.duplicate_groups),
            "duplicate_tolerance_mm": _json_float(self.duplicate_tolerance_mm),
            "n_non_manifold_edges": int(self.non_manifold_edges.shape[0]),
            "n_boundary_edges": self.n_boundary_edges,
            "n_boundary_loops": self.n_boundary_loops,
            "n_pieces": self.n_pieces,
            "piece_sizes": self.piece_sizes.tolist(),
            "bounding_box_mm": self.bounding_box.tolist() if finite_box else None,
            "mean_edge_length_mm": _json_float(self.mean_edge_length),
            "problems": self.problems,
        }


def _first(a: np.ndarray) -> int:
    return int(a[0])


def _n(count: int, singular: str, plural: str) -> str:
    return f"{count} {singular if count == 1 else plural}"


def _json_float(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def check_mesh(
    V: Any,
    F: Any,
    *,
    duplicate_tolerance: float = 1e-6,
    degenerate_tolerance: float = 1e-8,
) -> MeshCheck:
    """Report the defects of a triangle mesh that make solvers fail.

    Takes raw arrays and never fails on a defect: out-of-range face indices
    and non-finite vertices are reported and left out of the other checks.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions; NaN and inf are allowed (and reported).
    F : (m, 3) int array
        Triangle vertex indices; out-of-range values are allowed (and reported).
    duplicate_tolerance : float, optional
        Two vertices are duplicates when at most this fraction of the mean
        edge length apart (exact copies only when there are no edges).
        Default 1e-6.
    degenerate_tolerance : float, optional
        A face is degenerate when its height over its longest edge, ``2 A /
        l_max^2``, is at most this. Default 1e-8 (cotangent weights reach
        ~1e8).

    Returns
    -------
    MeshCheck
        The findings; ``.problems`` lists them in words, ``.summary()`` as a
        JSON-ready dict.

    Raises
    ------
    InputError
        If ``V`` is not an (n, 3) numeric array, ``F`` not an (m, 3) integer
        array, or a tolerance is negative.

    Notes
    -----
    Edges are the sorted corner pairs of the faces that pass the index and
    repeat checks, counted with :func:`numpy.unique`: used once is boundary,
    more than twice non-manifold. Boundary loops are the connected components
    of the boundary edges; duplicates come from a k-d tree
    (:meth:`scipy.spatial.cKDTree.query_pairs`). Runs in O(m log m).

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [5, 5, 5]])
    >>> report = check_mesh(V, np.array([[0, 1, 2], [2, 3, 0]]))
    >>> for line in report.problems:
    ...     print(line)
    1 vertex used by no face (first: 4)
    1 vertex duplicates another within 1.17e-06 (1 group, e.g. UV-seam splits; first group: [1, 3])
    """
    V = as_points(V, name="V", allow_nan=True)
    Fa = np.asarray(F)
    if Fa.ndim != 2 or Fa.shape[1] != 3:
        raise MeshError(f"F: expected shape (m, 3), got {Fa.shape}")
    if Fa.size and not np.issubdtype(Fa.dtype, np.integer):
        if not np.issubdtype(Fa.dtype, np.floating) or not np.all(Fa == np.round(Fa)):
            raise MeshError(f"F: face indices must be integers, got dtype {Fa.dtype}")
    Fa = np.ascontiguousarray(Fa, dtype=np.int64)
    dup_tol = as_positive(duplicate_tolerance, name="duplicate_tolerance", allow_zero=True)
    deg_tol = as_positive(degenerate_tolerance, name="degenerate_tolerance", allow_zero=True)
    n, m = V.shape[0], Fa.shape[0]

    finite = np.all(np.isfinite(V), axis=1)
    nonfinite = np.flatnonzero(~finite)
    in_range = np.all((Fa >= 0) & (Fa < n), axis=1)
    out_of_range = np.flatnonzero(~in_range)
    F_ok = Fa[in_range]
    ok_index = np.flatnonzero(in_range)

    # degenerate: repeated index, non-finite corner, or tiny height / longest edge
    repeated = (F_ok[:, 0] == F_ok[:, 1]) | (F_ok[:, 1] == F_ok[:, 2]) | (F_ok[:, 2] == F_ok[:, 0])
    touches_nonfinite = ~(finite[F_ok[:, 0]] & finite[F_ok[:, 1]] & finite[F_ok[:, 2]])
    Vf = V if nonfinite.size == 0 else np.where(finite[:, None], V, 0.0)
    double_area, longest_sq = _double_area_and_longest_edge_sq(Vf, F_ok)
    thin = double_area <= deg_tol * longest_sq
    degenerate = ok_index[repeated | touches_nonfinite | thin]

    # unreferenced vertices and pieces (all in-range faces connect)
    used = np.zeros(n, dtype=bool)
    used[F_ok.ravel()] = True
    unreferenced = np.flatnonzero(~used)
    if F_ok.shape[0]:
        n_pieces, labels = connected_pieces(F_ok, n)
    else:
        n_pieces, labels = 0, np.full(n, -1, dtype=np.int64)

    # edges of the faces with three distinct corners
    F_top = F_ok[~repeated]
    a = np.concatenate([F_top[:, 0], F_top[:, 1], F_top[:, 2]])
    b = np.concatenate([F_top[:, 1], F_top[:, 2], F_top[:, 0]])
    stride = np.int64(max(n, 1))
    keys, counts = np.unique(np.minimum(a, b) * stride + np.maximum(a, b), return_counts=True)
    unique_edges = np.stack([keys // stride, keys % stride], axis=1)
    non_manifold = unique_edges[counts > 2]
    boundary = unique_edges[counts == 1]
    n_loops = 0
    if boundary.shape[0]:
        graph = sp.coo_matrix(
            (np.ones(boundary.shape[0], dtype=np.int8), (boundary[:, 0], boundary[:, 1])), shape=(n, n)
        )
        _, comp = connected_components(graph, directed=False)
        n_loops = int(np.unique(comp[boundary[:, 0]]).size)

    # sizes: bounding box, mean edge length of the usable edges
    seen = V if nonfinite.size == 0 else V[finite]
    box = np.stack([seen.min(axis=0), seen.max(axis=0)]) if seen.size else np.full((2, 3), np.nan)
    usable = finite[unique_edges[:, 0]] & finite[unique_edges[:, 1]]
    ue = unique_edges[usable]
    mean_edge = (
        float(np.linalg.norm(np.take(V, ue[:, 0], axis=0) - np.take(V, ue[:, 1], axis=0), axis=1).mean())
        if ue.size else float("nan")
    )

    # duplicates among finite vertices, within a fraction of the mean edge length
    tol = dup_tol * mean_edge if np.isfinite(mean_edge) else 0.0
    duplicate_of = np.arange(n, dtype=np.int64)
    fin_idx = np.flatnonzero(finite)
    if fin_idx.size > 1:
        duplicate_of[fin_idx] = fin_idx[duplicate_representatives(V[fin_idx], tol)]

    return MeshCheck(
        n_vertices=n,
        n_faces=m,
        nonfinite_vertices=nonfinite,
        out_of_range_faces=out_of_range,
        degenerate_faces=degenerate,
        unreferenced_vertices=unreferenced,
        duplicate_of=duplicate_of,
        duplicate_tolerance_mm=tol,
        non_manifold_edges=non_manifold,
        n_boundary_edges=int(boundary.shape[0]),
        n_boundary_loops=n_loops,
        n_pieces=n_pieces,
        piece_labels=labels,
        bounding_box=box,
        mean_edge_length=mean_edge,
    )


def _double_area_and_longest_edge_sq(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per face, twice its area and its longest edge squared (finite ``V``).

    One coordinate at a time on contiguous arrays: ``np.cross`` and row norms
    on (m, 3) arrays took twice as long at 1.4M faces.
    """
    corners = [np.ascontiguousarray(F[:, j]) for j in range(3)]
    edge_sq = [np.zeros(F.shape[0]) for _ in range(3)]
    e01, e02 = [], []  # per coordinate
    for c in range(3):
        x = np.ascontiguousarray(V[:, c])
        p0, p1, p2 = (np.take(x, i) for i in corners)
        for total, d in zip(edge_sq, (p1 - p0, p2 - p1, p0 - p2)):
            total += d * d
        e01.append(p1 - p0)
        e02.append(p2 - p0)
    (ax, ay, az), (bx, by, bz) = e01, e02
    cross_sq = (ay * bz - az * by) ** 2 + (az * bx - ax * bz) ** 2 + (ax * by - ay * bx) ** 2
    return np.sqrt(cross_sq), np.maximum(np.maximum(edge_sq[0], edge_sq[1]), edge_sq[2])
