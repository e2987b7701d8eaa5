"""principal_targets(_from_rig): exact on small rigs, error figures equal to brute force, streamed = rig."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.deform import principal_targets, principal_targets_from_rig
from facecap.errors import InputError

K, N, T = 12, 400, 90


def scalar_rig(seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((K, N))
    coefficients = rng.standard_normal((T, K, 3)) * np.linspace(3.0, 0.1, K)[None, :, None]
    frames = np.einsum("ki,tkc->tic", basis, coefficients)  # offsets, computed directly
    return basis, coefficients, frames


def vector_rig(seed: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    shapes = rng.standard_normal((K, N, 3))
    coefficients = rng.standard_normal((T, K)) * np.linspace(2.0, 0.2, K)
    return shapes, coefficients, np.einsum("kic,tk->tic", shapes, coefficients)


def brute_force(targets: np.ndarray, weights: np.ndarray, offsets: np.ndarray) -> dict[str, float]:
    rebuilt = np.einsum("tr,ric->tic", weights.astype(np.float64), targets.astype(np.float64))
    e = np.linalg.norm(offsets - rebuilt, axis=2)  # (T, n) vertex errors
    return {"max_mm": e.max(), "rms_mm": np.sqrt((e**2).mean()),
            "worst_frame_rms_mm": np.sqrt((e**2).mean(axis=1)).max(),
            "worst_vertex_rms_mm": np.sqrt((e**2).mean(axis=0)).max()}


@pytest.mark.parametrize("rig", [scalar_rig, vector_rig])
def test_small_rig_is_rebuilt_exactly(rig) -> None:
    basis, coefficients, offsets = rig()
    targets, weights, error = principal_targets_from_rig(basis, coefficients, max_targets=64)
    rank = 3 * K if basis.ndim == 2 else K
    assert targets.shape == (rank, N, 3) and weights.shape == (T, rank)
    assert error["rank"] == rank and error["n_targets"] == rank
    assert brute_force(targets, weights, offsets)["max_mm"] < 1e-4
    assert error["max_mm"] < 1e-4 and error["rms_mm"] < 1e-6
    np.testing.assert_allclose(np.abs(weights).max(axis=0), 1.0, rtol=1e-6)  # slider range



def test_a_basis_stored_vertex_by_vertex_gives_the_same_figures() -> None:
    # the thin shell's basis is Fortran-ordered (one vertex's K weights together); the per-vertex error
    # takes its own path through such blocks
    basis, coefficients, offsets = scalar_rig()
    by_vertex = np.asfortranarray(basis)
    targets, weights, error = principal_targets_from_rig(by_vertex, coefficients, max_targets=7)
    truth = brute_force(targets, weights, offsets)
    for key, value in truth.items():
        assert error[key] == pytest.approx(value, rel=1e-5), key
    _, _, error_c = principal_targets_from_rig(np.ascontiguousarray(basis), coefficients, max_targets=7)
    assert error["worst_vertex_rms_mm"] == pytest.approx(error_c["worst_vertex_rms_mm"], rel=1e-12)


def test_a_float32_basis_gives_the_targets_of_its_float64_copy_to_float32_rounding() -> None:
    basis, coefficients, offsets = scalar_rig()
    exact = principal_targets_from_rig(basis.astype(np.float32).astype(np.float64), coefficients, max_targets=64)
    single = principal_targets_from_rig(np.asfortranarray(basis.astype(np.float32)), coefficients, max_targets=64)
    scale = np.abs(exact.targets).max()
    assert np.abs(single.targets - exact.targets).max() < 2e-6 * scale
    assert single.error["rms_mm"] == pytest.approx(exact.error["rms_mm"], abs=1e-9)
    rebuilt = np.einsum("tr,ric->tic", single.weights.astype(np.float64), single.targets.astype(np.float64))
    assert np.abs(rebuilt - offsets).max() < 2e-5 * np.abs(offsets).max()  # the rank-36 take, rebuilt

@pytest.mark.parametrize("rig", [scalar_rig, vector_rig])
def test_error_figures_equal_brute_force(rig) -> None:
    basis, coefficients, offsets = rig()
    subset = np.arange(0, N, 3)
    targets, weights, error = principal_targets_from_rig(basis, coefficients, vertex_subset=subset, max_targets=7)
    assert targets.shape == (7, subset.size, 3)
    truth = brute_force(targets, weights, offsets[:, subset])
    for key, value in truth.items():
        assert error[key] == pytest.approx(value, rel=1e-5), key
    # Eckart-Young: no 7 targets do better; the SVD of the offsets directly gives the same RMS
    s = np.linalg.svd(offsets[:, subset].reshape(T, -1), compute_uv=False)
    assert error["rms_mm"] == pytest.approx(np.sqrt(np.sum(s[7:] ** 2) / (T * subset.size)), rel=1e-9)


def test_tolerance_keeps_the_fewest_targets() -> None:
    basis, coefficients, offsets = scalar_rig()
    _, _, error = principal_targets_from_rig(basis, coefficients, tolerance_mm=0.5)
    r = error["n_targets"]
    assert error["rms_mm"] <= 0.5
    fewer = principal_targets_from_rig(basis, coefficients, max_targets=r - 1).error
    assert fewer["rms_mm"] > 0.5


def test_streamed_take_matches_its_own_error_and_the_optimum() -> None:
    basis, coefficients, offsets = scalar_rig()
    rest = np.random.default_rng(5).uniform(-50, 50, (N, 3))
    frames = (rest + offsets).astype(np.float32)
    calls = []

    def blocks():
        calls.append(1)
        return ((s, frames[s:s + 16]) for s in range(0, T, 16))

    targets, weights, error = principal_targets(blocks, rest, n_frames=T, max_targets=7, power_iterations=2)
    assert len(calls) == 3 + 2 * 2
    truth = brute_force(targets, weights, frames.astype(np.float64) - rest)
    for key, value in truth.items():
        assert error[key] == pytest.approx(value, rel=1e-5), key
    optimum = principal_targets_from_rig(basis, coefficients, max_targets=7).error["rms_mm"]
    assert optimum * (1 - 1e-6) <= error["rms_mm"] <= 1.02 * optimum
    # rank within the sketch: exact
    _, _, exact = principal_targets(blocks, rest, n_frames=T, max_targets=40)
    assert exact["max_mm"] < 1e-4


def test_bad_input_raises() -> None:
    basis, coefficients, _ = scalar_rig()
    with pytest.raises(InputError, match="coefficients"):
        principal_targets_from_rig(basis, coefficients[:, :, :2])
    with pytest.raises(InputError, match="basis"):
        principal_targets_from_rig(basis[None], coefficients)
    with pytest.raises(InputError, match="vertex_subset"):
        principal_targets_from_rig(basis, coefficients, vertex_subset=[0, N])
    with pytest.raises(InputError, match="finite"):
        principal_targets_from_rig(np.where(basis > 2, np.nan, basis), coefficients)
    with pytest.raises(InputError, match="max_targets"):
        principal_targets_from_rig(basis, coefficients, max_targets=0)
    rest = np.zeros((N, 3))
    frames = np.zeros((T, N, 3), np.float32)
    with pytest.raises(InputError, match="never came"):
        principal_targets(lambda: iter([(0, frames[:10])]), rest, n_frames=T)
    with pytest.raises(InputError, match="expected"):
        principal_targets(lambda: iter([(0, frames[:, :5])]), rest, n_frames=T)
