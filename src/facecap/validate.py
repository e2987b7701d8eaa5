"""Validators shared by every public entry point.

Each names the argument, what was expected and what arrived, and raises an
:class:`~facecap.errors.InputError` subclass. Never use ``assert`` for input.
"""

from __future__ import annotations

import operator
from typing import Any

import numpy as np

from .errors import InputError, MarkerError, MeshError
from .rotations import nearest_rotation
from .typing import FloatArray, IntArray

__all__ = ["as_vertices", "as_faces", "as_marker_positions", "as_points", "as_positive", "as_positive_range",
           "as_rigid_transform", "as_count", "as_frame_index"]


def as_points(X: Any, *, name: str, dim: int = 3, allow_nan: bool = False) -> FloatArray:
    """Return ``X`` as a C-contiguous (k, dim) float64 array, or raise."""
    try:
        A = np.ascontiguousarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a numeric (k, {dim}) array ({exc})") from None
    if A.ndim != 2 or A.shape[1] != dim:
        raise InputError(f"{name}: expected shape (k, {dim}), got {A.shape}")
    if not allow_nan and not np.all(np.isfinite(A)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return A


def as_vertices(V: Any, *, name: str = "V") -> FloatArray:
    """Return ``V`` as (n, 3) float64, finite, with at least 3 rows, or raise MeshError."""
    try:
        A = as_points(V, name=name)
    except InputError as exc:
        raise MeshError(str(exc)) from None
    if A.shape[0] < 3:
        raise MeshError(f"{name}: expected at least 3 vertices, got {A.shape[0]}")
    return A


def as_faces(F: Any, n_vertices: int, *, name: str = "F", corners: int = 3) -> IntArray:
    """Return ``F`` as (m, corners) int64 with every index in ``[0, n_vertices)``, or raise.

    Out-of-range indices crash some libraries (libigl segfaults) and pass
    silently through others, so they are always checked here.
    """
    A = np.asarray(F)
    if A.ndim != 2 or A.shape[1] != corners:
        raise MeshError(f"{name}: expected shape (m, {corners}), got {A.shape}")
    if A.shape[0] == 0:
        raise MeshError(f"{name}: the mesh has no faces")
    if not np.issubdtype(A.dtype, np.integer):
        if not np.all(np.isfinite(A)) or np.any(A != np.round(A)):
            raise MeshError(f"{name}: face indices must be integers")
    A = np.ascontiguousarray(A, dtype=np.int64)
    lo, hi = int(A.min()), int(A.max())
    if lo < 0 or hi >= n_vertices:
        bad = int(np.flatnonzero(np.any((A < 0) | (A >= n_vertices), axis=1))[0])
        raise MeshError(
            f"{name}: face {bad} has vertex index out of range "
            f"(indices span {lo}..{hi}, mesh has {n_vertices} vertices)"
        )
    return A


def as_marker_positions(P: Any, *, name: str = "positions") -> FloatArray:
    """Return marker positions as (T, M, 3) float64; NaN marks a gap, inf is rejected."""
    try:
        A = np.ascontiguousarray(P, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MarkerError(f"{name}: expected a numeric (T, M, 3) array ({exc})") from None
    if A.ndim != 3 or A.shape[2] != 3:
        raise MarkerError(f"{name}: expected shape (T, M, 3), got {A.shape}")
    if A.shape[0] < 1 or A.shape[1] < 1:
        raise MarkerError(f"{name}: expected at least one frame and one marker, got {A.shape}")
    if np.any(np.isinf(A)):
        raise MarkerError(f"{name}: contains infinite values (use NaN for gaps)")
    return A


def as_positive(x: Any, *, name: str, allow_zero: bool = False) -> float:
    """Return ``x`` as a finite float that is > 0 (or >= 0), or raise."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {x!r}") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{name}: expected a {'non-negative' if allow_zero else 'positive'} number, got {x!r}")
    return v


def as_frame_index(value: object, n_frames: int, *, name: str) -> int:
    """Return ``value`` as a frame index of a take of ``n_frames`` frames, or raise.

    Parameters
    ----------
    value : int
        A Python or NumPy integer (not a bool, not a float) in ``[0, n_frames)``.
    n_frames : int
        The take's length.
    name : str
        The argument's name in the message.

    Returns
    -------
    int

    Raises
    ------
    InputError
        If ``value`` is not an integer or lies outside the take.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name}: expected an integer frame index, got {value!r}")
    if not 0 <= int(value) < n_frames:
        raise InputError(f"{name}: expected a frame index in [0, {n_frames}), got {value}")
    return int(value)


def as_count(x: Any, *, name: str, minimum: int = 1) -> int:
    """Return ``x`` as an int >= ``minimum``, or raise: any integer type (numpy's too), never a bool or a float."""
    if not isinstance(x, bool):
        try:
            number = operator.index(x)
        except TypeError:
            number = None
        if number is not None and number >= minimum:
            return int(number)
    raise InputError(f"{name}: expected an integer >= {minimum}, got {x!r}")


def as_positive_range(x: Any, *, name: str) -> tuple[float, float]:
    """``x`` as a ``(low, high)`` pair of positive finite numbers with ``low <= high``, or InputError naming ``name``."""
    try:
        lo, hi = (as_positive(v, name=name) for v in x)
    except InputError:
        raise
    except (TypeError, ValueError):  # not iterable, or not two items
        raise InputError(f"{name}: expected (low, high), got {x!r}") from None
    if lo > hi:
        raise InputError(f"{name}: expected (low, high) with low <= high, got {x!r}")
    return lo, hi


def as_rigid_transform(T: Any, *, name: str, project: bool = False) -> FloatArray:
    """Return ``T`` as a finite (4, 4) float64 rigid transform, or raise.

    With ``project=True`` the rotation block is replaced by the nearest proper
    rotation (for a caller's matrix that drifted, e.g. a starting pose);
    otherwise it must already be orthonormal with determinant +1, and the last
    row must be 0 0 0 1.
    """
    try:
        A = np.array(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a (4, 4) rigid transform ({exc})") from None
    if A.shape != (4, 4) or not np.all(np.isfinite(A)):
        raise InputError(f"{name}: expected a finite (4, 4) rigid transform, got shape {A.shape}")
    R = A[:3, :3]
    if project:
        A[:3, :3] = nearest_rotation(R)
        return A
    if (
        not np.allclose(R @ R.T, np.eye(3), atol=1e-6)
        or np.linalg.det(R) < 0
        or not np.allclose(A[3], [0.0, 0.0, 0.0, 1.0], atol=1e-12)
    ):
        raise InputError(f"{name}: expected a rotation (orthonormal, det +1) and translation, last row 0 0 0 1")
    return A
