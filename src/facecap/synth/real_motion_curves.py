"""Blendshape-weight curves from real motion: the 53 ICT weights fitted to the bundled AnimFace take."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import FileFormatError, InputError
from ..typing import FloatArray
from ..validate import as_positive, as_positive_range
from .smoothstep import smoothstep

__all__ = ["REAL_CURVE_NAMES", "RealCurveFit", "load_real_curve_fit", "real_motion_curves"]

CURVES_FILE = "animface_curves.npz"
CROSSFADE_S = 0.2
"""Crossfade between two played segments of the real take, s."""


class RealCurveFit(NamedTuple):
    """The stored fit (``facecap/data/animface_curves.npz``, built by ``tools/build_animface_curves.py``).

    Attributes
    ----------
    weights : (902, 53) float64 array
        Weights per frame of the real take, in [0, 1]; frame 0 (the rest) is 0.
    names : tuple of str
        The 53 ICT expression names, column order.
    rate : float
        Hz (60).
    residual_rms_mm : float
        RMS marker residual of the fit over the take, mm.
    zero_weights_rms_mm : float
        RMS marker displacement from the rest frame (the residual of w = 0), mm.
    provenance : str
        How it was made, and its licence (CC BY-SA 4.0, derived from the AnimFace take).
    """

    weights: FloatArray
    names: tuple[str, ...]
    rate: float
    residual_rms_mm: float
    zero_weights_rms_mm: float
    provenance: str


@lru_cache(maxsize=1)
def load_real_curve_fit() -> RealCurveFit:
    """Read the bundled fit of the ICT weights to the real AnimFace take (cached, read-only arrays).

    Returns
    -------
    RealCurveFit

    Raises
    ------
    FileFormatError
        If the file is missing from the installation.
    """
    path = Path(str(resources.files("facecap") / "data" / CURVES_FILE))
    if not path.is_file():
        raise FileFormatError("bundled data file missing (run tools/build_animface_curves.py)", path=str(path))
    with np.load(path) as z:
        W = z["weights"].astype(np.float64)
        W.setflags(write=False)
        return RealCurveFit(W, tuple(str(s) for s in z["names"]), float(z["rate"]),
                            float(z["residual_rms_mm"]), float(z["zero_weights_rms_mm"]), str(z["provenance"]))


REAL_CURVE_NAMES: tuple[str, ...] = (
    "browDown_L", "browDown_R", "browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R",
    "cheekPuff_L", "cheekPuff_R", "cheekSquint_L", "cheekSquint_R", "eyeBlink_L", "eyeBlink_R",
    "eyeLookDown_L", "eyeLookDown_R", "eyeLookIn_L", "eyeLookIn_R", "eyeLookOut_L", "eyeLookOut_R",
    "eyeLookUp_L", "eyeLookUp_R", "eyeSquint_L", "eyeSquint_R", "eyeWide_L", "eyeWide_R", "jawForward",
    "jawLeft", "jawOpen", "jawRight", "mouthClose", "mouthDimple_L", "mouthDimple_R", "mouthFrown_L",
    "mouthFrown_R", "mouthFunnel", "mouthLeft", "mouthLowerDown_L", "mouthLowerDown_R", "mouthPress_L",
    "mouthPress_R", "mouthPucker", "mouthRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower",
    "mouthShrugUpper", "mouthSmile_L", "mouthSmile_R", "mouthStretch_L", "mouthStretch_R",
    "mouthUpperUp_L", "mouthUpperUp_R", "noseSneer_L", "noseSneer_R",
)
"""Column order of :func:`real_motion_curves` (the ICT expression order, as stored)."""


def _source_times(n_frames: int, rate: float, take_s: float, seed: int,
                  segment_s: tuple[float, float], stretch: tuple[float, float]) -> list[tuple[FloatArray, FloatArray]]:
    """Per played segment: (output frames it covers, source times in the take, s)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / rate
    pieces = []
    start_out = 0.0
    first = True
    while start_out < t[-1] + 1e-9 or first:
        if seed == 0 and first:
            length, factor, src0, reverse = take_s, 1.0, 0.0, False
        else:
            length = min(rng.uniform(*segment_s), take_s)
            factor = rng.uniform(*stretch)
            src0 = 0.0 if first else rng.uniform(0.0, take_s - length)
            reverse = False if first else bool(rng.uniform() < 0.5)
        out_len = length * factor
        frames = np.flatnonzero((t >= start_out) & (t < start_out + out_len + CROSSFADE_S))
        local = (t[frames] - start_out) / factor
        local = np.minimum(local, length)
        src = src0 + (length - local if reverse else local)
        pieces.append((frames, src))
        start_out += out_len
        first = False
    return pieces


