"""Tests for facecap.blendshapes.select_scan_frames against a literal Algorithm 1 built on scipy.optimize.nnls."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import nnls
from scipy.spatial.transform import Rotation

from facecap.blendshapes import ScanPlan, select_scan_frames
from facecap.errors import InputError, MarkerError
from facecap.synth import generate_performance


def _brute_force(positions: np.ndarray, n_steps: int, first: int | None = None) -> tuple[list[int], list[float]]:
    """Algorithm 1 of Huang et al. 2011 as written: every candidate, NNLS for every frame.

    Returns the frames in the order chosen and the RMS per-marker error (mm) after each.
    Ties keep the earliest frame (``if error < minError``).
    """
    T, M, _ = positions.shape
    X = positions.reshape(T, -1).T
    chosen: list[int] = []
    errors: list[float] = []
    for step in range(n_steps):
        best, best_j = np.inf, -1
        for j in [first] if (step == 0 and first is not None) else range(T):
            if j in chosen:
                continue
            B = X[:, chosen + [j]]
            total = sum(nnls(B, X[:, t], maxiter=100 * B.shape[1])[1] ** 2 for t in range(T))
            if total < best:
                best, best_j = total, j
        chosen.append(best_j)
        errors.append(float(np.sqrt(best / (T * M))))
    return chosen, errors


@pytest.fixture(scope="module")
def face_take() -> np.ndarray:
    """A stabilised synthetic take (no head motion, no band, no gaps), 600 frames of 40
    markers at 60 Hz, in the mocap frame about 1.5 m from the origin."""
    case = generate_performance(
        n_frames=600, n_markers=40, rate=60.0, headband_markers=0, head_rotation_deg=0.0,
        head_translation_mm=0.0, gap_fraction=0.0, noise_mm=0.1, seed=3,
    )
    return case.markers.positions


@pytest.mark.parametrize("kind", ["face", "face_centred", "random"])
def test_same_choice_as_brute_force(kind: str, face_take: np.ndarray) -> None:
    rng = np.random.default_rng(7)
    if kind == "random":
        P = rng.normal(size=(60, 20, 3)) * 10.0 + [40.0, 0.0, 20.0]
    else:
        P = face_take[::10, ::2]  # 60 frames spread over the performance, 20 markers
        if kind == "face_centred":
            P = P - P.mean(axis=(0, 1))
    frames, errors = _brute_force(P, 5)
    plan = select_scan_frames(P, tolerance=0.0, max_frames=5)
    assert plan.frames.tolist() == frames
    np.testing.assert_allclose(plan.error_after_each, errors, rtol=1e-9)


def test_rest_frame_is_taken_first(face_take: np.ndarray) -> None:
    P = face_take[5::12, 1::3]
    frames, errors = _brute_force(P, 3, first=17)
    plan = select_scan_frames(P, tolerance=0.0, max_frames=3, rest_frame=17)
    assert plan.frames.tolist() == frames and frames[0] == 17
    np.testing.assert_allclose(plan.error_after_each, errors, rtol=1e-9)


def test_error_decreases_and_tolerance_is_met_at_the_first_set_that_meets_it(face_take: np.ndarray) -> None:
    P = face_take[::2]
    plan = select_scan_frames(P, tolerance=0.002, rate=60.0)
    err = plan.error_after_each
    worst = plan.worst_frame_after_each
    assert plan.converged and worst[-1] <= plan.tolerance_mm
    assert np.all(worst[:-1] > plan.tolerance_mm)  # stopped at the first set meeting it
    assert np.all(np.diff(err) < 0) and np.all(np.diff(worst) <= 1e-12)
    assert worst[-1] == pytest.approx(plan.per_frame_residual.max(), rel=1e-9)
    rms_plan = select_scan_frames(P, tolerance=0.002, rate=60.0, stop_on="rms")
    rms_err = rms_plan.error_after_each
    assert rms_err[-1] <= plan.tolerance_mm and np.all(rms_err[:-1] > plan.tolerance_mm)
    np.testing.assert_array_equal(rms_plan.frames, plan.frames[: rms_plan.n_frames])  # same order, earlier stop
    flat = P.reshape(-1, 3)
    assert plan.diagonal_mm == pytest.approx(np.linalg.norm(flat.max(0) - flat.min(0)), rel=1e-12)
    assert plan.tolerance_mm == pytest.approx(0.002 * plan.diagonal_mm, rel=1e-12)
    # weights and residuals describe the same reconstruction, and are NNLS optimal
    T, M, _ = P.shape
    X = P.reshape(T, -1).T
    B = X[:, plan.frames]
    assert plan.weights.shape == (plan.n_frames, T) and np.all(plan.weights >= 0)
    fit = np.linalg.norm((B @ plan.weights - X).reshape(M, 3, T), axis=1)  # (M, T) distances
    np.testing.assert_allclose(plan.per_frame_residual, np.sqrt((fit**2).mean(axis=0)), rtol=1e-9, atol=1e-9)
    assert np.sqrt((fit**2).mean()) == pytest.approx(err[-1], rel=1e-9)
    for t in range(0, T, 37):
        assert np.linalg.norm(B @ plan.weights[:, t] - X[:, t]) == pytest.approx(nnls(B, X[:, t])[1], rel=1e-9, abs=1e-9)
    np.testing.assert_allclose(plan.times, plan.frames / 60.0)


def test_frames_on_k_rays_need_exactly_k_scans() -> None:
    """Every frame is a positive multiple of one of K poses (+ tiny noise): each pick covers
    one ray, a second pick on a covered ray gains nothing, so greedy takes one frame per ray."""
    rng = np.random.default_rng(8)
    K, T, M = 5, 150, 25
    poses = rng.normal(size=(K, M, 3)) * 20.0 + [0.0, 0.0, 300.0]
    ray = rng.integers(K, size=T)
    ray[:K] = np.arange(K)
    P = poses[ray] * rng.uniform(0.8, 1.2, size=(T, 1, 1)) + rng.normal(size=(T, M, 3)) * 1e-3
    plan = select_scan_frames(P, tolerance=0.01 / np.linalg.norm(np.ptp(P.reshape(-1, 3), axis=0)))
    assert plan.converged and plan.n_frames == K
    assert sorted(ray[plan.frames].tolist()) == list(range(K))
    # the noise level: frame and basis both carry 1e-3 mm per axis, sqrt(3 * 2) * 1e-3 mm
    assert plan.error_after_each[-1] < 3e-3


def test_blends_of_k_frames_are_rebuilt_to_the_noise_level() -> None:
    """A take of non-negative blends of K of its own frames: the chosen frames rebuild every
    frame to the noise. (Greedy need not stop at K here: its first picks are blends, which
    explain most frames at once but leave the extreme frames to be added too.)"""
    rng = np.random.default_rng(9)
    K, T, M = 4, 120, 20
    keys = rng.normal(size=(K, M, 3)) * 15.0 + [0.0, 0.0, 1000.0]
    w = rng.random((T, K)) ** 2
    w[:K] = np.eye(K)
    noise = 1e-3
    P = np.einsum("tk,kmc->tmc", w, keys) + rng.normal(size=(T, M, 3)) * noise
    diagonal = np.linalg.norm(np.ptp(P.reshape(-1, 3), axis=0))
    plan = select_scan_frames(P, tolerance=3 * noise / diagonal)
    assert plan.converged and plan.error_after_each[-1] <= 3 * noise
    assert plan.per_frame_residual.max() < 6 * noise


def test_rotation_and_marker_order_do_not_change_the_choice(face_take: np.ndarray) -> None:
    # eq. (3) only sees inner products of frames: a rigid rotation about the origin and a
    # permutation of the markers leave every candidate's error unchanged
    P = face_take[::6, :20]
    plan = select_scan_frames(P, tolerance=0.0, max_frames=5)
    R = Rotation.from_rotvec([0.3, -0.7, 0.2]).as_matrix()
    Q = (P @ R.T)[:, np.random.default_rng(0).permutation(P.shape[1])]
    moved = select_scan_frames(Q, tolerance=0.0, max_frames=5)
    assert moved.frames.tolist() == plan.frames.tolist()
    np.testing.assert_allclose(moved.error_after_each, plan.error_after_each, rtol=1e-9)


def test_max_frames_stops_before_the_tolerance() -> None:
    P = np.random.default_rng(10).normal(size=(40, 10, 3))
    plan = select_scan_frames(P, tolerance=0.0, max_frames=3)
    assert plan.n_frames == 3 and not plan.converged
    assert plan.error_after_each[-1] > 0


def test_to_dict_is_json_ready_with_timecodes(face_take: np.ndarray) -> None:
    P = face_take[:200, :12]
    plan = select_scan_frames(P, max_frames=4, rate=60.0, first_frame=100)
    d = json.loads(json.dumps(plan.to_dict(include_weights=True)))
    assert d["frames"] == plan.frames.tolist()
    assert d["capture_frames"] == [100 + f for f in plan.frames.tolist()]
    assert d["times_s"] == pytest.approx((plan.frames / 60.0).tolist())
    assert np.asarray(d["weights"]).shape == (plan.n_frames, 200)
    for f, tc in zip(d["capture_frames"], d["timecodes"]):
        hh, mm, ss, ff = map(int, tc.split(":"))
        assert ((hh * 60 + mm) * 60 + ss) * 60 + ff == f
    # the format itself, on a hand-made plan: 24 fps, one hour, one minute, one second and 5 frames
    hand = ScanPlan(
        frames=np.array([5]), times=np.array([5 / 24]), error_after_each=np.array([0.1]),
        worst_frame_after_each=np.array([0.2]), per_frame_residual=np.zeros(10), tolerance_mm=0.1, diagonal_mm=100.0, weights=np.ones((1, 10)),
        converged=True, tolerance=0.001, rate=24.0, first_frame=24 * 3661,
    )
    assert hand.timecodes() == ["01:01:01:05"]
    assert hand.to_dict()["timecodes"] == ["01:01:01:05"] and "weights" not in hand.to_dict()
    no_rate = select_scan_frames(P, max_frames=1)
    assert no_rate.times is None and no_rate.to_dict()["timecodes"] is None


def test_rejects_bad_input() -> None:
    P = np.random.default_rng(12).normal(size=(10, 4, 3))
    Q = P.copy()
    Q[3, 1] = np.nan
    with pytest.raises(MarkerError, match="fill_gaps"):
        select_scan_frames(Q)
    with pytest.raises(MarkerError, match=r"\(T, M, 3\)"):
        select_scan_frames(P[:, :, :2])
    with pytest.raises(MarkerError, match="one point"):
        select_scan_frames(np.ones((5, 3, 3)))
    with pytest.raises(InputError, match="tolerance"):
        select_scan_frames(P, tolerance=-0.1)
    with pytest.raises(InputError, match="max_frames"):
        select_scan_frames(P, max_frames=0)
    with pytest.raises(InputError, match="rest_frame"):
        select_scan_frames(P, rest_frame=10)
    with pytest.raises(InputError, match="rate"):
        select_scan_frames(P, rate=0.0)
    with pytest.raises(InputError, match="first_frame"):
        select_scan_frames(P, first_frame=-1)
