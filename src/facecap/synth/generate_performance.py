"""Synthetic facial performances with dense ground truth, for tests, benchmarks and the demo."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import igl
import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InputError
from ..mesh.vertex_normals import vertex_normals
from ..structures import MarkerSequence, Mesh
from ..typing import FloatArray, IntArray
from ..validate import as_count, as_positive, as_rigid_transform
from .expression_curves import smooth_expression_curves
from .smoothstep import smoothstep
from ..io.ict_sample import IctSample, load_ict_sample
from .marker_layout import animface_marker_map, choose_marker_vertices
from .real_motion_curves import REAL_CURVE_NAMES, real_motion_curves
from .rest_expression import as_rest_weights
from .rotational_jaw import ICT_JAW_SCREW, JAW_MODES, JAW_SHAPE, rotational_jaw_correction
from .speech_curves import speech_expression_curves

__all__ = ["CURVE_GENERATORS", "HEAD_PIVOTS_MM", "SyntheticCase", "generate_performance", "named_curves",
           "random_identity", "RANDOM_IDENTITY_SD"]

DEFAULT_FRAMES = 240
DEFAULT_MARKERS = 90
HEADBAND_OFFSET_MM = 15.0
"""Height of the head-band markers above the skin."""
MAX_HEADBAND_MARKERS = 16
HEAD_PIVOTS_MM: dict[str, tuple[float, float, float]] = {
    "upper_neck": (0.0, -30.0, -110.0),
    "neck": (0.0, -90.0, -80.0),
}
"""Head pivot relative to the chin (ICT landmark 8), mm: the upper neck (near C1-C2, the default)
or the lower cervical spine (near C6-C7), about which a talking actor's whole head and neck sway."""
TURN_DURATION_S = (0.3, 0.8)
"""Duration of one head turn or nod of ``head_motion='turns'``, s."""
HEAD_MOTIONS = ("sway", "turns")


@dataclass(frozen=True, eq=False)
class SyntheticCase:
    """A generated capture with everything that made it.

    Attributes
    ----------
    scan : Mesh
        The actor's neutral face: the mesh to animate (mm, ICT topology).
    markers : MarkerSequence
        The take, in the mocap system's frame (mm): first the face markers
        (``M000``, ``M001``, ... or the layout's own labels), then the
        head-band markers ``HB0``, ``HB1``, ... (rigid with the head, not in
        the map). NaN where occluded.
    correspondence : dict of str to int or list of 3 floats
        Face marker label -> scan vertex (what a user picks by hand); with
        ``map_error_mm`` > 0, label -> the point on the scan (mm) the user
        picked, off the marker's true place along the skin.
    truth_vertices : (T, n, 3) float32 array, mm
        The dense expression in the scan's frame, without head motion:
        ``scan + weights[t] @ expression_deltas``, plus
        :func:`~facecap.synth.rotational_jaw_correction` when ``jaw`` is 'rotational'.
        Displacements from the scan: with a ``rest_expression`` frame 0 is not the scan.
    head_pose : (T, 4, 4) float64 array
        Rigid head motion in scan coordinates (mm): the face at frame t is
        ``head_pose[t]`` applied to ``truth_vertices[t]``. ``head_pose[0]`` is
        the identity.
    mocap_from_scan : (4, 4) float64 array
        Fixed rigid transform from the scan's frame to the mocap system's.
    weights : (T, k) float64 array
        The blendshape weights that drove the expression (k = 53), the
        resting expression included.
    marker_vertices : (M,) int64 array
        Scan vertex under each face marker, in the order of the first M labels
        (the true place, whatever ``correspondence`` says).
    noiseless_markers : (T, M + H, 3) float64 array, mm
        The markers before noise and gaps, same columns as ``markers``.
    headband_points : (H, 3) float64 array, mm
        The head-band markers in the scan's frame (they move with ``head_pose`` only).
    jaw : {'linear', 'rotational'}
        How ``jawOpen`` was blended (:func:`generate_performance`).
    rest_weights : (k,) float64 array or None
        The resting expression held under the whole take (None: neutral,
        frame 0 is the scan).
    """

    scan: Mesh
    markers: MarkerSequence
    correspondence: dict[str, int]
    truth_vertices: np.ndarray
    head_pose: FloatArray
    mocap_from_scan: FloatArray
    weights: FloatArray
    marker_vertices: IntArray
    noiseless_markers: FloatArray
    headband_points: FloatArray
    jaw: str = "linear"
    rest_weights: FloatArray | None = None

    @property
    def n_face_markers(self) -> int:
        """Number of face markers M (the first M columns of ``markers``)."""
        return int(self.marker_vertices.size)

    @property
    def face_labels(self) -> tuple[str, ...]:
        """Labels of the face markers."""
        return self.markers.labels[: self.n_face_markers]

    @property
    def headband_labels(self) -> tuple[str, ...]:
        """Labels of the head-band markers."""
        return self.markers.labels[self.n_face_markers :]


