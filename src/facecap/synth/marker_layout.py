"""Where the virtual markers go on the face: a realistic facial marker layout."""

from __future__ import annotations

import json
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from ..errors import FileFormatError, InputError
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices
from ..io.ict_sample import bundled_path

__all__ = ["animface_marker_map", "boundary_vertices", "choose_marker_vertices"]


def boundary_vertices(F: IntArray, n_vertices: int) -> BoolArray:
    """Vertices on a boundary edge (an edge used by exactly one triangle).

    Parameters
    ----------
    F : (m, 3) int64 array
    n_vertices : int

    Returns
    -------
    (n_vertices,) bool array

    Examples
    --------
    >>> boundary_vertices(np.array([[0, 1, 2]]), 4).tolist()
    [True, True, True, False]
    """
    F = as_faces(F, n_vertices)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, counts = np.unique(E, axis=0, return_counts=True)
    mask = np.zeros(n_vertices, dtype=bool)
    mask[edges[counts == 1].ravel()] = True
    return mask


def _edge_graph(V: FloatArray, F: IntArray) -> sp.csr_matrix:
    """(n, n) symmetric sparse matrix of edge lengths (mm)."""
    n = V.shape[0]
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    E = np.unique(E, axis=0)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.coo_matrix((w, (E[:, 0], E[:, 1])), shape=(n, n)).tocsr()
    return (G + G.T).tocsr()


def _mask(x: Any, n: int, name: str) -> BoolArray:
    """A (n,) bool mask from a bool mask or an index array."""
    a = np.asarray(x)
    if a.dtype == bool:
        if a.shape != (n,):
            raise InputError(f"{name}: expected a ({n},) bool mask, got shape {a.shape}")
        return a.copy()
    if a.ndim != 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
        raise InputError(f"{name}: expected a ({n},) bool mask or 1-D vertex indices, got {a.dtype} {a.shape}")
    if a.size and (a.min() < 0 or a.max() >= n):
        raise InputError(f"{name}: vertex index out of range 0..{n - 1}")
    m = np.zeros(n, dtype=bool)
    m[a] = True
    return m


