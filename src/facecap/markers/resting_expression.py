"""How far a take's rest frame is from the scan's expression, and whether that is an expression or the map."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError, MarkerError
from ..typing import BoolArray, FloatArray
from ..validate import as_marker_positions, as_points, as_positive
from .rigid_fit import RigidTransform, rigid_fit

__all__ = ["RestingExpression", "measure_resting_expression", "robust_rigid_fit", "MIN_COHERENCE",
           "NEIGHBOUR_SCALE_MM", "ABOVE_NOISE", "MISPLACED_MM", "MAX_SCALE_ERROR", "MAX_RESTING_MM",
           "MOTION_Z_SCORE", "PLACEMENT_LIMIT_MM", "PLACEMENT_LIMIT_PER_NOISE", "MIN_RESTING_MM"]

NEIGHBOUR_SCALE_MM = 20.0
"""Gaussian scale (mm) of the neighbourhood that predicts a marker's mismatch from its neighbours'."""

MIN_COHERENCE = 0.25
"""Share of the mismatch its neighbours predict above which it is an expression (the first cue). On the tuned takes:
a resting expression with an exact map 0.37 and 0.17 (-0.69 on a 45-marker layout, whose neighbours are far: the
motion cue catches those); hand-picked maps -0.07 to 0.32; no expression -0.30 to -0.03 (noise)."""

ABOVE_NOISE = 2.5
"""How many times the rest markers' noise (RMS, 3-D) the mismatch must reach to count at all. On the tuned takes
(rest frame 0, so the rest average is one-sided) without a resting expression it was 0.9-1.2 times, with one and an
exact map 3.9-4.8, with a hand-picked map 13-17."""

MIN_RESTING_MM = 0.15
"""And at least this RMS (mm, less calibration): a smaller mismatch is no expression worth keeping, however clean the
take (a synthetic take of 0.02 mm noise with markers on the skin read with a 1.5 mm offset left 0.04 mm)."""

MOTION_Z_SCORE = 10.0
"""How many standard deviations above what each marker's own error and noise would put there the mismatch along
the take's own motion must reach to be an expression the take shows (the second cue, for expressions too local
for neighbours to share: a blink, pressed lips)."""

PLACEMENT_LIMIT_MM = 0.5
"""Largest RMS per coordinate of the markers' own parts (``placement_sd_mm``) under which the mismatch is kept as
an expression (or :data:`PLACEMENT_LIMIT_PER_NOISE` noise deviations, whichever is larger). Beyond it the map is off marker by marker (picked by hand) and keeping the mismatch keeps its
errors too: on tuned takes with a resting expression and a map 0.8-1.0 mm off, the own parts were 0.76-1.02 mm
and keeping cost 0.31-0.73 mm of dense error against absorbing; with exact maps they were 0.19 and 0.36 mm and
keeping saved 0.10-0.13 mm (``benchmarks/RESULTS.md``). Added after the first held-out run, where a take with
both (a map 0.8 mm off) was kept and lost 0.19 mm."""

PLACEMENT_LIMIT_PER_NOISE = 2.0
"""The same limit in noise deviations: sparse, noisy layouts leave larger own parts with an exact map (45 markers,
0.3 mm noise: 0.53 mm, keeping saved 0.05 mm; with a map 0.8 mm off: 0.86 mm, keeping cost 0.19 mm). Added after
the second held-out run, where a 60-marker take with 0.3 mm noise and an exact map was absorbed."""

MAX_MOTION_FRAMES = 2000
"""Frames of the take (evenly spaced) that give its motion directions."""

MISPLACED_MM = 2.5
"""A marker whose own part of the mismatch (what its neighbours do not share) exceeds this, and four times that
part's RMS, is taken as misplaced in the map: the warp absorbs it even where the rest is kept as an expression."""

MAX_SCALE_ERROR = 0.03
"""A take larger or smaller than the scan by more than this share is not of this actor on this scan (another
actor's markers, a unit slip): its mismatch is no resting expression. The same actor's mocap and scan agree to
a percent or so."""

MAX_RESTING_MM = 3.0
"""RMS mismatch (mm, less calibration) beyond which the rest frame is no resting expression of this face: a
resting face moves the skin by tenths of a millimetre to a millimetre or two; the bundled take of another actor
on the bundled face is 8 mm off."""

