"""Where the detail layer solves by default: the skin that every camera sees, one of them well, and a light reaches.

The paper solved regions a user brushed (its Fig. 7) and named the whole face as
future work; the default here is the whole face that shading can speak for: seen by
every camera (two views make the specular tell from the diffuse), by at least one of
them at a useful angle, reached by a light, and away from the mesh's open edges, whose
normals are one-sided. Asking every camera for a useful angle left out the side of the
face each camera sees obliquely, where crow's feet are: on the generator's seed 0, 63 %
of the lines' vertices (``benchmarks/RESULTS.md``, "Fine detail from video": the region).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from ..typing import BoolArray

__all__ = ["select_detail_region", "locality_order", "MIN_VIEW_WEIGHT", "MIN_LIGHT_SHARE", "BOUNDARY_RINGS"]

MIN_VIEW_WEIGHT = 0.5
"""The least observation weight (:func:`~facecap.sfs.sample_footage`) one camera at least must give a sample
(a view about 65 degrees from the normal)."""

MIN_LIGHT_SHARE = 0.1
"""The least direct irradiance on the surface, as a share of the region's 95th percentile (shadowed skin is
left out)."""

BOUNDARY_RINGS = 3
"""Rings of vertices next to the mesh's open edges left out."""


def select_detail_region(weight: Any, direct: Any, faces: Any, *, mask: Any = None) -> BoolArray:
    """The vertices the detail is solved at.

    Parameters
    ----------
    weight : (C, n) float array
        Each camera's observation weight at each vertex, at the rest frame.
    direct : (n,) float array
        Direct irradiance on the surface there (``sum_l s_l E_l max(0, n.l)``).
    faces : (m, 3) int array
    mask : (n,) bool array, optional
        A user's region (``--regions``): the result is within it.

    Returns
    -------
    (n,) bool array
    """
    W = np.asarray(weight, dtype=np.float64)
    E = np.asarray(direct, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    n = W.shape[1]
    seen = np.all(W > 0, axis=0) & np.any(W >= MIN_VIEW_WEIGHT, axis=0)
    reference = np.percentile(E[seen], 95) if seen.any() else 0.0
    chosen = seen & (E >= MIN_LIGHT_SHARE * reference) & (E > 0)
    # open edges: edges used by one triangle
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    near = np.zeros(n, dtype=bool)
    near[unique[counts == 1].ravel()] = True
    i = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    j = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    adjacency = sp.csr_matrix((np.ones(2 * i.size), (np.r_[i, j], np.r_[j, i])), shape=(n, n))
    for _ in range(BOUNDARY_RINGS):
        near = near | ((adjacency @ near.astype(np.float64)) > 0)
    chosen &= ~near
    if mask is not None:
        chosen &= np.asarray(mask, dtype=bool)
    return chosen


def locality_order(region: Any, faces: Any) -> np.ndarray:
    """An order of the region's vertices in which mesh neighbours lie close in memory (reverse Cuthill-McKee).

    A scan refined where the lines are numbers its new vertices last, so the one-ring of a sample is spread
    over the whole array and every sparse pass of the solve waits on memory; in this order the blur's pass
    over a 140 880-sample region took 3.3 ms instead of 6.1 (``benchmarks/RESULTS.md``).

    Parameters
    ----------
    region : (r,) int array
        Vertex indices.
    faces : (m, 3) int array
        The mesh's triangles (all of them; those leaving the region are ignored).

    Returns
    -------
    (r,) int array
        A permutation of ``range(r)``: ``region[order]`` is the region in the new order.

    Examples
    --------
    >>> order = locality_order(np.arange(4), np.array([[0, 2, 3], [0, 3, 1]]))
    >>> sorted(order.tolist())
    [0, 1, 2, 3]
    """
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    region = np.asarray(region, dtype=np.int64)
    F = np.asarray(faces, dtype=np.int64)
    index = np.full(max(int(F.max(initial=-1)), int(region.max(initial=-1))) + 1, -1, dtype=np.int64)
    index[region] = np.arange(region.size)
    inside = F[np.all(index[F] >= 0, axis=1)]
    local = index[inside]
    i = local.ravel()
    j = np.roll(local, 1, axis=1).ravel()
    adjacency = sp.csr_matrix((np.ones(2 * i.size), (np.r_[i, j], np.r_[j, i])), shape=(region.size, region.size))
    return np.asarray(reverse_cuthill_mckee(adjacency, symmetric_mode=True), dtype=np.int64)
