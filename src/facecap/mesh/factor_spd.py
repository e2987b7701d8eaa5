"""Sparse symmetric positive-definite factorisation with a choice of backend."""

from __future__ import annotations

import warnings
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp

from .._mkl import locate_mkl_runtime
from ..errors import FacecapWarning, InputError, SolverError
from ..typing import FloatArray

__all__ = ["SpdFactor", "available_backends", "load_backend"]

Backend = Literal["auto", "pardiso", "scipy"]


def available_backends() -> list[str]:
    """Names of the sparse factorisation backends importable here, fastest first."""
    names = []
    try:
        locate_mkl_runtime()
        import pypardiso  # noqa: F401

        names.append("pardiso")
    except Exception:  # MKL is x86-only: pypardiso may be missing or fail to load
        pass
    names.append("scipy")
    return names


def load_backend(backend: Backend = "auto") -> str:
    """Load the compiled libraries ``backend`` solves with, on this thread, now; returns the backend's name.

    MKL's runtime loads its computational libraries (core, threading, the
    CPU's kernels: eight shared objects) at the first PARDISO call, not at
    import. A job that runs other work on a second thread beside its first
    factorisation calls this first, so that no library loads on one thread
    while another thread loads one (seen to deadlock: usd-core's initialisers
    against MKL's first load). It factors and solves a 2 x 2 system; the
    SciPy backend needs nothing loaded.

    Raises
    ------
    InputError
        If ``backend`` is not one of ``'auto'``, ``'pardiso'``, ``'scipy'`` or is not available here.
    """
    if backend not in ("auto", "pardiso", "scipy"):
        raise InputError(f"backend: expected one of 'auto', 'pardiso', 'scipy', got {backend!r}")
    have = available_backends()
    name = have[0] if backend == "auto" else backend
    if name not in have:
        raise InputError(f"backend: {backend!r} is not available here (have {have})")
    if name == "pardiso":
        tiny = SpdFactor(sp.csr_matrix(np.array([[2.0, 0.5], [0.5, 1.0]])), backend="pardiso")
        tiny.solve(np.ones(2))
        tiny.free()
    return name


def _new_pardiso_solver() -> Any:
    """A PARDISO solver in real symmetric positive-definite mode."""
    locate_mkl_runtime()
    import pypardiso

    return pypardiso.PyPardisoSolver(mtype=2)


def _within_pattern(a: sp.csr_matrix, pattern: sp.csr_matrix) -> sp.csr_matrix | None:
    """``a`` stored in ``pattern``'s non-zeros (explicit zeros where ``a`` has none), or None when ``a``
    has a non-zero outside them. Both have sorted indices. Sums of sparse matrices drop the entries
    that cancel, so successive systems of one mesh differ by a few stored zeros (13 of 760,779 in a
    bi-Laplacian at 78k vertices); PARDISO's analysis holds for any subset of its pattern."""
    if a.shape != pattern.shape:
        return None
    if np.array_equal(a.indptr, pattern.indptr) and np.array_equal(a.indices, pattern.indices):
        return a
    n = a.shape[1]
    keys = np.repeat(np.arange(a.shape[0], dtype=np.int64), np.diff(a.indptr)) * n + a.indices
    known = np.repeat(np.arange(a.shape[0], dtype=np.int64), np.diff(pattern.indptr)) * n + pattern.indices
    at = np.searchsorted(known, keys)
    if np.any(at >= known.size) or not np.array_equal(known[np.minimum(at, known.size - 1)], keys):
        return None
    data = np.zeros(pattern.nnz)
    data[at] = a.data
    return sp.csr_matrix((data, pattern.indices, pattern.indptr), shape=pattern.shape)


