"""Gap filling, head stabilisation and filtering of a whole take, in the order the pipelines need."""

from __future__ import annotations

import re
import warnings
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import FacecapWarning, InputError, MarkerError
from ..structures import ConditionedTake, MarkerSequence
from .bilateral_filter import bilateral_filter
from .choose_temporal_sigma import choose_temporal_sigma
from .fill_gaps import fill_gaps
from .rigid_fit import RigidTransform
from .consensus_stabilize import consensus_stabilize, estimate_marker_noise
from .stabilize_head import Stabilization, stabilize_head

__all__ = ["condition_take", "moving_stable_markers", "DEFAULT_HEAD_MOTION_SIGMA_S",
           "SKIN_HEAD_POSES", "STILL_HEAD_RATIO", "HEAD_POSE_SOURCES", "STABLE_MARKER_MOTION_MM",
           "savitzky_golay"]

STILL_HEAD_RATIO = 2.0
"""A head counts as still when its motion is under this many times the disagreement of two estimates of it."""

SKIN_HEAD_POSES = ("consensus", "rigid_set")
"""How :func:`auto_stabilize` poses a head without a rigid head band (its ``skin_head_pose``)."""

STILL_HEAD_WITNESS_ROUNDS = 3
"""Rounds of the consensus the stillness test compares the rigid set with: re-estimating its motion prior lets it
leave a wrong start behind (the consensus of releases before 2026-12-04)."""

STILL_HEAD_WITNESS_MOTION_MM = 2.0
"""Scale (mm) of that consensus's motion prior."""

DEFAULT_HEAD_MOTION_SIGMA_S = 0.05
"""Half-width (s) of the smoothing of the stabilising transform over time (see :func:`condition_take`)."""

HEAD_POSE_SOURCES = ("head band", "consensus of the skin markers", "most rigid skin markers", "named markers")
"""Where a stabilised take's head pose came from (:attr:`ConditionedTake.head_pose_from`)."""

STABLE_MARKER_MOTION_MM = 1.0
"""A marker the head pose rests on that moves further than this from its rest place (95th percentile, after
stabilisation) moves with the face, not the skull: :func:`moving_stable_markers` names it."""

_JAW_OR_LIPS = re.compile(r"chin|jaw|lip|mouth|mth", re.IGNORECASE)
"""Label words of markers on the jaw or the lips, as vendors' face marker sets name them."""