ROBUST_SCALE_PER_SPREAD = 2.5
"""Starting Welsch scale of :func:`robust_rigid_fit`, in median residuals."""

ANNEALING = 0.7
"""Factor the scale of :func:`robust_rigid_fit` shrinks by each round."""

MIN_CARRIERS = 0.2
"""Share of the points (weight above 0.1) that must still carry :func:`robust_rigid_fit` at a scale."""

FIT_SCALE_PER_NOISE = 1.5
"""The narrowest scale of the rest frame's rigid fit, in noise deviations (at least 0.1 mm)."""


class RestingExpression(NamedTuple):
    """The rest frame's markers against their places on the scan, by :func:`measure_resting_expression`.

    Attributes
    ----------
    alignment : RigidTransform
        The robust rigid motion from the take's (stabilised) frame to the scan's: ``rotation`` (3, 3),
        ``translation`` (3,) mm.
    residual : (K, 3) float64 array, mm
        ``alignment(rest) - targets``: how far each rest marker remains from its place on the scan.
    calibration : (K, 3) float64 array, mm
        The part of ``residual`` a wrong marker offset (all markers further from the skin, along its
        normals), a scale between the mocap system and the scanner, and a last rigid correction explain
        (a weighted least-squares fit); never an expression, always absorbed by the warp.
    offset_error_mm : float
        How much further from the skin the markers sit than ``targets`` say, mm (0 without normals).
    scale_error : float
        The mocap's size against the scan's, less 1 (``0.002``: the take 0.2 % larger).
    expression : (K, 3) float64 array, mm
        The part of each marker's residual (less ``calibration``) its neighbours share (their
        Gaussian-weighted mean, the marker itself left out): what an expression, which moves neighbouring
        skin together, explains.
    placement : (K, 3) float64 array, mm
        ``residual - calibration - expression``: the marker's own part, which a misplaced map entry (the map's place against
        the marker's real place), sharp detail of an expression and noise make.
    weights : (K,) float64 array
        Weights of the markers in the robust fit (1: carried it; near 0: moved or misplaced).
    noise_mm : float
        The markers' noise per coordinate, mm.
    placement_sd_mm : float
        RMS per coordinate of ``placement``, mm.
    coherence : float
        The share of the mismatch the neighbours predict, ``1 - |placement|^2 / |residual|^2`` (1: a smooth
        field; 0 or below: independent per marker).
    rest_noise_mm : float
        The rest markers' noise per coordinate, mm (``noise_mm`` over the square root of the samples averaged).
    above_noise : float
        The mismatch (less ``calibration``, RMS over the markers) over the rest markers' 3-D noise.
    is_significant : bool
        The mismatch (less ``calibration``, RMS over the markers) exceeds :data:`ABOVE_NOISE` times the rest
        markers' noise (3-D RMS, ``sqrt(3) rest_noise_mm``) and :data:`MIN_RESTING_MM`.
    fits_scan : bool
        The take looks like this actor on this scan: its scale within :data:`MAX_SCALE_ERROR` and the mismatch
        (less calibration) within :data:`MAX_RESTING_MM`.
    motion_z : float
        How far the mismatch along the directions the take's markers move in exceeds what the markers' own
        errors would put there, in standard deviations (0 without the take's motion).
    is_expression : bool
        ``fits_scan``, significant, ``placement_sd_mm`` within :data:`PLACEMENT_LIMIT_MM` (or
        :data:`PLACEMENT_LIMIT_PER_NOISE` noise deviations), and either cue: ``coherence`` at least :data:`MIN_COHERENCE` (neighbours
        share it) or ``motion_z`` above :data:`MOTION_Z_SCORE` (the take's own motion shows it). A map picked
        by hand, off by a millimetre per marker, is significant but shows neither; another actor's markers are
        coherent but do not fit the scan.
    misplaced : (K,) bool array
        Markers whose own part exceeds :data:`MISPLACED_MM` and four ``placement`` RMS.
    """

    alignment: RigidTransform
    residual: FloatArray
    calibration: FloatArray
    offset_error_mm: float
    scale_error: float
    expression: FloatArray
    placement: FloatArray
    weights: FloatArray
    noise_mm: float
    placement_sd_mm: float
    coherence: float
    rest_noise_mm: float
    above_noise: float
    is_significant: bool
    fits_scan: bool
    motion_z: float
    is_expression: bool
    misplaced: BoolArray

    @property
    def mismatch_mm(self) -> FloatArray:
        """(K,) distance of each rest marker from its place on the scan after the alignment, mm."""
        return np.linalg.norm(self.residual, axis=1)

    def kept_targets(self, targets: FloatArray) -> FloatArray:
        """Where the warp should put the rest markers to keep their mismatch as motion, (K, 3) mm.

        The rest markers moved by the rigid :attr:`alignment`, less the :attr:`calibration` part
        (``targets + residual - calibration``): the warp then absorbs nothing of the rest frame's expression,
        only a wrong marker offset and a scale. A :attr:`misplaced` marker gets ``targets + expression``
        instead: its own error is absorbed, its neighbours' share kept.
        """
        c = as_points(targets, name="targets", allow_nan=True)
        kept = c + np.nan_to_num(self.residual - self.calibration)
        kept[self.misplaced] = c[self.misplaced] + np.nan_to_num(self.expression[self.misplaced])
        return kept


