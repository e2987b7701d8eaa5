"""Markers as barycentric points of the tetrahedral mesh, with their rest offsets (Sifakis et al. 2005, sec. 5)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import CorrespondenceError, InputError
from ..typing import FloatArray, IntArray
from ..validate import as_points

__all__ = ["MarkerEmbedding", "marker_embedding", "DEFAULT_MAX_OFFSET_MM"]

DEFAULT_MAX_OFFSET_MM = 10.0
"""A rest marker farther than this from its skin point does not belong to the model."""


class MarkerEmbedding(NamedTuple):
    """The markers of a take in the flesh mesh.

    Attributes
    ----------
    vertices : (M,) int64 array
        The scan vertex under each marker.
    matrix : scipy.sparse.csr_matrix, (M, N) float64
        ``W`` with ``skin points = W @ x`` for node positions ``x`` (the anatomy's embedding
        of each marker's vertex: one tetrahedron, four barycentric weights).
    offsets : (M, 3) float64 array, mm
        Rest marker minus its embedded skin point at rest, in the cranium's (rest) frame;
        the model's marker is ``skin point + offset``, the offset carried by the cranium.
    """

    vertices: IntArray
    matrix: sp.csr_matrix
    offsets: FloatArray


def marker_embedding(anatomy: Any, marker_vertices: Any, rest_markers: Any, *,
                     max_offset_mm: float = DEFAULT_MAX_OFFSET_MM) -> MarkerEmbedding:
    """Embed the markers of a take in an anatomy's flesh mesh.

    Parameters
    ----------
    anatomy : FaceAnatomy
    marker_vertices : (M,) int array
        Scan vertex of each marker (the marker map).
    rest_markers : (M, 3) float64 array, mm
        The markers at the rest (neutral) frame, in the scan's coordinates.
    max_offset_mm : float, default 10
        Largest allowed distance of a rest marker from its skin point.

    Returns
    -------
    MarkerEmbedding

    Raises
    ------
    CorrespondenceError
        A vertex out of range, or outside the meshed face (ears, scalp, neck, inner lips:
        the marker would land off the model).
    InputError
        Rest markers of the wrong shape, not finite, or farther than ``max_offset_mm``
        from their skin points.
    """
    n_scan = int(anatomy.skin_tets.shape[0])
    idx = np.asarray(marker_vertices)
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise CorrespondenceError(f"marker_vertices: expected a non-empty 1-D integer array, got shape {idx.shape}")
    idx = idx.astype(np.int64)
    if idx.min() < 0 or idx.max() >= n_scan:
        raise CorrespondenceError(f"marker_vertices: indices span {idx.min()}..{idx.max()}, "
                                  f"the scan has {n_scan} vertices")
    rest = as_points(rest_markers, name="rest_markers")
    if rest.shape[0] != idx.size:
        raise InputError(f"rest_markers: expected {idx.size} rows (one per marker vertex), got {rest.shape[0]}")
    weights = np.asarray(anatomy.skin_weights)[idx]
    off_model = ~np.asarray(anatomy.skin_meshed)[idx] | (np.abs(weights).max(axis=1) > 3.0)
    if off_model.any():
        bad = np.flatnonzero(off_model)
        raise CorrespondenceError(f"markers {bad[:8].tolist()}{' ...' if bad.size > 8 else ''} land off the model: "
                                  "their vertices are outside the meshed face (ears, scalp, neck, inner lips)")
    tets = np.asarray(anatomy.tets)[np.asarray(anatomy.skin_tets)[idx]]
    rows = np.repeat(np.arange(idx.size), 4)
    W = sp.csr_matrix((weights.ravel(), (rows, tets.ravel())), shape=(idx.size, int(anatomy.nodes.shape[0])))
    offsets = rest - W @ np.asarray(anatomy.nodes)
    far = np.linalg.norm(offsets, axis=1) > float(max_offset_mm)
    if far.any():
        bad = np.flatnonzero(far)
        raise InputError(f"rest_markers: markers {bad[:8].tolist()} lie more than {max_offset_mm} mm from their "
                         "skin points at rest (wrong map, or a take not in the scan's frame)")
    return MarkerEmbedding(idx, W, offsets)
