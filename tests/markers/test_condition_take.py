import numpy as np
import pytest

from facecap.errors import InputError, MarkerError
from facecap.markers.condition_take import condition_take, savitzky_golay
from facecap.synth import generate_performance


@pytest.fixture(scope="module")
def take():
    case = generate_performance(n_frames=120, seed=5, n_markers=40)
    return case


def test_prefers_rigid_head_band_markers_and_recovers_head_motion(take):
    band = [s for s in take.markers.labels if s.startswith("HB")]
    out = condition_take(take.markers, stabilize=True, smooth=False, preferred_stable=band)
    assert sorted(out.stable_labels) == sorted(band)
    # stabilised noiseless markers: every frame's head band sits where it was at frame 0
    cols = [take.markers.labels.index(s) for s in band]
    moved = np.einsum("tij,tkj->tki", out.head_rotations, take.noiseless_markers[:, cols]) + out.head_translations[:, None]
    assert np.abs(moved - take.noiseless_markers[0, cols]).max() < 1.0  # within marker noise
    assert out.filled.sum() == np.isnan(take.markers.positions).any(axis=2).sum()
    assert not np.isnan(out.positions).any()


def test_order_is_fill_then_stabilise_then_filter(take):
    out = condition_take(take.markers, stabilize=False, smooth=True)
    raw = condition_take(take.markers, stabilize=False, smooth=False)
    # the filter reduces the noise against the noiseless truth
    err_raw = np.linalg.norm(raw.positions - take.noiseless_markers, axis=2).mean()
    err = np.linalg.norm(out.positions - take.noiseless_markers, axis=2).mean()
    assert err < 0.7 * err_raw


def test_the_filters_temporal_sigma_is_chosen_for_the_take_or_given(take):
    from facecap.markers import bilateral_filter, choose_temporal_sigma

    raw = condition_take(take.markers, smooth=False)
    auto = condition_take(take.markers)  # the default: chosen by cross-validation
    choice = choose_temporal_sigma(raw.positions, rate=take.markers.rate)
    assert auto.temporal_sigma_s == choice.sigma_s == auto.temporal_sigma_choice.sigma_s
    np.testing.assert_array_equal(
        auto.positions, bilateral_filter(raw.positions, rate=take.markers.rate, temporal_sigma_s=choice.sigma_s))
    given = condition_take(take.markers, temporal_sigma_s=0.02)
    assert given.temporal_sigma_s == 0.02 and given.temporal_sigma_choice is None
    assert raw.temporal_sigma_s is None
    # on this noisy generated take the chosen window denoises at least as well as the earlier fixed 0.02 s
    error = {name: np.linalg.norm(c.positions - take.noiseless_markers, axis=2).mean()
             for name, c in (("auto", auto), ("given", given))}
    assert error["auto"] <= error["given"] + 1e-3


def test_bad_arguments(take):
    with pytest.raises(MarkerError, match="outside the take"):
        condition_take(take.markers, rest_frame=500)
    with pytest.raises(MarkerError, match="not in the take"):
        condition_take(take.markers, stabilize=["nope", "HB0", "HB1"])
    with pytest.raises(MarkerError, match="temporal_sigma_s"):
        condition_take(take.markers, temporal_sigma_s="wide")


def test_a_still_head_without_band_is_left_unstabilised_and_a_moving_one_is_not():
    # Strong, frequent expressions and skin markers only: on a still head the most rigid markers
    # still turn with the expressions, which stabilisation would add to every frame.
    from facecap.errors import FacecapWarning
    from facecap.synth import smooth_expression_curves
    from facecap.io.ict_sample import load_ict_sample

    names = load_ict_sample().expression_names
    W = smooth_expression_curves(400, names, rate=60, seed=21, expressions_per_second=1.5, intensity=(0.9, 1.0))
    common = dict(curves=W, seed=21, identity=[0.7, -0.5, 0.3], headband_markers=0)
    still = generate_performance(head_rotation_deg=0.0, head_translation_mm=0.0, **common)
    with pytest.warns(FacecapWarning, match="left unstabilised"):
        out = condition_take(still.markers, stabilize=True, smooth=False)
    assert out.head_rotations is None
    moving = generate_performance(head_rotation_deg=4.0, head_pivot="neck", **common)
    out = condition_take(moving.markers, stabilize=True, smooth=False)
    assert out.head_rotations is not None


def test_skin_head_pose_chooses_between_the_consensus_and_the_rigid_set() -> None:
    # Skin markers only, the head turning about the neck: 'rigid_set' is the most rigid set's own
    # per-frame fit, 'consensus' is consensus_stabilize started from it (both before smoothing).
    from facecap.markers import consensus_stabilize, fill_gaps, stabilize_head

    case = generate_performance(n_frames=200, seed=14, n_markers=60, headband_markers=0, head_rotation_deg=6.0,
                                head_pivot="neck", head_motion="turns")
    P = fill_gaps(case.markers.positions, rate=case.markers.rate).positions
    start = stabilize_head(P)
    consensus = consensus_stabilize(P, start=start)
    assert np.abs(consensus.rotations - start.rotations).max() > 1e-3  # the two poses differ
    for choice, expected in (("rigid_set", start), ("consensus", consensus)):
        out = condition_take(case.markers, stabilize=True, smooth=False, head_motion_sigma_s=0.0,
                             skin_head_pose=choice)
        np.testing.assert_allclose(out.head_rotations, expected.rotations, atol=1e-12)
    with pytest.raises(MarkerError, match="skin_head_pose"):
        condition_take(case.markers, stabilize=True, skin_head_pose="band")


@pytest.mark.parametrize(("n", "window", "order"), [(200, 31, 3), (13, 13, 3), (60, 7, 2), (40, 5, 4)])
def test_savitzky_golay_matches_scipy(n: int, window: int, order: int) -> None:
    # scipy.signal's filter (mode 'interp': the end samples from the end windows' fits) is the reference
    from scipy.signal import savgol_filter

    values = np.random.default_rng(n).normal(size=(n, 3)).cumsum(axis=0)
    expected = savgol_filter(values, window, order, axis=0, mode="interp")
    np.testing.assert_allclose(savitzky_golay(values, window, order), expected, rtol=0, atol=1e-9)


def test_savitzky_golay_keeps_a_polynomial_of_its_order() -> None:
    t = np.linspace(-1, 1, 50)
    cubic = np.stack([1 + 2 * t - t**2 + 0.5 * t**3, t**3], axis=1)
    np.testing.assert_allclose(savitzky_golay(cubic, 9, 3), cubic, atol=1e-12)
    with pytest.raises(InputError, match="odd"):
        savitzky_golay(cubic, 8, 3)