def robust_rigid_fit(source: FloatArray, target: FloatArray, *, prior: FloatArray | None = None,
                     floor_mm: float = 0.1, iterations: int = 5) -> tuple[RigidTransform, FloatArray]:
    """Rigid motion of ``source`` onto ``target`` carried by the points that agree with it to ``floor_mm``.

    Iteratively reweighted Kabsch fits with Welsch weights ``exp(-(r / s)^2)``, starting from the plain
    least-squares fit with ``s`` = :data:`ROBUST_SCALE_PER_SPREAD` median residuals and shrinking ``s``
    by :data:`ANNEALING` a round down to ``floor_mm`` (graduated: a wide scale first finds the bulk, a narrow
    one then keeps the points that fit within noise). Where an expression moves a region of markers, the
    rest (forehead, nose bridge, temples) carry the fit; the scale stops shrinking while fewer than
    :data:`MIN_CARRIERS` of the points (at least 6) would still carry it.

    Parameters
    ----------
    source, target : (K, 3) float64 arrays, mm
        Matching points; rows with NaN are ignored.
    prior : (K,) float64 array, optional
        Non-negative weight of each point before any residual is seen; multiplies the robust weights.
        Default: all 1.
    floor_mm : float, default 0.1
        The narrowest scale, mm: about the points' noise (1.5 noise deviations in
        :func:`measure_resting_expression`).
    iterations : int, default 5
        Reweighting steps per scale.

    Returns
    -------
    fit : RigidTransform
    weights : (K,) float64 array
        The final weights (0 for ignored rows).

    Notes
    -----
    On eight generated takes with a resting expression (0.45 mm over the face, 0.2 mm noise), the rest
    markers' residual after the fit was 0.13-0.27 mm from the truth's with the scale shrunk to 1.5 noise
    deviations, against 0.13-0.50 with the scale held at 2.5 median residuals and 0.16-0.93 for plain least
    squares (``benchmarks/RESULTS.md``).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> X = rng.normal(size=(30, 3)) * 40
    >>> Y = X + [5.0, 0.0, 0.0]
    >>> Y[:3] += 4.0  # three points moved
    >>> fit, w = robust_rigid_fit(X, Y)
    >>> bool(np.allclose(fit.translation, [5, 0, 0], atol=1e-6)), bool(w[:3].max() < 1e-3)
    (True, True)
    """
    X = as_points(source, name="source", allow_nan=True)
    Y = as_points(target, name="target", allow_nan=True)
    if X.shape != Y.shape:
        raise InputError(f"source and target: expected the same shape, got {X.shape} and {Y.shape}")
    seen = np.isfinite(X).all(axis=1) & np.isfinite(Y).all(axis=1)
    if seen.sum() < 3:
        raise MarkerError(f"robust_rigid_fit: expected at least 3 points seen in both sets, got {int(seen.sum())}")
    p = np.ones(X.shape[0]) if prior is None else np.asarray(prior, dtype=np.float64)
    if p.shape != (X.shape[0],) or not np.all(np.isfinite(p)) or p.min() < 0 or p.max() <= 0:
        raise InputError(f"prior: expected {X.shape[0]} non-negative weights, not all 0")
    floor_mm = as_positive(floor_mm, name="floor_mm")
    weights = np.where(seen, p, 0.0)
    fit = rigid_fit(X, Y, weights=weights)
    r = np.linalg.norm(fit.apply(X) - Y, axis=1)
    scale = max(ROBUST_SCALE_PER_SPREAD * float(np.median(r[seen])), floor_mm) / ANNEALING
    carriers = max(6, int(np.ceil(MIN_CARRIERS * seen.sum())))
    while scale > floor_mm:
        scale = max(scale * ANNEALING, floor_mm)
        trial_fit, trial_weights = fit, weights
        for _ in range(iterations):
            r = np.linalg.norm(trial_fit.apply(X) - Y, axis=1)
            trial_weights = np.where(seen, p * np.exp(-(np.nan_to_num(r, nan=np.inf) / scale) ** 2), 0.0)
            if np.count_nonzero(trial_weights > 0.1 * p.max()) < carriers:
                break
            trial_fit = rigid_fit(X, Y, weights=trial_weights)
        else:
            fit, weights = trial_fit, trial_weights
            continue
        break  # too few points left at this scale: keep the last one that had enough
    return fit, weights


