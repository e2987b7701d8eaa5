"""The small frozen records that travel together through I/O and the CLI.

Algorithms take and return plain arrays; these records only bundle what a file
holds so that nothing (units, labels, rate, UVs) gets lost on the way. They hold
no hidden caches. :class:`Mesh` (a scan), :class:`MarkerSequence` (a take),
:class:`Correspondence` (where each marker sits on the scan: what
:func:`facecap.io.read_correspondence` reads), :class:`ConditionedTake` (a take
after :func:`facecap.markers.condition_take`, as
:func:`facecap.io.write_conditioned_take` stores it) with its
:class:`TemporalSigmaChoice` (:func:`facecap.markers.choose_temporal_sigma`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .errors import CorrespondenceError, InputError, MarkerError, MeshError
from .typing import BoolArray, FloatArray, IntArray
from .units import mm_per_unit, normalize_unit
from .validate import as_faces, as_marker_positions, as_vertices

if TYPE_CHECKING:
    import scipy.sparse as sp

__all__ = ["Mesh", "MarkerSequence", "Correspondence", "ConditionedTake", "TemporalSigmaChoice"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """A surface mesh in millimetres, keeping the file's vertex order and polygons.

    Parameters
    ----------
    vertices : (n, 3) float64 array, mm
        Vertex positions, in the file's order and count.
    faces : (m, 3) int64 array
        Triangles used by the solvers (polygons fan-triangulated).
    polygon_sizes : (k,) int64 array or None
        Corner count of each original polygon, for export; None if the file
        held triangles only (then ``faces`` are the polygons).
    polygon_indices : (sum(polygon_sizes),) int64 array or None
        Vertex index of each polygon corner, polygons one after another.
    uvs : (u, 2) float64 array or None
        Texture coordinates.
    uv_indices : (sum(polygon_sizes) or 3 m,) int64 array or None
        UV index of each polygon corner (face-varying), aligned with
        ``polygon_indices`` (or with ``faces.ravel()`` when there are no polygons).
    source_unit : {'mm', 'cm', 'm', 'in'}
        The length unit of the file the mesh came from; ``vertices`` are
        already converted to mm.
    source_path : str or None
        The file the mesh was read from.
    vertex_colors : (n, 3) float32 array in [0, 1], or None
        Per-vertex RGB colour as stored in the file, i.e. sRGB-encoded (not
        linear light), scaled to [0, 1]; None (default) when the mesh has no
        colours. Readers convert 8-bit values (0..255) before building the mesh.
        Kept by :meth:`with_vertices` (the colours belong to the vertices, not
        to their positions).
    texture : (h, w, 3) uint8 or uint16 array, or None
        The colour image the UVs index (a scanner's texture atlas), as stored:
        sRGB-encoded, row 0 the image's top, RGB order; None (default) when the
        mesh has none. UVs follow the OBJ convention (``v = 0`` at the image's
        bottom, ``u`` wrapping). Needs ``uvs`` and ``uv_indices``. Kept by
        :meth:`with_vertices`; :func:`facecap.mesh.surface_colors` reads it.
    """

    vertices: FloatArray
    faces: IntArray
    polygon_sizes: IntArray | None = None
    polygon_indices: IntArray | None = None
    uvs: FloatArray | None = None
    uv_indices: IntArray | None = None
    source_unit: str = "mm"
    source_path: str | None = None
    vertex_colors: FloatArray | None = field(default=None, repr=False)
    texture: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        V = as_vertices(self.vertices, name="vertices")
        object.__setattr__(self, "vertices", V)
        if self.texture is not None:
            object.__setattr__(self, "texture", _as_texture(self.texture, self.uvs, self.uv_indices))
        if self.vertex_colors is not None:
            object.__setattr__(
                self, "vertex_colors", _as_vertex_colors(self.vertex_colors, V.shape[0])
            )
        object.__setattr__(self, "faces", as_faces(self.faces, V.shape[0], name="faces"))
        object.__setattr__(self, "source_unit", normalize_unit(self.source_unit, name="source_unit"))
        if (self.polygon_sizes is None) != (self.polygon_indices is None):
            raise ValueError("polygon_sizes and polygon_indices go together")
        if self.polygon_sizes is not None:
            sizes = np.ascontiguousarray(self.polygon_sizes, dtype=np.int64)
            idx = np.ascontiguousarray(self.polygon_indices, dtype=np.int64)
            if sizes.sum() != idx.size:
                raise ValueError("polygon_sizes do not add up to len(polygon_indices)")
            object.__setattr__(self, "polygon_sizes", sizes)
            object.__setattr__(self, "polygon_indices", idx)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return int(self.faces.shape[0])

    def export_polygons(self) -> tuple[IntArray, IntArray]:
        """Return ``(sizes, indices)`` of the faces to export: the original polygons if kept."""
        if self.polygon_sizes is not None and self.polygon_indices is not None:
            return self.polygon_sizes, self.polygon_indices
        return np.full(self.n_faces, 3, dtype=np.int64), self.faces.ravel()

    def to_source_unit(self, points_mm: np.ndarray) -> np.ndarray:
        """Convert points in mm back to this mesh's source unit (for export)."""
        return points_mm / mm_per_unit(self.source_unit)

    def with_vertices(self, vertices: FloatArray) -> "Mesh":
        """A copy of this mesh with other vertex positions (mm), same topology."""
        return replace(self, vertices=vertices)


def _as_texture(image: object, uvs: object, uv_indices: object) -> np.ndarray:
    """``image`` as a C-contiguous (h, w, 3) uint8 or uint16 array, or raise; the UVs must exist."""
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise MeshError(f"texture: expected an (h, w, 3) RGB image, got shape {arr.shape}")
    if arr.dtype not in (np.uint8, np.uint16):
        raise MeshError(f"texture: expected 8- or 16-bit values as stored, got {arr.dtype}")
    if uvs is None or uv_indices is None:
        raise MeshError("texture: a texture needs uvs and uv_indices to say where it goes")
    return np.ascontiguousarray(arr)


def _as_vertex_colors(C: object, n_vertices: int) -> np.ndarray:
    """``C`` as a C-contiguous (n, 3) float32 array of finite values in [0, 1], or raise."""
    try:
        arr = np.asarray(C, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshError(
            f"vertex_colors: expected an ({n_vertices}, 3) array of numbers, got {type(C).__name__}"
        ) from None
    if arr.shape != (n_vertices, 3):
        raise MeshError(
            f"vertex_colors: expected shape ({n_vertices}, 3) (one RGB per vertex), got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise MeshError("vertex_colors: expected finite values, got NaN or infinity")
    if arr.size and (arr.min() < 0.0 or arr.max() > 1.0):
        raise MeshError(
            f"vertex_colors: expected values in [0, 1], got [{arr.min():.6g}, {arr.max():.6g}] "
            "(divide 8-bit colours by 255)"
        )
    return np.ascontiguousarray(arr, dtype=np.float32)


@dataclass(frozen=True, eq=False)
class MarkerSequence:
    """A labelled marker take in millimetres, NaN for occluded samples.

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        Marker positions per frame; NaN where the marker was not seen.
    labels : tuple of str, length M
        Marker names, unique.
    rate : float
        Frame rate in Hz.
    source_unit : {'mm', 'cm', 'm', 'in'}
        Unit of the file the take came from; ``positions`` are in mm.
    source_path : str or None
        The file the take was read from.
    first_frame : int
        0-based number of the first frame in the capture system's own
        numbering (C3D header frame 1 and TRC ``Frame#`` 1 are 0), for timecodes.
    residuals : (T, M) float64 array, mm, or None
        Per-sample C3D residual, NaN at gaps; None for formats without one.
    subjects : tuple of str, length M, or None
        Per-marker subject name split off a ``Subject:Marker`` label (Vicon
        Nexus, OptiTrack Motive), ``''`` for a marker without one; None when
        the file's labels carry no subject.
    timecode : str or None
        SMPTE timecode of the first frame as the file states it,
        ``'HH:MM:SS:FF'`` (``;`` before the frames for drop-frame timecode, a
        ``.n`` suffix for a subframe); None when the file holds none.
    capture_start : str or None
        Date and time the capture started, as the file writes it (QTM
        ``TIME_STAMP``, Motive ``Capture Start Time``); None when it holds none.
    """

    positions: FloatArray
    labels: tuple[str, ...]
    rate: float
    source_unit: str = "mm"
    source_path: str | None = None
    first_frame: int = 0
    residuals: FloatArray | None = field(default=None, repr=False)
    subjects: tuple[str, ...] | None = None
    timecode: str | None = None
    capture_start: str | None = None

    def __post_init__(self) -> None:
        P = as_marker_positions(self.positions, name="positions")
        object.__setattr__(self, "positions", P)
        labels = tuple(str(s) for s in self.labels)
        if len(labels) != P.shape[1]:
            raise MarkerError(f"labels: expected {P.shape[1]} labels, got {len(labels)}")
        if self.subjects is not None:
            subjects = tuple(str(s) for s in self.subjects)
            if len(subjects) != len(labels):
                raise MarkerError(f"subjects: expected {len(labels)} subject names, got {len(subjects)}")
            object.__setattr__(self, "subjects", subjects)
        if len(set(labels)) != len(labels):
            dup = sorted({s for s in labels if labels.count(s) > 1})
            raise MarkerError(f"labels: duplicate marker labels {dup}")
        object.__setattr__(self, "labels", labels)
        rate = float(self.rate)
        if not np.isfinite(rate) or rate <= 0:
            raise MarkerError(f"rate: expected a positive frame rate in Hz, got {self.rate!r}")
        object.__setattr__(self, "rate", rate)
        object.__setattr__(self, "source_unit", normalize_unit(self.source_unit, name="source_unit"))

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.positions.shape[0])

    @property
    def n_markers(self) -> int:
        """Number of markers M."""
        return int(self.positions.shape[1])

    @property
    def times(self) -> FloatArray:
        """(T,) float64 time of each frame in seconds, from the start of the take."""
        return np.arange(self.n_frames, dtype=np.float64) / self.rate

    @property
    def gap_mask(self) -> BoolArray:
        """(T, M) bool, True where a marker is occluded."""
        return np.isnan(self.positions).any(axis=2)

    def label_index(self) -> dict[str, int]:
        """Map of label to marker column."""
        return {s: i for i, s in enumerate(self.labels)}

    def select(self, labels: list[str] | tuple[str, ...]) -> "MarkerSequence":
        """The take restricted to ``labels``, in that order."""
        index = self.label_index()
        missing = [s for s in labels if s not in index]
        if missing:
            raise MarkerError(f"labels not in the take: {missing}")
        cols = [index[s] for s in labels]
        return replace(
            self,
            positions=self.positions[:, cols],
            labels=tuple(labels),
            residuals=None if self.residuals is None else self.residuals[:, cols],
            subjects=None if self.subjects is None else tuple(self.subjects[c] for c in cols),
        )

    def with_positions(self, positions: FloatArray) -> "MarkerSequence":
        """A copy with other positions (mm), same labels and rate."""
        return replace(self, positions=positions, residuals=None)


@dataclass(frozen=True, eq=False)
class Correspondence:
    """Where each marker sits on the scan, as a weighted sum of three vertices.

    Marker ``k`` sits at ``sum_j weights[k, j] * V[vertex_indices[k, j]]``
    for any vertex positions ``V`` of the scan's topology, so the same map
    follows the scan as it deforms.

    Parameters
    ----------
    labels : tuple of str, length K
        Marker labels, unique.
    vertex_indices : (K, 3) int64 array
        The vertices each marker is attached to: the corners of the triangle
        its point was snapped to, or ``(i, i, i)`` for a vertex-index entry.
    weights : (K, 3) float64 array
        Barycentric weights, non-negative, each row summing to 1;
        ``(1, 0, 0)`` for a vertex-index entry.
    triangles : (K,) int64 array
        Triangle each point was snapped to (row of ``mesh.faces``), -1 for a
        vertex-index entry.
    snap_distances : (K,) float64 array, mm
        Distance from a given point to the surface point it was snapped to;
        0 for a vertex-index entry. A large value usually means the point is
        in another unit than assumed.
    source_path : str or None
        The map file, for error messages.
    """

    labels: tuple[str, ...]
    vertex_indices: IntArray
    weights: FloatArray
    triangles: IntArray = field(default=None)  # type: ignore[assignment]
    snap_distances: FloatArray = field(default=None, repr=False)  # type: ignore[assignment]
    source_path: str | None = None

    def __post_init__(self) -> None:
        labels = tuple(str(s) for s in self.labels)
        K = len(labels)
        idx = np.ascontiguousarray(self.vertex_indices, dtype=np.int64)
        w = np.ascontiguousarray(self.weights, dtype=np.float64)
        if idx.shape != (K, 3) or w.shape != (K, 3):
            raise CorrespondenceError(
                f"vertex_indices and weights: expected shape ({K}, 3), got {idx.shape} and {w.shape}",
                path=self.source_path,
            )
        if len(set(labels)) != K:
            raise CorrespondenceError("labels: duplicate marker labels", path=self.source_path)
        tri = np.full(K, -1, np.int64) if self.triangles is None else np.ascontiguousarray(self.triangles, np.int64)
        dist = np.zeros(K) if self.snap_distances is None else np.ascontiguousarray(self.snap_distances, np.float64)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "vertex_indices", idx)
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "triangles", tri)
        object.__setattr__(self, "snap_distances", dist)

    def __len__(self) -> int:
        return len(self.labels)

    def points(self, V: Any) -> FloatArray:
        """Marker positions on a scan with vertex positions ``V``.

        Parameters
        ----------
        V : (n, 3) or (T, n, 3) float64 array, mm
            Vertex positions of the scan's topology (one pose or T poses).

        Returns
        -------
        P : (K, 3) or (T, K, 3) float64 array, mm
            ``P[..., k, :] = sum_j weights[k, j] * V[..., vertex_indices[k, j], :]``.

        Raises
        ------
        InputError
            If ``V`` is not (n, 3) or (T, n, 3) or has fewer vertices than the
            map refers to.
        """
        A = np.asarray(V, dtype=np.float64)
        if A.ndim not in (2, 3) or A.shape[-1] != 3:
            raise InputError(f"V: expected shape (n, 3) or (T, n, 3), got {A.shape}")
        if len(self) and int(self.vertex_indices.max()) >= A.shape[-2]:
            raise InputError(
                f"V: the map refers to vertex {int(self.vertex_indices.max())} but V has {A.shape[-2]} vertices"
            )
        return np.einsum("kj,...kjd->...kd", self.weights, A[..., self.vertex_indices, :])

    def matrix(self, n_vertices: int) -> sp.csr_matrix:
        """The map as a sparse (K, n_vertices) matrix ``W`` with ``W @ V == self.points(V)``."""
        import scipy.sparse as sp  # not at import: ``import facecap`` stays light

        if len(self) and int(self.vertex_indices.max()) >= n_vertices:
            raise InputError(
                f"n_vertices: the map refers to vertex {int(self.vertex_indices.max())}, got n_vertices={n_vertices}"
            )
        rows = np.repeat(np.arange(len(self)), 3)
        return sp.csr_matrix(
            (self.weights.ravel(), (rows, self.vertex_indices.ravel())), shape=(len(self), int(n_vertices))
        )

    def select(self, labels: tuple[str, ...] | list[str]) -> "Correspondence":
        """The map restricted to ``labels``, in that order."""
        index = {s: i for i, s in enumerate(self.labels)}
        missing = [s for s in labels if s not in index]
        if missing:
            raise CorrespondenceError(f"labels not in the map: {missing}", path=self.source_path)
        rows = np.array([index[s] for s in labels], dtype=np.int64)
        return Correspondence(
            labels=tuple(labels),
            vertex_indices=self.vertex_indices[rows],
            weights=self.weights[rows],
            triangles=self.triangles[rows],
            snap_distances=self.snap_distances[rows],
            source_path=self.source_path,
        )