def condition_take(
    markers: MarkerSequence,
    *,
    rest_frame: int = 0,
    stabilize: bool | str | Sequence[str] = False,
    smooth: bool = True,
    preferred_stable: Sequence[str] = (),
    head_motion_sigma_s: float = DEFAULT_HEAD_MOTION_SIGMA_S,
    temporal_sigma_s: float | str = "auto",
    skin_head_pose: str = "consensus",
) -> ConditionedTake:
    """Fill gaps, optionally remove head motion, then filter (Bickel 2007, section 3).

    Parameters
    ----------
    markers : MarkerSequence
    rest_frame : int, default 0
        The frame stabilisation aligns every frame to.
    stabilize : bool, 'consensus' or sequence of str, default False
        ``True``: a rigid head band among ``preferred_stable`` when there is
        one, else the consensus of the skin markers, or nothing on a still
        head (:func:`auto_stabilize`); ``'consensus'``: that consensus
        (:func:`consensus_stabilize`) always; labels: use those markers.
    smooth : bool, default True
        Apply the spatio-temporal bilateral filter.
    preferred_stable : sequence of str
        Markers to prefer for automatic stabilisation when they are rigid
        (markers not in the map: head bands and reference markers), see
        :func:`auto_stabilize`.
    head_motion_sigma_s : float, default 0.05
        Half-width (seconds) of the Savitzky-Golay cubic smoothing of the
        per-frame stabilising transform before it is applied. Each frame's
        rigid fit to a handful of noisy stable markers jitters by a few tenths
        of a degree, which moves the whole face; head motion is smoother than
        that, and local cubic fits follow even a fast nod. 0 applies the raw
        per-frame fits.
    temporal_sigma_s : float or 'auto', default 'auto'
        The bilateral filter's temporal sigma, s. ``'auto'`` chooses it for
        this take by cross-validation (:func:`choose_temporal_sigma`: each
        sample predicted from its neighbours in time and space, the
        candidate that predicts best), after stabilisation; 0.02 is the
        fixed value of earlier releases.
    skin_head_pose : {'consensus', 'rigid_set'}, default 'consensus'
        With ``stabilize=True`` and no rigid head band among
        ``preferred_stable``: the head pose from the consensus of the skin
        markers, or from the most rigid set of them (see
        :func:`auto_stabilize`, which checks it).

    Returns
    -------
    ConditionedTake

    Raises
    ------
    MarkerError
        If ``rest_frame`` is outside the take or ``stabilize`` names unknown markers.
    """
    T = markers.n_frames
    if not (0 <= rest_frame < T):
        raise MarkerError(f"--rest-frame {rest_frame} is outside the take (0..{T - 1})", path=markers.source_path)
    index = markers.label_index()
    filled = fill_gaps(markers.positions, rate=markers.rate)
    P = filled.positions
    stab: Stabilization | None = None
    source: str | None = None
    if stabilize is not False and stabilize is not None:
        if isinstance(stabilize, str) and stabilize == "consensus":
            stab = consensus_stabilize(P, rest_frame=rest_frame)
            source = HEAD_POSE_SOURCES[1]
        elif isinstance(stabilize, bool):
            preferred = [index[s] for s in preferred_stable if s in index]
            stab = auto_stabilize(P, rest_frame, preferred, skin_head_pose=skin_head_pose)
            if stab is not None:
                band = set(stab.stable_markers.tolist()) <= set(preferred)
                source = HEAD_POSE_SOURCES[0 if band else (1 if skin_head_pose == "consensus" else 2)]
            if stab is None:
                warnings.warn(
                    f"{markers.source_path or 'take'}: no head motion beyond what the expressions move the "
                    "most rigid markers by; the take is left unstabilised (name the stable markers to force it)",
                    FacecapWarning, stacklevel=2)
        else:
            unknown = [s for s in stabilize if s not in index]
            if unknown:
                raise MarkerError(f"--stabilize names markers not in the take: {unknown}", path=markers.source_path)
            stab = stabilize_head(P, rest_frame=rest_frame, stable_markers=[index[s] for s in stabilize])
            source = HEAD_POSE_SOURCES[3]
        if stab is not None:
            if head_motion_sigma_s > 0:
                stab = _smooth_stabilization(stab, filled.positions, head_motion_sigma_s * markers.rate, rest_frame)
            P = stab.positions
    sigma, choice = None, None
    if smooth:
        if isinstance(temporal_sigma_s, str):
            if temporal_sigma_s != "auto":
                raise MarkerError(f"temporal_sigma_s: expected a number of seconds or 'auto', got {temporal_sigma_s!r}")
            choice = choose_temporal_sigma(P, rate=markers.rate, rest_frame=rest_frame)
            sigma = choice.sigma_s
        else:
            sigma = float(temporal_sigma_s)
        P = bilateral_filter(P, rate=markers.rate, rest_frame=rest_frame, temporal_sigma_s=sigma)
    return ConditionedTake(
        positions=P,
        filled=filled.filled_mask,
        head_rotations=None if stab is None else stab.rotations,
        head_translations=None if stab is None else stab.translations,
        stabilization_residual=None if stab is None else stab.residual_rms,
        stable_labels=() if stab is None else tuple(markers.labels[i] for i in stab.stable_markers),
        temporal_sigma_s=sigma,
        temporal_sigma_choice=choice,
        head_pose_from=source,
    )