def real_motion_curves(
    n_frames: int | None = None,
    *,
    rate: float = 60.0,
    seed: int = 0,
    segment_s: tuple[float, float] = (3.0, 8.0),
    stretch: tuple[float, float] = (0.8, 1.25),
    asymmetry: float = 0.0,
    max_timing_offset_s: float = 0.0,
    lead_in_s: float = 0.25,
) -> FloatArray:
    """Blendshape weights from real motion: the ICT weights fitted to the bundled AnimFace take.

    The stored fit (:func:`load_real_curve_fit`; 902 frames at 60 Hz, 15 s:
    brow raises and frowns, blinks, eye and some mouth motion of a real
    actor) is played back at ``rate``. ``seed=0`` plays the take as
    recorded from its rest frame; any other seed starts at the rest frame
    with a random-length segment and continues with segments of
    ``segment_s`` from random places, each time-stretched by a factor in
    ``stretch`` and reversed (played backwards) half the time. Segments join
    with 0.2 s crossfades; a take longer than the recording continues the
    same way. Frame 0 is neutral and the first ``lead_in_s`` eases in.

    Parameters
    ----------
    n_frames : int, optional
        Number of frames T (>= 1). Default: the take's duration at ``rate``.
    rate : float, default 60.0
        Output frame rate, Hz; the take is resampled linearly in time.
    seed : int, default 0
        0: the take as recorded (looped past its end); otherwise the seed of
        the segment shuffling and of the asymmetry.
    segment_s : (float, float), default (3.0, 8.0)
        Range of the played segments' lengths in the take, s.
    stretch : (float, float), default (0.8, 1.25)
        Range of the time-stretch factor of each segment (> 1: slower).
    asymmetry : float, default 0.0
        In [0, 1): ``_L`` columns scaled by ``1 + a u`` and ``_R`` columns by
        ``1 - a u``, ``|u|`` uniform in [0.25, 1] with a random sign (clipped to [0, 1]).
    max_timing_offset_s : float, default 0.0
        The ``_R`` columns lag (or lead) the ``_L`` ones by a random time up
        to this, s.
    lead_in_s : float, default 0.25
        The weights are multiplied by a smoothstep from 0 to 1 over this time, s.

    Returns
    -------
    (n_frames, 53) float64 array in [0, 1]
        Columns in :data:`REAL_CURVE_NAMES` order (``load_ict_sample().expression_names``).

    Raises
    ------
    InputError
        If an option has the wrong type or range.

    Notes
    -----
    The fit (``tools/build_animface_curves.py``) solves, frame by frame,
    ``min_w |B w - d_t|^2 + lam |w|^2 + mu |w - w_prev|^2`` over ``[0, 1]^53``
    with ``B`` the ICT expression deltas at the 41 mapped marker vertices and
    ``d_t`` the stabilised marker displacements from the rest frame, carried
    into the ICT face frame by a rigid alignment of the rest frame. The
    actor is not the ICT face: the RMS marker residual is 1.85 mm against
    3.09 mm for w = 0 (1.34 mm for unbounded least squares).

    Examples
    --------
    >>> W = real_motion_curves(120)
    >>> W.shape, float(W[0].max())
    ((120, 53), 0.0)
    """
    fit = load_real_curve_fit()
    rate = as_positive(rate, name="rate")
    source_T = fit.weights.shape[0]
    take_s = (source_T - 1) / fit.rate
    if n_frames is None:
        n_frames = max(1, int(round(take_s * rate)) + 1)
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected an integer >= 0, got {seed!r}")
    segment_s = as_positive_range(segment_s, name="segment_s")
    stretch = as_positive_range(stretch, name="stretch")
    asymmetry = as_positive(asymmetry, name="asymmetry", allow_zero=True)
    if asymmetry >= 1:
        raise InputError(f"asymmetry: expected a value in [0, 1), got {asymmetry}")
    max_timing_offset_s = as_positive(max_timing_offset_s, name="max_timing_offset_s", allow_zero=True)
    lead_in_s = as_positive(lead_in_s, name="lead_in_s", allow_zero=True)

    def sample_at(src: FloatArray) -> FloatArray:
        x = np.clip(src * fit.rate, 0.0, source_T - 1)
        i = np.minimum(np.floor(x).astype(np.int64), source_T - 2)
        f = (x - i)[:, None]
        return (1 - f) * fit.weights[i] + f * fit.weights[i + 1]

    rng_side = np.random.default_rng((seed, 1))
    lag = rng_side.uniform(-max_timing_offset_s, max_timing_offset_s)
    u = rng_side.uniform(0.25, 1.0) * rng_side.choice((-1.0, 1.0))
    t = np.arange(n_frames) / rate
    W = np.zeros((n_frames, len(fit.names)))
    right = np.array([s.endswith("_R") for s in fit.names])
    filled = np.zeros(n_frames, dtype=bool)
    for frames, src in _source_times(n_frames, rate, take_s, seed, segment_s, stretch):
        if frames.size == 0:
            continue
        piece = sample_at(src)
        if lag != 0:
            piece[:, right] = sample_at(src - lag)[:, right]
        # crossfade from what is already there into the new segment
        seen = filled[frames]
        if seen.any():
            start = t[frames[~seen][0]] if (~seen).any() else t[frames[-1]]
            blend = smoothstep((t[frames] - t[frames[0]]) / max(start - t[frames[0]], 1e-9))[:, None]
            piece = np.where(seen[:, None], (1 - blend) * W[frames] + blend * piece, piece)
        W[frames] = piece
        filled[frames] = True
    if asymmetry > 0:
        gain = np.ones(len(fit.names))
        gain[[s.endswith("_L") for s in fit.names]] = 1 + asymmetry * u
        gain[right] = 1 - asymmetry * u
        W *= gain
    if lead_in_s > 0:
        W *= smoothstep(t / lead_in_s)[:, None]
    np.clip(W, 0.0, 1.0, out=W)
    W[0] = 0.0
    return W