class TemporalSigmaChoice(NamedTuple):
    """The sigma chosen and the cross-validation score of every candidate."""

    sigma_s: float
    """The candidate with the smallest score, s."""
    candidates_s: tuple[float, ...]
    scores_mm2: tuple[float, ...]
    """Mean squared distance (mm^2) from each scored sample to the filter's prediction of it from the
    other samples (nearby frames and markers), per candidate."""
    scored_frames: int
    """Frames the scores are averaged over (spread over the take; all of it when short)."""


@dataclass(frozen=True, eq=False)
class ConditionedTake:
    """A take after conditioning, all markers kept in the take's column order.

    Attributes
    ----------
    positions : (T, M, 3) float64 array, mm
        Gap-filled, stabilised (if asked) and filtered positions; NaN only
        where a marker could not be recovered.
    filled : (T, M) bool array
        Samples made up by gap filling.
    head_rotations, head_translations : (T, 3, 3), (T, 3) float64 arrays or None
        The stabilising transform of each frame (``x' = R x + t``), if stabilised.
    stabilization_residual : (T,) float64 array or None, mm
        RMS misfit of the stable markers after stabilisation.
    stable_labels : tuple of str
        Markers the stabilisation used.
    temporal_sigma_s : float or None
        The bilateral filter's temporal sigma (s); None where the take was not filtered.
    temporal_sigma_choice : TemporalSigmaChoice or None
        How it was chosen, when it was (``temporal_sigma_s='auto'``): every
        candidate's cross-validation score.
    head_pose_from : str or None
        One of :data:`facecap.markers.HEAD_POSE_SOURCES`; None where the take was not stabilised.
    """

    positions: np.ndarray
    filled: np.ndarray
    head_rotations: np.ndarray | None
    head_translations: np.ndarray | None
    stabilization_residual: np.ndarray | None
    stable_labels: tuple[str, ...]
    temporal_sigma_s: float | None = None
    temporal_sigma_choice: TemporalSigmaChoice | None = None
    head_pose_from: str | None = None
