"""A take made ready for any solver: matched to the map, conditioned, its rest markers and head pose.

Every job that drives a face from a take (``animate``, ``solve-muscles``, ``facecap map``) starts
here: :func:`check_take_against_map` before any long work, :func:`prepare_markers` (match,
gap-fill, stabilise, filter; a :class:`PreparedMarkers`), :func:`rest_average` (the rest frame's
markers averaged over the frames round it) and :func:`head_pose_in_scan` (the head motion found,
carried into the scan's coordinates).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..errors import MarkerError
from ..io.read_correspondence import match_correspondence
from ..structures import Correspondence, MarkerSequence, Mesh, TemporalSigmaChoice
from .condition_take import condition_take
from .rigid_fit import rigid_fit

__all__ = ["PreparedMarkers", "prepare_markers", "check_take_against_map", "rest_average", "head_pose_in_scan",
           "DEFAULT_REST_AVERAGE_S", "MIN_DRIVING_MARKERS"]

MIN_DRIVING_MARKERS = 4
"""The fewest mapped markers a take must hold to drive a face."""

DEFAULT_REST_AVERAGE_S = 0.1
"""Half-width (Gaussian sigma, seconds) of the average that gives the warp its rest markers."""


@dataclass(frozen=True)
class PreparedMarkers:
    """Conditioned markers mapped onto the scan, ready to drive the deformation.

    Attributes
    ----------
    labels : tuple of str, length K
        Markers that drive the scan, in column order.
    positions : (T, K, 3) float64 array, mm
        Conditioned mocap-space positions (gap-filled, stabilised, filtered).
    raw_positions : (T, K, 3) float64 array, mm
        The same markers as read, NaN in gaps.
    scan_points : (K, 3) float64 array, mm
        Where each marker sits on the scan.
    constrained_vertices : (K,) int64 array
        Scan vertex that carries each marker in the shell solve.
    filled : (T, K) bool array
        Samples made up by gap filling.
    head_rotations, head_translations : (T, 3, 3), (T, 3) float64 arrays or None
        Stabilising transform per frame (mocap space), when stabilised.
    stabilization_residual : (T,) float64 array or None, mm
        RMS misfit of the stable markers after stabilisation.
    stable_labels : tuple of str
        Markers used for stabilisation.
    notes : list of str
        What was dropped, filled or ignored.
    temporal_sigma_s : float or None
        The bilateral filter's temporal sigma (s); None when not filtered.
    temporal_sigma_choice : TemporalSigmaChoice or None
        Its cross-validation, when it was chosen for the take.
    head_pose_from : str or None
        Where the head pose came from (:data:`~facecap.markers.condition_take.HEAD_POSE_SOURCES`);
        None when the take was not stabilised.
    """

    labels: tuple[str, ...]
    positions: np.ndarray
    raw_positions: np.ndarray
    scan_points: np.ndarray
    constrained_vertices: np.ndarray
    filled: np.ndarray
    head_rotations: np.ndarray | None = None
    head_translations: np.ndarray | None = None
    stabilization_residual: np.ndarray | None = None
    stable_labels: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)
    temporal_sigma_s: float | None = None
    temporal_sigma_choice: TemporalSigmaChoice | None = None
    head_pose_from: str | None = None


def check_take_against_map(markers: MarkerSequence, correspondence: Correspondence,
                           rest_frame: int) -> tuple[Correspondence, list[int], list[str]]:
    """The map's markers in the take, checked before any long work: ``(matched map, take columns, ignored labels)``.

    Raises MarkerError if the rest frame is out of range, fewer than 4 markers of the take are in the map,
    or every mapped marker is missing at the rest frame.
    """
    T = markers.n_frames
    if not (0 <= rest_frame < T):
        raise MarkerError(f"--rest-frame {rest_frame} is outside the take (0..{T - 1})", path=markers.source_path)
    corr, columns, ignored = match_correspondence(correspondence, markers.labels)
    if len(columns) < MIN_DRIVING_MARKERS:
        raise MarkerError(
            f"only {len(columns)} marker(s) of the take are in the map; at least {MIN_DRIVING_MARKERS} are needed",
            path=markers.source_path,
        )
    if not (~np.isnan(markers.positions[rest_frame, columns]).any(axis=1)).any():
        raise MarkerError(
            f"every mapped marker is missing at the rest frame {rest_frame}; choose another --rest-frame",
            path=markers.source_path,
        )
    return corr, columns, ignored


def prepare_markers(
    markers: MarkerSequence,
    scan: Mesh,
    correspondence: Correspondence,
    *,
    rest_frame: int = 0,
    stabilize: bool | str | Sequence[str] = True,
    smooth: bool = True,
    temporal_sigma_s: float | str = "auto",
) -> PreparedMarkers:
    """Match, gap-fill, stabilise and filter a take for a solver (``animate``, ``solve-muscles``).

    Parameters
    ----------
    markers : MarkerSequence
        The take, all markers (unmapped head-band markers help stabilisation).
    scan : Mesh
        The scan the correspondence refers to.
    correspondence : Correspondence
        Marker label -> scan point map.
    rest_frame : int, default 0
        Frame whose expression matches the scan's.
    stabilize : bool, 'consensus' or sequence of str, default True
        Remove rigid head motion: ``True`` finds the head pose automatically
        (a head band, else the consensus of the skin markers, nothing on a
        still head), ``'consensus'`` always from the skin markers, a list of
        labels names the stable markers, ``False`` leaves the head as captured.
    smooth : bool, default True
        Apply the spatio-temporal bilateral filter (section 3).
    temporal_sigma_s : float or 'auto', default 'auto'
        Its temporal sigma in seconds, or chosen for the take by
        cross-validation (see :func:`~facecap.markers.condition_take`).

    Returns
    -------
    PreparedMarkers

    Raises
    ------
    MarkerError
        If the rest frame is out of range, every mapped marker is missing at
        the rest frame, or fewer than 4 markers are usable.
    """
    corr, columns, ignored = check_take_against_map(markers, correspondence, rest_frame)
    notes: list[str] = []
    if ignored:
        notes.append(f"markers not in the map, used only for stabilisation: {', '.join(ignored)}")
    raw = markers.positions

    conditioned = condition_take(
        markers, rest_frame=rest_frame, stabilize=stabilize, smooth=smooth, preferred_stable=ignored,
        temporal_sigma_s=temporal_sigma_s,
    )
    P = conditioned.positions
    P = P[:, columns]
    usable = ~np.isnan(P[rest_frame]).any(axis=1) & ~np.isnan(P).all(axis=(0, 2))
    if not usable.all():
        dropped = [corr.labels[i] for i in np.flatnonzero(~usable)]
        notes.append(f"markers never seen or unrecoverable at the rest frame, dropped: {', '.join(dropped)}")
    if usable.sum() < MIN_DRIVING_MARKERS:
        raise MarkerError(
            f"only {int(usable.sum())} usable marker(s) at the rest frame {rest_frame}; at least {MIN_DRIVING_MARKERS} are needed",
            path=markers.source_path,
        )
    keep = np.flatnonzero(usable)
    scan_points = corr.points(scan.vertices)[keep]
    constrained = corr.vertex_indices[keep, np.argmax(corr.weights[keep], axis=1)]
    n_filled = int(conditioned.filled[:, columns][:, keep].sum())
    if n_filled:
        notes.append(f"{n_filled} occluded marker samples filled")
    return PreparedMarkers(
        labels=tuple(corr.labels[i] for i in keep),
        positions=P[:, keep],
        raw_positions=raw[:, columns][:, keep],
        scan_points=scan_points,
        constrained_vertices=np.asarray(constrained, dtype=np.int64),
        filled=conditioned.filled[:, columns][:, keep],
        head_rotations=conditioned.head_rotations,
        head_translations=conditioned.head_translations,
        stabilization_residual=conditioned.stabilization_residual,
        stable_labels=conditioned.stable_labels,
        notes=notes,
        temporal_sigma_s=conditioned.temporal_sigma_s,
        temporal_sigma_choice=conditioned.temporal_sigma_choice,
        head_pose_from=conditioned.head_pose_from,
    )


def head_pose_in_scan(prepared: PreparedMarkers, sources: np.ndarray, targets: np.ndarray,
                       rest_frame: int) -> np.ndarray:
    """Head motion per frame as 4x4 transforms in scan coordinates (mm), absolute.

    The stabiliser maps frame t onto the rest frame in mocap space
    (``x' = S_t x``). The face is made in the frame of the warp's rest markers
    ``sources`` (``A``: them onto the scan, ``targets``); the head motion
    carries it back to where the capture saw it, in the scan's coordinates of
    the rest frame's *raw* capture (``W``: the rest frame's markers as
    captured onto the scan): ``P_t = W S_t^-1 A^-1``. Writing ``A S_t^-1 A^-1``
    instead assumed the face's frame is the rest frame's; the rest average and
    the smoothing of ``S_t`` move it by a few tenths of a degree, which then
    sat in every frame of the face in the world (a generated head-band take:
    0.52 mm against 0.25 with ``W``).
    """
    def as_matrix(fit: Any) -> np.ndarray:
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = fit.rotation, fit.translation
        return M

    A = as_matrix(rigid_fit(sources, targets))  # the face's frame: its rest markers -> the scan
    world = as_matrix(rigid_fit(prepared.raw_positions[rest_frame], targets))  # the capture at rest -> the scan
    if not np.all(np.isfinite(world)):
        world = A
    S = np.tile(np.eye(4), (prepared.head_rotations.shape[0], 1, 1))
    S[:, :3, :3], S[:, :3, 3] = prepared.head_rotations, prepared.head_translations
    return world[None] @ np.linalg.inv(S) @ np.linalg.inv(A)[None]


def rest_average(P: np.ndarray, rest_frame: int, sigma_frames: float, *, noise_mm: float | None = None) -> np.ndarray:
    """The rest frame's markers refined by a Gaussian average of the frames round it (K, 3), mm.

    Computed as the rest sample plus the weighted mean deviation from it (cut at
    2.5 sigma, within the take), so a still take keeps its rest frame (to rounding).
    Each frame of the window is first moved rigidly onto the rest frame (a
    least-squares fit of the markers both see), so a head that moves while the
    window lasts (a take left unstabilised) does not smear the average. With
    ``noise_mm``, each sample also counts by how close it stays to the rest
    sample (``exp(-(d / 3 noise)^2 / 2)``, a bilateral weight): a face that
    leaves its rest expression within the window (a take that starts to smile
    after 60 ms) does not pull the average towards the smile.
    """
    rest = P[rest_frame]
    if sigma_frames <= 0:
        return rest
    reach = int(2.5 * sigma_frames + 0.5)
    lo, hi = max(0, rest_frame - reach), min(P.shape[0], rest_frame + reach + 1)
    w = np.exp(-0.5 * ((np.arange(lo, hi) - rest_frame) / sigma_frames) ** 2)
    window = P[lo:hi]
    fit = rigid_fit(window, rest[None])
    moved = np.isfinite(fit.rotation).all(axis=(1, 2))
    window = np.where(moved[:, None, None], fit.apply(window), window)
    dev = window - rest[None]
    seen = np.isfinite(dev).all(axis=2)  # (window, K)
    weight = w[:, None] * seen
    if noise_mm is not None and noise_mm > 0:
        distance = np.linalg.norm(np.where(seen[..., None], dev, 0.0), axis=2)
        weight = weight * np.exp(-0.5 * (distance / (3.0 * noise_mm)) ** 2)
    mean_dev = np.einsum("tk,tkc->kc", weight, np.where(seen[..., None], dev, 0.0)) / weight.sum(axis=0)[:, None]
    return rest + mean_dev
