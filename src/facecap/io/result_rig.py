"""The exact compact form of a result that is linear in per-frame coefficients: a rig.

Both pipelines of the first release are linear in what they solve per frame:

- the large scale (``facecap animate``) is ``V(t) = V0 + B^T d(t)``: one scalar
  weight per vertex and marker (the thin shell's basis, ``basis`` ``(K, n)``)
  applied to each marker's displacement (``coefficients`` ``(T, K, 3)``);
- the blend (``facecap blend``) is ``V(t) = V0 + sum_k w_k(t) S_k``: vector
  shapes (``basis`` ``(K, n, 3)``) with scalar weights (``coefficients`` ``(T, K)``).

A :class:`ResultRig` holds either form and evaluates any block of frames. At
700k vertices, 90 markers and 10,000 frames it is 0.26 GB where the frames
are 86 GB. The head motion of a stabilised result is not part of the rig
(it stays in ``head_motion.npy``, as for ``vertices.npy``).

On disk, in a result folder's ``rig/`` (see ``docs/output_format.md``)::

    rig/rig.json            format, kind, sizes, unit, precision, error bound
    rig/rest.npy            float32 (n, 3)
    rig/basis.npy           float32 (K, n) or (K, n, 3); int16 with --rig-precision int16
    rig/basis_scale.npy     float32 (n,): per-vertex scale of an int16 basis
    rig/coefficients.npy    float32 (T, K, 3) or (T, K)

Everything is in the result's unit (that of ``vertices.npy``). Arrays are
memory-mapped on reading, so opening a rig costs nothing until frames are asked for.

The int16 form stores each vertex's basis values as ``q * s_i`` with
``|q| <= 32767`` and one scale ``s_i`` per vertex (the largest magnitude of its
row over 32767). Rounding leaves at most ``s_i / 2`` per basis value, so a
coordinate of vertex ``i`` at frame ``t`` is off by at most
``s_i / 2 * sum_k |c_k(t)|`` (``c``: that frame's coefficients; for the
per-vertex form, that axis's). :attr:`ResultRig.error_bound` is the maximum of
this over the take, written into ``rig.json``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..units import mm_per_unit, normalize_unit

__all__ = ["ResultRig", "write_rig", "read_rig", "RIG_FORMAT", "RIG_PRECISIONS", "check_frame_range"]

RIG_FORMAT = "facecap-rig"
"""``format`` field of ``rig.json``."""

RIG_PRECISIONS = ("float32", "int16")
"""Storage precisions of a rig's basis (``--rig-precision``)."""

_INT16_MAX = 32767


