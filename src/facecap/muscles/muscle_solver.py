"""Muscle activations and bone frames from markers by Gauss-Newton (Sifakis et al. 2005, sec. 5-8)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..markers.rigid_fit import rigid_fit
from ..typing import FloatArray
from .control_penalty import control_penalty
from .marker_embedding import DEFAULT_MAX_OFFSET_MM, MarkerEmbedding, marker_embedding
from .muscle_controls import MuscleControls
from .muscle_model import MuscleModel, apply_affine

__all__ = ["MuscleSolver", "MuscleFrame"]

_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)
_MAX_CONTINUATION_STEPS = 4000
FLAG_RESIDUAL_MM = 5.0
"""Default marker residual above which a frame is flagged ``large_residual``, mm (a frame the model
reaches leaves 0.3-0.5 mm rms at 0.2 mm marker noise: docs/muscles.md, "Measured")."""


@dataclass(frozen=True, eq=False)
class MuscleFrame:
    """The controls solved for one frame and the face they make.

    Attributes
    ----------
    activations : (k,) float64 array
        Muscle activations, in [0, 1] to the penalty's tolerance.
    cranium : (3, 4) float64 array, mm
        Head frame ``[M_c | t_c]`` (rest coordinates to world).
    mandible : (3, 4) float64 array, mm
        Jaw frame relative to the cranium (:class:`MuscleControls`).
    jaw_pose : (3,) float64 array
        ``(opening_rad, slide_left_mm, slide_right_mm)`` of the mandible (:meth:`JawConstraints.pose`).
    nodes : (N, 3) float64 array, mm
        Equilibrium flesh nodes, world.
    skin : (n_scan, 3) float64 array, mm
        The scan's vertices, world, in the scan's order.
    markers : (M, 3) float64 array, mm
        The model's markers, world.
    marker_residuals : (M,) float64 array, mm
        Distance from each model marker to its observed marker (NaN where the marker is missing).
    rms_mm : float
        Root-mean-square marker residual over the observed markers.
    steps : int
        Gauss-Newton steps taken.
    quasistatic_solves : int
        Quasistatic solves run (a request at the controls and state of the last solve reuses it
        and is not counted).
    newton_iterations : int
        Newton iterations summed over the quasistatic solves.
    inverted_tets : int
        Inverted tetrahedra in the solved state.
    constraint_violation : dict of str to float
        ``activations`` (distance outside [0, 1]), ``rigidity`` (largest ``|sigma - 1|`` of
        ``M_c`` and ``M_m``), ``jaw_mm`` (largest violation of psi2-psi5) and ``jaw`` (of psi1, psi6).
    flags : tuple of str
        Anything worth a look: ``'too_few_markers'`` (not solved: the previous controls are
        carried), ``'inverted_tets'``, ``'not_converged'`` (a quasistatic solve did not reach
        its tolerance), ``'constraint_violation'`` (above ``1e-4``), ``'jaw_at_limit'`` (the
        opening or a slide at its upper bound: the markers may ask for more than the joint
        allows), ``'large_residual'`` (a marker farther than ``flag_residual_mm``).
    timings : dict of str to float, s
        ``linearise`` (equilibrium at the start of a step, factorisation and the eq. 5 and 6
        Jacobians), ``gauss_newton`` (the penalty continuation), ``full_step`` (the
        quasistatic solve at the full step), ``line_search``, ``total``.
    """

    activations: FloatArray
    cranium: FloatArray
    mandible: FloatArray
    jaw_pose: FloatArray
    nodes: FloatArray
    skin: FloatArray
    markers: FloatArray
    marker_residuals: FloatArray
    rms_mm: float
    steps: int
    quasistatic_solves: int
    newton_iterations: int
    inverted_tets: int
    constraint_violation: dict[str, float] = field(default_factory=dict)
    flags: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def controls(self) -> MuscleControls:
        """The solved controls."""
        return MuscleControls(self.activations, self.cranium, self.mandible)


def _invert_affine(transform: FloatArray, points: FloatArray) -> FloatArray:
    M, t = transform[:, :3], transform[:, 3]
    return np.linalg.solve(M, (points - t).T).T


class MuscleSolver:
    """Controls (activations, cranium and jaw) that make the face's markers match a take's.

    Set-up (the flesh model, its sparsity pattern, the marker embedding) happens once;
    :meth:`solve_frame` is the per-frame call, warm-started from the previous frame.

    Parameters
    ----------
    anatomy : FaceAnatomy
    marker_vertices : (M,) int array
        Scan vertex of each marker.
    rest_markers : (M, 3) float64 array, mm
        The markers at the rest frame, in the scan's coordinates (their offsets from the
        embedded skin points are subtracted, :func:`marker_embedding`).
    solve_cranium : bool, default True
        Solve the head's frame; False keeps it at the identity (a take already stabilised
        into the scan's frame).
    solve_jaw : bool, default True
        Solve the jaw's frame; False keeps it at the identity (closed).
    max_steps : int, default 5
        Gauss-Newton steps of a frame without a previous one (the paper: 3-5).
    max_warm_steps : int, default 2
        Gauss-Newton steps of a frame warm-started from the previous one (the paper: 1).
    step_tolerance : float, default 0.01
        Stop when a step lowers the marker objective by less than this fraction.
    line_search_evaluations : int, default 6
        Golden-section evaluations (quasistatic solves) when the full step falls short.
    always_search : bool, default False
        Run the golden-section search after every full step, as the paper did, even when
        the full step delivers at least half the decrease the linearisation predicted.
    marker_noise_mm : float, default 0.2
        Expected marker noise: the penalty weight starts at its square (the paper's
        "variance of the localization error").
    penalty_growth : float, default 1.05
        The paper's 5 % steps of the penalty weight.
    penalty_ratio : float, default 1e6
        The weight grows until it is this many times the objective.
    constraint_tolerance : float, default 1e-5
        ... and until the linearised solution violates no constraint by more than this.
    flag_residual_mm : float, default 5
        Flag a frame with a marker residual above this.
    min_markers : int, default 6
        Frames with fewer observed markers are not solved (flagged).
    max_offset_mm : float, default 10
        See :func:`marker_embedding`.
    model : MuscleModel, optional
        A prepared model of this anatomy (else built here with ``model_options``).
    **model_options
        Passed to :class:`MuscleModel` (``muscle_strength``, ``material``, ``fibre``, ``jaw``,
        ``rim``, ``backend``, ``tolerance``).

    Attributes
    ----------
    model : MuscleModel
        The face driven by the controls (its solver holds the last equilibrium's factor).
    embedding : MarkerEmbedding
        The markers in the flesh mesh, with their rest offsets.

    Raises
    ------
    InputError, CorrespondenceError
        Bad options, or markers that land off the model (:func:`marker_embedding`).
    """

    def __init__(self, anatomy: Any, marker_vertices: Any, rest_markers: Any, *, solve_cranium: bool = True,
                 solve_jaw: bool = True, max_steps: int = 5, max_warm_steps: int = 2,
                 step_tolerance: float = 0.01, line_search_evaluations: int = 6, always_search: bool = False,
                 marker_noise_mm: float = 0.2,
                 penalty_growth: float = 1.05, penalty_ratio: float = 1e6, constraint_tolerance: float = 1e-5,
                 flag_residual_mm: float = FLAG_RESIDUAL_MM, min_markers: int = 6,
                 max_offset_mm: float = DEFAULT_MAX_OFFSET_MM, model: MuscleModel | None = None,
                 **model_options: Any) -> None:
        if int(max_steps) < 1 or int(max_warm_steps) < 1 or int(line_search_evaluations) < 0:
            raise InputError("max_steps and max_warm_steps must be at least 1, line_search_evaluations at least 0")
        if not (penalty_growth > 1.0 and penalty_ratio > 0 and constraint_tolerance > 0 and marker_noise_mm > 0):
            raise InputError("penalty_growth must exceed 1; penalty_ratio, constraint_tolerance and "
                             "marker_noise_mm must be positive")
        self.model = model if model is not None else MuscleModel(anatomy, **model_options)
        self.embedding: MarkerEmbedding = marker_embedding(anatomy, marker_vertices, rest_markers,
                                                           max_offset_mm=max_offset_mm)
        self.n_markers = int(self.embedding.vertices.size)
        k = self.model.n_muscles
        self.n_muscles = k
        free = [np.arange(k)]
        if solve_cranium:
            free.append(k + np.arange(12))
        if solve_jaw:
            free.append(k + 12 + np.arange(12))
        self.free = np.concatenate(free)
        self.solve_cranium, self.solve_jaw = bool(solve_cranium), bool(solve_jaw)
        self.max_steps, self.max_warm_steps = int(max_steps), int(max_warm_steps)
        self.step_tolerance = float(step_tolerance)
        self.line_search_evaluations = int(line_search_evaluations)
        self.always_search = bool(always_search)
        self.initial_penalty = float(marker_noise_mm) ** 2
        self.penalty_growth, self.penalty_ratio = float(penalty_growth), float(penalty_ratio)
        self.constraint_tolerance = float(constraint_tolerance)
        self.flag_residual_mm = float(flag_residual_mm)
        self.min_markers = int(min_markers)
        self._rest_model_markers = self.embedding.matrix @ self.model.rest_positions + self.embedding.offsets

    # -- pieces ----------------------------------------------------------------------------------
    def _model_markers(self, c: FloatArray, x: FloatArray) -> FloatArray:
        k = self.n_muscles
        cranium = np.hstack([c[k:k + 9].reshape(3, 3), c[k + 9:k + 12, None]])
        return apply_affine(cranium, self.embedding.matrix @ x + self.embedding.offsets)

    def _jacobian(self, c: FloatArray, x: FloatArray, valid: np.ndarray, timings: dict[str, float], *,
                  jaw: bool) -> tuple[FloatArray, FloatArray, FloatArray | None]:
        """``d markers / d c`` (3 Mv, k + 24) at the model's last equilibrium, and ``dX/da``, ``dX/db_m``."""
        t0 = time.perf_counter()
        k, W = self.n_muscles, self.embedding.matrix[valid]
        Mc = c[k:k + 9].reshape(3, 3)
        dXa, dXb = self.model.jacobians(jaw=jaw)
        n = x.shape[0]
        Mv = int(valid.sum())
        cols = np.zeros((Mv, 3, k + 24))
        Sa = (W @ dXa.transpose(1, 0, 2).reshape(n, -1)).reshape(Mv, k, 3) @ Mc.T
        cols[:, :, :k] = Sa.transpose(0, 2, 1)
        Q = W @ x + self.embedding.offsets[valid]
        for i in range(3):
            for j in range(3):
                cols[:, i, k + 3 * i + j] = Q[:, j]
            cols[:, i, k + 9 + i] = 1.0
        if dXb is not None:
            Sb = (W @ dXb.transpose(1, 0, 2).reshape(n, -1)).reshape(Mv, 12, 3) @ Mc.T
            cols[:, :, k + 12:] = Sb.transpose(0, 2, 1)
        timings["linearise"] += time.perf_counter() - t0
        return cols.reshape(3 * Mv, -1), dXa, dXb

    def marker_jacobian(self, controls: MuscleControls, x0: FloatArray | None = None) -> FloatArray:
        """``d markers / d c`` at the equilibrium of ``controls``: (M, 3, k + 24) mm per unit control.

        Columns in the order of :meth:`MuscleControls.as_vector`; the activation columns by
        eq. 5, the mandible's by eq. 6, the cranium's analytically (the whole face moves with
        the cranium's affine map). ``x0``: initial guess of the nodes in the cranium's frame.
        """
        if not isinstance(controls, MuscleControls) or controls.n_muscles != self.n_muscles:
            raise InputError(f"controls: expected MuscleControls with {self.n_muscles} activations")
        c = controls.as_vector()
        result = self._solve_at(c, self.model.rest_positions if x0 is None else x0)
        timings = {"linearise": 0.0}
        J = self._jacobian(c, result.positions, np.ones(self.n_markers, dtype=bool), timings, jaw=True)[0]
        return J.reshape(self.n_markers, 3, -1)

    def _violations(self, c: FloatArray) -> dict[str, float]:
        k = self.n_muscles
        a = c[:k]
        out = {"activations": float(max(0.0, -a.min(initial=0.0), a.max(initial=0.0) - 1.0))}
        rigid = 0.0
        for start in (k, k + 12):
            sigma = np.linalg.svd(c[start:start + 9].reshape(3, 3), compute_uv=False)
            rigid = max(rigid, float(np.abs(sigma - 1.0).max()))
        out["rigidity"] = rigid
        jaw = self.model.jaw.violations(np.hstack([c[k + 12:k + 21].reshape(3, 3), c[k + 21:, None]]))
        out["jaw_mm"] = float(jaw[1:5].max())
        out["jaw"] = float(max(jaw[0], jaw[5]))
        return out

    def _step(self, c: FloatArray, r: FloatArray, J: FloatArray, phi: float,
              timings: dict[str, float]) -> FloatArray:
        """Minimise ``|r + J dc|^2 + rho phi_p(c + dc)`` with the paper's continuation in ``rho`` (eq. 7)."""
        t0 = time.perf_counter()
        k, free = self.n_muscles, self.free
        H0 = 2.0 * J.T @ J
        g0 = 2.0 * J.T @ r
        damping = 1e-9 * max(float(np.trace(H0)) / max(H0.shape[0], 1), 1e-12)
        A0 = H0 + damping * np.eye(H0.shape[0])
        rho = self.initial_penalty
        rho_final = self.penalty_ratio * max(phi, self.initial_penalty)
        trial = c.copy()
        for _ in range(_MAX_CONTINUATION_STEPS):
            pen = control_penalty(trial, k, self.model.jaw)
            dc = trial[free] - c[free]
            A = A0 + rho * pen.hessian[np.ix_(free, free)]
            b = g0 + H0 @ dc + rho * pen.gradient[free]
            try:
                delta = np.linalg.solve(A, -b)
            except np.linalg.LinAlgError:
                delta = np.linalg.lstsq(A, -b, rcond=None)[0]
            trial[free] += delta
            if rho >= rho_final:
                v = self._violations(trial)
                if max(v["activations"], v["rigidity"], v["jaw"], v["jaw_mm"]) <= self.constraint_tolerance:
                    break
            rho *= self.penalty_growth
        timings["gauss_newton"] += time.perf_counter() - t0
        return trial

    def _objective(self, c: FloatArray, x: FloatArray, targets: FloatArray,
                   valid: np.ndarray) -> tuple[float, FloatArray]:
        r = (self._model_markers(c, x)[valid] - targets[valid]).reshape(-1)
        return float(r @ r), r

    def _solve_at(self, c: FloatArray, x0: FloatArray) -> Any:
        k = self.n_muscles
        mandible = np.hstack([c[k + 12:k + 21].reshape(3, 3), c[k + 21:, None]])
        return self.model.equilibrium(c[:k], mandible, x0=x0)

    # -- the per-frame call -----------------------------------------------------------------------
    def solve_frame(self, markers: Any, previous: MuscleFrame | None = None) -> MuscleFrame:
        """Solve one frame.

        Parameters
        ----------
        markers : (M, 3) float64 array, mm
            Observed markers, world coordinates, in the order of ``marker_vertices``; NaN rows
            are missing markers (left out of the objective).
        previous : MuscleFrame, optional
            The previous frame's result: its controls and equilibrium start this frame
            (then at most ``max_warm_steps`` steps). None: from rest, the cranium started by a
            rigid fit of the rest markers (at most ``max_steps`` steps).

        Returns
        -------
        MuscleFrame

        Raises
        ------
        InputError
            Markers of the wrong shape or with infinite values.

        Notes
        -----
        Each Gauss-Newton step linearises the equilibrium at the current controls (eq. 3;
        ``dX/da`` by eq. 5, ``dX/db`` of the jaw by eq. 6, the cranium's analytically),
        minimises the linearised marker objective plus ``rho phi_p`` while ``rho`` grows by
        5 % steps (eq. 7), solves the quasistatic equilibrium at the full step (warm-started
        by the linearised prediction) and, if that falls short of half the predicted
        decrease, searches the segment by golden sections, each trial warm-started by
        interpolating the nearest solved states.
        """
        t_start = time.perf_counter()
        timings = {"linearise": 0.0, "gauss_newton": 0.0, "full_step": 0.0, "line_search": 0.0, "total": 0.0}
        try:
            targets = np.array(markers, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"markers: expected a numeric ({self.n_markers}, 3) array ({exc})") from None
        if targets.shape != (self.n_markers, 3):
            raise InputError(f"markers: expected shape ({self.n_markers}, 3), got {targets.shape}")
        if np.any(np.isinf(targets)):
            raise InputError("markers: infinite values (use NaN for a missing marker)")
        if previous is not None and not isinstance(previous, MuscleFrame):
            raise InputError(f"previous: expected a MuscleFrame, got {type(previous).__name__}")
        valid = np.all(np.isfinite(targets), axis=1)
        k = self.n_muscles
        if previous is not None:
            c = previous.controls.as_vector()
            x = _invert_affine(previous.cranium, previous.nodes)
        else:
            c = MuscleControls.rest(k).as_vector()
            x = self.model.rest_positions.copy()
            if self.solve_cranium and valid.sum() >= 3:
                fit = rigid_fit(self._rest_model_markers[valid], targets[valid])
                c[k:k + 9] = fit.rotation.ravel()
                c[k + 9:k + 12] = fit.translation
        if valid.sum() < self.min_markers:
            return self._frame(c, x, targets, valid, 0, 0, 0, 0, timings, t_start, extra=("too_few_markers",))
        max_steps = self.max_steps if previous is None else self.max_warm_steps
        solves = newton = steps = 0
        inverted = 0
        not_converged = False
        t0 = time.perf_counter()
        result = self._solve_at(c, x)
        timings["linearise"] += time.perf_counter() - t0
        solves, newton = int(not self.model.reused_last), result.iterations
        x, inverted, not_converged = result.positions, result.inverted_tets, not result.converged
        phi, r = self._objective(c, x, targets, valid)
        while steps < max_steps:
            J_full, dXa, dXb = self._jacobian(c, x, valid, timings, jaw=self.solve_jaw)
            J = J_full[:, self.free]
            c_new = self._step(c, r, J, phi, timings)
            dc = (c_new - c)[self.free]
            phi_linear = float(np.sum((r + J @ dc) ** 2))
            predicted = phi - phi_linear
            # the full step, warm-started by the linearised equilibrium (unless that inverts tetrahedra)
            t0 = time.perf_counter()
            guess = self._predicted_nodes(x, c, c_new, dXa, dXb)
            result = self._solve_at(c_new, guess if not self.model.flesh.inverted_tets(guess).any() else x)
            timings["full_step"] += time.perf_counter() - t0
            solves += not self.model.reused_last
            newton += result.iterations
            phi_new, _ = self._objective(c_new, result.positions, targets, valid)
            best = (1.0, phi_new, result)
            delivered = phi_new <= phi and (predicted <= 0 or phi - phi_new >= 0.5 * predicted)
            if self.always_search or not delivered:
                t0 = time.perf_counter()
                best, n_solves, n_newton = self._line_search(c, c_new, x, phi, result, targets, valid)
                timings["line_search"] += time.perf_counter() - t0
                solves += n_solves
                newton += n_newton
            t_best, phi_best, result_best = best
            steps += 1
            if phi_best >= phi:  # no decrease along the step: keep the current controls
                break
            c = c_new if t_best == 1.0 else c + t_best * (c_new - c)  # the very controls solved at
            x = result_best.positions
            inverted, not_converged = result_best.inverted_tets, not result_best.converged
            decrease = phi - phi_best
            phi = phi_best
            r = self._objective(c, x, targets, valid)[1]
            if steps >= max_steps or decrease < self.step_tolerance * (phi + decrease):
                break
            # re-establish the solver's state (and factor) at the accepted controls
            t0 = time.perf_counter()
            result = self._solve_at(c, x)
            timings["linearise"] += time.perf_counter() - t0
            solves += not self.model.reused_last
            newton += result.iterations
            x = result.positions
        extra = []
        if inverted:
            extra.append("inverted_tets")
        if not_converged:
            extra.append("not_converged")
        return self._frame(c, x, targets, valid, steps, solves, newton, inverted, timings, t_start, extra=tuple(extra))

    def _predicted_nodes(self, x: FloatArray, c: FloatArray, c_new: FloatArray, dXa: FloatArray,
                         dXb: FloatArray | None) -> FloatArray:
        """The linearised equilibrium at ``c_new`` (eq. 3) from the Jacobians at ``c`` (cranium frame)."""
        k = self.n_muscles
        out = x + np.tensordot(c_new[:k] - c[:k], dXa, axes=1)
        if dXb is not None:
            out += np.tensordot(c_new[k + 12:] - c[k + 12:], dXb, axes=1)
        return out

    def _line_search(self, c: FloatArray, c_new: FloatArray, x: FloatArray, phi: float, full: Any,
                     targets: FloatArray, valid: np.ndarray) -> tuple[tuple[float, float, Any], int, int]:
        """Golden-section search of the marker objective along ``c + t (c_new - c)``, ``t`` in [0, 1]."""
        states: dict[float, FloatArray] = {0.0: x, 1.0: full.positions}
        best = (1.0, self._objective(c_new, full.positions, targets, valid)[0], full)
        solves = newton = 0

        def evaluate(t: float) -> float:
            nonlocal best, solves, newton
            lower = max(s for s in states if s <= t)
            upper = min(s for s in states if s >= t)
            w = 0.0 if upper == lower else (t - lower) / (upper - lower)
            guess = (1 - w) * states[lower] + w * states[upper]
            ct = c + t * (c_new - c)
            result = self._solve_at(ct, guess)
            solves += not self.model.reused_last
            newton += result.iterations
            states[t] = result.positions
            value = self._objective(ct, result.positions, targets, valid)[0]
            if value < best[1]:
                best = (t, value, result)
            return value

        lo, hi = 0.0, 1.0
        t1, t2 = hi - _GOLDEN * (hi - lo), lo + _GOLDEN * (hi - lo)
        f1 = f2 = None
        for _ in range(self.line_search_evaluations):
            if f1 is None:
                f1 = evaluate(t1)
                continue
            if f2 is None:
                f2 = evaluate(t2)
                continue
            if f1 < f2:
                hi, t2, f2 = t2, t1, f1
                t1 = hi - _GOLDEN * (hi - lo)
                f1 = evaluate(t1)
            else:
                lo, t1, f1 = t1, t2, f2
                t2 = lo + _GOLDEN * (hi - lo)
                f2 = evaluate(t2)
        return best, solves, newton

    def _frame(self, c: FloatArray, x: FloatArray, targets: FloatArray, valid: np.ndarray, steps: int,
               solves: int, newton: int, inverted: int, timings: dict[str, float], t_start: float, *,
               extra: tuple[str, ...] = ()) -> MuscleFrame:
        controls = MuscleControls.from_vector(c, self.n_muscles)
        model_markers = self._model_markers(c, x)
        residuals = np.linalg.norm(model_markers - targets, axis=1)
        residuals[~valid] = np.nan
        rms = float(np.sqrt(np.nanmean(residuals[valid] ** 2))) if valid.any() else float("nan")
        violation = self._violations(c)
        flags = list(extra)
        if max(violation.values()) > 1e-4:
            flags.append("constraint_violation")
        jaw = self.model.jaw
        psi = jaw.values(controls.mandible)
        if self.solve_jaw and (psi[5] <= -np.sin(jaw.max_opening_rad) + 1e-4
                               or max(psi[3], psi[4]) >= jaw.track_length_mm - 1e-3):
            flags.append("jaw_at_limit")
        if valid.any() and np.nanmax(residuals) > self.flag_residual_mm:
            flags.append("large_residual")
        timings["total"] = time.perf_counter() - t_start
        return MuscleFrame(
            activations=controls.activations, cranium=controls.cranium, mandible=controls.mandible,
            jaw_pose=jaw.pose(controls.mandible), nodes=apply_affine(controls.cranium, x),
            skin=apply_affine(controls.cranium, self.model.skin(x)), markers=model_markers,
            marker_residuals=residuals, rms_mm=rms, steps=steps, quasistatic_solves=solves,
            newton_iterations=newton, inverted_tets=int(inverted), constraint_violation=violation,
            flags=tuple(flags), timings={key: round(value, 4) for key, value in timings.items()})
