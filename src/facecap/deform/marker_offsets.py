"""Skin displacements from marker displacements: the marker's height above the skin turns with the skin.

Optical markers sit a few millimetres above the skin (the centre of a 3 mm
marker is 1.5 mm up). Where the skin under a marker tilts by an angle ``a``,
the marker moves by about ``h a`` more (or less) than the skin does, so
driving the shell with the marker's own displacement bends the surface by
that much. :class:`MarkerOffsets` removes it: each marker is taken to sit at
``skin + h n`` with ``n`` the unit normal of the skin at its vertex, so

``d_skin = d_marker - h (n_t - n_0)``

where ``n_0`` is the scan's normal and ``n_t`` the normal of the deformed
shell at that vertex, which itself depends on ``d_skin``: a fixed point,
reached in one or two steps because ``h (n_t - n_0)`` is a fraction of a
millimetre. The rest offset ``h n_0`` needs no correction: the warp maps the
rest-frame markers onto the scan points, so it absorbs it.

The deformed normal is the area-weighted vertex normal of the shell's surface,
computed only on the triangles round the marker vertices, from the shell's
weights of those triangles' vertices (a few hundred rows of the basis): per
frame, a (ring x K) product instead of the shell's (n x K).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices
from .basis_product import BasisProduct
from .thin_shell import ThinShellSolver

__all__ = ["MarkerOffsets", "MarkerRing", "marker_ring", "DEFAULT_MARKER_OFFSET_MM", "DEFAULT_OFFSET_ITERATIONS"]

DEFAULT_MARKER_OFFSET_MM = 1.5
"""Marker centre above the skin, mm: half a 3 mm marker glued on (as ``register_scans`` assumes)."""

DEFAULT_OFFSET_ITERATIONS = 2
"""Fixed-point steps of :meth:`MarkerOffsets.skin_displacements`."""

# Frames per vectorised step: keeps the (faces, 3, frames) temporaries in cache.
_CHUNK_FRAMES = 64


class MarkerRing(NamedTuple):
    """The triangles round each marker vertex, welded across UV seams: the mesh side of :class:`MarkerOffsets`."""

    marker_vertices: np.ndarray
    """(K,) int64: the marker vertices, in order."""
    ring_vertices: np.ndarray
    """(r,) int64: the vertices of those triangles (their rows of the shell's basis)."""
    local_faces: np.ndarray
    """(f, 3) int64: the triangles, as indices into ``ring_vertices``."""
    scatter: sp.csr_matrix
    """(K, f): which triangles are round which marker vertex."""
    rest_normals: np.ndarray
    """(K, 3) float64: the scan's unit area-weighted normal at each marker vertex."""


def marker_ring(V: FloatArray, F: IntArray, marker_vertices: IntArray) -> MarkerRing:
    """The triangles round each marker vertex and the scan's normal there, from the mesh alone.

    What :class:`MarkerOffsets` needs of the mesh, before any shell exists
    (``animate`` builds it beside the shell's set-up, and the warp its rest
    normals give); pass it as ``MarkerOffsets(..., ring=...)``.

    Raises
    ------
    InputError
        On bad arrays, a marker vertex in no triangle, or one whose triangles are all degenerate.
    """
    V = as_vertices(V)
    F = as_faces(F, V.shape[0])
    c = np.asarray(marker_vertices, dtype=np.int64).ravel()
    if c.size == 0 or c.min() < 0 or c.max() >= V.shape[0]:
        raise InputError(f"marker_vertices: expected indices in [0, {V.shape[0]}), got {c.tolist()[:10]}")
    K = c.size
    _, Fw, welded_index = weld_duplicate_vertices(V, F)
    marker_of = np.full(int(welded_index.max()) + 1, -1, dtype=np.int64)
    marker_of[welded_index[c]] = np.arange(K)
    at_marker = marker_of[Fw]  # (m, 3): marker owning each corner, -1 if none
    ring_faces = np.flatnonzero((at_marker >= 0).any(axis=1))
    corners = F[ring_faces]  # original indices: their rows of the basis
    owners = at_marker[ring_faces]
    hit = owners >= 0
    S = sp.csr_matrix(
        (np.ones(int(hit.sum())), (owners[hit], np.broadcast_to(np.arange(ring_faces.size)[:, None], owners.shape)[hit])),
        shape=(K, ring_faces.size),
    )
    missing = np.flatnonzero(np.diff(S.indptr) == 0)
    if missing.size:
        raise InputError(f"marker vertices in no triangle: {c[missing].tolist()}")
    ring, local = np.unique(corners, return_inverse=True)
    local = local.reshape(corners.shape)
    rest = V[ring].astype(np.float32)[None]  # the float32 ring positions the deformed normals start from
    rest_normals = _ring_normals(rest, local, S, K)[0]
    if not np.isfinite(rest_normals).all():
        bad = c[~np.isfinite(rest_normals).all(axis=1)]
        raise InputError(f"marker vertices with degenerate triangles only (no normal): {bad.tolist()}")
    return MarkerRing(c, ring, local, S, rest_normals)


def _ring_normals(X: np.ndarray, faces: np.ndarray, scatter: sp.csr_matrix, n_markers: int) -> np.ndarray:
    """Area-weighted unit normals (t, K, 3) at the marker vertices, the ring's vertices at ``X`` (t, r, 3) float32."""
    t, f = X.shape[0], faces.shape[0]
    # (r, 3, t): a corner's coordinates contiguous over the frames, so the gathers below copy whole rows
    # and the products run on contiguous memory (half the time of gathering from (t, r, 3); same values)
    corners = np.ascontiguousarray(X.transpose(1, 2, 0))
    a = corners[faces[:, 0]]
    u = corners[faces[:, 1]]  # (faces, 3, t): each triangle's two edges
    u -= a
    w = corners[faces[:, 2]]
    w -= a
    fn = np.empty((f, 3, t), np.float32)  # the cross product, component by component
    np.multiply(u[:, 1], w[:, 2], out=fn[:, 0])
    fn[:, 0] -= u[:, 2] * w[:, 1]
    np.multiply(u[:, 2], w[:, 0], out=fn[:, 1])
    fn[:, 1] -= u[:, 0] * w[:, 2]
    np.multiply(u[:, 0], w[:, 1], out=fn[:, 2])
    fn[:, 2] -= u[:, 1] * w[:, 0]
    N = (scatter @ fn.reshape(f, 3 * t)).reshape(n_markers, 3, t).astype(np.float64)
    N /= np.sqrt(np.einsum("kct,kct->kt", N, N))[:, None]
    return N.transpose(2, 0, 1)


class MarkerOffsets:
    """Turn marker displacements into skin displacements for a thin shell.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Rest (scan) vertex positions, the shell's.
    F : (m, 3) int64 array
        Triangles, consistently oriented (normals out of the face).
    shell : ThinShellSolver
        The shell the skin displacements will drive; its weights of the
        marker vertices' 1-rings give the deformed normals.
    marker_offset_mm : float, default 1.5
        Height of the marker centre above the skin, mm (half the marker's
        diameter for markers glued on). 0 makes :meth:`skin_displacements`
        the identity.
    iterations : int, default 2
        Fixed-point steps.
    ring : MarkerRing, optional
        :func:`marker_ring` of ``V``, ``F`` and the shell's marker vertices,
        when it was built already (before the shell); default: built here.

    Attributes
    ----------
    rest_normals : (K, 3) float64 array
        Unit normal of the scan at each marker vertex.

    Raises
    ------
    InputError
        On bad arrays or options, or a marker vertex without a triangle.

    Notes
    -----
    The marker sits at ``x + h n(x)`` on the skin point ``x``; with the skin
    displaced by ``d`` the marker moves by ``d + h (n_t - n_0)``. Given the
    marker's displacement ``m`` (face space), the skin displacement solves
    ``d = m - h (n_t(d) - n_0)``, iterated from ``d = m``. ``n_t`` is the
    area-weighted normal ``normalize(sum_f (x_1 - x_0) x (x_2 - x_0))`` over
    the triangles at the marker vertex (welded across UV seams), with the
    triangle corners moved by the shell: ``x = V + B^T d``. For a locally
    linear displacement ``x -> x + G x`` every triangle's normal becomes
    ``cof(I + G) n``, so the 1-ring normal turns as the smooth field does,
    whatever the mesh resolution.

    Examples
    --------
    >>> import numpy as np
    >>> from facecap.deform.thin_shell import ThinShellSolver
    >>> g = np.arange(5.0)
    >>> V = np.array([[x, y, 0.0] for y in g for x in g])
    >>> F = np.array([[i + 5 * j, i + 1 + 5 * j, i + 5 * (j + 1)] for j in range(4) for i in range(4)]
    ...              + [[i + 1 + 5 * j, i + 6 + 5 * j, i + 5 * (j + 1)] for j in range(4) for i in range(4)])
    >>> shell = ThinShellSolver(V, F, np.array([6, 8, 16, 18]))
    >>> offsets = MarkerOffsets(V, F, shell, marker_offset_mm=1.5)
    >>> d = np.zeros((1, 4, 3)); d[..., 2] = 0.3  # a lift: the normals do not turn
    >>> bool(np.allclose(offsets.skin_displacements(d), d))
    True
    """

    def __init__(
        self,
        V: FloatArray,
        F: IntArray,
        shell: ThinShellSolver,
        *,
        marker_offset_mm: float = DEFAULT_MARKER_OFFSET_MM,
        iterations: int = DEFAULT_OFFSET_ITERATIONS,
        ring: MarkerRing | None = None,
    ) -> None:
        V = as_vertices(V)
        F = as_faces(F, V.shape[0])
        if not isinstance(shell, ThinShellSolver):
            raise InputError(f"shell: expected a ThinShellSolver, got {type(shell).__name__}")
        if shell.n_vertices != V.shape[0]:
            raise InputError(f"shell: built for {shell.n_vertices} vertices, V has {V.shape[0]}")
        self.marker_offset_mm = as_positive(marker_offset_mm, name="marker_offset_mm", allow_zero=True)
        if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
            raise InputError(f"iterations: expected a non-negative integer, got {iterations!r}")
        self.iterations = int(iterations)
        c = shell.constrained_vertices
        if ring is None:
            ring = marker_ring(V, F, c)
        elif not np.array_equal(ring.marker_vertices, c):
            raise InputError("ring: built for other marker vertices than the shell's")
        self.n_markers = c.size
        W = shell.product.weight_rows(ring.ring_vertices).astype(np.float64)  # (r, K): the shell's rows of the ring
        # The ring moves by one small product per step, run like the shell's own
        # (single-threaded MKL where present: too small to share out between threads).
        self._ring = BasisProduct(W, precision="float32", workers=1)
        self._ring_rest = V[ring.ring_vertices].astype(np.float32)
        self._local_faces = ring.local_faces
        self._scatter = ring.scatter
        self.ring_vertices = ring.ring_vertices
        self.rest_normals = ring.rest_normals

    def deformed_normals(self, skin_displacements: FloatArray) -> FloatArray:
        """Unit normal of the deformed shell at each marker vertex.

        Parameters
        ----------
        skin_displacements : (T, K, 3) float array, mm
            The shell's marker displacements.

        Returns
        -------
        (T, K, 3) float64 array
        """
        D = self._as_frames(skin_displacements, "skin_displacements")
        out = np.empty_like(D)
        for lo in range(0, D.shape[0], _CHUNK_FRAMES):
            d = D[lo : lo + _CHUNK_FRAMES]
            out[lo : lo + _CHUNK_FRAMES] = self._normals(d)
        return out

    def skin_displacements(self, marker_displacements: FloatArray) -> FloatArray:
        """Skin displacements whose markers, ``h`` above the deformed skin, move as observed.

        Parameters
        ----------
        marker_displacements : (T, K, 3) float array, mm
            Marker displacements in face space (the warp's), no NaN.

        Returns
        -------
        (T, K, 3) float64 array, mm
            ``d = m - h (n_t(d) - n_0)`` after :attr:`iterations` steps.
        """
        M = self._as_frames(marker_displacements, "marker_displacements")
        if self.marker_offset_mm == 0 or self.iterations == 0:
            return M.copy()
        h = self.marker_offset_mm
        n0 = self.rest_normals[None]
        out = np.empty_like(M)
        for lo in range(0, M.shape[0], _CHUNK_FRAMES):
            m = M[lo : lo + _CHUNK_FRAMES]
            d = m
            for _ in range(self.iterations):
                d = m - h * (self._normals(d) - n0)
            out[lo : lo + _CHUNK_FRAMES] = d
        return out

    def _as_frames(self, D: FloatArray, name: str) -> np.ndarray:
        A = np.asarray(D, dtype=np.float64)
        if A.ndim != 3 or A.shape[1:] != (self.n_markers, 3):
            raise InputError(f"{name}: expected (T, {self.n_markers}, 3), got {A.shape}")
        if not np.isfinite(A).all():
            raise InputError(f"{name}: contain NaN or infinite values (fill the gaps first)")
        return A

    def _normals(self, d: np.ndarray) -> np.ndarray:
        """Area-weighted unit normals (t, K, 3) at the marker vertices of the shell moved by d (t, K, 3)."""
        X = np.empty((d.shape[0], self._ring_rest.shape[0], 3), np.float32)
        self._ring.apply_into(d, self._ring_rest, X)  # the ring's vertices, moved
        return _ring_normals(X, self._local_faces, self._scatter, self.n_markers)