def measure_resting_expression(
    rest_markers: FloatArray,
    targets: FloatArray,
    *,
    noise_mm: float,
    rest_samples: float = 1.0,
    normals: FloatArray | None = None,
    motion: FloatArray | None = None,
) -> RestingExpression:
    """Fit a take's rest frame to the scan rigidly and tell whether what remains is an expression.

    A take's rest frame is supposed to show the scan's expression, and the warp of Bickel et al. (2007,
    section 4.1) maps its markers exactly onto the scan; where the actor rests with an expression of their
    own (a slight smile, lowered brows), that expression is taken out of every frame. One marker cannot
    tell an expression from a misplaced map entry, but its neighbours can: an expression moves neighbouring
    skin together, so each marker's mismatch is largely predicted by its neighbours'; errors of a map picked
    by hand are one independent offset per marker, which the neighbours do not predict.

    Parameters
    ----------
    rest_markers : (K, 3) float64 array, mm
        The rest frame's markers (averaged over a few frames), in the take's stabilised frame.
    targets : (K, 3) float64 array, mm
        Where the map puts them on the scan (the marker centres, lifted off the skin), scan frame.
    noise_mm : float
        The markers' noise standard deviation per coordinate
        (:func:`~facecap.markers.estimate_marker_noise` of the raw take).
    rest_samples : float, default 1.0
        How many frames' worth of samples the rest markers average (their noise is ``noise_mm`` over its
        square root): the effective count of the rest average's weights.
    normals : (K, 3) float64 array, optional
        The scan's unit normals at the targets: lets a wrong marker offset (every marker further from the
        skin than assumed) be told from an expression. Without them it is not looked for.
    motion : (T, K, 3) float64 array, optional
        The conditioned take in the rest markers' frame: the directions its markers move in give the second
        cue (:attr:`RestingExpression.motion_z`). Without it only the neighbours are asked.

    Returns
    -------
    RestingExpression

    Raises
    ------
    MarkerError
        If fewer than 4 markers are seen at rest.
    InputError
        If the shapes disagree.

    Notes
    -----
    ``R, t`` is :func:`robust_rigid_fit` narrowed down to :data:`FIT_SCALE_PER_NOISE` noise deviations, so
    that the markers the expression left in place carry it; ``r_i = R m_i + t - c_i`` the residual. The
    ``calibration`` part ``delta n_i + s p_i + w x p_i + tau`` (``p_i`` the target about the fit's weighted
    centroid) is fitted to it by weighted least squares with the fit's weights and taken out: a marker
    offset wrong by ``delta`` moves every marker along the skin's normal, a scale moves them all from the
    centre, and such shared shifts would otherwise look like an expression. With
    Gaussian weights ``w_ij`` of the distance between ``c_i`` and ``c_j`` (scale :data:`NEIGHBOUR_SCALE_MM`,
    ``w_ii = 0``, rows summing to 1), the neighbours' prediction is ``e_i = sum_j w_ij r_j`` (the
    ``expression``) and ``u_i = r_i - e_i`` the marker's own part; ``coherence = 1 - sum |u|^2 / sum |r|^2``.

    The second cue: the take's motion ``d(t) = R (m(t) - m)`` about its mean gives orthonormal directions
    ``u_k`` with variances ``lambda_k``. An expression held at rest is modelled along them with prior
    variances ``(lambda_k - sigma^2)_+``, the markers' own errors as independent, ``sigma_p^2`` per coordinate;
    the Wiener gains are ``g_k = (lambda_k - sigma^2)_+ / ((lambda_k - sigma^2)_+ + sigma_p^2)``, with
    ``sigma_p^2`` the mean square of ``r - sum_k g_k (u_k . r) u_k`` over its ``3K - 6 - sum g_k`` degrees of
    freedom (floored at the raw noise: the rest average's smaller noise let takes without an expression
    score 11-34), iterated. Without an expression ``S = sum_k g_k (u_k . r)^2 / sigma_p^2``
    has mean ``sum g_k`` and variance ``2 sum g_k^2``: ``motion_z`` is how many deviations ``S`` lies above.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> c = rng.normal(size=(60, 3)) * [40.0, 50.0, 15.0]
    >>> smile = np.exp(-np.sum((c - c[0]) ** 2, axis=1) / 800.0)[:, None] * [1.5, 1.0, 0.5]
    >>> m = measure_resting_expression(c + smile + rng.normal(scale=0.05, size=c.shape), c, noise_mm=0.05)
    >>> m.is_expression, bool(m.coherence > 0.5)
    (True, True)
    >>> m = measure_resting_expression(c + rng.normal(scale=1.0, size=c.shape), c, noise_mm=0.05)
    >>> m.is_significant, m.is_expression  # a map 1 mm off: above the noise, but not an expression
    (True, False)
    """
    m = as_points(rest_markers, name="rest_markers", allow_nan=True)
    c = as_points(targets, name="targets", allow_nan=True)
    if c.shape != m.shape:
        raise InputError(f"rest_markers {m.shape} and targets {c.shape}: expected the same (K, 3) shape")
    noise = float(noise_mm) if np.isfinite(noise_mm) else 0.0
    noise = as_positive(noise, name="noise_mm", allow_zero=True)
    rest_noise = noise / np.sqrt(max(as_positive(rest_samples, name="rest_samples"), 1.0))
    if motion is not None:
        motion = as_marker_positions(motion, name="motion")
        if motion.shape[1:] != m.shape:
            raise InputError(f"motion {motion.shape}: expected (T, {m.shape[0]}, 3) like the rest markers")
    seen = np.isfinite(m).all(axis=1) & np.isfinite(c).all(axis=1)
    if seen.sum() < 4:
        raise MarkerError(f"fewer than 4 markers seen at rest ({int(seen.sum())})")
    K = m.shape[0]
    mk, ck = m[seen], c[seen]
    fit, weights = robust_rigid_fit(mk, ck, floor_mm=max(FIT_SCALE_PER_NOISE * noise, 0.1))
    r = fit.apply(mk) - ck
    n = None if normals is None else as_points(normals, name="normals", allow_nan=True)
    if n is not None and n.shape != m.shape:
        raise InputError(f"normals {n.shape}: expected {m.shape} like the targets")
    calibration, offset_error, scale_error = _calibration(r, ck, None if n is None else n[seen], weights)
    r_free = r - calibration
    d2 = np.sum((ck[:, None] - ck[None]) ** 2, axis=2)
    W = np.exp(-d2 / (2.0 * NEIGHBOUR_SCALE_MM**2))
    np.fill_diagonal(W, 0.0)
    W /= np.maximum(W.sum(axis=1, keepdims=True), 1e-300)
    expression = W @ r_free
    own = r_free - expression
    total = float(np.sum(r_free**2))
    coherence = 1.0 - float(np.sum(own**2)) / total if total > 0 else 0.0
    motion_z = 0.0 if motion is None else _motion_z(r_free, motion[:, seen], mk, fit.rotation, noise)
    free_rms = float(np.sqrt(np.mean(np.sum(r_free**2, axis=1))))
    above_noise = free_rms / (np.sqrt(3.0) * max(rest_noise, 1e-6))
    significant = bool(above_noise > ABOVE_NOISE and free_rms > MIN_RESTING_MM)
    own_rms = float(np.sqrt(np.mean(np.sum(own**2, axis=1))))
    fits = abs(scale_error) <= MAX_SCALE_ERROR and free_rms <= MAX_RESTING_MM
    far = np.linalg.norm(own, axis=1) > max(MISPLACED_MM, 4.0 * own_rms)

    def full(rows: FloatArray) -> FloatArray:
        out = np.full((K, 3), np.nan)
        out[seen] = rows
        return out

    misplaced = np.zeros(K, dtype=bool)
    misplaced[seen] = far
    all_weights = np.zeros(K)
    all_weights[seen] = weights
    return RestingExpression(
        alignment=fit,
        residual=full(r),
        calibration=full(calibration),
        offset_error_mm=offset_error,
        scale_error=scale_error,
        expression=full(expression),
        placement=full(own),
        weights=all_weights,
        noise_mm=noise,
        placement_sd_mm=float(own_rms / np.sqrt(3.0)),
        coherence=coherence,
        rest_noise_mm=float(rest_noise),
        above_noise=float(above_noise),
        is_significant=significant,
        fits_scan=bool(fits),
        motion_z=float(motion_z),
        is_expression=bool(significant and fits
                           and own_rms / np.sqrt(3.0) <= max(PLACEMENT_LIMIT_MM, PLACEMENT_LIMIT_PER_NOISE * noise)
                           and (coherence >= MIN_COHERENCE or motion_z > MOTION_Z_SCORE)),
        misplaced=misplaced,
    )