@dataclass(frozen=True, eq=False)
class ResultRig:
    """A result as rest vertices, a basis and per-frame coefficients.

    Parameters
    ----------
    rest : (n, 3) float32 array
        Added to every frame.
    basis : (K, n) or (K, n, 3) array, float32 (or int16 with ``basis_scale``)
        ``(K, n)``: a scalar weight per basis element and vertex, multiplied by
        vector coefficients; ``(K, n, 3)``: vector shapes, multiplied by scalar
        coefficients.
    coefficients : (T, K, 3) or (T, K) float32 array
        Per frame; ``(T, K, 3)`` with a ``(K, n)`` basis, ``(T, K)`` with ``(K, n, 3)``.
    units : str, default 'mm'
        Length unit of ``rest``, of the vector parts, and of the frames.
    basis_scale : (n,) float32 array or None
        Per-vertex scale of an int16 ``basis``.
    names : tuple of str, optional
        A name per basis element (the markers, the scanned expressions).

    Raises
    ------
    InputError
        If the shapes do not agree (the basis and the coefficients disagree on
        K, or the rest and the basis on n) or any value is not finite.

    Examples
    --------
    >>> rig = ResultRig(rest=np.zeros((2, 3), np.float32),
    ...                 basis=np.array([[1.0, 0.5]], np.float32),
    ...                 coefficients=np.array([[[0.0, 0.0, 2.0]]], np.float32))
    >>> rig.frames(0, 1)[0, :, 2].tolist()
    [2.0, 1.0]
    """

    rest: np.ndarray
    basis: np.ndarray
    coefficients: np.ndarray
    units: str = "mm"
    basis_scale: np.ndarray | None = None
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        rest = np.asarray(self.rest)
        basis = self.basis if isinstance(self.basis, np.ndarray) else np.asarray(self.basis)  # a memory map stays one
        coefficients = np.asarray(self.coefficients)
        if rest.ndim != 2 or rest.shape[1] != 3 or rest.shape[0] == 0:
            raise InputError(f"rig: rest must be (n, 3), got {rest.shape}")
        n = rest.shape[0]
        if basis.ndim == 2:
            expected = ("(T, K, 3)", 3)
        elif basis.ndim == 3 and basis.shape[2] == 3:
            expected = ("(T, K)", 2)
        else:
            raise InputError(f"rig: basis must be (K, n) or (K, n, 3), got {basis.shape}")
        if basis.shape[1] != n:
            raise InputError(f"rig: the basis is for {basis.shape[1]} vertices, the rest shape has {n}")
        if coefficients.ndim != expected[1] or coefficients.shape[1] != basis.shape[0] \
                or (expected[1] == 3 and coefficients.shape[2] != 3):
            raise InputError(
                f"rig: the basis {basis.shape} and the coefficients {coefficients.shape} disagree "
                f"(a {basis.shape} basis needs coefficients {expected[0]} with K = {basis.shape[0]})"
            )
        if basis.dtype == np.int16:
            scale = None if self.basis_scale is None else np.asarray(self.basis_scale, np.float32)
            if scale is None or scale.shape != (n,):
                raise InputError(f"rig: an int16 basis needs a ({n},) basis_scale")
            object.__setattr__(self, "basis_scale", scale)
        elif basis.dtype != np.float32:
            basis = basis.astype(np.float32)
        if self.names and len(self.names) != basis.shape[0]:
            raise InputError(f"rig: {len(self.names)} names for {basis.shape[0]} basis elements")
        for name, arr in (("rest", rest), ("coefficients", coefficients)):
            if not np.isfinite(arr).all():
                raise InputError(f"rig: {name} hold NaN or infinite values")
        object.__setattr__(self, "rest", rest.astype(np.float32, copy=False))
        object.__setattr__(self, "basis", basis)
        object.__setattr__(self, "coefficients", coefficients.astype(np.float32, copy=False))
        object.__setattr__(self, "units", normalize_unit(self.units, name="units"))
        object.__setattr__(self, "names", tuple(str(s) for s in self.names))

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.coefficients.shape[0])

    @property
    def n_vertices(self) -> int:
        """Number of vertices n."""
        return int(self.rest.shape[0])

    @property
    def n_basis(self) -> int:
        """Number of basis elements K."""
        return int(self.basis.shape[0])

    @property
    def n_shapes(self) -> int:
        """Blend shapes the exact rig takes (:meth:`shapes`): ``3 K`` for per-vertex weights, ``K`` for shapes."""
        return 3 * self.n_basis if self.basis.ndim == 2 else self.n_basis

    @property
    def kind(self) -> str:
        """``'vertex-weights'`` (a ``(K, n)`` basis) or ``'shapes'`` (a ``(K, n, 3)`` basis)."""
        return "vertex-weights" if self.basis.ndim == 2 else "shapes"

    @property
    def precision(self) -> str:
        """``'float32'`` or ``'int16'``: how the basis is stored."""
        return "int16" if self.basis.dtype == np.int16 else "float32"

    @property
    def n_bytes(self) -> int:
        """Bytes of the arrays (what ``rig/`` holds, less its JSON)."""
        extra = 0 if self.basis_scale is None else self.basis_scale.nbytes
        return int(self.rest.nbytes + self.basis.nbytes + self.coefficients.nbytes + extra)

    @property
    def error_bound(self) -> float:
        """Largest coordinate error of any frame from the basis's storage, in :attr:`units` (0 for float32)."""
        if self.basis_scale is None:
            return 0.0
        c = np.abs(self.coefficients.astype(np.float64))
        worst_sum = float(c.sum(axis=1).max(initial=0.0))  # max over frames (and axes) of sum_k |c_k|
        return float(self.basis_scale.max(initial=0.0)) / 2.0 * worst_sum

    def dense_basis(self, vertices: slice | np.ndarray = slice(None)) -> np.ndarray:
        """The basis as float32 (dequantised for int16), for some or all vertices."""
        B = self.basis[:, vertices]
        if self.basis_scale is None:
            return np.asarray(B, dtype=np.float32)
        scale = self.basis_scale[vertices]
        return B.astype(np.float32) * (scale[None, :, None] if B.ndim == 3 else scale[None, :])

    def in_mm(self, vertices: slice | np.ndarray = slice(None)) -> tuple[np.ndarray, np.ndarray]:
        """``(basis, coefficients)`` float32 with the rig's length unit converted to mm, for some or all vertices.

        The unit sits in the coefficients of per-vertex weights (marker
        displacements) and in the basis of shapes; the other factor is unitless.
        """
        to_mm = np.float32(mm_per_unit(self.units))
        basis = self.dense_basis(vertices)
        if self.basis.ndim == 2:
            return basis, self.coefficients * to_mm
        return basis * to_mm, self.coefficients

    def frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``start`` to ``stop`` as a float32 ``(stop - start, n, 3)`` array, in :attr:`units`."""
        start, stop = check_frame_range(start, stop, self.n_frames)
        out = np.empty((stop - start, self.n_vertices, 3), np.float32)
        return self.frames_into(start, stop, out)

    def frames_into(self, start: int, stop: int, out: np.ndarray, *, vertex_block: int = 65536) -> np.ndarray:
        """Write frames ``start`` to ``stop`` into ``out`` ((stop - start, n, 3) float32) and return it.

        Vertex block by vertex block, so an int16 or memory-mapped basis is
        dequantised or paged in a slice at a time.
        """
        c = self.coefficients[start:stop]
        b, n = stop - start, self.n_vertices
        if out.shape != (b, n, 3) or out.dtype != np.float32:
            raise InputError(f"out: expected a float32 ({b}, {n}, 3) array, got {out.dtype} {out.shape}")
        for lo in range(0, n, vertex_block):
            hi = min(lo + vertex_block, n)
            B = self.dense_basis(slice(lo, hi))
            if B.ndim == 2:  # (K, v) weights, (b, K, 3) coefficients
                part = np.einsum("kv,bkc->bvc", B, c, optimize=True)
            else:  # (K, v, 3) shapes, (b, K) coefficients
                part = (c @ B.reshape(B.shape[0], -1)).reshape(b, hi - lo, 3)
            np.add(part, self.rest[lo:hi][None], out=out[:, lo:hi])
        return out

    def shapes(self) -> tuple[np.ndarray, list[str]]:
        """The basis as vector shapes ``(m, n, 3)`` with their names, the form blendshape clients read.

        A ``(K, n)`` basis becomes ``3 K`` shapes, one per element and axis
        (element k moved along x, y, z), with :meth:`shape_weights` their
        animated weights. A ``(K, n, 3)`` basis is returned as it is.
        """
        names = list(self.names) or [f"b{k:03d}" for k in range(self.n_basis)]
        B = self.dense_basis()
        if B.ndim == 3:
            return B, names
        K, n = B.shape
        S = np.zeros((K, 3, n, 3), np.float32)
        for axis in range(3):
            S[:, axis, :, axis] = B
        return S.reshape(self.n_shapes, n, 3), [f"{name}_{axis}" for name in names for axis in "xyz"]

    def shape_weights(self) -> np.ndarray:
        """Per-frame weights of :meth:`shapes`, ``(T, m)`` float32."""
        c = np.asarray(self.coefficients)
        return c.reshape(c.shape[0], -1)

    def quantized(self) -> "ResultRig":
        """The same rig with an int16 basis (per-vertex scale); see the module docstring for the bound."""
        if self.precision == "int16":
            return self
        B = np.asarray(self.basis, dtype=np.float32)
        per_vertex = np.abs(B).max(axis=(0, 2)) if B.ndim == 3 else np.abs(B).max(axis=0)
        scale = np.where(per_vertex > 0, per_vertex / _INT16_MAX, 1.0).astype(np.float32)
        divisor = scale[None, :, None] if B.ndim == 3 else scale[None, :]
        q = np.clip(np.rint(B / divisor), -_INT16_MAX, _INT16_MAX).astype(np.int16)
        return ResultRig(self.rest, q, self.coefficients, units=self.units, basis_scale=scale, names=self.names)

    def to_dict(self) -> dict[str, Any]:
        """The JSON description written as ``rig.json``."""
        return {
            "format": RIG_FORMAT,
            "version": 1,
            "kind": self.kind,
            "n_frames": self.n_frames,
            "n_vertices": self.n_vertices,
            "n_basis": self.n_basis,
            "units": self.units,
            "precision": self.precision,
            "error_bound": self.error_bound,
            "names": list(self.names),
            "formula": "V(t) = rest + sum_k basis[k] * coefficients[t, k]",
        }


def write_rig(folder: str | os.PathLike[str], rig: ResultRig) -> dict[str, int]:
    """Write ``rig`` into ``folder`` (created; normally a result's staging ``rig/``).

    Returns
    -------
    dict of str to int
        Each file written and its size in bytes.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {"rest.npy": rig.rest, "basis.npy": rig.basis, "coefficients.npy": rig.coefficients}
    if rig.basis_scale is not None:
        arrays["basis_scale.npy"] = rig.basis_scale
    for name, arr in arrays.items():
        # a Fortran-ordered array (the shell's basis is the transpose of its (n, K) weights) is saved as
        # it lies, in the format's fortran_order: a C-ordered copy of 0.26 GB cost 0.5 s at 700k vertices
        np.save(folder / name, arr if arr.flags.f_contiguous else np.ascontiguousarray(arr))
    (folder / "rig.json").write_text(json.dumps(rig.to_dict(), indent=1))
    return {f"rig/{p.name}": p.stat().st_size for p in sorted(folder.iterdir())}


def read_rig(folder: str | os.PathLike[str]) -> ResultRig:
    """Read a rig written by :func:`write_rig`, its basis memory-mapped.

    Raises
    ------
    FileFormatError
        If ``rig.json`` is missing or not a facecap rig, or an array is missing.
    InputError
        If the arrays disagree with each other (see :class:`ResultRig`) or with ``rig.json``.
    """
    folder = Path(folder)
    try:
        info = json.loads((folder / "rig.json").read_text())
    except FileNotFoundError:
        raise FileFormatError("no rig.json: not a facecap rig", path=str(folder)) from None
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"unreadable rig.json ({exc})", path=str(folder)) from None
    if info.get("format") != RIG_FORMAT:
        raise FileFormatError(f"rig.json: format is {info.get('format')!r}, not {RIG_FORMAT!r}", path=str(folder))

    def load(name: str, mmap: bool) -> np.ndarray:
        try:
            return np.load(folder / name, mmap_mode="r" if mmap else None)
        except FileNotFoundError:
            raise FileFormatError(f"the rig has no {name}", path=str(folder)) from None
        except ValueError as exc:
            raise FileFormatError(f"{name} is not a readable .npy ({exc})", path=str(folder)) from None

    scale = load("basis_scale.npy", False) if (folder / "basis_scale.npy").exists() else None
    try:
        rig = ResultRig(load("rest.npy", False), load("basis.npy", True), load("coefficients.npy", False),
                        units=info.get("units", "mm"), basis_scale=scale, names=tuple(info.get("names", ())))
    except InputError as exc:
        raise InputError(exc.message, path=str(folder)) from None
    stated = (info.get("n_frames"), info.get("n_vertices"), info.get("n_basis"))
    if stated != (rig.n_frames, rig.n_vertices, rig.n_basis):
        raise InputError(
            f"rig.json states {stated[0]} frames, {stated[1]} vertices, {stated[2]} basis elements; "
            f"the arrays hold {rig.n_frames}, {rig.n_vertices}, {rig.n_basis}",
            path=str(folder),
        )
    return rig


def check_frame_range(start: int, stop: int | None, n_frames: int) -> tuple[int, int]:
    """Frames ``start`` to ``stop`` (None: the end) of a take of ``n_frames``, as ints, checked.

    Raises
    ------
    InputError
        If not ``0 <= start <= stop <= n_frames``.
    """
    stop = n_frames if stop is None else int(stop)
    start = int(start)
    if not (0 <= start <= stop <= n_frames):
        raise InputError(f"frames {start}..{stop}: outside the take's 0..{n_frames}")
    return start, stop
