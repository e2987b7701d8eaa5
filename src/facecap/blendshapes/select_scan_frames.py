"""Choose the fewest take frames whose non-negative blends rebuild every frame (Huang et al. 2011, Alg. 1)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from tqdm.auto import tqdm

from ..errors import FacecapWarning, InputError, MarkerError
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_frame_index, as_marker_positions
from .lawson_hanson import BorderedGram, lawson_hanson, refine_on_passive, solve_on_passive

__all__ = ["ScanPlan", "select_scan_frames"]

_EPS = float(np.finfo(np.float64).eps)
_GRAD_TOL = 1e-12  # relative KKT tolerance of every NNLS solve (see nnls_weights)
_TINY_Y = 1e-4  # |y|^2 / |r|^2 below which the duality bound is not trusted
_ROUNDING = 64.0  # safety factor on the eps-level rounding bounds of Gram-space values
_LOWER_SLACK = 1e-9  # relative slack on the duality bounds (computed in the original space)
_BLOCK_ELEMENTS = 2**21  # elements per temporary (candidates x frames x bases) block
_ROW_BLOCK_ELEMENTS = 2**22  # elements per temporary (candidates x frames) block

# (V, |v|^2, Q^T x, Q^T r): see _GreedySearch.projected
_Projection = tuple[FloatArray, FloatArray, FloatArray, FloatArray]


def _timecode(frame: int, rate: float) -> str:
    """Non-drop-frame ``HH:MM:SS:FF`` of a 0-based frame number at the nominal rate ``round(rate)``."""
    fps = max(1, round(rate))
    seconds, ff = divmod(int(frame), fps)
    minutes, ss = divmod(seconds, 60)
    hh, mm = divmod(minutes, 60)
    width = max(2, len(str(fps - 1)))
    return f"{hh:02d}:{mm:02d}:{ss:02d}:{ff:0{width}d}"


@dataclass(frozen=True, eq=False)
class ScanPlan:
    """The frames to scan, chosen by :func:`select_scan_frames`, and how well they rebuild the take.

    Attributes
    ----------
    frames : (K,) int64 array
        0-based frame indices into the take, in the order the greedy search
        chose them (the first one explains the most).
    times : (K,) float64 array, s, or None
        ``frames / rate`` (from the start of the take); None when no rate was given.
    error_after_each : (K,) float64 array, mm
        RMS per-marker reconstruction distance over all frames after
        ``frames[:i + 1]`` were chosen; non-increasing.
    worst_frame_after_each : (K,) float64 array, mm
        The worst frame's RMS marker distance after each addition;
        non-increasing too (adding a basis never shrinks a frame's cone).
    per_frame_residual : (T,) float64 array, mm
        RMS over markers of the reconstruction distance of each frame with
        all K frames.
    tolerance_mm : float
        The threshold ``tolerance * diagonal_mm`` the stopping error was compared with.
    diagonal_mm : float
        Diagonal of the bounding box of all markers over all frames.
    weights : (K, T) float64 array
        Non-negative blend weights of the chosen frames for every frame
        (rows in the order of ``frames``).
    converged : bool
        True when the stopping error (``stop_on``) met ``tolerance_mm``.
    tolerance : float
        The tolerance as a fraction of the diagonal.
    rate : float or None
        Frame rate in Hz, for times and timecodes.
    first_frame : int
        0-based number of the take's first frame in the capture system's
        numbering, added for capture frame numbers and timecodes.
    """

    frames: IntArray
    times: FloatArray | None
    error_after_each: FloatArray
    worst_frame_after_each: FloatArray
    per_frame_residual: FloatArray
    tolerance_mm: float
    diagonal_mm: float
    weights: FloatArray
    converged: bool
    tolerance: float
    rate: float | None
    first_frame: int = 0

    @property
    def n_frames(self) -> int:
        """Number of frames chosen, K."""
        return int(self.frames.size)

    def timecodes(self) -> list[str] | None:
        """``HH:MM:SS:FF`` (non-drop-frame, at the nominal rate) of each chosen frame,
        counted from capture frame 0; None without a rate."""
        if self.rate is None:
            return None
        return [_timecode(self.first_frame + int(f), self.rate) for f in self.frames]

    def to_dict(self, *, include_weights: bool = False) -> dict[str, Any]:
        """A JSON-ready summary (plain lists, floats and ints).

        Parameters
        ----------
        include_weights : bool, default False
            Also list the (K, T) weights (large for long takes).

        Returns
        -------
        dict
            ``frames`` (0-based in the take), ``capture_frames``
            (``first_frame + frames``), ``times_s``, ``timecodes``,
            ``error_after_each_mm``, ``per_frame_residual_mm``,
            ``tolerance``, ``tolerance_mm``, ``diagonal_mm``, ``converged``,
            ``rate``, ``first_frame``, ``n_take_frames``, and ``weights``
            when asked for.
        """
        out: dict[str, Any] = {
            "frames": [int(f) for f in self.frames],
            "capture_frames": [self.first_frame + int(f) for f in self.frames],
            "times_s": None if self.times is None else [float(t) for t in self.times],
            "timecodes": self.timecodes(),
            "error_after_each_mm": [float(e) for e in self.error_after_each],
            "worst_frame_error_after_each_mm": [float(e) for e in self.worst_frame_after_each],
            "per_frame_residual_mm": [float(e) for e in self.per_frame_residual],
            "tolerance": float(self.tolerance),
            "tolerance_mm": float(self.tolerance_mm),
            "diagonal_mm": float(self.diagonal_mm),
            "converged": bool(self.converged),
            "rate": None if self.rate is None else float(self.rate),
            "first_frame": int(self.first_frame),
            "n_take_frames": int(self.per_frame_residual.size),
        }
        if include_weights:
            out["weights"] = self.weights.tolist()
        return out


class _Trial:
    """Frames solved with one more basis: the rows' new state (see ``_GreedySearch.solve_pairs``).

    ``residual`` (n, 3M) is empty and ``error`` (n,) the rounding bound of ``e2`` when the
    squared errors come from the Gram matrix; ``error`` is zero when they come from
    residuals in the original coordinates.
    """

    __slots__ = ("P", "R", "W", "cand", "count", "e2", "error", "residual", "rows")

    def __init__(self, cand: IntArray, rows: IntArray, W: FloatArray, P: BoolArray, R: FloatArray,
                 count: IntArray, residual: FloatArray, e2: FloatArray, error: FloatArray) -> None:
        self.cand, self.rows, self.W, self.P, self.R = cand, rows, W, P, R
        self.count, self.residual, self.e2, self.error = count, residual, e2, error


class _GreedySearch:
    """Greedy forward selection for eq. (3) with exact NNLS, pruned by bounds.

    State per frame t: the NNLS weights on the chosen set S, the passive set and
    the factor of the Lawson-Hanson kernel of ``nnls_weights``, the residual
    ``r_t = x_t - X_S w_t`` (kept in the original coordinates) and its squared
    norm ``e2[t]``.
    """

    def __init__(self, XT: FloatArray) -> None:
        self.XT = XT  # (T, D): frame t's stacked marker coordinates in row t
        self.T, self.D = XT.shape
        self.sqn = np.einsum("td,td->t", XT, XT)
        self.xnorm = np.sqrt(self.sqn)
        self.S: list[int] = []
        self.cap = 0
        self.W = np.zeros((self.T, 0))
        self.P = np.zeros((self.T, 0), dtype=bool)
        self.R = np.zeros((self.T, 0, 0))
        self.count = np.zeros(self.T, dtype=np.int64)
        self.Gs = np.zeros((0, 0))  # x_s . x_s' for s, s' in S
        self.C = np.zeros((self.T, 0))  # x_t . x_s for s in S
        self.residual = XT.copy()
        self.e2 = self.sqn.copy()
        self.in_S = np.zeros(self.T, dtype=bool)
        self.solved_candidates = 0  # candidates solved with the active-set kernel (statistics)

    @property
    def total(self) -> float:
        return float(self.e2.sum())

    # ------------------------------------------------------------------ exact solves

    def solve_pairs(self, cand: IntArray, rows: IntArray, *, precise: bool) -> _Trial:
        """Exact NNLS of frames ``rows[i]`` with the bases S + [cand[i]], all pairs at once,
        each continued from the frame's current state.

        With ``precise`` the residuals are taken in the original coordinates after one
        step of iterative refinement (state fit to commit); otherwise the squared errors
        come from the Gram matrix, ``|x|^2 - 2 w.c + w.G w``, which needs no (pairs, 3M)
        arrays but loses about ``eps (|x|^2 + 2 |w||c| + |w||Gw|)`` to cancellation: that
        bound is returned in ``error``.
        """
        k = len(self.S)
        n = rows.size
        XT, S = self.XT, self.S
        uc, inv = np.unique(cand, return_inverse=True)
        columns = XT @ XT[uc].T  # (T, u): x_t . x_j
        a = columns[S][:, inv].T if k else np.zeros((n, 0))  # (n, k): x_s . x_j
        C = np.empty((n, k + 1))
        C[:, :k] = self.C[rows]
        C[:, k] = columns[rows, inv]
        W = np.zeros((n, k + 1))
        W[:, :k] = self.W[rows, :k]
        P = np.zeros((n, k + 1), dtype=bool)
        P[:, :k] = self.P[rows, :k]
        R = np.zeros((n, k + 1, k + 1))
        R[:, :k, :k] = self.R[rows, :k, :k]
        count = self.count[rows].copy()
        basis_norms = np.empty((n, k + 1))
        basis_norms[:, :k] = self.xnorm[S]
        basis_norms[:, k] = self.xnorm[cand]
        tolg = _GRAD_TOL * self.xnorm[rows, None] * basis_norms
        gram = BorderedGram(self.Gs, a, self.sqn[cand])
        lawson_hanson(gram, C, W, P, R, count, tolg)
        if not precise:
            GW = gram.times(W, np.arange(n))
            e2 = self.sqn[rows] - 2.0 * np.einsum("nk,nk->n", W, C) + np.einsum("nk,nk->n", W, GW)
            scale = self.sqn[rows] + 2.0 * np.einsum("nk,nk->n", W, np.abs(C)) + np.einsum("nk,nk->n", W, np.abs(GW))
            error = _ROUNDING * (k + 1) * _EPS * scale
            return _Trial(cand, rows, W, P, R, count, np.zeros((0, self.D)), np.maximum(e2, 0.0), error)
        Xr = XT[rows]
        Xc = XT[cand]
        residual = Xr - W[:, :k] @ XT[S] - W[:, k:] * Xc
        # one step of iterative refinement: make r_t orthogonal to its passive bases to the
        # precision of the original coordinates (the Gram solve leaves ~cond(G) eps)
        grad = np.empty((n, k + 1))
        grad[:, :k] = residual @ XT[S].T
        grad[:, k] = np.einsum("nd,nd->n", residual, Xc)
        dW = solve_on_passive(R, count, np.arange(n), grad)
        dW[~P] = 0.0
        W = np.maximum(W + dW, 0.0)
        residual = Xr - W[:, :k] @ XT[S] - W[:, k:] * Xc
        e2 = np.einsum("nd,nd->n", residual, residual)
        return _Trial(cand, rows, W, P, R, count, residual, e2, np.zeros(n))

    def positive_rows(self, j: int) -> IntArray:
        """Frames whose residual has a positive component along x_j (the only ones j changes)."""
        g = self.residual @ self.XT[j]
        return np.flatnonzero(g > _GRAD_TOL * self.xnorm[j] * self.xnorm)

    def full_total(self, j: int) -> tuple[float, _Trial]:
        """The total after adding j, every changed frame solved in full."""
        rows = self.positive_rows(j)
        tr = self.solve_pairs(np.full(rows.size, j), rows, precise=True)
        self.solved_candidates += 1
        return self.total - float(self.e2[rows].sum()) + float(tr.e2.sum()), tr

    def commit(self, j: int, trial: _Trial) -> None:
        k = len(self.S)
        if k + 1 > self.cap:
            cap = max(8, 2 * self.cap)
            W = np.zeros((self.T, cap))
            W[:, :k] = self.W[:, :k]
            P = np.zeros((self.T, cap), dtype=bool)
            P[:, :k] = self.P[:, :k]
            R = np.zeros((self.T, cap, cap))
            R[:, :k, :k] = self.R[:, :k, :k]
            self.W, self.P, self.R, self.cap = W, P, R, cap
        rows = trial.rows
        self.W[rows, : k + 1] = trial.W
        self.P[rows, : k + 1] = trial.P
        self.R[rows, : k + 1, : k + 1] = trial.R
        self.count[rows] = trial.count
        self.residual[rows] = trial.residual
        self.e2[rows] = trial.e2
        column = self.XT @ self.XT[j]
        Gs = np.empty((k + 1, k + 1))
        Gs[:k, :k] = self.Gs
        Gs[:k, k] = Gs[k, :k] = column[self.S]
        Gs[k, k] = self.sqn[j]
        self.Gs = Gs
        self.C = np.concatenate([self.C, column[:, None]], axis=1)
        self.S.append(j)
        self.in_S[j] = True

    def weights(self) -> FloatArray:
        """(K, T) weights, refined once with residuals in the original space."""
        k = len(self.S)
        if k == 0:
            return np.zeros((0, self.T))
        B = self.XT[self.S].T
        W = refine_on_passive(B, self.XT, self.W[:, :k].copy(), self.P[:, :k], self.R[:, :k, :k], self.count)
        return np.ascontiguousarray(W.T)

    # ------------------------------------------------------------------ bounds

    def projected(self) -> _Projection:
        """``V`` (T, D): rows ``v_j = x_j - P_S x_j``, orthogonal to every chosen frame; their
        squared norms (T,); and the coordinates of x_j and of r_t in an orthonormal basis
        of span(S), (T, rank) each, whose products give ``(P_S x_j) . r_t``."""
        if not self.S:
            return self.XT, self.sqn, np.zeros((self.T, 0)), np.zeros((self.T, 0))
        XS = self.XT[self.S].T
        Q, Rq, _ = scipy.linalg.qr(XS, mode="economic", pivoting=True)
        diag = np.abs(np.diag(Rq))
        rank = int(np.count_nonzero(diag > diag[0] * max(XS.shape) * _EPS)) if diag[0] > 0 else 0
        Q = Q[:, :rank]
        Qx = self.XT @ Q
        V = self.XT - Qx @ Q.T
        return V, np.einsum("td,td->t", V, V), Qx, self.residual @ Q

    def pair_bounds(
        self, J: IntArray, projection: _Projection, *,
        keep_gradient: bool = False
    ) -> tuple[FloatArray, FloatArray]:
        """(c, T) gradients ``g = x_j . r_t`` (if asked for, else empty) and lower bounds
        on the new squared errors.

        Weak duality for ``min_{w >= 0} |X_{S+j} w - x_t|``: every y with
        ``X_S^T y <= 0`` and ``x_j . y <= 0`` gives ``error >= (y . x_t) / |y|``. With
        ``y = r_t - beta v_j`` (``v_j`` orthogonal to all of S, so the first condition is
        the current optimum's KKT condition; ``beta = max(g, 0) / |v_j|^2`` meets the
        second): ``y . x_t = e2 - beta h`` and ``|y|^2 = e2 - 2 beta h + beta^2 |v_j|^2``
        with ``h = v_j . x_t``. It equals e2 where ``g <= 0`` (the frame keeps its
        solution) and is exact for a frame that uses every chosen basis and stays
        non-negative.
        """
        V, nv, Qx, Qr = projection
        h = V[J] @ V.T  # v_j . x_t (= v_j . v_t)
        g = h + Qx[J] @ Qr.T  # x_j . r_t = v_j . r_t + (P_S x_j) . r_t
        gradient = g.copy() if keep_gradient else np.empty((0, 0))
        nj = nv[J]
        ok = nj > 16.0 * (len(self.S) + 1) * _EPS * self.sqn[J]
        e2 = self.e2[None, :]
        beta = np.maximum(g, 0.0, out=g)
        beta /= np.where(ok, nj, 1.0)[:, None]
        h *= beta  # beta h
        yx = e2 - h  # y . x_t
        beta *= beta
        beta *= nj[:, None]
        beta -= h  # beta^2 n - beta h
        beta += yx  # |y|^2
        yy = beta
        # where y almost vanishes (the candidate nearly fits the frame) the ratio is rounding
        # over rounding: bound by 0 there
        trusted = yy > _TINY_Y * e2
        np.maximum(yx, 0.0, out=yx)
        yx *= yx
        np.divide(yx, yy, out=yx, where=trusted)
        yx[~trusted] = 0.0
        np.minimum(yx, e2, out=yx)
        if not ok.all():  # x_j in span(S): no certificate; only frames it cannot change keep e2
            bad = np.flatnonzero(~ok)
            gb = self.XT[J[bad]] @ self.residual.T
            positive = gb > (_GRAD_TOL * self.xnorm[J[bad]])[:, None] * self.xnorm[None, :]
            yx[bad] = np.where(positive, 0.0, e2)
        return gradient, yx

    def lower_bounds(self, projection: _Projection) -> FloatArray:
        """(T,) lower bound on the total squared error after adding each frame; inf for chosen ones."""
        LB = np.empty(self.T)
        block = max(1, _ROW_BLOCK_ELEMENTS // self.T)
        for lo in range(0, self.T, block):
            J = np.arange(lo, min(lo + block, self.T))
            LB[J] = self.pair_bounds(J, projection)[1].sum(axis=1)
        LB[self.in_S] = np.inf
        return LB

    def closed_form(
        self, J: IntArray, projection: _Projection
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
        """Bounds and exact values for candidates ``J`` from one bordering step of each frame's factor.

        For each (candidate j, frame t) with a positive gradient, bordering t's factor
        with x_j gives the least-squares solution on ``P_t + j`` in closed form: the
        new weight is ``sigma = g / d`` (``d = |x_j - P_{P_t} x_j|^2``) and the squared
        error ``e2 - 2 sigma g + sigma^2 d``. If that solution is non-negative and no
        inactive basis then wants to enter, it is t's exact NNLS solution; otherwise
        the step to the feasible boundary gives an upper bound and the duality bound
        a lower one. ``d`` comes from the Gram matrix and loses about
        ``eps |x_j|^2 (1 + |u|_1)^2`` to cancellation (u: the coefficients of x_j on
        P_t), so each closed-form value carries that error bar, times sigma^2.

        Returns
        -------
        lower, upper : (c,) float64 arrays
            Bounds on the total squared error after adding each candidate,
            rounding included.
        known, known_error : (c,) float64 arrays
            The part of the total from frames whose new error is known in closed
            form (or unchanged), and its rounding bound.
        open_pairs : (c, T) bool array
            Frames that still need the full active-set solve.
        """
        k = len(self.S)
        g, lb = self.pair_bounds(J, projection, keep_gradient=True)
        pos = g > (_GRAD_TOL * self.xnorm[J])[:, None] * self.xnorm[None, :]
        gT, lbT, posT = g.T, lb.T, pos.T  # (T, c)
        e2 = self.e2[:, None]
        sqnJ = self.sqn[J][None, :]
        if k == 0:
            d = np.broadcast_to(sqnJ, gT.shape)
            alpha = np.ones_like(gT)
            u_l1 = np.zeros_like(gT)
            settled = d > 0
        else:
            XS = self.XT[self.S].T
            AJ = XS.T @ self.XT[J].T  # (k, c): x_s . x_j
            pm = int(self.count.max())
            Rv = self.R[:, :pm, :k]
            L = Rv @ AJ  # (T, pm, c)
            d = sqnJ - np.einsum("tpc,tpc->tc", L, L)
            U = np.swapaxes(Rv, 1, 2) @ L  # (T, k, c): LS coefficients of x_j on P_t
            u_l1 = np.abs(U).sum(axis=1)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                step = np.where(posT & (d > 0), gT / d, 0.0)  # new weight of x_j
                # largest feasible fraction of the step: w_i - alpha step u_i >= 0
                room = np.full_like(U, np.inf)
                np.divide(self.W[:, :k, None], U, out=room, where=U > 0)
                alpha = np.minimum(1.0, room.min(axis=1) / step)
            alpha[step == 0] = 1.0
            # gradients of the inactive bases after the step (KKT of the new solution):
            # grad_i - step (x_i . x_j - (Gs u)_i)
            GU = self.Gs @ U
            GU -= AJ[None]
            GU *= step[:, None, :]
            GU += (self.residual @ XS)[:, :, None]  # gradients now, in the original space
            tol_S = _GRAD_TOL * self.xnorm[:, None] * self.xnorm[self.S][None, :]
            wants_in = ((GU > tol_S[:, :, None]) & ~self.P[:, :k, None]).any(axis=1)
            independent = d > 16.0 * (k + 1) * _EPS * sqnJ
            settled = independent & (alpha >= 1.0) & ~wants_in
        usable = posT & (d > 0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            sigma = np.where(usable, alpha * gT / d, 0.0)  # weight of x_j at the point used
        exact = posT & settled
        open_pairs = posT & ~exact
        value = np.where(usable, e2 - sigma * (2.0 * gT - sigma * d), e2)
        error = np.where(
            posT, _ROUNDING * (k + 1) * _EPS * (self.sqn[:, None] + sigma * sigma * sqnJ * (1.0 + u_l1) ** 2), 0.0
        )
        known = np.where(~posT, e2, np.where(exact, np.maximum(value, 0.0), 0.0)).sum(axis=0)
        known_error = np.where(exact, error, 0.0).sum(axis=0)
        lower = known - known_error + np.where(open_pairs, lbT, 0.0).sum(axis=0)
        upper = known + np.where(open_pairs, value + error, 0.0).sum(axis=0) + known_error
        return lower, np.maximum(upper, lower), known, known_error, open_pairs.T

    # ------------------------------------------------------------------ one greedy step

    def step(self, forced: int | None = None) -> float | None:
        """Add the frame that minimises the total squared error (or ``forced``).

        Returns the new total, or None (nothing added) when no frame lowers it. The
        choice is the brute-force one: candidates are visited in order of a lower
        bound and each is bounded or solved exactly; one is passed over only when
        its lower bound exceeds a total already reached. Those left within rounding
        of the best are solved in full with residuals in the original coordinates
        and the smallest total wins (ties: the earliest frame, as in Algorithm 1).
        """
        if forced is not None:
            total, trial = self.full_total(forced)
            self.commit(forced, trial)
            return total
        projection = self.projected()
        LB = self.lower_bounds(projection) * (1.0 - _LOWER_SLACK)
        order = np.argsort(LB, kind="stable")
        order = order[np.isfinite(LB[order])]
        if order.size == 0:
            return None
        k = len(self.S)
        block = int(np.clip(_BLOCK_ELEMENTS // (self.T * max(k, 1)), 4, 256))
        # every candidate examined gets an interval [lower, upper] on its total, rounding
        # included; ``best`` is the smallest upper end so far
        lower: dict[int, float] = {}
        upper: dict[int, float] = {}
        known: dict[int, tuple[float, float]] = {}
        pending: dict[int, IntArray] = {}

        def settle(batch: list[int]) -> float:
            """Solve the open frames of ``batch`` with the kernel; the smallest new upper end."""
            rows = np.concatenate([pending[j] for j in batch])
            which = np.repeat(np.arange(len(batch)), [pending[j].size for j in batch])
            trial = self.solve_pairs(np.asarray(batch, dtype=np.int64)[which], rows, precise=False)
            sums = np.bincount(which, weights=trial.e2, minlength=len(batch))
            errs = np.bincount(which, weights=trial.error, minlength=len(batch))
            self.solved_candidates += len(batch)
            for i, j in enumerate(batch):
                del pending[j]
                value, error = known[j][0] + float(sums[i]), known[j][1] + float(errs[i])
                lower[j], upper[j] = value - error, value + error
            return min(upper[j] for j in batch)

        best = np.inf
        pos = 0
        while pos < order.size and LB[order[pos]] <= best:
            J = order[pos : pos + block]
            J = J[LB[J] <= best]
            pos += block
            lo, hi, kn, kn_err, open_pairs = self.closed_form(J, projection)
            for i, j in enumerate(J.tolist()):
                lower[j], upper[j] = max(float(lo[i]), float(LB[j])), float(hi[i])
                if open_pairs[i].any():
                    pending[j] = np.flatnonzero(open_pairs[i])
                    known[j] = (float(kn[i]), float(kn_err[i]))
            best = min(best, float(hi.min()))
            # settle the most promising candidate now: a tight best prunes the rest sooner
            if pending:
                first = min(pending, key=lambda c: (lower[c], c))
                if lower[first] <= best:
                    best = min(best, settle([first]))
        # solve the frames the closed form left open, for the candidates that could still
        # win, the most promising first, several candidates per call
        pair_budget = max(self.T, _ROW_BLOCK_ELEMENTS // (k + 1) ** 2)
        while True:
            todo = sorted((j for j in pending if lower[j] <= best), key=lambda c: (lower[c], c))
            if not todo:
                break
            batch, n_pairs = [], 0
            for j in todo:
                if batch and n_pairs + pending[j].size > pair_budget:
                    break
                batch.append(j)
                n_pairs += pending[j].size
            best = min(best, settle(batch))
        # the finalists (every candidate that may still be the best), solved in full with
        # residuals in the original coordinates; the smallest total wins, ties to the earliest
        finalists = sorted(j for j in lower if j not in pending and lower[j] <= best)
        chosen: tuple[int, _Trial] | None = None
        best_total = self.total
        for j in finalists:
            total, trial = self.full_total(j)
            if total < best_total:
                chosen, best_total = (j, trial), total
        if chosen is None:
            return None
        self.commit(*chosen)
        return self.total

def select_scan_frames(
    positions: FloatArray,
    *,
    tolerance: float = 0.003,
    max_frames: int | None = None,
    rest_frame: int | None = None,
    rate: float | None = None,
    first_frame: int = 0,
    stop_on: str = "worst_frame",
    progress: bool = False,
) -> ScanPlan:
    """Choose the take frames to scan: the fewest whose non-negative blends rebuild every frame.

    Algorithm 1 of Huang et al. 2011: start from an empty set, and at each
    step add the frame whose marker configuration minimises the total
    non-negative least-squares reconstruction error of all frames (eq. 3);
    stop when the error falls to the tolerance. The choice at every step is
    the one the brute-force search makes, found without solving for every
    candidate (see Notes).

    Parameters
    ----------
    positions : (T, M, 3) float64 array, mm
        The conditioned take: gap-filled and head-stabilised (the markers of
        each frame stacked form one column of eq. 3). No NaN. Rigid head
        markers may be left out; they only add a constant to every frame.
    tolerance : float, default 0.003
        Stopping threshold as a fraction of the diagonal of the bounding box
        of all markers over all frames (the paper's 0.3 %).
    max_frames : int or None, optional
        Stop after this many frames even if the tolerance is not met
        (``converged`` is then False). Default: no limit.
    rest_frame : int or None, optional
        A frame to take first, before the search (e.g. the neutral pose that
        matches a scan you already have). Default None: Algorithm 1 as
        published, starting from the empty set.
    rate : float or None, optional
        Frame rate in Hz, for ``times`` and timecodes.
    first_frame : int, default 0
        0-based number of the take's first frame in the capture system
        (``MarkerSequence.first_frame``), for capture frame numbers and timecodes.
    stop_on : {'worst_frame', 'rms'}, default 'worst_frame'
        Which error must fall within the tolerance: the worst frame's, or
        the RMS over all frames (see Notes).
    progress : bool, default False
        Show a progress bar (tqdm) with the error after each frame.

    Returns
    -------
    ScanPlan
        The frames in the order chosen, the error after each, the final
        weights and per-frame residuals.

    Raises
    ------
    MarkerError
        If ``positions`` is not (T, M, 3), has NaN (fill the gaps first) or
        spans no volume (all markers at one point).
    InputError
        On a negative tolerance, a non-positive ``max_frames`` or ``rate``,
        or ``rest_frame`` outside the take.

    Warns
    -----
    FacecapWarning
        When no further frame lowers the error and the tolerance is not met.

    Notes
    -----
    With ``x_t`` the 3M stacked coordinates of frame t and S the chosen
    frames, the error of eq. (3) is
    ``E(S) = sum_t min_{w >= 0} ||X_S w - x_t||^2``. It is reported as the RMS
    per-marker distance ``sqrt(E / (T M))`` in mm. Each step adds the frame
    that minimises E (Algorithm 1); the search stops, with ``stop_on=
    'worst_frame'`` (default), at the first S whose worst frame's RMS marker
    distance is within ``tolerance * diagonal``: a capture TD needs every
    frame of the take rebuilt within tolerance, not the average. With
    ``stop_on='rms'`` it stops when ``sqrt(E / (T M))`` is (the choice of
    frames is the same; only where it stops differs). At least one
    frame is always chosen. Eq. (3) is not invariant to where the origin is:
    positions far from it (a mocap volume's origin a metre away) make the
    blends nearly convex (weights summing to about 1), as suits absolute
    marker positions; the result is the exact answer for the coordinates given.

    Exactness and speed. The paper solved NNLS for every candidate at every
    step (2-3 hours for 1500 frames). Here each frame keeps its NNLS state
    (the batched Lawson-Hanson kernel of :func:`nnls_weights`), and a
    candidate j only changes frames whose residual has a positive component
    along ``x_j`` (KKT: the others keep their solution). Each step then:

    1. bounds every candidate's total from below by weak duality (computed
       in the original coordinates; exact for frames that use every chosen
       basis) and visits candidates in that order;
    2. borders every frame's factor with the candidate in closed form: the
       exact new solution where it stays feasible and optimal, an upper
       bound (the feasible boundary point) and the duality bound elsewhere;
    3. solves the remaining frames of the candidates that can still win
       with the active-set kernel, several candidates per batch;
    4. solves every candidate whose interval still reaches the best upper
       end again, with residuals in the original coordinates, and takes the
       smallest total (ties to the earliest frame, as in Algorithm 1).

    Every interval includes a rounding bound on the Gram-space values
    (cancellation against ``|x|^2``, large when markers are far from the
    origin), so a candidate is only passed over when it provably cannot
    win: the choice is the brute-force one, which the tests check against a
    literal Algorithm 1 on ``scipy.optimize.nnls``. Cost per step: one
    (T x 3M) by (3M x T) product and a few passes over (T x T) values for
    the bounds, plus O(T k^2) per candidate examined. Memory: the take,
    O(T K^2) for the per-frame state, and blocks of a few million values.

    References
    ----------
    .. [1] H. Huang, J. Chai, X. Tong and H.-T. Wu, "Leveraging motion
       capture and 3D scanning for high-fidelity facial performance
       acquisition", ACM Trans. Graph. 30(4), 2011, sec. 4, eq. (3), Alg. 1.

    Examples
    --------
    A take that only ever holds three distinct expressions needs three scans:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> poses = rng.normal(size=(3, 5, 3)) * 10 + [0.0, 0.0, 1000.0]  # 3 poses, 5 markers
    >>> take = poses[[0, 1, 1, 2, 0, 2, 2, 1]]                        # 8 frames
    >>> plan = select_scan_frames(take, rate=24.0)
    >>> sorted(take[plan.frames].tolist()) == sorted(poses.tolist()), plan.converged
    (True, True)
    """
    X = as_marker_positions(positions, name="positions")
    if np.isnan(X).any():
        frames, markers = np.nonzero(np.isnan(X).any(axis=2))
        raise MarkerError(
            f"positions: {frames.size} marker samples are gaps (NaN), first at frame {frames[0]}, "
            f"marker {markers[0]}; fill them first (facecap.markers.fill_gaps)"
        )
    T, M, _ = X.shape
    try:
        tolerance = float(tolerance)
    except (TypeError, ValueError):
        raise InputError(f"tolerance: expected a number, got {tolerance!r}") from None
    if not np.isfinite(tolerance) or tolerance < 0:
        raise InputError(f"tolerance: expected a non-negative fraction of the diagonal, got {tolerance!r}")
    if max_frames is not None and (
        isinstance(max_frames, (bool, np.bool_)) or not isinstance(max_frames, (int, np.integer)) or max_frames < 1
    ):
        raise InputError(f"max_frames: expected a positive integer or None, got {max_frames!r}")
    if rest_frame is not None:
        rest_frame = as_frame_index(rest_frame, T, name="rest_frame")
    if rate is not None:
        try:
            rate = float(rate)
        except (TypeError, ValueError):
            raise InputError(f"rate: expected a frame rate in Hz, got {rate!r}") from None
        if not np.isfinite(rate) or rate <= 0:
            raise InputError(f"rate: expected a positive frame rate in Hz, got {rate!r}")
    if isinstance(first_frame, (bool, np.bool_)) or not isinstance(first_frame, (int, np.integer)) or first_frame < 0:
        raise InputError(f"first_frame: expected a non-negative integer, got {first_frame!r}")

    flat = X.reshape(-1, 3)
    diagonal = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    if diagonal <= 0:
        raise MarkerError("positions: all markers are at one point in every frame (bounding box diagonal 0)")
    tolerance_mm = tolerance * diagonal
    limit = T if max_frames is None else min(int(max_frames), T)
    search = _GreedySearch(np.ascontiguousarray(X.reshape(T, 3 * M)))

    def rms(total: float) -> float:
        return float(np.sqrt(max(total, 0.0) / (T * M)))

    if stop_on not in ("worst_frame", "rms"):
        raise InputError(f"stop_on: expected 'worst_frame' or 'rms', got {stop_on!r}")
    errors: list[float] = []
    worst: list[float] = []

    def met() -> bool:
        return bool(errors) and (worst[-1] if stop_on == "worst_frame" else errors[-1]) <= tolerance_mm

    stuck = False
    with tqdm(total=max_frames, disable=not progress, desc="select_scan_frames", unit="frame") as bar:
        while len(search.S) < limit and not met():
            forced = rest_frame if not search.S else None
            total = search.step(forced)
            if total is None:
                stuck = True
                break
            errors.append(rms(total))
            worst.append(float(np.sqrt(max(float(np.max(search.e2)), 0.0) / M)))
            bar.update(1)
            bar.set_postfix(rms_mm=f"{errors[-1]:.4f}", worst_mm=f"{worst[-1]:.4f}", goal_mm=f"{tolerance_mm:.4f}")
    if not errors:  # a take no frame improves (every frame is 0): take the first
        errors.append(rms(search.step(0) or 0.0))
        worst.append(float(np.sqrt(max(float(np.max(search.e2)), 0.0) / M)))
    converged = met()
    if stuck and not converged:
        warnings.warn(
            f"select_scan_frames: no further frame lowers the error; stopped at {len(search.S)} frames "
            f"with {errors[-1]:.4g} mm RMS above the tolerance {tolerance_mm:.4g} mm",
            FacecapWarning,
            stacklevel=2,
        )
    frames = np.asarray(search.S, dtype=np.int64)
    return ScanPlan(
        frames=frames,
        times=None if rate is None else frames / rate,
        error_after_each=np.asarray(errors),
        worst_frame_after_each=np.asarray(worst),
        per_frame_residual=np.sqrt(np.maximum(search.e2, 0.0) / M),
        tolerance_mm=tolerance_mm,
        diagonal_mm=diagonal,
        weights=search.weights(),
        converged=bool(converged),
        tolerance=tolerance,
        rate=rate,
        first_frame=int(first_frame),
    )