def _calibration(r: FloatArray, c: FloatArray, normals: FloatArray | None,
                 weights: FloatArray) -> tuple[FloatArray, float, float]:
    """The shared shifts of ``r`` (K, 3): ``delta n + s p + w x p + tau``, weighted least squares; and delta, s."""
    w = np.maximum(weights, 0.0)
    centre = (w @ c) / max(float(w.sum()), 1e-300)
    p = c - centre
    K = c.shape[0]
    columns = [np.zeros((K, 3, 1)) for _ in range(7)]
    for axis in range(3):
        columns[axis][:, :, 0] = np.cross(np.eye(3)[axis], p)  # small rotation about the axis: e_a x p
        columns[3 + axis][:, axis, 0] = 1.0
    columns[6][:, :, 0] = p  # scale about the centre
    if normals is not None:
        columns.append(np.nan_to_num(normals)[:, :, None])
    A = np.concatenate(columns, axis=2)  # (K, 3, unknowns)
    sw = np.sqrt(np.repeat(w, 3))
    x, *_ = np.linalg.lstsq(A.reshape(3 * K, -1) * sw[:, None], r.ravel() * sw, rcond=None)
    part = (A @ x).reshape(K, 3)
    return part, float(x[7]) if normals is not None else 0.0, float(x[6])