def moving_stable_markers(labels: Sequence[str], stable_labels: Sequence[str], positions: np.ndarray, *,
                          rest_frame: int = 0) -> dict[str, str]:
    """The markers a head pose rests on that are likely on the jaw or lips, each with why.

    A head pose taken from markers that move with the face carries their motion into every frame (a jaw
    opening read as a nod). Two signs are checked: the marker moves further than
    :data:`STABLE_MARKER_MOTION_MM` from its rest place in the stabilised take (95th percentile), or its
    label names the chin, jaw, lips or mouth (a still marker there is still in this take, not in the next).

    Parameters
    ----------
    labels : sequence of str, length M
        The take's labels, in the column order of ``positions``.
    stable_labels : sequence of str
        The markers the head pose rests on.
    positions : (T, M, 3) float64 array, mm
        The stabilised take.
    rest_frame : int, default 0

    Returns
    -------
    dict of str to str
        Label -> the reason, e.g. ``'moves 2.1 mm'`` or ``'named as on the jaw or lips'``; empty when none.

    Examples
    --------
    >>> P = np.zeros((10, 3, 3)); P[:, 2, 0] = np.linspace(0, 3, 10)
    >>> moving_stable_markers(["HB0", "Chin_R2", "HB1"], ["HB0", "Chin_R2", "HB1"], P)
    {'Chin_R2': 'named as on the jaw or lips', 'HB1': 'moves 2.8 mm'}
    """
    index = {label: i for i, label in enumerate(labels)}
    out: dict[str, str] = {}
    for label in stable_labels:
        column = positions[:, index[label]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a marker never seen
            motion = float(np.nanpercentile(np.linalg.norm(column - column[rest_frame], axis=1), 95))
        reasons = []
        if _JAW_OR_LIPS.search(label):
            reasons.append("named as on the jaw or lips")
        if np.isfinite(motion) and motion > STABLE_MARKER_MOTION_MM:
            reasons.append(f"moves {motion:.1f} mm")
        if reasons:
            out[label] = ", ".join(reasons)
    return out


def auto_stabilize(P: np.ndarray, rest_frame: int, preferred: Sequence[int], *,
                   skin_head_pose: str = "consensus") -> Stabilization | None:
    """Stabilise on a rigid head band when there is one, else on the rigid motion most skin markers agree on.

    Markers that are in the take but not in the map are usually on a head
    band or the skull; on a face that barely moves in parts of a take, some
    face markers can look just as rigid, and would then carry expression into
    the stabilisation. So when at least three preferred markers exist and they
    fit rigidly about as well as the most rigid set of markers
    (:func:`stabilize_head`'s automatic choice; median residual within 1.5x +
    0.1 mm), they are used.

    Without a usable band, the head pose of each frame is the rigid motion
    most skin markers agree on (:func:`consensus_stabilize`, started from the
    most rigid set), unless the head does not visibly move: every skin marker
    moves with some expression, so any estimate from them turns with the
    expressions even on a still head (on a generated take with the head still,
    0.5 degrees at the 95th percentile), and stabilising such a take only adds
    that error (animate 0.43 against 0.37 mm). The test: the most rigid set's
    rotation against a consensus that re-estimates its motion prior
    (:data:`STILL_HEAD_WITNESS_ROUNDS`, :data:`STILL_HEAD_WITNESS_MOTION_MM`):
    two estimates that both carry expression, differently. Where the head
    moves they agree to a fraction of its motion (their disagreement is at
    most a quarter of the motion on the seven tuned takes that move, 3.4-5.7
    degrees); where it stays still the motion found is no larger than their
    disagreement (0.50 against 0.43 degrees). Below :data:`STILL_HEAD_RATIO`
    times the disagreement, None is returned.

    The consensus rather than the most rigid set (the choice before
    2026-12-04): a set of 4-8 skin markers chosen for keeping their distances
    can hold one that an expression moves, and then carries it into every
    frame (on a tuned take turning 8 degrees about the neck, a member moving
    2.7 mm made the set 0.43 degrees off at the median; the consensus 0.12).
    On the five tuned takes without a head band animate's mean error moved
    from 0.697 to 0.391 mm (the neck-turn take), 0.352 to 0.305, 0.438 to 0.384
    and 0.392 to 0.441 mm (a 60-marker sway, where for stretches most markers
    move at once and the consensus follows them: worst 5 % of frames 0.95
    degrees against the set's 0.46); ``benchmarks/RESULTS.md``.

    ``skin_head_pose='rigid_set'`` keeps the most rigid set instead (what
    plans written before 2026-12-04 replay).
    """
    if skin_head_pose not in SKIN_HEAD_POSES:
        raise MarkerError(f"skin_head_pose: expected one of {SKIN_HEAD_POSES}, got {skin_head_pose!r}")
    auto = stabilize_head(P, rest_frame=rest_frame)
    usable = [i for i in preferred if not np.isnan(P[rest_frame, i]).any()]
    if len(usable) >= 3:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FacecapWarning)
            band = stabilize_head(P, rest_frame=rest_frame, stable_markers=usable)
        if np.nanmedian(band.residual_rms) <= 1.5 * np.nanmedian(auto.residual_rms) + 0.1:
            return band
    # The stillness test weighs two estimates that err differently; the consensus that stabilises trusts the
    # start's stillest markers, which makes it closer to the start and so a weaker witness (on a noise-free
    # take with a still head the rigid set turned 2.7 degrees and it followed to 2.1)
    # The test reads the 95th percentiles of two rotations, and 600 evenly spaced frames give them as every
    # frame does (on the 18 tuned takes at 3,000 frames and the AnimFace take: the same decisions, each
    # percentile within 0.1 degrees), while the witness's three rounds cost 10 s on a 10,000-frame take of
    # 90 markers (0.6 s on 600)
    frames = _test_frames(P.shape[0], rest_frame)
    start = Stabilization(auto.positions[frames], auto.rotations[frames], auto.translations[frames],
                          auto.stable_markers, auto.residual_rms[frames])
    witness = consensus_stabilize(P[frames], rest_frame=int(np.searchsorted(frames, rest_frame)), start=start,
                                  rounds=STILL_HEAD_WITNESS_ROUNDS, motion_scale_mm=STILL_HEAD_WITNESS_MOTION_MM,
                                  noise_mm=estimate_marker_noise(P))  # the noise of consecutive frames
    if _head_is_still(start, witness):
        return None
    if skin_head_pose == "rigid_set":
        return auto
    return consensus_stabilize(P, rest_frame=rest_frame, start=auto)


STILL_HEAD_TEST_FRAMES = 600
"""Most frames (evenly spaced, the rest frame among them) the still-head test reads."""