def _smooth_signals(rng: np.random.Generator, n_frames: int, rate: float, n: int) -> tuple[FloatArray, FloatArray]:
    """(T, n) smooth signals, 0 at frame 0: sums of 3 slow sinusoids (0.1-0.6 Hz) each.

    Also returns the same signals over ``max(T, 10 s)``, the reference for
    scaling: short takes get proportionally less motion, not faster motion.
    """
    n_ref = max(n_frames, round(10.0 * rate))
    t = np.arange(n_ref) / rate
    out = np.zeros((n_ref, n))
    for j in range(n):
        for _ in range(3):
            amp, freq, phase = rng.uniform(0.3, 1.0), rng.uniform(0.1, 0.6), rng.uniform(0, 2 * np.pi)
            out[:, j] += amp * (np.sin(2 * np.pi * freq * t + phase) - np.sin(phase))
    return out[:n_frames], out


def _scaled_motion(rng: np.random.Generator, n_frames: int, rate: float, amplitude: float) -> FloatArray:
    """(T, 3) smooth vector signal, 0 at frame 0, whose norm peaks at ``amplitude`` over max(T, 10 s)."""
    sig, ref = _smooth_signals(rng, n_frames, rate, 3)
    peak = float(np.linalg.norm(ref, axis=1).max())
    return sig * (amplitude / peak) if peak > 0 and amplitude > 0 else np.zeros_like(sig)


def _turn_motion(rng: np.random.Generator, n_frames: int, rate: float, n_signals: int,
                 amplitudes: Sequence[float]) -> list[FloatArray]:
    """(T, 3) piecewise-constant poses joined by quick C2 turns, one per amplitude, 0 at frame 0.

    A talking actor holds a pose for 0.4-2.5 s, then turns or nods to a new
    one within 0.3-0.8 s (quintic smoothstep). Every signal shares the same
    timing (a turn moves the rotation and the translation together); each
    has its own random targets, scaled so that its norm peaks at its
    amplitude over ``max(T, 10 s)``. The first hold starts at the rest pose.
    """
    n_ref = max(n_frames, round(10.0 * rate))
    t = np.arange(n_ref) / rate
    starts, durations = [], []
    at = rng.uniform(0.2, 1.0)
    while at < t[-1] + 1.0:
        duration = rng.uniform(TURN_DURATION_S[0], TURN_DURATION_S[1])
        starts.append(at)
        durations.append(duration)
        at += duration + rng.uniform(0.4, 2.5)
    out = []
    for amplitude in amplitudes:
        directions = rng.normal(size=(len(starts), n_signals))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        targets = directions * rng.uniform(0.3, 1.0, size=(len(starts), 1))
        sig = np.zeros((n_ref, n_signals))
        previous = np.zeros(n_signals)
        for start, duration, target in zip(starts, durations, targets):
            step = smoothstep((t - start) / duration)[:, None]
            sig += step * (target - previous)
            previous = target
        peak = float(np.linalg.norm(sig, axis=1).max())
        out.append(sig[:n_frames] * (amplitude / peak) if peak > 0 and amplitude > 0 else np.zeros((n_frames, n_signals)))
    return out