def _motion_z(r: FloatArray, motion: FloatArray, rest: FloatArray, rotation: FloatArray, noise: float) -> float:
    """How far ``r`` (K, 3) lies along the take's motion directions beyond its own errors (see the Notes above)."""
    T = motion.shape[0]
    frames = np.unique(np.linspace(0, T - 1, min(T, MAX_MOTION_FRAMES)).round().astype(np.int64))
    D = ((motion[frames] - rest[None]) @ rotation.T).reshape(len(frames), -1)
    D = D[np.isfinite(D).all(axis=1)]
    if D.shape[0] < 2:
        return 0.0
    # about the take's mean, not the rest frame: the rest sample's own noise, common to every frame's
    # displacement from it, would otherwise be a direction of the motion and explain itself
    D = D - D.mean(axis=0)
    _, singular, U = np.linalg.svd(D / np.sqrt(D.shape[0]), full_matrices=False)
    signal = np.maximum(singular**2 - noise**2, 0.0)
    x = r.ravel()
    coefficients = U @ x
    floor = max(noise, 1e-3) ** 2
    sigma_p2 = max(float(np.mean(x**2)), floor)
    for _ in range(50):  # sigma_p and the gains depend on each other: a fixed point
        gains = signal / (signal + sigma_p2)
        e = (gains * coefficients) @ U
        updated = max(float(np.sum((x - e) ** 2)) / max(x.size - 6 - float(gains.sum()), 1.0), floor)
        if abs(updated - sigma_p2) <= 1e-6 * sigma_p2:
            break
        sigma_p2 = updated
    statistic = float(np.sum(gains * coefficients**2) / sigma_p2)
    spread = float(np.sqrt(2.0 * np.sum(gains**2)))
    return (statistic - float(gains.sum())) / spread if spread > 0 else 0.0