class SpdFactor:
    """Factor a sparse symmetric positive-definite matrix once, solve many times.

    Parameters
    ----------
    A : (n, n) scipy.sparse matrix, float64
        Symmetric positive definite.
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'
        ``'pardiso'``: MKL PARDISO in real-symmetric-positive-definite mode
        (``mtype=2``, upper triangle only) through pypardiso; at 700k
        vertices it factors the thin-shell system in seconds and about
        1.5 GB. ``'scipy'``: SuperLU (``scipy.sparse.linalg.splu``); always
        available but about 20x slower and 8x the memory on large meshes.
        ``'auto'`` takes PARDISO where it loads, else SuperLU with a warning.

    Raises
    ------
    SolverError
        If the factorisation fails (the matrix is singular or not SPD).

    Examples
    --------
    >>> import scipy.sparse as sp, numpy as np
    >>> A = sp.diags([4.0, 5.0, 6.0]).tocsr()
    >>> np.allclose(SpdFactor(A).solve(np.ones(3)), [0.25, 0.2, 1 / 6])
    True
    """

    def __init__(self, A: sp.spmatrix, *, backend: Backend = "auto") -> None:
        if not sp.issparse(A) or A.shape[0] != A.shape[1]:
            raise InputError(f"A: expected a square sparse matrix, got {type(A).__name__} {getattr(A, 'shape', '')}")
        self._choose_backend(backend)
        self.n = int(A.shape[0])
        A = sp.csr_matrix(A, dtype=np.float64)
        self._impl: Any
        if self.backend == "pardiso":
            self._factor_pardiso(A)
        else:
            self._factor_scipy(A)

    @classmethod
    def unfactored(cls, n: int, *, backend: Backend = "auto") -> "SpdFactor":
        """A factor of an ``n x n`` system yet to come: its first :meth:`refactor` factors it.

        For a loop that factors one matrix after another and keeps one factor
        for all of them.
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"n: expected a positive integer, got {n!r}")
        factor = cls.__new__(cls)
        factor._choose_backend(backend)
        factor.n = int(n)
        factor._impl = None
        return factor

    def _choose_backend(self, backend: Backend) -> None:
        if backend not in ("auto", "pardiso", "scipy"):
            raise InputError(f"backend: expected one of 'auto', 'pardiso', 'scipy', got {backend!r}")
        have = available_backends()
        if backend == "auto":
            backend = have[0]  # type: ignore[assignment]
            if backend != "pardiso":
                warnings.warn(
                    "pypardiso (MKL PARDISO) is not available; using SciPy's SuperLU, "
                    "which is much slower and uses more memory on large scans",
                    FacecapWarning,
                    stacklevel=3,
                )
        elif backend not in have:
            raise InputError(f"backend: {backend!r} is not available here (have {have})")
        self.backend: str = backend

    def refactor(self, A: sp.spmatrix) -> None:
        """Factor a new matrix in place of this one, keeping the analysis when the pattern is the same.

        Solvers that iterate (a registration's closest-point rounds, a flow's
        updates) factor one matrix after another with the same non-zeros and
        new values. PARDISO's analysis (fill-reducing ordering and symbolic
        factorisation) is about two thirds of a factorisation of a mesh's
        bi-Laplacian system (0.27 of 0.40 s at 78k vertices, measured); here
        only the numeric factorisation runs again, for any matrix whose
        non-zeros lie within the analysed ones. Any other matrix (or the
        SciPy backend) is factored from scratch.

        Parameters
        ----------
        A : (n, n) scipy.sparse matrix, float64
            Symmetric positive definite, of this factor's size.

        Raises
        ------
        SolverError
            If the factorisation fails; the factor is then released, as after ``free``.
        """
        if not sp.issparse(A) or A.shape != (self.n, self.n):
            raise InputError(f"A: expected a ({self.n}, {self.n}) sparse matrix, got {getattr(A, 'shape', type(A))}")
        A = sp.csr_matrix(A, dtype=np.float64)
        if self.backend != "pardiso":
            self._factor_scipy(A)
            return
        upper = sp.triu(A, format="csr")
        upper.sort_indices()
        within = None if self._impl is None else _within_pattern(upper, self._impl[1])
        if within is None:
            self.free()
            self._factor_pardiso(A)
            return
        solver, upper = self._impl[0], within
        try:
            # pypardiso has no public call for PARDISO's numeric phase alone: its own internals, and
            # its record of the factored matrix (solve() recognises the factor by the matrix's values)
            solver.set_phase(22)
            solver._call_pardiso(upper, np.zeros((self.n, 1), order="F"))
            solver.factorized_A = (solver._hash_csr_matrix(upper) if upper.nnz > solver.size_limit_storage
                                   else upper.copy())
        except Exception:
            # a refused matrix, or a pypardiso whose internals moved: the whole factorisation, which
            # raises SolverError itself if the matrix is at fault
            self.free()
            self._factor_pardiso(A)
            return
        self._impl = (solver, upper)

    def _factor_pardiso(self, A: sp.csr_matrix) -> None:
        solver = _new_pardiso_solver()
        # No iterative refinement: the factor of an SPD system is accurate, and
        # refinement would re-read A on every solve.
        solver.set_iparm(8, 0)
        upper = sp.triu(A, format="csr")
        upper.sort_indices()
        try:
            solver.factorize(upper)
        except Exception as exc:  # pypardiso raises its own PyPardisoError
            # MKL keeps a failed factorisation's memory until told (about 9 MB per failure at 22k unknowns,
            # measured by the FEM solver, which tries the exact stiffness first and may be refused often)
            solver.free_memory(everything=True)
            raise SolverError(f"sparse factorisation failed: {exc}") from None
        self._impl = (solver, upper)

    def _factor_scipy(self, A: sp.csr_matrix) -> None:
        from scipy.sparse.linalg import splu

        try:
            lu = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:
            raise SolverError(f"sparse factorisation failed: {exc}") from None
        # Refuse what PARDISO's SPD mode refuses, so that a caller falling back on another matrix (the FEM
        # solver's projected stiffness) runs the same algorithm on either backend. Without pivoting, on a
        # symmetric permutation, U's diagonal is the D of A = L D L^T: its signs are A's inertia (Sylvester).
        if not (np.array_equal(lu.perm_r, lu.perm_c) and np.all(lu.U.diagonal() > 0)):
            raise SolverError("sparse factorisation failed: the matrix is not positive definite")
        self._impl = lu

    def solve(self, b: FloatArray) -> FloatArray:
        """Solve ``A x = b``.

        Parameters
        ----------
        b : (n,) or (n, k) float64 array
            Right-hand side(s).

        Returns
        -------
        x : float64 array, same shape as ``b``
        """
        if self._impl is None:
            raise SolverError("solve: nothing is factored (freed, or an unfactored factor never refactored)")
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.n:
            raise InputError(f"b: expected {self.n} rows, got {b.shape[0]}")
        if self.backend == "pardiso":
            solver, upper = self._impl
            x = solver.solve(upper, np.ascontiguousarray(b))
        else:
            x = self._impl.solve(b)
        if not np.all(np.isfinite(x)):
            raise SolverError("the sparse solve produced non-finite values (singular system)")
        return x

    def free(self) -> None:
        """Release the factor's memory now rather than at garbage collection."""
        if self.backend == "pardiso" and self._impl is not None:
            solver, _ = self._impl
            solver.free_memory(everything=True)
        self._impl = None