def _default_mocap_frame(rng: np.random.Generator) -> FloatArray:
    """A Z-up capture volume: the head about 1.5 m up, facing a random direction."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler(
        "xyz", [90.0 + rng.uniform(-10, 10), rng.uniform(-20, 20), rng.uniform(-180, 180)], degrees=True
    ).as_matrix()
    T[:3, 3] = [rng.uniform(-500, 500), rng.uniform(-500, 500), 1500.0]
    return T


def _headband(sample: IctSample, scan: Mesh, count: int, rng: np.random.Generator) -> FloatArray:
    """(count, 3) head-band points: 15 mm off the upper forehead and temples, spread by FPS."""
    if count == 0:
        return np.zeros((0, 3))
    V = scan.vertices
    brow_top = float(V[sample.landmarks[17:27], 1].max())
    front = V[:, 2] > float(V[sample.landmarks[[0, 16]], 2].mean())  # in front of the ears
    band = np.flatnonzero((V[:, 1] > brow_top + 15.0) & (V[:, 1] < brow_top + 50.0) & front)
    picks = [int(band[rng.integers(band.size)])]
    d = np.full(band.size, np.inf)
    for _ in range(count):
        d = np.minimum(d, np.linalg.norm(V[band] - V[picks[-1]], axis=1))
        picks.append(int(band[np.argmax(d)]))
    picks = np.asarray(picks[1:], dtype=np.int64)  # drop the random seed point, keep the spread ones
    N = vertex_normals(V, scan.faces, picks)
    return V[picks] + HEADBAND_OFFSET_MM * N


def _layout(marker_layout: Any, n_markers: int | None, sample: IctSample, scan: Mesh,
            seed: int) -> tuple[tuple[str, ...], IntArray]:
    n = scan.n_vertices
    if marker_layout is None:
        count = DEFAULT_MARKERS if n_markers is None else n_markers
        # markers go on the front of the face: not on the ears, scalp or neck, nor under the chin
        normals = vertex_normals(scan.vertices, scan.faces, np.arange(n))
        exclude = (sample.region_labels == sample.region_names.index("other")) | (normals[:, 1] < -0.6)
        mv = choose_marker_vertices(scan.vertices, scan.faces, sample.expression_deltas, count,
                                    seed=seed, exclude=exclude)
        return tuple(f"M{i:03d}" for i in range(mv.size)), mv
    if isinstance(marker_layout, str):
        if marker_layout != "animface":
            raise InputError(f"marker_layout: expected 'animface', a vertex array or a label map, got {marker_layout!r}")
        marker_layout = animface_marker_map()
    if isinstance(marker_layout, Mapping):
        labels = tuple(str(k) for k in marker_layout)
        values = list(marker_layout.values())
    else:
        values = marker_layout
        labels = ()
    try:
        mv = np.asarray(values)
        if mv.ndim != 1 or mv.size == 0 or not np.issubdtype(mv.dtype, np.integer):
            raise ValueError
    except (TypeError, ValueError):
        raise InputError("marker_layout: expected a non-empty 1-D array of vertex indices or a label -> vertex map") from None
    mv = mv.astype(np.int64)
    if mv.min() < 0 or mv.max() >= n:
        raise InputError(f"marker_layout: vertex index out of range 0..{n - 1}")
    if np.unique(mv).size != mv.size:
        raise InputError("marker_layout: two markers on the same vertex")
    if not labels:
        labels = tuple(f"M{i:03d}" for i in range(mv.size))
    if n_markers is not None and n_markers != mv.size:
        raise InputError(f"n_markers: {n_markers} given with a layout of {mv.size} markers (leave it None)")
    return labels, mv


def _gaps(rng: np.random.Generator, n_frames: int, n_total: int, fraction: float) -> np.ndarray:
    """(T, M) occlusion mask: runs of 3-30 frames, frame 0 clear, never every marker at once."""
    missing = np.zeros((n_frames, n_total), dtype=bool)
    target = round(fraction * n_frames * n_total)
    if n_frames < 2 or n_total < 2:
        return missing
    target = min(target, (n_frames - 1) * (n_total - 1))
    count = 0
    per_frame = np.zeros(n_frames, dtype=np.int64)
    for _ in range(100 * target + 100):
        if count >= target:
            break
        marker = int(rng.integers(n_total))
        start = int(rng.integers(1, n_frames))
        frames = np.arange(start, min(n_frames, start + int(rng.integers(3, 31))))
        frames = frames[~missing[frames, marker] & (per_frame[frames] < n_total - 1)]
        frames = frames[: target - count]
        missing[frames, marker] = True
        per_frame[frames] += 1
        count += frames.size
    return missing


CURVE_GENERATORS = ("smooth", "speech", "real", "rapid_asymmetric")
"""Names ``generate_performance(curves=...)`` accepts."""

RAPID_ASYMMETRIC = {"ramp_in_s": (0.06, 0.15), "ramp_out_s": (0.06, 0.15), "asymmetry": 0.4,
                    "max_timing_offset_s": 0.08}
"""Options of :func:`smooth_expression_curves` behind ``curves='rapid_asymmetric'``."""


def named_curves(kind: str, n_frames: int, names: Sequence[str], *, rate: float, seed: int) -> FloatArray:
    """(T, len(names)) weights from the generator called ``kind`` (one of :data:`CURVE_GENERATORS`)."""
    if kind == "smooth":
        return smooth_expression_curves(n_frames, names, rate=rate, seed=seed)
    if kind == "rapid_asymmetric":
        return smooth_expression_curves(n_frames, names, rate=rate, seed=seed, **RAPID_ASYMMETRIC)
    if kind == "speech":
        return speech_expression_curves(n_frames, names, rate=rate, seed=seed)
    if kind == "real":
        W = real_motion_curves(n_frames, rate=rate, seed=seed)
        index = {s: i for i, s in enumerate(REAL_CURVE_NAMES)}
        out = np.zeros((n_frames, len(names)))
        for j, s in enumerate(names):
            if s in index:
                out[:, j] = W[:, index[s]]
        return out
    raise InputError(f"curves: expected an array or one of {CURVE_GENERATORS}, got {kind!r}")


RANDOM_IDENTITY_SD = 0.7
"""Spread of :func:`random_identity`'s ICT identity coefficients (clipped at +-1.3)."""


