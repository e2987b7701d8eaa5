"""What the take's rest frame means for the warp: the scan's expression, an expression of its own, or a neutral given."""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple, Sequence

import numpy as np

from ..errors import InputError, MarkerError
from ..markers.fill_gaps import fill_gaps
from ..markers.resting_expression import RestingExpression, measure_resting_expression, robust_rigid_fit
from ..markers.rigid_fit import rigid_fit
from ..structures import MarkerSequence
from ..typing import FloatArray

__all__ = ["REST_POSES", "RestPose", "choose_rest_pose", "neutral_from_frames", "neutral_from_take",
           "parse_frame_range"]

REST_POSES = ("auto", "scan", "expression")
"""``rest_pose`` choices: measure and choose; the rest frame shows the scan's expression (the warp maps it onto
the scan, Bickel et al. 2007 sec. 4.1); the rest frame holds an expression of its own (kept as motion)."""


class RestPose(NamedTuple):
    """How the warp's rest markers meet the scan, by :func:`choose_rest_pose`.

    Attributes
    ----------
    mode : {'scan', 'expression', 'neutral_reference'}
        'scan': the rest markers are mapped exactly onto their places on the scan (the paper);
        'expression': onto their rigidly aligned selves, so the resting expression stays in every frame;
        'neutral_reference': a neutral given by the user is mapped onto the scan instead of the rest frame.
    chosen_by : {'auto', 'option'}
    reason : str
        One sentence: what was measured and why this mode.
    sources : (K, 3) float64 array, mm
        The warp's source points (take's stabilised frame).
    targets : (K, 3) float64 array, mm
        Where the warp puts them (scan frame).
    measurement : RestingExpression
        The rest frame against the scan (:func:`~facecap.markers.measure_resting_expression`).
    warn : bool
        Whether ``reason`` deserves a warning line (a choice made for the user, or a doubt).
    """

    mode: str
    chosen_by: str
    reason: str
    sources: FloatArray
    targets: FloatArray
    measurement: RestingExpression
    warn: bool

    def to_dict(self, labels: Sequence[str]) -> dict[str, Any]:
        """The ``rest_pose`` section of ``report.json``."""
        m = self.measurement

        def rms(rows: FloatArray) -> float:
            return float(np.sqrt(np.nanmean(np.sum(rows**2, axis=1))))

        return {
            "mode": self.mode, "chosen_by": self.chosen_by, "reason": self.reason,
            "noise_mm": round(m.noise_mm, 4), "mismatch_rms_mm": round(rms(m.residual), 4),
            "expression_rms_mm": round(rms(m.expression), 4), "placement_rms_mm": round(rms(m.placement), 4),
            "placement_sd_mm": round(m.placement_sd_mm, 4), "coherence": round(m.coherence, 3),
            "offset_error_mm": round(m.offset_error_mm, 3), "scale_error": round(m.scale_error, 5),
            "fits_scan": m.fits_scan, "motion_z": round(m.motion_z, 2), "above_noise": round(m.above_noise, 2),
            "rest_noise_mm": round(m.rest_noise_mm, 4),
            "per_marker_mm": {label: round(float(d), 3) for label, d in zip(labels, m.mismatch_mm)},
            "misplaced": [label for label, bad in zip(labels, m.misplaced) if bad],
        }


