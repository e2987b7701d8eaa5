"""The anatomical face model: one record, saved as ``anatomy.npz`` plus ``anatomy.json``.

:func:`~facecap.anatomy.build_anatomy` makes it from a scan; the finite
element model (``facecap.fem``) reads it. Everything is in millimetres.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import FileFormatError, InputError
from ..io.atomic_write import atomic_path, atomic_write_text, recorded_path, resolve_recorded_path
from ..structures import Mesh
from ..typing import FloatArray, IntArray
from .skin_embedding import SkinEmbedding, embedding_matrix

__all__ = ["FaceAnatomy", "load_anatomy", "ANATOMY_FORMAT"]

ANATOMY_FORMAT = "facecap-anatomy/1"
"""Format tag written in ``anatomy.json``; :func:`load_anatomy` refuses others."""

_ARRAYS = (
    "nodes", "tets", "muscle_fractions", "muscle_fibres", "muscle_curves", "muscle_rings",
    "muscle_widths_mm", "muscle_thicknesses_mm", "cranium_nodes", "mandible_nodes", "rim_nodes",
    "skin_tets", "skin_weights", "skin_inside", "skin_meshed", "condyles", "landmark_vertices",
    "landmark_points", "scan_vertices", "scan_faces", "bone_vertices", "bone_faces", "tissue_thickness_mm",
)
_SCAN_EXPORT_ARRAYS = ("scan_polygon_sizes", "scan_polygon_indices", "scan_uvs", "scan_uv_indices")
"""The scan's polygons and UVs, for the exports only; optional (a triangle scan without UVs has none, and a
model saved before they were kept loads without them)."""


@dataclass(frozen=True, eq=False)
class FaceAnatomy:
    """The soft-tissue mesh of a face with its muscles, bones and skin.

    Attributes
    ----------
    nodes : (N, 3) float64 array, mm
        Tetrahedral mesh nodes (rest pose).
    tets : (M, 4) int64 array
        Tetrahedra, positively oriented.
    muscle_names : tuple of str, length K
    muscle_fractions : (M, K) float64 array in [0, 1]
        Volume fraction of each tetrahedron inside each muscle.
    muscle_fibres : (M, K, 3) float64 array
        Unit fibre direction per tetrahedron and muscle (zero where the fraction is 0).
    muscle_curves : (K, 64, 3) float64 array, mm
        Centre curve of each muscle, origin first (rings closed).
    muscle_rings : (K,) bool array
        Sphincters (fibres round the ring).
    muscle_widths_mm, muscle_thicknesses_mm : (K,) float64 arrays, mm
    cranium_nodes, mandible_nodes : (a,), (b,) int64 arrays
        Nodes on the bone surface, above and below the jaw cut: Dirichlet
        nodes that move with the cranium or with the jaw.
    rim_nodes : (c,) int64 array
        Nodes on the wall that closes the tissue at the outer edge of the
        meshed region, where real tissue continues (not bone; the FEM may
        fix them or leave them free).
    skin_tets : (n,) int64 array
        Tetrahedron carrying each scan vertex.
    skin_weights : (n, 4) float64 array
        Barycentric weights: ``scan_vertices = sum_i w_i nodes[tets[skin_tets, i]]``.
    skin_inside : (n,) bool array
        Scan vertices inside their tetrahedron (the rest are up to the
        fTetWild envelope outside the mesh, or outside the meshed region, and
        are carried by affine extrapolation of the nearest tetrahedron).
    skin_meshed : (n,) bool array
        Scan vertices of the meshed region (the face in front of the ears).
        Those far outside it (ears, scalp, neck: more than 10 mm from every
        node) should move with the cranium: their embedding extrapolates a
        distant tetrahedron (weights up to ~35), exact only at rest.
    condyles : (2, 3) float64 array, mm
        Left and right temporomandibular joint centres.
    landmark_names : tuple of str
    landmark_vertices : (k,) int64 array
        Scan vertex of each named landmark.
    landmark_points : (k, 3) float64 array, mm
    scan_vertices : (n, 3) float64 array, mm
        The scan's vertices (file order).
    scan_faces : (f, 3) int64 array
        The scan's triangles.
    bone_vertices : (s, 3) float64 array, mm
        The bone surface (one vertex under each meshed skin vertex).
    bone_faces : (g, 3) int64 array
        Its triangles, facing away from the tissue (into the skull).
    tissue_thickness_mm : (s,) float64 array, mm
        Skin-to-bone depth along the smoothed normal at each meshed skin
        vertex (row ``i`` is the ``i``-th vertex of ``np.flatnonzero(skin_meshed)``;
        at least 1 mm).
    provenance : dict
        How the model was made (source scan, options, timings, quality, sources).
    scan_polygon_sizes, scan_polygon_indices, scan_uvs, scan_uv_indices : arrays or None
        The scan's polygons (quads) and UVs as :class:`~facecap.structures.Mesh` holds them, so that a
        result written from the model (``solve-muscles``, ``edit-muscles``) exports the scan's own
        polygons and texture coordinates (:meth:`scan_mesh`); None where the scan had none.
    """

    nodes: FloatArray
    tets: IntArray
    muscle_names: tuple[str, ...]
    muscle_fractions: FloatArray
    muscle_fibres: FloatArray
    muscle_curves: FloatArray
    muscle_rings: np.ndarray
    muscle_widths_mm: FloatArray
    muscle_thicknesses_mm: FloatArray
    cranium_nodes: IntArray
    mandible_nodes: IntArray
    rim_nodes: IntArray
    skin_tets: IntArray
    skin_weights: FloatArray
    skin_inside: np.ndarray
    skin_meshed: np.ndarray
    condyles: FloatArray
    landmark_names: tuple[str, ...]
    landmark_vertices: IntArray
    landmark_points: FloatArray
    scan_vertices: FloatArray
    scan_faces: IntArray
    bone_vertices: FloatArray
    bone_faces: IntArray
    tissue_thickness_mm: FloatArray
    provenance: dict[str, Any] = field(default_factory=dict)
    scan_polygon_sizes: IntArray | None = None
    scan_polygon_indices: IntArray | None = None
    scan_uvs: FloatArray | None = None
    scan_uv_indices: IntArray | None = None

    @property
    def n_nodes(self) -> int:
        """Number of nodes N."""
        return int(self.nodes.shape[0])

    @property
    def n_tets(self) -> int:
        """Number of tetrahedra M."""
        return int(self.tets.shape[0])

    @property
    def n_muscles(self) -> int:
        """Number of muscles K."""
        return len(self.muscle_names)

    @property
    def dirichlet_nodes(self) -> IntArray:
        """All bone nodes: ``cranium_nodes`` then ``mandible_nodes`` (the FEM's Dirichlet set, in that order)."""
        return np.concatenate([self.cranium_nodes, self.mandible_nodes])

    def skin_matrix(self) -> sp.csr_matrix:
        """Sparse ``(n, N)`` matrix ``W`` with ``skin = W @ nodes`` (any deformed nodes too)."""
        return embedding_matrix(SkinEmbedding(self.skin_tets, self.skin_weights, self.skin_inside), self.n_nodes, self.tets)

    def skin_positions(self, nodes: Any | None = None) -> FloatArray:
        """The scan's vertices carried by the mesh: ``(n, 3)`` mm for the given (default rest) nodes."""
        X = self.nodes if nodes is None else np.asarray(nodes, dtype=np.float64)
        corners = X[self.tets[self.skin_tets]]
        return np.einsum("ij,ijk->ik", self.skin_weights, corners)

    def scan_mesh(self) -> Mesh:
        """The scan as the output mesh of a result: its vertices at rest, triangles, and its polygons and UVs
        where it had them (millimetres)."""
        source = self.provenance.get("scan")
        return Mesh(np.array(self.scan_vertices), np.array(self.scan_faces), source_unit="mm",
                    polygon_sizes=self.scan_polygon_sizes, polygon_indices=self.scan_polygon_indices,
                    uvs=self.scan_uvs, uv_indices=self.scan_uv_indices, source_path=str(source) if source else None)

    def _provenance_in(self, folder: Path) -> dict[str, Any]:
        """The provenance as ``anatomy.json`` in ``folder`` records it: the scan's path final, never a staging name."""
        scan = self.provenance.get("scan")
        return {**self.provenance, "scan": recorded_path(scan, folder=folder)} if scan else dict(self.provenance)

    def save(self, folder: str | os.PathLike[str]) -> Path:
        """Write ``anatomy.npz`` and ``anatomy.json`` into ``folder`` (created if needed).

        Each file is written under a temporary name and renamed when complete
        (:func:`~facecap.io.atomic_write.atomic_path`); the JSON, written last,
        marks a finished model.

        Parameters
        ----------
        folder : str or path-like

        Returns
        -------
        pathlib.Path
            The folder.
        """
        out = Path(folder)
        if out.exists() and not out.is_dir():
            raise InputError("exists and is not a folder", path=str(out))
        out.mkdir(parents=True, exist_ok=True)
        with atomic_path(out / "anatomy.npz") as tmp:
            with open(tmp, "wb") as handle:
                optional = {name: getattr(self, name) for name in _SCAN_EXPORT_ARRAYS if getattr(self, name) is not None}
                np.savez_compressed(handle, **{name: getattr(self, name) for name in _ARRAYS}, **optional)
        meta = {
            "format": ANATOMY_FORMAT,
            "units": "mm",
            "muscle_names": list(self.muscle_names),
            "landmark_names": list(self.landmark_names),
            "counts": {
                "nodes": self.n_nodes, "tets": self.n_tets, "muscles": self.n_muscles,
                "cranium_nodes": int(self.cranium_nodes.size), "mandible_nodes": int(self.mandible_nodes.size),
                "rim_nodes": int(self.rim_nodes.size), "scan_vertices": int(self.scan_vertices.shape[0]),
            },
            "provenance": self._provenance_in(out),
        }
        atomic_write_text(out / "anatomy.json", json.dumps(meta, indent=2) + "\n")
        return out


def load_anatomy(folder: str | os.PathLike[str]) -> FaceAnatomy:
    """Read a model written by :meth:`FaceAnatomy.save`.

    Parameters
    ----------
    folder : str or path-like
        Holds ``anatomy.json`` and ``anatomy.npz``.

    Returns
    -------
    FaceAnatomy

    Raises
    ------
    FileFormatError
        If a file is missing, unreadable, of another format, or its arrays
        disagree with the counts in ``anatomy.json``.
    """
    folder = Path(folder)
    meta_path, npz_path = folder / "anatomy.json", folder / "anatomy.npz"
    for p in (meta_path, npz_path):
        if not p.is_file():
            raise FileFormatError("missing; not an anatomy folder written by build-anatomy", path=str(p))
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"not readable JSON ({exc})", path=str(meta_path)) from None
    if not isinstance(meta, dict) or meta.get("format") != ANATOMY_FORMAT:
        raise FileFormatError(f"expected format {ANATOMY_FORMAT!r}", path=str(meta_path))
    try:
        with np.load(npz_path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in _ARRAYS}
            arrays.update({name: data[name] for name in _SCAN_EXPORT_ARRAYS if name in data.files})
    except (OSError, ValueError, KeyError) as exc:
        raise FileFormatError(f"cannot read the arrays ({exc})", path=str(npz_path)) from None
    counts = meta.get("counts", {})
    if (arrays["nodes"].shape[0] != counts.get("nodes") or arrays["tets"].shape[0] != counts.get("tets")
            or len(meta.get("muscle_names", [])) != arrays["muscle_fractions"].shape[1]):
        raise FileFormatError("the arrays disagree with the counts in anatomy.json", path=str(npz_path))
    anatomy = FaceAnatomy(
        muscle_names=tuple(meta["muscle_names"]),
        landmark_names=tuple(meta["landmark_names"]),
        provenance=_provenance_from(meta.get("provenance", {}), folder),
        **arrays,
    )
    try:
        anatomy.scan_mesh()
    except (ValueError, InputError) as exc:
        raise FileFormatError(f"the scan's polygons or UVs do not fit its vertices ({exc})", path=str(npz_path)) from None
    return anatomy


def _provenance_from(recorded: dict[str, Any], folder: Path) -> dict[str, Any]:
    """``anatomy.json``'s provenance with the scan's path as a path again (a relative one is the folder's)."""
    scan = recorded.get("scan")
    if not (isinstance(scan, str) and scan):
        return dict(recorded)
    return {**recorded, "scan": str(resolve_recorded_path(scan, folder=folder))}
