"""Synthetic marker takes with known truth, shared by the marker-conditioning tests, and one generated case with its
scan stored in each length unit, shared by the scan-unit and take-unit checks."""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import pytest
from scipy.spatial.transform import Rotation


class SyntheticTake(NamedTuple):
    positions: np.ndarray  # (T, M, 3) mm, observed (moving head)
    local: np.ndarray  # (T, M, 3) mm, head-local positions (deformation only)
    rotations: np.ndarray  # (T, 3, 3) head rotation: positions = local @ R^T + c
    translations: np.ndarray  # (T, 3) mm
    rest: np.ndarray  # (M, 3) mm, undeformed head-local layout
    rate: float


def sphere_points(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` points spread over the front half of a sphere (a face-like cap), mm."""
    golden = np.pi * (3.0 - np.sqrt(5.0))
    k = np.arange(n)
    z = 1.0 - (k + 0.5) / n  # front hemisphere, z in (0, 1)
    r = np.sqrt(1.0 - z * z)
    phi = golden * k + rng.uniform(0, 2 * np.pi)
    return radius * np.c_[r * np.cos(phi), r * np.sin(phi), z]


def make_take(
    *,
    n_frames: int = 600,
    n_markers: int = 40,
    rate: float = 120.0,
    deformation_mm: float = 0.0,
    rotation_deg: float = 20.0,
    translation_mm: float = 30.0,
    rigid_markers: int = 0,
    seed: int = 0,
) -> SyntheticTake:
    """Markers on a 90 mm sphere, moving rigidly and smoothly, plus smooth local deformation.

    The first ``rigid_markers`` markers sit on a ring behind the face (a
    "headband") and never deform. Head rotation and translation are smooth
    (sums of a few low-frequency sines, < 1.5 Hz); the deformation is a smooth
    field of amplitude ``deformation_mm``, varying over ~60 mm and < 2 Hz.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / rate
    face = sphere_points(n_markers - rigid_markers, 90.0, rng)
    ang = np.linspace(0, 2 * np.pi, rigid_markers, endpoint=False) + 0.3
    band = np.c_[100 * np.cos(ang), 100 * np.sin(ang), -20 + 15 * np.sin(3 * ang)] if rigid_markers else np.zeros((0, 3))
    rest = np.concatenate([band, face])

    # smooth local deformation: d_i(t) = sum_k a_k(t) * sin(w_k . x_i + p_k) e_k
    n_modes = 4
    wvec = rng.normal(size=(n_modes, 3)) / 60.0
    phase = rng.uniform(0, 2 * np.pi, n_modes)
    direc = rng.normal(size=(n_modes, 3))
    direc /= np.linalg.norm(direc, axis=1, keepdims=True)
    freq = rng.uniform(0.3, 2.0, n_modes)
    tphase = rng.uniform(0, 2 * np.pi, n_modes)
    amp = np.sin(2 * np.pi * freq[None] * t[:, None] + tphase[None])  # (T, K)
    spatial = np.sin(face @ wvec.T + phase[None])  # (Mf, K)
    disp = np.einsum("tk,mk,kd->tmd", amp, spatial, direc) * deformation_mm / np.sqrt(n_modes)
    local = np.broadcast_to(rest, (n_frames,) + rest.shape).copy()
    local[:, rigid_markers:] += disp

    # smooth head motion
    rot_freq = rng.uniform(0.2, 1.5, (3, 3))
    rot_phase = rng.uniform(0, 2 * np.pi, (3, 3))
    rotvec = np.deg2rad(rotation_deg) / 3 * np.sin(2 * np.pi * rot_freq[None] * t[:, None, None] + rot_phase[None]).sum(axis=2)
    R = Rotation.from_rotvec(rotvec).as_matrix()
    tr_freq = rng.uniform(0.2, 1.5, 3)
    c = translation_mm * np.sin(2 * np.pi * tr_freq[None] * t[:, None] + rng.uniform(0, 6, 3)[None])
    c = c + np.array([5.0, -300.0, 1500.0])
    P = np.einsum("tij,tmj->tmi", R, local) + c[:, None, :]
    return SyntheticTake(P, local, R, c, rest, rate)


@pytest.fixture
def synthetic_take() -> Callable[..., SyntheticTake]:
    """Factory fixture: ``synthetic_take(**options)`` returns a :class:`SyntheticTake`."""
    return make_take


@pytest.fixture(scope="session")
def case():
    """A short synthetic take with its scan (shared by the scan-unit and take-unit tests; tests must not change it)."""
    from facecap.synth import generate_performance

    return generate_performance(n_frames=20, seed=0)


@pytest.fixture(scope="session")
def written(case, tmp_path_factory):
    """The same case with its scan stored in each unit."""
    from facecap.synth import write_synthetic_case

    root = tmp_path_factory.mktemp("units")
    return {unit: write_synthetic_case(case, root / unit, scan_unit=unit) for unit in ("mm", "cm", "m", "in")}