def choose_rest_pose(
    rest_markers: FloatArray,
    centres: FloatArray,
    *,
    noise_mm: float,
    rest_samples: float = 1.0,
    normals: FloatArray | None = None,
    motion: FloatArray | None = None,
    rest_pose: str = "auto",
    neutral_markers: FloatArray | None = None,
) -> RestPose:
    """Measure the rest frame against the scan and choose where the warp puts the rest markers.

    Parameters
    ----------
    rest_markers : (K, 3) float64 array, mm
        The rest frame's markers (averaged round it), take's stabilised frame.
    centres : (K, 3) float64 array, mm
        Their places on the scan (marker centres, lifted off the skin).
    normals : (K, 3) float64 array, optional
        The scan's normals there (to tell a wrong marker offset from an expression).
    rest_samples : float, default 1.0
        Effective frames the rest markers average (:func:`~facecap.markers.measure_resting_expression`).
    motion : (T, K, 3) float64 array, optional
        The conditioned take, in the rest markers' frame (its motion directions are the second cue).
    noise_mm : float
        The markers' noise per coordinate.
    rest_pose : {'auto', 'scan', 'expression'}, default 'auto'
        See :data:`REST_POSES`. 'auto' keeps the mismatch as an expression when
        :attr:`~facecap.markers.RestingExpression.is_expression` says so (it is above the noise,
        neighbouring markers share it or it lies along the take's own motion, and each marker's own part is small).
    neutral_markers : (K, 3) float64 array or None, optional
        A neutral reference in the take's stabilised frame (:func:`neutral_from_frames`,
        :func:`neutral_from_take`): mapped onto ``centres``, whatever ``rest_pose`` says.

    Returns
    -------
    RestPose
    """
    if rest_pose not in REST_POSES:
        raise InputError(f"rest_pose: expected one of {REST_POSES}, got {rest_pose!r}")
    m = measure_resting_expression(rest_markers, centres, noise_mm=noise_mm, rest_samples=rest_samples,
                                   normals=normals, motion=motion)
    mismatch = float(np.sqrt(np.nanmean(m.mismatch_mm**2)))
    off = f"{mismatch:.2f} mm (RMS) off the scan after a rigid fit"
    along = (f"{m.above_noise:.0f} times the rest frame's noise, {100 * max(m.coherence, 0.0):.0f} % of it shared by "
             f"neighbouring markers, {max(m.motion_z, 0.0):.0f} deviations along the take's own motion")
    if neutral_markers is not None:
        return RestPose("neutral_reference", "option",
                        f"replaced by the given neutral reference, which is mapped onto the scan (the rest frame is {off})",
                        np.asarray(neutral_markers, dtype=np.float64), np.asarray(centres, dtype=np.float64), m, False)
    if rest_pose == "scan":
        return RestPose("scan", "option", f"taken to show the scan's expression (--rest-pose scan; it is {off})",
                        rest_markers, centres, m, False)
    if rest_pose == "auto" and not m.is_expression:
        if not m.fits_scan:
            reason = (f"is no resting expression of this scan's face ({off}, the take {100 * m.scale_error:+.0f} % in "
                      "size): another actor's markers or a loose map; the warp maps it onto the scan, as the paper "
                      "does")
            return RestPose("scan", "auto", reason, rest_markers, centres, m, False)
        if m.is_significant:
            reason = (f"differs from the scan ({off}, {along}), but the markers' own parts ({m.placement_sd_mm:.2f} mm) "
                      "say the map is off marker by marker, as a map picked by hand is: the warp absorbs it; if the "
                      "actor rests with an expression, give a neutral reference (--neutral) or a closer map "
                      "(facecap map; docs/own_data.md)")
            return RestPose("scan", "auto", reason, rest_markers, centres, m, True)
        return RestPose("scan", "auto", f"matches the scan ({off}, {m.above_noise:.1f} times the rest frame's "
                        f"noise)", rest_markers, centres, m, False)
    if rest_pose == "auto":
        reason = (f"holds an expression of its own ({off}, {along}): kept as motion, not taken out of every frame "
                  "(--rest-pose scan absorbs it into the warp instead)")
    else:
        reason = f"kept as an expression the face holds (--rest-pose expression; it is {off})"
    if m.misplaced.any():
        reason += f"; {int(m.misplaced.sum())} marker(s) look misplaced in the map and are absorbed"
    return RestPose("expression", "auto" if rest_pose == "auto" else "option", reason, rest_markers,
                    m.kept_targets(centres), m, rest_pose == "auto")