def random_identity(seed: int, n_coefficients: int = 8) -> np.ndarray:
    """ICT identity coefficients of a random actor (``facecap synth --identity K``): N(0, 0.7^2), clipped at +-1.3.

    The spread of the benchmark's identities (``benchmarks/cases.py``), whose
    coefficients lie within +-1.3.
    """
    rng = np.random.default_rng([int(seed), 0x1D])
    return np.clip(rng.normal(scale=RANDOM_IDENTITY_SD, size=n_coefficients), -1.3, 1.3)


def generate_performance(
    *,
    n_frames: int | None = None,
    rate: float = 60.0,
    n_markers: int | None = None,
    identity: Any = None,
    curves: Any = None,
    marker_layout: Any = None,
    marker_offset_mm: float = 1.5,
    noise_mm: float = 0.2,
    gap_fraction: float = 0.02,
    head_rotation_deg: float = 4.0,
    head_translation_mm: float = 5.0,
    head_pivot: str = "upper_neck",
    head_motion: str = "sway",
    headband_markers: int = 4,
    mocap_frame: Any = None,
    seed: int = 0,
    sample: IctSample | None = None,
    jaw: str = "linear",
    rest_expression: Any = None,
    map_error_mm: float = 0.0,
) -> SyntheticCase:
    """Generate a facial mocap take on the ICT face with dense ground truth.

    The expression is ``truth[t] = scan + weights[t] @ expression_deltas``
    (smooth, performance-like curves; frame 0 neutral; with ``jaw='rotational'`` the jaw
    opens along its arc). Markers sit
    ``marker_offset_mm`` above the skin along the vertex normal, move with
    the expression and a smooth rigid head motion, are seen in the mocap
    system's own rigid frame, with Gaussian noise and occlusion gaps, as an
    optical system would give them; head-band markers ride rigidly with the
    head.

    Parameters
    ----------
    n_frames : int, optional
        Number of frames T (>= 1). Default: the length of ``curves``, or 240.
    rate : float, default 60.0
        Frame rate, Hz.
    n_markers : int, optional
        Face markers to place when ``marker_layout`` is None (default 90);
        with a layout, leave None or give its length.
    identity : (k,) float array, optional
        ICT identity coefficients (k <= 8): who the actor is. Default: the
        generic ICT face.
    curves : {None, 'smooth', 'speech', 'real', 'rapid_asymmetric'} or (T, 53) float array, optional
        Blendshape weights per frame, or the name of a generator run with
        ``(T, sample.expression_names, rate=rate, seed=seed)``: 'smooth' (the
        default, :func:`smooth_expression_curves`), 'speech'
        (:func:`speech_expression_curves`), 'real' (:func:`real_motion_curves`,
        fitted to the bundled real take) or 'rapid_asymmetric'
        (:func:`smooth_expression_curves` with ramps of 60-150 ms, L/R
        intensities differing by up to 40 % and L/R timing offsets up to 80 ms).
    marker_layout : {None, 'animface'} or (M,) int array or dict of str to int, optional
        Where the face markers go. None: :func:`choose_marker_vertices` on
        the front of the face (ears, scalp, neck and the underside of the
        chin excluded) with ``seed``; 'animface': the 41 markers of the
        bundled real take (:func:`animface_marker_map`); an array of scan
        vertices (labelled ``M000``...); or a label -> vertex map.
    marker_offset_mm : float, default 1.5
        Marker centre height above the skin (half a 3 mm marker).
    noise_mm : float, default 0.2
        Standard deviation of the Gaussian noise on each coordinate (mm).
    gap_fraction : float, default 0.02
        Fraction of marker samples (frame x marker) occluded, in runs of 3-30
        frames, in [0, 0.5]. Frame 0 is always complete and no frame loses
        every marker.
    head_rotation_deg : float, default 4.0
        Peak rotation of the head about ``head_pivot``, over the take or its
        first 10 s.
    head_translation_mm : float, default 5.0
        Peak head translation, likewise.
    head_pivot : {'upper_neck', 'neck'}, default 'upper_neck'
        Centre of the head rotation (:data:`HEAD_PIVOTS_MM`, from the chin,
        on the face's mid-plane): 'upper_neck' 3 cm below and 11 cm behind
        the chin; 'neck' 9 cm below and 8 cm behind it (the lower cervical
        spine), so that a rotation also swings the face sideways.
    head_motion : {'sway', 'turns'}, default 'sway'
        'sway': sums of three slow sinusoids (0.1-0.6 Hz) per axis. 'turns':
        holds of 0.4-2.5 s joined by quick turns or nods of 0.3-0.8 s
        (quintic smoothstep) to a new random pose, like a talking actor.
        Either is zero at frame 0 and peaks at the amplitudes above.
    headband_markers : int, default 4
        Markers on a head band 15 mm off the upper forehead and temples
        (0 to 16).
    mocap_frame : (4, 4) float array, optional
        The rigid transform ``mocap_from_scan``. Default: a seeded Z-up
        frame, the head about 1.5 m up and facing a random direction.
    seed : int, default 0
        Everything random follows from it: the curves and the layout use it
        directly; the head band, head motion, mocap frame, noise and gaps use
        independent streams spawned from it, so changing ``noise_mm`` or
        ``gap_fraction`` changes nothing else.
    sample : IctSample, optional
        Default: :func:`load_ict_sample`.
    jaw : {'linear', 'rotational'}, default 'linear'
        How ``jawOpen`` blends. 'linear': the blendshape's straight lines, as ICT defines it (at
        half weight the jaw is the chord of its 25 degree rotation, about 2 mm short at the chin).
        'rotational': the part of each vertex's displacement that the jaw's rotation explains is
        taken along the arc (:mod:`facecap.synth.rotational_jaw`); full weight is ICT's shape
        either way.
    rest_expression : dict of str to float or (k,) float array, optional
        An expression the actor holds under the whole take (a slight smile,
        lowered brows): added to every frame's weights (clipped to [0, 1]),
        so the take's first frame is not the scan's expression and no frame
        need be. :func:`~facecap.synth.random_rest_expression` draws one.
        Default: none, frame 0 shows the scan.
    map_error_mm : float, default 0.0
        Standard deviation, per direction along the skin, of where the map
        places each marker against its true place (a map picked by hand):
        ``correspondence`` then holds points on the scan, off the true
        vertex, and ``marker_vertices`` the truth. Drawn from its own
        stream, so it changes nothing else.

    Returns
    -------
    SyntheticCase

    Raises
    ------
    InputError
        If an option has the wrong type, shape or range.

    Notes
    -----
    Face marker i at frame t:
    ``m_i(t) = mocap_from_scan @ head_pose[t] @ (truth[t, v_i] + offset * n_t(v_i)) + e``,
    ``e ~ N(0, noise_mm^2 I)``, with ``n_t`` the area-weighted vertex normal
    of ``truth[t]``. ``head_pose[t] = [R(t) | p - R(t) p + s(t)]`` for a
    pivot ``p``, where the rotation vector of ``R`` and the shift ``s`` are
    sums of slow sinusoids (0.1-0.6 Hz) or piecewise holds joined by quick
    turns, zero at frame 0.

    Examples
    --------
    >>> case = generate_performance(n_frames=30, n_markers=20, seed=1)
    >>> case.markers.positions.shape, case.truth_vertices.shape
    ((30, 24, 3), (30, 9409, 3))
    """
    sample = load_ict_sample() if sample is None else sample
    if not isinstance(sample, IctSample):
        raise InputError(f"sample: expected an IctSample, got {type(sample).__name__}")
    seed = as_count(seed, name="seed", minimum=0)
    rate = as_positive(rate, name="rate")
    offset = as_positive(marker_offset_mm, name="marker_offset_mm", allow_zero=True)
    noise_mm = as_positive(noise_mm, name="noise_mm", allow_zero=True)
    gap_fraction = as_positive(gap_fraction, name="gap_fraction", allow_zero=True)
    if gap_fraction > 0.5:
        raise InputError(f"gap_fraction: expected a fraction in [0, 0.5], got {gap_fraction}")
    rot_rad = np.deg2rad(as_positive(head_rotation_deg, name="head_rotation_deg", allow_zero=True))
    shift_mm = as_positive(head_translation_mm, name="head_translation_mm", allow_zero=True)
    n_band = as_count(headband_markers, name="headband_markers", minimum=0)
    if n_band > MAX_HEADBAND_MARKERS:
        raise InputError(f"headband_markers: expected at most {MAX_HEADBAND_MARKERS}, got {n_band}")
    if n_markers is not None:
        n_markers = as_count(n_markers, name="n_markers", minimum=1)
    if mocap_frame is not None:
        mocap_frame = as_rigid_transform(mocap_frame, name="mocap_frame")
    if head_pivot not in HEAD_PIVOTS_MM:
        raise InputError(f"head_pivot: expected one of {tuple(HEAD_PIVOTS_MM)}, got {head_pivot!r}")
    if head_motion not in HEAD_MOTIONS:
        raise InputError(f"head_motion: expected one of {HEAD_MOTIONS}, got {head_motion!r}")
    if jaw not in JAW_MODES:
        raise InputError(f"jaw: expected one of {JAW_MODES}, got {jaw!r}")
    names = sample.expression_names
    rest_weights = as_rest_weights(rest_expression, names)
    map_error_mm = as_positive(map_error_mm, name="map_error_mm", allow_zero=True)

    if curves is None or isinstance(curves, str):
        T = DEFAULT_FRAMES if n_frames is None else as_count(n_frames, name="n_frames", minimum=1)
        W = named_curves("smooth" if curves is None else curves, T, names, rate=rate, seed=seed)
    else:
        try:
            W = np.array(curves, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("curves: expected a numeric (T, 53) array") from None
        T = W.shape[0] if W.ndim == 2 else -1
        if n_frames is not None:
            T = as_count(n_frames, name="n_frames", minimum=1)
        if W.shape != (T, len(names)) or T < 1:
            raise InputError(f"curves: expected shape ({'T' if T < 1 else T}, {len(names)}), got {W.shape}")
        if not np.all(np.isfinite(W)):
            raise InputError("curves: contains NaN or infinite values")

    if rest_weights.any():
        W = np.clip(W + rest_weights[None], 0.0, 1.0)
    # spawn keys are positional: a sixth stream leaves the first five (and every earlier take) as they were
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(6)]
    rng_band, rng_head, rng_mocap, rng_noise, rng_gaps, rng_map = streams

    scan = sample.face(identity)
    V0, F = scan.vertices, scan.faces
    labels, mv = _layout(marker_layout, n_markers, sample, scan, seed)
    band = _headband(sample, scan, n_band, rng_band)
    if set(labels) & {f"HB{i}" for i in range(n_band)}:
        raise InputError("marker_layout: labels HB0, HB1, ... are reserved for the head band")

    deltas32 = sample.expression_deltas.astype(np.float32)
    truth = V0.astype(np.float32)[None] + np.tensordot(W.astype(np.float32), deltas32, axes=1)
    if jaw == "rotational":
        k = names.index(JAW_SHAPE)
        truth += rotational_jaw_correction(V0, sample.expression_deltas[k], W[:, k], ICT_JAW_SCREW).astype(np.float32)

    skin = truth[:, mv].astype(np.float64)
    face_points = skin + offset * vertex_normals(truth, F, mv) if offset > 0 else skin
    points = np.concatenate([face_points, np.broadcast_to(band, (T, band.shape[0], 3))], axis=1)

    pivot = V0[sample.landmarks[8]] + np.array(HEAD_PIVOTS_MM[head_pivot])  # from the chin
    pivot[0] = float(V0[:, 0].mean())
    if head_motion == "sway":
        rotvec = _scaled_motion(rng_head, T, rate, rot_rad)
        shift = _scaled_motion(rng_head, T, rate, shift_mm)
    else:
        rotvec, shift = _turn_motion(rng_head, T, rate, 3, (rot_rad, shift_mm))
    R = Rotation.from_rotvec(rotvec).as_matrix().reshape(T, 3, 3)
    head_pose = np.tile(np.eye(4), (T, 1, 1))
    head_pose[:, :3, :3] = R
    head_pose[:, :3, 3] = pivot - R @ pivot + shift
    head_pose[0] = np.eye(4)

    mocap_from_scan = _default_mocap_frame(rng_mocap) if mocap_frame is None else mocap_frame
    world = mocap_from_scan[None] @ head_pose
    noiseless = np.einsum("tij,tkj->tki", world[:, :3, :3], points) + world[:, None, :3, 3]

    observed = noiseless.copy()
    if noise_mm > 0:
        observed += rng_noise.normal(scale=noise_mm, size=observed.shape)
    if gap_fraction > 0:
        observed[_gaps(rng_gaps, T, observed.shape[1], gap_fraction)] = np.nan

    all_labels = labels + tuple(f"HB{i}" for i in range(n_band))
    markers = MarkerSequence(observed, all_labels, rate=rate, source_unit="mm")
    if map_error_mm > 0:
        picked = _picked_points(V0, F, mv, map_error_mm, rng_map)
        correspondence: dict[str, Any] = {s: [float(x) for x in p] for s, p in zip(labels, picked)}
    else:
        correspondence = {s: int(v) for s, v in zip(labels, mv)}
    return SyntheticCase(
        scan=scan,
        markers=markers,
        correspondence=correspondence,
        truth_vertices=truth,
        head_pose=head_pose,
        mocap_from_scan=mocap_from_scan,
        weights=W,
        marker_vertices=mv,
        noiseless_markers=noiseless,
        headband_points=band,
        jaw=jaw,
        rest_weights=rest_weights if rest_weights.any() else None,
    )


def _picked_points(V: FloatArray, F: IntArray, vertices: IntArray, error_mm: float,
                   rng: np.random.Generator) -> FloatArray:
    """(k, 3) points on the surface, off ``V[vertices]`` along the skin by N(0, error_mm^2) per tangent direction.

    The offset is taken in the tangent plane of the vertex normal and the result is put back on the
    surface by its closest point, as a user's click on the scan would land.
    """
    N = vertex_normals(V, F, vertices)
    step = rng.normal(scale=error_mm, size=(vertices.size, 3))
    step -= np.einsum("kd,kd->k", step, N)[:, None] * N
    _, _, C = igl.point_mesh_squared_distance(V[vertices] + step, V, F)
    return np.asarray(C, dtype=np.float64)
