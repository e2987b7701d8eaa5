"""Synthetic facial performances with dense ground truth, for tests, benchmarks and the demo."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from ..errors import InputError
from ..structures import MarkerSequence, Mesh
from .expression_curves import smooth_expression_curves
from .ict_sample import IctSample, load_ict_sample
from .marker_layout import choose_marker_vertices

__all__ = ["SyntheticCase", "generate_performance", "vertex_normals_at"]


@dataclass(frozen=True, eq=False)
class SyntheticCase:
    """A generated capture with everything that made it.

    Attributes
    ----------
    scan : Mesh
        The actor's neutral face: the mesh to animate (mm).
    markers : MarkerSequence
        The take, in the mocap system's frame: face markers ``M000...`` and
        head-band markers ``HB0...`` (rigid with the head, not in the map).
    correspondence : dict of str to int
        Face marker label -> scan vertex (what a user picks by hand).
    truth_vertices : (T, n, 3) float32 array, mm
        The dense expression in the scan's frame, without head motion.
    head_pose : (T, 4, 4) float64 array
        Rigid head motion in scan coordinates (mm): the face at frame t is
        ``head_pose[t]`` applied to ``truth_vertices[t]``.
    mocap_from_scan : (4, 4) float64 array
        Fixed rigid transform from the scan's frame to the mocap system's.
    weights : (T, k) float64 array
        The blendshape weights that drove the expression.
    marker_vertices : (M,) int64 array
        Scan vertex under each face marker, in label order.
    noiseless_markers : (T, M + H, 3) float64 array, mm
        The markers before noise and gaps.
    """

    scan: Mesh
    markers: MarkerSequence
    correspondence: dict[str, int]
    truth_vertices: np.ndarray
    head_pose: np.ndarray
    mocap_from_scan: np.ndarray
    weights: np.ndarray
    marker_vertices: np.ndarray
    noiseless_markers: np.ndarray


def vertex_normals_at(V: np.ndarray, F: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Area-weighted unit normals at some vertices, for one or many frames.

    Parameters
    ----------
    V : (n, 3) or (T, n, 3) float array
    F : (m, 3) int64 array
    vertices : (k,) int64 array

    Returns
    -------
    (k, 3) or (T, k, 3) float64 array
    """
    vertices = np.asarray(vertices, dtype=np.int64)
    incident = np.isin(F, vertices).any(axis=1)
    Fi = F[incident]
    X = np.asarray(V, dtype=np.float64)
    face_normals = np.cross(X[..., Fi[:, 1], :] - X[..., Fi[:, 0], :], X[..., Fi[:, 2], :] - X[..., Fi[:, 0], :])
    row = np.full(V.shape[-2], -1)
    row[vertices] = np.arange(vertices.size)
    r = row[Fi].ravel()
    c = np.repeat(np.arange(Fi.shape[0]), 3)
    keep = r >= 0
    S = sp.csr_matrix((np.ones(keep.sum()), (r[keep], c[keep])), shape=(vertices.size, Fi.shape[0]))
    N = np.stack([(S @ face_normals[..., a].T).T for a in range(3)], axis=-1)
    return N / np.linalg.norm(N, axis=-1, keepdims=True)


def _smooth_signal(rng: np.random.Generator, t: np.ndarray, n: int) -> np.ndarray:
    """n smooth signals in [-1, 1]: sums of slow sinusoids (0.1-0.6 Hz), one per column."""
    out = np.zeros((t.size, n))
    for j in range(n):
        for _ in range(3):
            out[:, j] += rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
        out[:, j] /= max(float(np.abs(out[:, j]).max()), 1e-12)
    return out


