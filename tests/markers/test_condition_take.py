import numpy as np
import pytest

from facecap.errors import MarkerError
from facecap.markers.condition_take import condition_take
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


def test_bad_arguments(take):
    with pytest.raises(MarkerError, match="outside the take"):
        condition_take(take.markers, rest_frame=500)
    with pytest.raises(MarkerError, match="not in the take"):
        condition_take(take.markers, stabilize=["nope", "HB0", "HB1"])
