"""Linear thin-shell deformation driven by marker displacements (Bickel et al. 2007, section 4.2)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import igl
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import CorrespondenceError, FacecapWarning, InputError
from ..mesh.connected_pieces import connected_pieces
from ..mesh.laplacian import laplace_operators
from ..mesh.weld_duplicate_vertices import weld_duplicate_vertices
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_positive, as_vertices
from .basis_product import BasisProduct, Precision
from ..mesh.factor_spd import Backend, SpdFactor

__all__ = ["ThinShellSolver", "PieceReport", "thin_shell_deform", "DEFAULT_KS", "DEFAULT_KB_MM2"]

DEFAULT_KS = 1.0
"""Default stretching stiffness ``ks`` (dimensionless)."""

DEFAULT_KB_MM2 = 100.0
"""Default bending stiffness ``kb`` in mm^2 (``sqrt(kb / ks)`` = 10 mm is the length
scale below which bending dominates stretching)."""

UnmarkedPieces = Literal["carry", "rigid"]

# Relative to the mean triangle area: anything smaller has no usable cotangents.
_DEGENERATE_AREA = 1e-10
# Unmarked pieces follow the average motion of this many nearest marked vertices.
_CARRY_NEIGHBOURS = 32
# Marker right-hand sides per sparse solve during set-up: bounds its memory.
_RHS_PER_SOLVE = 32


@dataclass(frozen=True)
class PieceReport:
    """What the solver did with each connected piece of the scan.

    Attributes
    ----------
    n_pieces : int
        Connected pieces after welding duplicate vertices.
    marked_pieces : list of int
        Pieces holding at least one marker: solved as thin shells.
    unmarked_pieces : list of int
        Pieces with no marker (eyes, teeth, ...): carried or left rigid.
    piece_sizes : list of int
        Vertex count of each piece.
    unmarked_policy : {'carry', 'rigid'}
    welded_vertices : int
        Vertices merged into another one at the same position (UV-seam splits).
    degenerate_faces : int
        Zero-area or repeated-index triangles left out of the operators.
    unreferenced_vertices : int
        Vertices in no triangle; treated like an unmarked piece.
    """

    n_pieces: int
    marked_pieces: list[int]
    unmarked_pieces: list[int]
    piece_sizes: list[int]
    unmarked_policy: str
    welded_vertices: int
    degenerate_faces: int
    unreferenced_vertices: int

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return dict(self.__dict__)


class ThinShellSolver:
    """Precomputed linear thin-shell deformation with markers as hard constraints.

    Minimises ``int ks |grad d|^2 + kb |Laplacian d|^2`` over the displacement
    field ``d`` with ``d = d_i`` at the marker vertices (Bickel et al. 2007,
    eq. 3-4). The discrete Euler-Lagrange system is

    ``(ks L + kb L M^-1 L) d = 0`` on free vertices,

    with ``L`` the cotangent Laplacian and ``M`` the mixed Voronoi mass. The
    right-hand side changes per frame only through the K marker displacements,
    so the set-up factors the system once and solves it for K unit right-hand
    sides, giving a basis ``B`` (K x n): every frame is then one dense product
    ``d = B^T d_markers``, batched over frames (:class:`BasisProduct`).

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Rest (scan) vertex positions.
    F : (m, 3) int64 array
        Triangles.
    constrained_vertices : (K,) int64 array
        Vertex index of each marker on the scan (distinct).
    ks : float, default 1.0
        Stretching stiffness, dimensionless.
    kb : float, default 100.0
        Bending stiffness in mm^2. Only the ratio ``kb / ks`` matters (there is
        no load besides the markers); ``sqrt(kb / ks)`` is a length: the scale
        below which the deformation is bending-dominated (smooth) rather than
        stretching-dominated (tent-like). Since facecap works in mm, the same
        defaults behave the same for scans stored in mm, cm or m. ``ks = 0``
        gives the pure biharmonic deformation (libigl ``harmonic(..., k=2)``).
    unmarked_pieces : {'carry', 'rigid'}, default 'carry'
        Connected pieces with no marker (eyes, teeth, tongue): ``'carry'`` moves
        each by the mean displacement of the nearest marked surface;
        ``'rigid'`` leaves them where they are.
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
        Sparse factorisation backend, see :class:`SpdFactor`.
    keep_factor : bool, default False
        Keep the sparse factor after set-up so :meth:`solve_direct` can run the
        per-frame sparse solve (for checks and benchmarks); costs its memory.
    weld_tolerance_mm : float, default 1e-6
        Vertices closer than this are one vertex for the solve (UV seams).
    precision : {'float32', 'int16'}, default 'float32'
        Arithmetic of the per-frame product, see :class:`BasisProduct`.
        ``'int16'`` is about 1.5x faster on AVX-512 VNNI machines with MKL and
        differs by about 1e-4 of the displacement.

    Attributes
    ----------
    basis : (K, n) float32 array
        Displacement of every vertex per unit displacement of each marker (a
        copy made on access; the hot path keeps its own blocked layout).
    product : BasisProduct
        The per-frame product.
    pieces : PieceReport

    Raises
    ------
    InputError, CorrespondenceError
        On bad arrays, markers out of range or sharing a vertex.

    References
    ----------
    .. [1] B. Bickel et al., "Multi-Scale Capture of Facial Geometry and Motion",
       SIGGRAPH 2007, section 4.2.
    .. [2] M. Botsch, L. Kobbelt, "An Intuitive Framework for Real-Time Freeform
       Modeling", SIGGRAPH 2004.
    """

    def __init__(
        self,
        V: FloatArray,
        F: IntArray,
        constrained_vertices: IntArray,
        *,
        ks: float = DEFAULT_KS,
        kb: float = DEFAULT_KB_MM2,
        unmarked_pieces: UnmarkedPieces = "carry",
        backend: Backend = "auto",
        keep_factor: bool = False,
        weld_tolerance_mm: float = 1e-6,
        precision: Precision = "float32",
    ) -> None:
        V = as_vertices(V)
        F = as_faces(F, V.shape[0])
        ks = as_positive(ks, name="ks", allow_zero=True)
        kb = as_positive(kb, name="kb", allow_zero=True)
        if ks == 0 and kb == 0:
            raise InputError("ks and kb: at least one stiffness must be positive")
        if unmarked_pieces not in ("carry", "rigid"):
            raise InputError(f"unmarked_pieces: expected 'carry' or 'rigid', got {unmarked_pieces!r}")
        c = np.asarray(constrained_vertices)
        if c.ndim != 1 or c.size == 0 or not np.issubdtype(c.dtype, np.integer):
            raise InputError(f"constrained_vertices: expected a non-empty (K,) integer array, got {c.shape} {c.dtype}")
        c = c.astype(np.int64)
        if c.min() < 0 or c.max() >= V.shape[0]:
            raise CorrespondenceError(
                f"constrained_vertices: index out of range 0..{V.shape[0] - 1} (got {c.min()}..{c.max()})"
            )
        n = V.shape[0]
        self.n_vertices = n
        self.ks, self.kb = ks, kb

        # Weld UV-seam duplicates so the solve sees one connected surface.
        Vw, Fw, welded_index = weld_duplicate_vertices(V, F, tolerance=weld_tolerance_mm)
        cw = welded_index[c]
        if np.unique(cw).size != cw.size:
            _, first, counts = np.unique(cw, return_index=True, return_counts=True)
            dup = [int(c[i]) for i, k in zip(first, counts) if k > 1]
            raise CorrespondenceError(f"several markers sit on the same scan vertex: {dup}")

        # Degenerate triangles have infinite cotangents: leave them out.
        area2 = igl.doublearea(Vw, Fw)
        repeated = (Fw[:, 0] == Fw[:, 1]) | (Fw[:, 1] == Fw[:, 2]) | (Fw[:, 0] == Fw[:, 2])
        degenerate = repeated | ~(area2 > _DEGENERATE_AREA * max(float(np.mean(area2)), 1e-300))
        Fs = Fw[~degenerate]
        nw = Vw.shape[0]
        referenced = np.zeros(nw, dtype=bool)
        referenced[Fs.ravel()] = True
        if not referenced[cw].all():
            bad = [int(c[i]) for i in np.flatnonzero(~referenced[cw])]
            raise CorrespondenceError(f"markers on vertices that belong to no usable triangle: {bad}")

        n_pieces, labels = connected_pieces(Fs, nw)
        labels = np.where(referenced, labels, -1)
        marked = np.unique(labels[cw])
        solve_mask = np.isin(labels, marked) & referenced
        all_pieces = list(range(n_pieces))
        sizes = np.bincount(labels[labels >= 0], minlength=n_pieces)
        self.pieces = PieceReport(
            n_pieces=int(n_pieces),
            marked_pieces=[int(p) for p in marked],
            unmarked_pieces=[p for p in all_pieces if p not in set(marked.tolist())],
            piece_sizes=[int(s) for s in sizes],
            unmarked_policy=unmarked_pieces,
            welded_vertices=int(n - nw),
            degenerate_faces=int(degenerate.sum()),
            unreferenced_vertices=int((~referenced).sum()),
        )

        # Operators on the marked pieces only (unmarked ones would make A singular).
        solve_vertices = np.flatnonzero(solve_mask)
        local = np.full(nw, -1, dtype=np.int64)
        local[solve_vertices] = np.arange(solve_vertices.size)
        Fl = local[Fs[np.all(solve_mask[Fs], axis=1)]]
        ops = laplace_operators(Vw[solve_vertices], Fl)
        L = ops.L
        inv_mass = sp.diags(1.0 / ops.mass)
        A = (ks * L + kb * (L @ inv_mass @ L)).tocsr()

        cl = local[cw]
        free = np.ones(solve_vertices.size, dtype=bool)
        free[cl] = False
        free_idx = np.flatnonzero(free)
        A_ff = A[free_idx][:, free_idx]
        A_fc = A[free_idx][:, cl]
        self._factor: SpdFactor | None = SpdFactor(A_ff.tocsr(), backend=backend)
        self.backend = self._factor.backend
        Ww = np.zeros((nw, c.size), dtype=np.float32)  # welded-vertices-by-markers weights
        free_rows = solve_vertices[free_idx]
        A_fc = A_fc.tocsc()
        # A few markers' right-hand sides at a time: the dense float64 right-hand
        # sides and solutions (and the solver's copies) of all K at once were the
        # set-up's memory peak (over 2 GB at 700k vertices).
        for first in range(0, c.size, _RHS_PER_SOLVE):
            cols = slice(first, min(first + _RHS_PER_SOLVE, c.size))
            Ww[free_rows, cols] = -self._factor.solve(A_fc[:, cols].toarray())
        Ww[cw, np.arange(c.size)] = 1.0
        if not keep_factor:  # free the factor before the weights are copied into the product
            self._factor.free()
            self._factor = None

        unmarked_vertices = np.flatnonzero(~solve_mask)
        if unmarked_vertices.size and unmarked_pieces == "carry":
            tree = cKDTree(Vw[solve_vertices])
            kn = min(_CARRY_NEIGHBOURS, solve_vertices.size)
            for piece in np.unique(labels[unmarked_vertices]):
                members = unmarked_vertices[labels[unmarked_vertices] == piece]
                if piece < 0:  # unreferenced vertices: each follows its own neighbourhood
                    _, nb = tree.query(Vw[members], k=kn)
                    nb = np.atleast_2d(nb)
                    Ww[members] = Ww[solve_vertices[nb]].mean(axis=1)
                    continue
                dist, nearest = tree.query(Vw[members], k=1)
                attach = np.argsort(dist)[:kn]  # the piece's vertices closest to the skin
                anchors = np.unique(solve_vertices[nearest[attach]])
                Ww[members] = Ww[anchors].mean(axis=0)

        self.constrained_vertices = c
        if keep_factor:
            unmarked = ~solve_mask[welded_index]
            self._direct = (A_fc.tocsr(), solve_vertices[free_idx], welded_index, solve_mask,
                            Ww[welded_index[unmarked]].astype(np.float64))
        self.product = BasisProduct(Ww, precision=precision, vertex_rows=welded_index)
        del Ww

        if self.pieces.unmarked_pieces:
            warnings.warn(
                f"{len(self.pieces.unmarked_pieces)} piece(s) of the scan carry no marker "
                f"({sum(self.pieces.piece_sizes[p] for p in self.pieces.unmarked_pieces)} vertices); "
                f"they are {'carried by the nearest marked surface' if unmarked_pieces == 'carry' else 'left rigid'}",
                FacecapWarning,
                stacklevel=2,
            )

    @property
    def n_markers(self) -> int:
        """Number of constrained vertices K."""
        return self.product.n_markers

    @property
    def basis(self) -> np.ndarray:
        """(K, n) float32: every vertex's displacement per unit displacement of each marker."""
        return self.product.dense_weights().T

    def displacements(self, marker_displacements: FloatArray) -> FloatArray:
        """Vertex displacements for one frame or a batch of frames.

        Parameters
        ----------
        marker_displacements : (K, 3) or (T, K, 3) float array, mm

        Returns
        -------
        (n, 3) or (T, n, 3) float32 array, mm
        """
        D = np.asarray(marker_displacements, dtype=np.float32)
        single = D.ndim == 2
        Db = D[None] if single else D
        if Db.ndim != 3 or Db.shape[1:] != (self.n_markers, 3):
            raise InputError(f"marker_displacements: expected (T, {self.n_markers}, 3), got {D.shape}")
        out = np.empty((Db.shape[0], self.n_vertices, 3), dtype=np.float32)
        self.deform_into(Db, np.zeros((self.n_vertices, 3), np.float32), out)
        return out[0] if single else out

    def deform_into(self, marker_displacements: np.ndarray, rest: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Write ``rest + displacement`` for a batch of frames into ``out`` (the hot path).

        Parameters
        ----------
        marker_displacements : (b, K, 3) float32 array, mm
        rest : (n, 3) float32 array
            Added to every frame (the rest shape, in whatever unit the caller
            wants ``out`` in, with displacements pre-scaled to match).
        out : (b, n, 3) float32 array
            Written in place and returned.

        Notes
        -----
        See :class:`BasisProduct` for how the batch is computed: in vertex
        blocks that stay in cache, one thread per core.
        """
        return self.product.apply_into(marker_displacements, rest, out)

    def solve_direct(self, marker_displacements: FloatArray) -> FloatArray:
        """One frame by a sparse back-substitution with the kept factor (reference path).

        Parameters
        ----------
        marker_displacements : (K, 3) float64 array, mm

        Returns
        -------
        (n, 3) float64 array, mm
            Same as :meth:`displacements` up to float32 rounding, for marked pieces.
        """
        if self._factor is None:
            raise InputError("solve_direct needs the solver built with keep_factor=True")
        A_fc, free_welded, welded_index, solve_mask, unmarked_weights = self._direct
        d = np.asarray(marker_displacements, dtype=np.float64)
        x = self._factor.solve(-(A_fc @ d))
        nw = solve_mask.size
        Dw = np.zeros((nw, 3))
        Dw[free_welded] = x
        Dw[welded_index[self.constrained_vertices]] = d
        full = Dw[welded_index]
        unmarked = ~solve_mask[welded_index]
        if unmarked.any():  # pieces without markers follow the rule built into the basis
            full[unmarked] = unmarked_weights @ d
        return full


def thin_shell_deform(
    V: FloatArray,
    F: IntArray,
    constrained_vertices: IntArray,
    marker_displacements: FloatArray,
    *,
    ks: float = DEFAULT_KS,
    kb: float = DEFAULT_KB_MM2,
) -> FloatArray:
    """Deform a mesh so its marker vertices move by the given displacements (one-shot).

    Parameters
    ----------
    V : (n, 3) float64 array, mm
    F : (m, 3) int64 array
    constrained_vertices : (K,) int64 array
    marker_displacements : (K, 3) or (T, K, 3) float array, mm
    ks, kb : float
        See :class:`ThinShellSolver`.

    Returns
    -------
    (n, 3) or (T, n, 3) float64 array, mm
        Deformed vertex positions ``V + d``.

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> F = np.array([[0, 1, 2], [1, 3, 2]])
    >>> out = thin_shell_deform(V, F, np.array([0, 3]), np.array([[0., 0, 1], [0, 0, 1]]))
    >>> bool(np.allclose(out[:, 2], 1.0))
    True
    """
    solver = ThinShellSolver(V, F, constrained_vertices, ks=ks, kb=kb)
    return V + solver.displacements(marker_displacements).astype(np.float64)