def _rigid(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def generate_performance(
    *,
    n_frames: int = 240,
    rate: float = 60.0,
    n_markers: int = 90,
    identity: np.ndarray | None = None,
    curves: np.ndarray | None = None,
    marker_vertices: np.ndarray | None = None,
    marker_offset_mm: float = 1.5,
    noise_mm: float = 0.2,
    gap_fraction: float = 0.02,
    head_rotation_deg: float = 4.0,
    head_translation_mm: float = 5.0,
    headband_markers: int = 4,
    seed: int = 0,
    sample: IctSample | None = None,
) -> SyntheticCase:
    """Generate a facial mocap take on the ICT face with dense ground truth.

    The expression is ``face + weights(t) @ expression_deltas`` (smooth,
    performance-like curves); markers sit ``marker_offset_mm`` above the skin
    along the normal, move with the expression and the rigid head motion, are
    seen in a different rigid frame than the scan (Z-up, a metre away), with
    Gaussian noise and occlusion gaps, as an optical system would give them.

    Parameters
    ----------
    n_frames : int, default 240
    rate : float, default 60.0
        Frame rate, Hz.
    n_markers : int, default 90
        Face markers (ignored when ``marker_vertices`` is given).
    identity : (k,) float array, optional
        ICT identity coefficients (k <= 8): who the actor is. Default: the
        generic face.
    curves : (n_frames, 53) float array, optional
        Blendshape weights; default :func:`smooth_expression_curves`.
    marker_vertices : (M,) int array, optional
        Marker layout; default :func:`choose_marker_vertices`.
    marker_offset_mm : float, default 1.5
        Marker centre height above the skin (half a 3 mm marker).
    noise_mm : float, default 0.2
        Standard deviation of the per-axis Gaussian noise.
    gap_fraction : float, default 0.02
        Fraction of marker samples occluded, in runs of 3-30 frames; frame 0
        is always complete.
    head_rotation_deg, head_translation_mm : float, default 4.0, 5.0
        Amplitude of the smooth rigid head motion (about a pivot in the neck).
    headband_markers : int, default 4
        Markers on a head band 15 mm off the forehead and temples.
    seed : int, default 0
    sample : IctSample, optional
        Default: the bundled sample.

    Returns
    -------
    SyntheticCase
    """
    if n_frames < 2:
        raise InputError(f"n_frames: expected at least 2, got {n_frames}")
    if not 0 <= gap_fraction < 0.5:
        raise InputError(f"gap_fraction: expected a fraction in [0, 0.5), got {gap_fraction}")
    rng = np.random.default_rng(seed)
    sample = sample or load_ict_sample()
    scan = sample.face(identity)
    V0, F = scan.vertices, scan.faces
    names = sample.expression_names
    if curves is None:
        W = smooth_expression_curves(n_frames, names, rate=rate, seed=seed)
    else:
        W = np.asarray(curves, dtype=np.float64)
        if W.shape != (n_frames, len(names)):
            raise InputError(f"curves: expected shape ({n_frames}, {len(names)}), got {W.shape}")
    truth = V0.astype(np.float32)[None] + np.tensordot(W.astype(np.float32), sample.expression_deltas, axes=1)

    if marker_vertices is None:
        mv = choose_marker_vertices(V0, F, sample.expression_deltas, n_markers, seed=seed)
    else:
        mv = np.asarray(marker_vertices, dtype=np.int64)
    normals = vertex_normals_at(truth, F, mv)  # (T, M, 3)
    face_markers = truth[:, mv].astype(np.float64) + marker_offset_mm * normals

    # head band: a ring of markers 15 mm off the skin, from the temples over the top of the
    # forehead, rigid with the skull; spread in height and depth so they fix all three rotations
    band = np.zeros((0, 3))
    if headband_markers > 0:
        nose_tip_z = V0[:, 2].max()
        upper = V0[V0[:, 1] > np.percentile(V0[:, 1], 70)]
        angles = np.linspace(-1.1, 1.1, headband_markers)  # radians around the head, 0 = front
        centre_z = nose_tip_z - 110.0
        radius = np.ptp(upper[:, 0]) / 2 + 15.0
        heights = upper[:, 1].max() - 15.0 - 35.0 * np.abs(angles) / 1.1
        band = np.stack([radius * np.sin(angles), heights, centre_z + radius * np.cos(angles) * 0.9], axis=1)
        band += rng.normal(scale=2.0, size=band.shape)
    points = np.concatenate([face_markers, np.broadcast_to(band, (n_frames, band.shape[0], 3))], axis=1)

    t = np.arange(n_frames) / rate
    pivot = np.array([0.0, V0[:, 1].min() + 20.0, V0[:, 2].min() - 40.0])
    rotvec = np.deg2rad(head_rotation_deg) * _smooth_signal(rng, t, 3) / np.sqrt(3)
    shift = head_translation_mm * _smooth_signal(rng, t, 3) / np.sqrt(3)
    R = Rotation.from_rotvec(rotvec).as_matrix()
    head_pose = np.tile(np.eye(4), (n_frames, 1, 1))
    head_pose[:, :3, :3] = R
    head_pose[:, :3, 3] = pivot - np.einsum("tij,j->ti", R, pivot) + shift
    mocap_from_scan = _rigid(
        Rotation.from_euler("xyz", [90.0 + rng.uniform(-10, 10), rng.uniform(-20, 20), rng.uniform(-180, 180)],
                            degrees=True).as_matrix(),
        np.array([rng.uniform(-500, 500), rng.uniform(-500, 500), 1500.0]),
    )
    world = mocap_from_scan[None] @ head_pose  # (T, 4, 4)
    noiseless = np.einsum("tij,tkj->tki", world[:, :3, :3], points) + world[:, None, :3, 3]
    observed = noiseless + rng.normal(scale=noise_mm, size=noiseless.shape) if noise_mm > 0 else noiseless.copy()

    n_total = observed.shape[1]
    if gap_fraction > 0:
        target = gap_fraction * n_frames * n_total
        missing = np.zeros((n_frames, n_total), dtype=bool)
        while missing.sum() < target:
            marker = rng.integers(n_total)
            length = int(rng.integers(3, 31))
            start = int(rng.integers(1, max(2, n_frames - 1)))
            missing[start : start + length, marker] = True
        missing[0] = False
        observed[missing] = np.nan

    labels = tuple(f"M{i:03d}" for i in range(mv.size)) + tuple(f"HB{i}" for i in range(band.shape[0]))
    markers = MarkerSequence(observed, labels, rate=rate, source_unit="mm", source_path="<generated>")
    return SyntheticCase(
        scan=scan,
        markers=markers,
        correspondence={labels[i]: int(v) for i, v in enumerate(mv)},
        truth_vertices=truth,
        head_pose=head_pose,
        mocap_from_scan=mocap_from_scan,
        weights=W,
        marker_vertices=mv,
        noiseless_markers=noiseless,
    )