def _test_frames(n_frames: int, rest_frame: int) -> np.ndarray:
    """Evenly spaced frames of a take for the still-head test, at most :data:`STILL_HEAD_TEST_FRAMES`, with the rest frame."""
    if n_frames <= STILL_HEAD_TEST_FRAMES:
        return np.arange(n_frames)
    spaced = np.linspace(0, n_frames - 1, STILL_HEAD_TEST_FRAMES - 1).round().astype(np.int64)
    return np.unique(np.append(spaced, rest_frame))


def _head_is_still(rigid_set: Stabilization, consensus: Stabilization) -> bool:
    """True when the motion ``rigid_set`` found is within :data:`STILL_HEAD_RATIO` of its disagreement with ``consensus``."""
    ok = np.all(np.isfinite(rigid_set.rotations), axis=(1, 2)) & np.all(np.isfinite(consensus.rotations), axis=(1, 2))
    if ok.sum() < 2:
        return False
    R, C = rigid_set.rotations[ok], consensus.rotations[ok]
    motion = np.percentile(Rotation.from_matrix(R).magnitude(), 95)
    disagreement = np.percentile(Rotation.from_matrix(R @ np.swapaxes(C, 1, 2)).magnitude(), 95)
    return bool(motion < STILL_HEAD_RATIO * disagreement)


def savitzky_golay(values: np.ndarray, window: int, order: int) -> np.ndarray:
    """Savitzky-Golay smoothing along axis 0: each sample's least-squares polynomial over ``window`` samples.

    ``scipy.signal.savgol_filter(values, window, order, axis=0, mode='interp')`` computes the
    same (the tests compare them); written here because importing ``scipy.signal`` takes about
    a second, on the path before a long run's set-up. The first and last ``window // 2``
    samples take the polynomial fitted to the first and last full window.

    Parameters
    ----------
    values : (n, ...) float64 array
    window : int
        Odd, ``order < window <= n``.
    order : int
        Degree of the local polynomials.
    """
    values = np.asarray(values, dtype=np.float64)
    n, half = len(values), window // 2
    if window % 2 == 0 or not order < window <= n:
        raise InputError(f"window {window}: expected an odd length above the order {order} and at most {n}")
    positions = np.arange(-half, half + 1, dtype=np.float64)
    vandermonde = positions[:, None] ** np.arange(order + 1)
    hat = vandermonde @ np.linalg.pinv(vandermonde)  # fitted values of a window from its samples
    flat = values.reshape(n, -1)
    smoothed = np.empty_like(flat)
    windows = np.lib.stride_tricks.sliding_window_view(flat, window, axis=0)  # (n - window + 1, m, window)
    smoothed[half:n - half] = windows @ hat[half]
    smoothed[:half] = hat[:half] @ flat[:window]
    smoothed[n - half:] = hat[half + 1:] @ flat[n - window:]
    return smoothed.reshape(values.shape)


def _smooth_stabilization(stab: Stabilization, positions: np.ndarray, sigma_frames: float,
                          rest_frame: int) -> Stabilization:
    """Low-pass the stabilising rigid transforms over time and re-apply them to ``positions``.

    The residual is recomputed against the rest frame's stable markers, which
    every frame is aligned to.
    """
    R, t = stab.rotations, stab.translations
    ok = np.all(np.isfinite(R), axis=(1, 2)) & np.all(np.isfinite(t), axis=1)
    if ok.sum() < 3:
        return stab
    frames = np.arange(len(R))
    idx = np.flatnonzero(ok)
    # rotation vectors relative to the mean rotation stay small and continuous
    mean = Rotation.from_matrix(R[ok]).mean()
    rv = (mean.inv() * Rotation.from_matrix(R[ok])).as_rotvec()
    rv = np.stack([np.interp(frames, idx, rv[:, k]) for k in range(3)], axis=1)
    tt = np.stack([np.interp(frames, idx, t[ok, k]) for k in range(3)], axis=1)
    # Savitzky-Golay (local cubic fits) rather than a Gaussian: it removes the
    # fit noise but follows a fast nod without flattening its peaks
    window = max(5, int(round(2 * sigma_frames)) * 2 + 1)
    if window >= len(R):
        return stab
    rv = savitzky_golay(rv, window, 3)
    tt = savitzky_golay(tt, window, 3)
    R_s = (mean * Rotation.from_rotvec(rv)).as_matrix()
    moved = RigidTransform(R_s, tt, np.full(len(R_s), np.nan)).apply(positions)
    stable = stab.stable_markers
    target = stab.positions[rest_frame, stable]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # frames with stable markers in gaps
        residual = np.sqrt(np.nanmean(np.sum((moved[:, stable] - target) ** 2, axis=2), axis=1))
    return stab._replace(positions=moved, rotations=R_s, translations=tt, residual_rms=residual)