def choose_marker_vertices(
    V: FloatArray,
    F: IntArray,
    expression_deltas: Any,
    n_markers: int,
    *,
    seed: int = 0,
    motion_weight: float = 3.0,
    exclude: Any = None,
    metric: Literal["geodesic", "euclidean"] = "geodesic",
) -> IntArray:
    """Pick marker vertices the way a facial capture layout is designed.

    Weighted farthest-point sampling over the allowed vertices: each new
    marker goes where the distance to the nearest marker, scaled up by how
    much the face moves there, is largest. Markers end up spread over the
    whole face and denser around the lips, eyelids, brows and cheeks (spacing
    roughly ``1 / (1 + motion_weight)`` of the static areas'), as in real
    60-120 marker layouts. Vertices on a boundary (the rim of the face, the
    eye openings and the lips' inner edge) and their 1-ring never carry a
    marker: a marker cannot sit on the lip seam or the eyelid margin.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Neutral face.
    F : (m, 3) int64 array
        Triangles.
    expression_deltas : (k, n, 3) float array, mm
        Per-expression vertex offsets, to find where the face moves. ``k``
        may be 0 (uniform spacing).
    n_markers : int
        Number of markers, at least 1.
    seed : int, default 0
        Picks the first marker among the 20 most mobile allowed vertices;
        the rest follows deterministically.
    motion_weight : float, default 3.0
        How strongly motion attracts markers; 0 gives uniform spacing.
    exclude : (n,) bool array or (e,) int array, optional
        Vertices that must not carry a marker besides the boundary ones
        (e.g. ears, neck, the underside of the chin).
    metric : {'geodesic', 'euclidean'}, default 'geodesic'
        Distance used for spacing: shortest paths along mesh edges (upper and
        lower lip, upper and lower eyelid are far apart, so both get markers;
        about 0.3 s for 90 markers on 9,409 vertices) or straight lines (faster).

    Returns
    -------
    (n_markers,) int64 array
        Distinct vertex indices, in picking order.

    Raises
    ------
    InputError
        If the arrays have the wrong shapes, or fewer than ``n_markers``
        vertices are allowed.

    Notes
    -----
    The motion of vertex ``v`` is ``m(v) = sqrt(mean_k (|d_k(v)| / max_u |d_k(u)|)^2)``:
    each expression counts by its own peak, so the large rigid jaw swing of
    ``jawOpen`` does not outweigh the many small lip and eyelid motions. The
    ``i``-th marker maximises ``dist(v, chosen) * (1 + motion_weight m(v) / max m)``
    (farthest-point sampling, Eldar et al. 1997, with a density weight).

    References
    ----------
    Y. Eldar, M. Lindenbaum, M. Porat, Y. Y. Zeevi, "The farthest point strategy
    for progressive image sampling", IEEE TIP 6(9), 1997.

    Examples
    --------
    >>> from ..io.ict_sample import load_ict_sample
    >>> s = load_ict_sample()
    >>> mv = choose_marker_vertices(s.mesh.vertices, s.mesh.faces, s.expression_deltas, 30, seed=1)
    >>> mv.shape, len(set(mv.tolist()))
    ((30,), 30)
    """
    V = as_vertices(V)
    F = as_faces(F, V.shape[0])
    n = V.shape[0]
    if isinstance(n_markers, bool) or not isinstance(n_markers, (int, np.integer)) or n_markers < 1:
        raise InputError(f"n_markers: expected a positive integer, got {n_markers!r}")
    if metric not in ("geodesic", "euclidean"):
        raise InputError(f"metric: expected 'geodesic' or 'euclidean', got {metric!r}")
    w = as_positive(motion_weight, name="motion_weight", allow_zero=True)
    try:
        D = np.asarray(expression_deltas, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("expression_deltas: expected a numeric (k, n, 3) array") from None
    if D.ndim != 3 or D.shape[1:] != (n, 3):
        raise InputError(f"expression_deltas: expected shape (k, {n}, 3), got {D.shape}")

    boundary = boundary_vertices(F, n)
    G = _edge_graph(V, F)
    near_boundary = boundary | ((G != 0) @ boundary.astype(np.float64) > 0)
    allowed = ~near_boundary
    if exclude is not None:
        allowed &= ~_mask(exclude, n, "exclude")
    candidates = np.flatnonzero(allowed)
    if candidates.size < n_markers:
        raise InputError(
            f"n_markers: only {candidates.size} vertices can carry a marker (off the boundary and "
            f"not excluded), asked for {n_markers}"
        )

    if D.shape[0]:
        mag = np.linalg.norm(D, axis=2)
        peak = mag.max(axis=1, keepdims=True)
        motion = np.sqrt(np.mean((mag / np.where(peak > 0, peak, 1.0)) ** 2, axis=0))
    else:
        motion = np.zeros(n)
    top_motion = float(motion[candidates].max())
    scale = 1.0 + w * motion / top_motion if top_motion > 0 else np.ones(n)

    rng = np.random.default_rng(seed)
    top = candidates[np.argsort(motion[candidates], kind="stable")[-20:]]
    chosen = [int(top[rng.integers(top.size)])]
    distance = np.full(n, np.inf)
    for _ in range(n_markers - 1):
        last = chosen[-1]
        if metric == "euclidean":
            d = np.linalg.norm(V - V[last], axis=1)
        else:
            reach = distance[allowed].max()
            d = dijkstra(G, directed=False, indices=last, limit=reach * 1.000001 if np.isfinite(reach) else np.inf)
        np.minimum(distance, d, out=distance)
        score = np.where(allowed, distance * scale, -1.0)
        score[chosen] = -1.0
        chosen.append(int(np.argmax(score)))
    return np.asarray(chosen, dtype=np.int64)


def animface_marker_map() -> dict[str, int]:
    """The 41 markers of the bundled AnimFace take, placed on the ICT face.

    The real layout of ``eyebrows.c3d`` (forehead, brows, eyes, cheeks, nose,
    mouth, chin), each marker on a vertex of the ICT face region (placed once
    by aligning the take to the face on landmarks and snapping to the nearest
    vertex). Usable as ``generate_performance(marker_layout='animface')``.

    Returns
    -------
    dict of str to int
        Marker label -> vertex index (< 9409), in the file's order.

    Raises
    ------
    FileFormatError
        If the bundled map is unreadable.

    Examples
    --------
    >>> m = animface_marker_map()
    >>> len(m), m["Chin"]
    (41, 963)
    """
    path = bundled_path("ict_generic_map.json")
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"cannot read the marker map ({exc})", path=str(path)) from None
    return {str(k): int(v) for k, v in raw.items()}
