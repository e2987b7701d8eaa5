"""A take's motion as a few principal morph targets and their weights, with the error they leave.

A viewer animates a mesh by morph targets (glTF, :func:`facecap.io.write_gltf`):
``frame_t = rest + sum_j w_j(t) target_j``. The best ``r`` targets in the
least-squares sense over the whole take are its first ``r`` principal
components (Eckart-Young): the right singular vectors of the offsets matrix
``D`` (T x 3n, row t the frame's offsets from rest, not centred: the rest shape
stays the base). Two ways in:

- :func:`principal_targets_from_rig`: the take is an exact rig, ``D = A M^T``
  with ``m`` columns (``m = 3K`` for the thin shell's scalar basis, ``K`` for
  vector shapes). Everything comes from ``M^T M`` (m x m) and ``A`` (T x m):
  no T x n matrix is formed.
- :func:`principal_targets`: frames streamed in blocks (no rig), a randomized
  SVD in five passes over them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any, NamedTuple

import numpy as np

from ..errors import InputError

__all__ = ["principal_targets", "principal_targets_from_rig", "PrincipalTargets"]

_RANK_TOLERANCE = 1e-7  # singular values below this fraction of the largest are numerical zeros


class PrincipalTargets(NamedTuple):
    """Morph targets, their weights over the take, and the error they leave."""

    targets: np.ndarray
    """(r, n_sub, 3) float32, mm: offsets from rest, each scaled so its weight peaks at magnitude 1."""
    weights: np.ndarray
    """(T, r) float32: weight of each target at each frame, in [-1, 1]."""
    error: dict[str, Any]
    """Vertex error (mm) the targets leave over the whole take, over the vertices of ``targets``:
    ``max_mm`` (worst vertex at its worst frame; None when not asked for), ``rms_mm`` (over all
    vertices and frames), ``worst_frame_rms_mm``, ``worst_vertex_rms_mm`` (RMS over frames of the
    worst vertex), ``rank`` (of the take) and ``n_targets``."""


def principal_targets_from_rig(
    basis: np.ndarray,
    coefficients: np.ndarray,
    *,
    vertex_subset: np.ndarray | None = None,
    max_targets: int = 64,
    tolerance_mm: float | None = None,
    exact_max: bool = True,
    progress: bool = False,
) -> PrincipalTargets:
    """The principal morph targets of a take given as an exact rig.

    Parameters
    ----------
    basis : (K, n) or (K, n, 3) float array
        Scalar basis (the thin shell: ``D_t[i] = sum_k basis[k, i] coefficients[t, k]``,
        a 3-vector per coefficient) or vector shapes in mm (the blend:
        ``D_t[i] = sum_k basis[k, i] coefficients[t, k]``, a scalar per coefficient).
    coefficients : (T, K, 3) or (T, K) float array
        ``(T, K, 3)`` mm with a scalar basis, ``(T, K)`` with vector shapes.
    vertex_subset : (n_sub,) int array or None
        Vertices to make targets for (a review mesh's ``vertex_subset``);
        default None: all. The error figures are over these vertices.
    max_targets : int, optional
        Most targets; default 64.
    tolerance_mm : float or None, optional
        Stop at the fewest targets whose RMS vertex error over the take is at
        most this (mm); default None: ``max_targets`` (or the rank, if smaller).
    exact_max : bool, optional
        Compute ``error['max_mm']`` exactly, by one pass over the take's
        residual in blocks of frames (T x n_sub x m multiply-adds: 7 s at
        n_sub = 100k, m = 270, T = 10,000 on 2 cores); default True. False
        leaves it None.
    progress : bool, optional
        Show a tqdm progress bar over that pass; default False.

    Returns
    -------
    PrincipalTargets
        ``(targets, weights, error)``. ``r`` is the rank of the take when it
        is at most ``max_targets``: the targets then rebuild it exactly (up
        to float32 storage).

    Raises
    ------
    InputError
        If the shapes disagree, values are not finite, ``vertex_subset`` is
        out of range, or an option is invalid.

    Notes
    -----
    With ``G = M^T M = E diag(lambda) E^T``, the columns of
    ``Q = M E lambda^-1/2`` are orthonormal, so ``D = (A E lambda^1/2) Q^T``
    and the SVD of the small ``A~ = A E lambda^1/2 = U S W^T`` (T x m) is
    the SVD of ``D``; ``W`` comes from the eigenvectors of ``A~^T A~``
    (m x m). Targets ``M E lambda^-1/2 W_r``, weights ``A~ W_r``. For the
    scalar basis ``G = (B B^T) kron I_3``. The error figures are exact: with
    ``Y = A~ W_res`` (the discarded coordinates of each frame), a frame's
    residual energy is its row of ``Y`` squared, the take's their sum, a
    vertex's ``m_i^T P Y^T Y P^T m_i`` with ``P = E lambda^-1/2 W_res``;
    the maximum needs the
    residual at every vertex and frame, computed block by block as
    ``A_res M^T`` (never the whole T x n at once). Figures are of the
    decomposition in float64; storing targets and weights in float32 moves
    frames by about 1e-7 of their size, and computing the targets in float32
    from a float32 basis (the thin shell's) by about 1e-6.
    """
    B, A, scalar = _rig_arrays(basis, coefficients, vertex_subset)
    max_r = _max_targets(max_targets)
    tol = _tolerance(tolerance_mm)
    T, K = A.shape[0], B.shape[0]
    n = B.shape[1]
    gram = _gram(B)  # (K, K): B B^T (scalar) or M^T M (vector)
    lam, E = np.linalg.eigh(gram)
    keep = lam > lam.max() * _RANK_TOLERANCE**2 if lam.size and lam.max() > 0 else np.zeros(K, bool)
    lam, E = lam[keep], E[:, keep]
    # coordinates of each frame in the orthonormal basis Q: A E lambda^1/2 (per coordinate for a scalar basis)
    coords = A.reshape(T, K, -1)  # (T, K, c) with c = 3 (scalar) or 1 (vector)
    c = coords.shape[2]
    # one matrix product per coordinate, laid out (T, L, c) as the rest expects (einsum took 0.5 s at T = 10,000)
    Atilde = np.matmul(coords.transpose(0, 2, 1), E * np.sqrt(lam)).transpose(0, 2, 1).reshape(T, -1)
    # right singular vectors of Atilde from its small Gram matrix (m x m); the weights and the
    # residual are then projections of Atilde itself, exact whatever the eigenvalues' round-off
    s2, W = np.linalg.eigh(Atilde.T @ Atilde)
    s2, W = np.clip(s2[::-1], 0.0, None), W[:, ::-1]
    S = np.sqrt(s2)
    rank = int(np.sum(s2 > s2[0] * _RANK_TOLERANCE**2)) if s2.size and s2[0] > 0 else 0
    r = _choose_r(S, rank, max_r, tol, T * n)
    # targets: M (E lambda^-1/2 (x) I) W_r ; P has shape (K, c, r)
    to_rig = E / np.sqrt(lam)
    P = np.einsum("kl,lcr->kcr", to_rig, W[:, :r].reshape(lam.size, c, r))
    weights = Atilde @ W[:, :r]

    # error figures: Y = the discarded coordinates of each frame
    q = W.shape[1] - r
    Y = Atilde @ W[:, r:]
    frame_energy = np.einsum("tq,tq->t", Y, Y)
    residual = float(frame_energy.sum())
    P_res = np.einsum("kl,lcq->kcq", to_rig, W[:, r:].reshape(lam.size, c, q))
    directions, vertex_energy = _targets_and_vertex_energy(B, P, P_res, Y.T @ Y, scalar)  # (r, n, 3), (n,)
    max_mm = None
    if exact_max:
        # residual coefficients A_res (T, K, c): the discarded part of each frame, in the rig's own terms
        A_res = np.einsum("tq,kcq->tkc", Y, P_res)
        max_mm = _max_residual(B, A_res, scalar, progress)
    error = _error_dict(residual, frame_energy, vertex_energy, max_mm, T, n, rank, r)
    return _scaled(directions, weights, error)


def principal_targets(
    blocks: Callable[[], Iterable[tuple[int, np.ndarray]]],
    rest: np.ndarray,
    *,
    n_frames: int,
    vertex_subset: np.ndarray | None = None,
    max_targets: int = 64,
    tolerance_mm: float | None = None,
    power_iterations: int = 1,
    oversampling: int = 10,
    seed: int = 0,
    progress: bool = False,
) -> PrincipalTargets:
    """The principal morph targets of a take streamed as blocks of frames (a randomized SVD).

    Parameters
    ----------
    blocks : callable
        Returns a fresh iterator of ``(start, block)``: ``block`` a
        ``(b, n, 3)`` float array of frames ``start .. start + b - 1`` in mm
        (``Result.blocks`` does). Called ``3 + 2 power_iterations`` times.
    rest : (n, 3) float array, mm
        The rest shape the targets are offsets from (the glTF base mesh).
    n_frames : int
        Number of frames the blocks cover (each exactly once).
    vertex_subset : (n_sub,) int array or None
        Vertices to make targets for; default None: all.
    max_targets : int, optional
        Most targets; default 64.
    tolerance_mm : float or None, optional
        Keep the fewest targets whose RMS vertex error is at most this (mm),
        judged on the randomized estimate; the reported error is exact.
    power_iterations : int, optional
        Power iterations of the range finder (two passes each); default 1.
    oversampling : int, optional
        Extra random directions; default 10.
    seed : int, optional
        Seed of the random test matrix; default 0.
    progress : bool, optional
        Show a tqdm progress bar over the passes; default False.

    Returns
    -------
    PrincipalTargets
        ``(targets, weights, error)``; the error is exact for the targets
        returned (the last pass projects every frame onto them and measures
        what is left), whatever the randomized approximation.

    Raises
    ------
    InputError
        If a block has the wrong shape, non-finite values or frames outside
        ``0 .. n_frames - 1``, frames are missing, or an option is invalid.

    Notes
    -----
    Halko, Martinsson and Tropp (2011), Algorithms 4.3 and 5.1: ``Y = D Omega``
    (pass 1), ``Y = D (D^T Y)`` per power iteration (two passes), then
    ``C = Q_Y^T D`` (one pass) and its SVD gives the top right singular
    vectors ``V_r``; the last pass computes the weights ``D V_r`` and the
    residual ``D - D V_r V_r^T`` frame by frame. When the take's rank is at
    most ``max_targets + oversampling`` the first pass already spans it and
    the targets are exact. Memory: three ``(3 n_sub, l)`` float64 matrices,
    ``l = max_targets + oversampling``.

    References
    ----------
    N. Halko, P.-G. Martinsson and J. A. Tropp, "Finding structure with
    randomness", SIAM Review 53(2), 2011.
    """
    rest_arr = np.asarray(rest, dtype=np.float64)
    if rest_arr.ndim != 2 or rest_arr.shape[1] != 3 or not np.all(np.isfinite(rest_arr)):
        raise InputError(f"rest: expected finite (n, 3) positions in mm, got shape {rest_arr.shape}")
    if not isinstance(n_frames, (int, np.integer)) or int(n_frames) < 1:
        raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
    if not callable(blocks):
        raise InputError("blocks: expected a callable returning a fresh iterator of (start, block)")
    for name, value, low in (("power_iterations", power_iterations, 0), ("oversampling", oversampling, 0)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise InputError(f"{name}: expected a non-negative integer, got {value!r}")
    T = int(n_frames)
    subset = _subset(vertex_subset, rest_arr.shape[0])
    base = rest_arr if subset is None else rest_arr[subset]
    n = base.shape[0]
    max_r = _max_targets(max_targets)
    tol = _tolerance(tolerance_mm)
    width = min(max_r + int(oversampling), T, 3 * n)
    rng = np.random.default_rng(seed)
    from tqdm import tqdm

    passes = 3 + 2 * int(power_iterations)
    bar = tqdm(total=passes * T, desc="principal targets", unit="frame", disable=not progress)

    def offsets() -> Iterator[tuple[int, np.ndarray]]:
        seen = np.zeros(T, dtype=bool)
        for start, block in blocks():
            frames = np.asarray(block)
            if frames.ndim != 3 or frames.shape[1:] != (rest_arr.shape[0], 3):
                raise InputError(f"blocks: expected (b, {rest_arr.shape[0]}, 3) frames, got shape {frames.shape}")
            start = int(start)
            if start < 0 or start + frames.shape[0] > T:
                raise InputError(f"blocks: frames {start}..{start + frames.shape[0] - 1} outside 0..{T - 1}")
            if subset is not None:
                frames = frames[:, subset]
            D = (frames.astype(np.float64) - base).reshape(frames.shape[0], -1)
            if not np.all(np.isfinite(D)):
                raise InputError(f"blocks: NaN or infinite position in frames {start}..{start + frames.shape[0] - 1}")
            if seen[start:start + frames.shape[0]].any():
                raise InputError(f"blocks: frames {start}..{start + frames.shape[0] - 1} came twice in one pass")
            seen[start:start + frames.shape[0]] = True
            bar.update(frames.shape[0])
            yield start, D
        if not seen.all():
            raise InputError(f"blocks: frame {int(np.flatnonzero(~seen)[0])} never came (n_frames={T})")

    try:
        omega = rng.standard_normal((3 * n, width))
        Y = np.zeros((T, width))
        for start, D in offsets():
            Y[start:start + D.shape[0]] = D @ omega
        del omega
        for _ in range(int(power_iterations)):
            Qy = np.linalg.qr(Y)[0]
            Z = np.zeros((3 * n, Qy.shape[1]))
            for start, D in offsets():
                Z += D.T @ Qy[start:start + D.shape[0]]
            Qz = np.linalg.qr(Z)[0]
            del Z
            Y = np.zeros((T, Qz.shape[1]))
            for start, D in offsets():
                Y[start:start + D.shape[0]] = D @ Qz
            del Qz
        Qy = np.linalg.qr(Y)[0]
        C = np.zeros((Qy.shape[1], 3 * n))
        for start, D in offsets():
            C += Qy[start:start + D.shape[0]].T @ D
        _, S, Vt = np.linalg.svd(C, full_matrices=False)
        del C
        rank = int(np.sum(S > S[0] * _RANK_TOLERANCE)) if S.size and S[0] > 0 else 0
        r = _choose_r(S, rank, max_r, tol, T * n)
        V_r = Vt[:r]  # (r, 3n), orthonormal rows
        weights = np.zeros((T, r))
        frame_energy = np.zeros(T)
        vertex_energy = np.zeros(n)
        max_sq = 0.0
        for start, D in offsets():
            w = D @ V_r.T
            R = (D - w @ V_r).reshape(D.shape[0], n, 3)
            sq = np.einsum("tic,tic->ti", R, R)
            weights[start:start + D.shape[0]] = w
            frame_energy[start:start + D.shape[0]] = sq.sum(axis=1)
            vertex_energy += sq.sum(axis=0)
            max_sq = max(max_sq, float(sq.max()))
    finally:
        bar.close()
    residual = float(frame_energy.sum())
    error = _error_dict(residual, frame_energy, vertex_energy, float(np.sqrt(max_sq)), T, n, rank, r)
    return _scaled(V_r.reshape(r, n, 3), weights, error)


# ----------------------------------------------------------------------------- helpers


def _rig_arrays(basis: object, coefficients: object, vertex_subset: object) -> tuple[np.ndarray, np.ndarray, bool]:
    """(B, A, scalar): B (K, n_sub) or (K, n_sub, 3) float32 or float64, restricted first; A (T, K, 3) or (T, K) float64."""
    try:
        B = np.asarray(basis)
        A = np.asarray(coefficients, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("basis, coefficients: expected numeric arrays") from None
    if B.dtype.kind not in "fiu":
        raise InputError(f"basis: expected a numeric array, got {B.dtype}")
    if B.ndim == 2:
        scalar = True
        if A.ndim != 3 or A.shape[1:] != (B.shape[0], 3):
            raise InputError(
                f"coefficients: a scalar basis {B.shape} needs (T, {B.shape[0]}, 3) coefficients, got {A.shape}"
            )
    elif B.ndim == 3 and B.shape[2] == 3:
        scalar = False
        if A.ndim != 2 or A.shape[1] != B.shape[0]:
            raise InputError(f"coefficients: vector shapes {B.shape} need (T, {B.shape[0]}) coefficients, got {A.shape}")
    else:
        raise InputError(f"basis: expected (K, n) scalar weights or (K, n, 3) shapes, got shape {B.shape}")
    if B.shape[0] < 1 or A.shape[0] < 1:
        raise InputError(f"basis, coefficients: expected at least one basis function and one frame, got {B.shape}, {A.shape}")
    subset = _subset(vertex_subset, B.shape[1])
    if subset is not None:
        B = B[:, subset]
    if B.dtype.kind != "f":
        B = B.astype(np.float64)
    # the basis keeps its float type (float32 from a rig: a float64 copy at 700k vertices cost 1.4 s);
    # the products below convert it block by block, and _gram checks it is finite on the way
    if not np.all(np.isfinite(A)):
        raise InputError("basis, coefficients: expected finite values, got NaN or infinity")
    return B, A, scalar


def _subset(vertex_subset: object, n: int) -> np.ndarray | None:
    if vertex_subset is None:
        return None
    idx = np.asarray(vertex_subset)
    if idx.ndim != 1 or idx.dtype.kind not in "iu" or idx.size == 0:
        raise InputError(f"vertex_subset: expected a non-empty 1-D integer array, got {idx.dtype} shape {idx.shape}")
    if idx.min() < 0 or idx.max() >= n:
        raise InputError(f"vertex_subset: indices must lie in [0, {n}), got [{idx.min()}, {idx.max()}]")
    return idx.astype(np.int64)


def _max_targets(max_targets: object) -> int:
    if not isinstance(max_targets, (int, np.integer)) or int(max_targets) < 1:
        raise InputError(f"max_targets: expected a positive integer, got {max_targets!r}")
    return int(max_targets)


def _tolerance(tolerance_mm: object) -> float | None:
    if tolerance_mm is None:
        return None
    try:
        tol = float(tolerance_mm)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        tol = float("nan")
    if not np.isfinite(tol) or tol < 0:
        raise InputError(f"tolerance_mm: expected a non-negative length in mm, got {tolerance_mm!r}")
    return tol


def _choose_r(S: np.ndarray, rank: int, max_r: int, tol: float | None, n_points: int) -> int:
    """The targets to keep: the rank, at most ``max_r``, fewer if ``tol`` is met sooner."""
    r = min(rank, max_r)
    if tol is not None and r > 0:
        left = np.cumsum((S**2)[::-1])[::-1]  # left[j]: energy of components j, j+1, ...
        rms_after = np.sqrt(np.r_[left[1:], 0.0][:r] / n_points)  # RMS left by keeping j + 1 targets
        meets = np.flatnonzero(rms_after <= tol)
        if meets.size:
            r = int(meets[0]) + 1
    return max(r, 1) if S.size and S[0] > 0 else 0


_VERTEX_BLOCK = 8192
"""Vertices per block of the basis products: a float64 block of 90 shell weights is 6 MB, in cache."""


def _vertex_blocks(B: np.ndarray) -> Iterator[tuple[slice, np.ndarray]]:
    """``(vertices, B[:, vertices] as float64 (K, b) or (K, b, 3))`` block by block."""
    n = B.shape[1]
    for start in range(0, n, _VERTEX_BLOCK):
        rows = slice(start, min(start + _VERTEX_BLOCK, n))
        yield rows, np.asarray(B[:, rows], dtype=np.float64)


def _gram(B: np.ndarray) -> np.ndarray:
    """``B B^T`` over all vertices (and coordinates) in float64, (K, K); raises on NaN or infinity."""
    K = B.shape[0]
    gram = np.zeros((K, K))
    for _, block in _vertex_blocks(B):
        flat = block.reshape(K, -1)
        if not np.all(np.isfinite(flat)):
            raise InputError("basis, coefficients: expected finite values, got NaN or infinity")
        gram += flat @ flat.T
    return gram


def _targets_and_vertex_energy(B: np.ndarray, P: np.ndarray, P_res: np.ndarray, YtY: np.ndarray,
                               scalar: bool) -> tuple[np.ndarray, np.ndarray]:
    """The targets ``M P`` (r, n, 3) float32 and each vertex's residual energy over the take, (n,).

    Block by block of vertices, so the product is transposed into the
    targets' layout while it is in cache (the whole (n, 3r) product, then one
    strided copy, took 3.7 s at 700k vertices and 48 targets; this 0.4 s). P is (K, 3, r) for a
    scalar basis, (K, 1, r) for vector shapes. The residual energy of vertex i
    is ``m_i^T (P_res Y^T Y P_res^T) m_i``.
    """
    K, c, r = P.shape
    n = B.shape[1]
    targets = np.empty((r, n, 3), np.float32)
    vertex_energy = np.zeros(n)
    q = P_res.shape[2]
    X = P_res.reshape(K * c, q)
    H = (X @ YtY @ X.T).reshape(K, c, K, c) if q else None
    H_shape = None if H is None else (np.einsum("kclc->kl", H) if scalar else H[:, 0, :, 0])
    # rows of the product ordered (target, coordinate): each target's (3, b) block is then transposed alone
    to_targets = np.ascontiguousarray(P.transpose(2, 1, 0).reshape(r * c, K)) if scalar else P[:, 0].T
    # a float32 basis (the thin shell's) gives float32 targets in float32 arithmetic: the targets are stored in
    # float32, and the sums of K products move them by about 1e-6 of their size (0.5 s against 0.8 at 700k)
    single = scalar and B.dtype == np.float32
    to_targets32 = to_targets.astype(np.float32) if single else None
    for rows, block in _vertex_blocks(B):
        b = rows.stop - rows.start
        if scalar:  # block (K, b): (3r, b) -> (r, b, 3)
            product = to_targets32 @ B[:, rows] if single else to_targets @ block
            targets[:, rows] = product.reshape(r, 3, b).transpose(0, 2, 1)
            if H_shape is not None and block.flags.f_contiguous:  # the shell's basis, stored vertex by vertex:
                by_vertex = block.T  # its rows are contiguous, so the quadratic form reads memory in order (2x)
                vertex_energy[rows] = np.einsum("ik,ik->i", by_vertex @ H_shape.T, by_vertex)
            elif H_shape is not None:
                vertex_energy[rows] = np.einsum("ki,ki->i", H_shape @ block, block)
        else:  # block (K, b, 3): (r, b * 3)
            flat = block.reshape(K, -1)
            targets[:, rows] = (to_targets @ flat).reshape(r, b, 3)
            if H_shape is not None:
                vertex_energy[rows] = np.einsum("kic,kic->i", (H_shape @ flat).reshape(K, b, 3), block)
    return targets, vertex_energy


def _max_residual(B: np.ndarray, A_res: np.ndarray, scalar: bool, progress: bool, block: int = 256) -> float:
    """The largest vertex residual over all frames, block by block of frames (float32 products)."""
    from tqdm import tqdm

    T = A_res.shape[0]
    n = B.shape[1]
    B32 = np.ascontiguousarray(B, dtype=np.float32)
    best = 0.0
    for start in tqdm(range(0, T, block), desc="max error", unit="block", disable=not progress):
        a = A_res[start:start + block].astype(np.float32)
        sq = np.zeros((a.shape[0], n), dtype=np.float32)
        if scalar:
            for c in range(3):
                part = a[:, :, c] @ B32
                part *= part
                sq += part
        else:
            for c in range(3):
                part = a[:, :, 0] @ B32[:, :, c]
                part *= part
                sq += part
        best = max(best, float(sq.max()))
    return float(np.sqrt(best))


def _error_dict(residual: float, frame_energy: np.ndarray, vertex_energy: np.ndarray, max_mm: float | None,
                T: int, n: int, rank: int, r: int) -> dict[str, Any]:
    clip = lambda x: float(np.sqrt(max(float(x), 0.0)))  # noqa: E731 - round-off can leave -1e-20
    return {
        "max_mm": max_mm,
        "rms_mm": clip(residual / (T * n)),
        "worst_frame_rms_mm": clip(np.max(frame_energy) / n) if frame_energy.size else 0.0,
        "worst_vertex_rms_mm": clip(np.max(vertex_energy) / T) if vertex_energy.size else 0.0,
        "rank": int(rank),
        "n_targets": int(r),
    }


def _scaled(directions: np.ndarray, weights: np.ndarray, error: dict[str, Any]) -> PrincipalTargets:
    """Scale each target so its weight peaks at magnitude 1 over the take (a slider's range)."""
    peak = np.abs(weights).max(axis=0) if weights.size else np.ones(weights.shape[1])
    peak = np.where(peak > 0, peak, 1.0)
    targets = directions.astype(np.float32, copy=False)  # scaled in place: no float64 copy of (r, n, 3)
    targets *= peak.astype(np.float32)[:, None, None]
    return PrincipalTargets(targets, (weights / peak).astype(np.float32), error)