def parse_frame_range(text: str, n_frames: int) -> tuple[int, int]:
    """``'A:B'`` -> ``(A, B)``, frames ``A <= t < B`` of a take of ``n_frames``; InputError naming the problem."""
    try:
        start_text, stop_text = str(text).split(":")
        start, stop = int(start_text), int(stop_text)
    except ValueError:
        raise InputError(f"--neutral: expected a frame range A:B or a take file, got {text!r}") from None
    if not 0 <= start < stop <= n_frames:
        raise InputError(f"--neutral {text}: expected 0 <= A < B <= {n_frames} (the take's frames)")
    return start, stop


def neutral_from_frames(positions: FloatArray, start: int, stop: int) -> FloatArray:
    """The mean of a take's conditioned markers over frames ``start <= t < stop``, (K, 3) mm.

    Each frame is moved rigidly onto the first complete one before averaging, so a head that moved in
    the range does not smear the mean.
    """
    window = np.asarray(positions[start:stop], dtype=np.float64)
    complete = np.flatnonzero(np.isfinite(window).all(axis=(1, 2)))
    if complete.size == 0:
        raise MarkerError(f"--neutral {start}:{stop}: no frame of the range sees every marker")
    return _aligned_mean(window, window[complete[0]])  # finite: the complete frame places itself


def neutral_from_take(neutral: MarkerSequence, labels: Sequence[str], rest_markers: FloatArray) -> tuple[FloatArray, list[str]]:
    """A separate neutral take's markers, averaged and carried into the main take's stabilised frame.

    Parameters
    ----------
    neutral : MarkerSequence
        A take of the actor holding the scan's neutral expression (any head pose, any length).
    labels : sequence of str, length K
        The main take's markers that drive the scan, in order.
    rest_markers : (K, 3) float64 array, mm
        The main take's rest markers, in its stabilised frame: the neutral is fitted onto them rigidly
        (robustly: the markers the expression moved between the two count little).

    Returns
    -------
    neutral_markers : (K, 3) float64 array, mm
    notes : list of str
        Markers the neutral take lacks (they keep the rest frame's places).

    Raises
    ------
    MarkerError
        If fewer than 4 of the markers are in the neutral take.
    """
    index = neutral.label_index()
    columns = [index.get(label, -1) for label in labels]
    present = np.array([c >= 0 for c in columns])
    if present.sum() < 4:
        raise MarkerError(f"the neutral take holds {int(present.sum())} of the take's {len(labels)} markers; "
                          "at least 4 are needed", path=neutral.source_path)
    P = fill_gaps(neutral.positions, rate=neutral.rate).positions[:, [c for c in columns if c >= 0]]
    seen = np.isfinite(P).all(axis=2)
    reference = P[int(np.argmax(seen.sum(axis=1)))]
    mean = _aligned_mean(P, reference)
    captured = np.isfinite(mean).all(axis=1)  # a label the neutral take holds but never saw counts as missing
    present[np.flatnonzero(present)[~captured]] = False
    if present.sum() < 4:
        raise MarkerError(f"the neutral take sees {int(present.sum())} of the take's {len(labels)} markers; "
                          "at least 4 are needed", path=neutral.source_path)
    mean = mean[captured]
    fit, _ = robust_rigid_fit(mean, np.asarray(rest_markers, dtype=np.float64)[present])
    out = np.array(rest_markers, dtype=np.float64)
    out[present] = fit.apply(mean)
    missing = [label for label, ok in zip(labels, present) if not ok]
    notes = [f"markers missing from the neutral take keep the rest frame's places: {', '.join(missing)}"] if missing else []
    return out, notes


def _aligned_mean(window: FloatArray, reference: FloatArray) -> FloatArray:
    """Mean over frames of ``window`` (t, K, 3) after moving each frame rigidly onto ``reference`` (K, 3).

    Frames the fit cannot place (fewer than 3 markers seen in both) are left out; a marker no placed
    frame sees is NaN.
    """
    moved = rigid_fit(window, reference[None]).apply(window)  # NaN throughout for a frame it cannot place
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a marker no frame sees: NaN, said by the caller
        return np.nanmean(moved, axis=0)
